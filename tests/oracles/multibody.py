"""A planar multibody in full coordinates with Lagrange multipliers: the tests' independent oracle
for linkages of one or several degrees of freedom (not shipped).

Written from the physics, sharing nothing with loopcheck's kinematics or engines. Each moving body
i has the coordinates (x_i, y_i, θ_i): its centre of mass and its frame's angle. A point s of the
body's frame (m) is at

    r = r_G + R(θ) (s − c),        c: the centre of mass in the body's frame,

and each revolute joint asks two such points, of two bodies or of a body and the ground, to
coincide: Φ(q) = 0. With M = diag(m, m, I_G) per body and Φ_q the constraints' Jacobian,

    [ M    Φ_qᵀ ] [ q̈ ]   [ Q ]
    [ Φ_q   0   ] [ λ  ] = [ γ ],     γ = −(Φ_q q̇)_q q̇ = Σ ± θ̇² R(θ) u   (u = s − c),

the index-1 form of the equations of motion (a ``redundant`` model, whose pins close a loop with
dependent rows, takes Φ_q q̈ = γ on an orthonormal basis of Φ_q's rows, by its SVD: the same q̈).
Q holds gravity, the joints' torques (τ on the body ``b`` of a joint, −τ on its body ``a``, for
the relative angle θ_b − θ_a), the torsion springs on a joint's relative angle (τ = −k (θ_b − θ_a −
u0), the same way round; potential ½ k (θ_b − θ_a − u0)², counted in the energy) and the
point-to-point dampers (force −c ḋ along the line between their points). The work of the torques
and the dampers' dissipation are integrated alongside, for the energy balance.

``simulate`` integrates it with scipy's DOP853 (restarted at every load edge) and states its own
accuracy: the largest differences of the body angles and of their rates between rtol and rtol / 2 — a
test compares an engine only to within more than those. The constraint's drift (|Φ| at the end,
with no stabilization) is reported too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np
from scipy.integrate import solve_ivp

GROUND = "ground"


def _rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


_PERP = np.array([[0.0, -1.0], [1.0, 0.0]])  # d/dθ R(θ) = PERP R(θ)


@dataclass(frozen=True)
class Body:
    name: str
    mass: float          # kg
    com: tuple           # m, in the body's frame
    inertia: float       # kg·m², about the centre of mass


@dataclass(frozen=True)
class Pin:
    """A revolute joint: point ``sa`` of body ``a`` on point ``sb`` of body ``b`` (frames' m;
    ``a`` may be the ground, its ``sa`` then in the world)."""
    name: str
    a: str
    sa: tuple
    b: str
    sb: tuple


@dataclass(frozen=True)
class Damper:
    a: str
    sa: tuple
    b: str
    sb: tuple
    coefficient: float  # N·s/m


@dataclass(frozen=True)
class Torque:
    """τ(t) (N·m) across a pin: on its body b, and −τ on its body a. Constant between the model's
    ``edges`` (it is read at the middle of each piece). With ``state``, τ(t, u, u̇) instead: a law
    of the pin's relative angle u = θ_b − θ_a (rad) and its rate (a servo)."""
    pin: str
    value: Callable[..., float]
    state: bool = False


@dataclass(frozen=True)
class TorsionSpring:
    """A torsion spring across a pin: τ = −k (θ_b − θ_a − u0) on its body b, −τ on its body a (the
    ground's angle 0); potential ½ k (θ_b − θ_a − u0)²."""
    pin: str
    stiffness: float    # N·m/rad
    rest: float = 0.0   # rad


@dataclass(frozen=True)
class Lock:
    """A pin held at its relative angle ``value`` (rad): one more constraint row θ_b − θ_a − value
    = 0 (Jacobian row: the pin's angle row, γ = 0); its multiplier μ gives the holding torque
    τ = −μ on the pin (on its body b, −τ on its body a): a stuck joint friction."""
    pin: str
    value: float


@dataclass(frozen=True)
class Model:
    bodies: tuple
    pins: tuple
    dampers: tuple = ()
    torques: tuple = ()
    springs: tuple = ()                          # TorsionSpring
    gravity: float = 0.0                         # m/s², along −y
    edges: tuple = ()                            # s: where a torque jumps (the integrator restarts)
    redundant: bool = False                      # pins that close a loop redundantly (accelerations)
    locks: tuple = ()                            # Lock: pins held (a stuck friction)
    index: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "index", {b.name: i for i, b in enumerate(self.bodies)})

    @property
    def n(self) -> int:
        return 3 * len(self.bodies)

    def _point(self, body: str, s, q):
        """(position, u rotated, body index or None) of point s of ``body``."""
        if body == GROUND:
            return np.asarray(s, float), None, None
        i = self.index[body]
        b = self.bodies[i]
        u = _rot(q[3 * i + 2]) @ (np.asarray(s, float) - np.asarray(b.com, float))
        return q[3 * i:3 * i + 2] + u, u, i

    def residual(self, q) -> np.ndarray:
        out = []
        for p in self.pins:
            ra, _, _ = self._point(p.a, p.sa, q)
            rb, _, _ = self._point(p.b, p.sb, q)
            out.append(ra - rb)
        out.append(np.array([self.relative(lock.pin, q) - lock.value for lock in self.locks]))
        return np.concatenate(out)

    def jacobian(self, q) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """Φ_q, and γ(q̇)."""
        J = np.zeros((2 * len(self.pins) + len(self.locks), self.n))
        for k, lock in enumerate(self.locks):
            J[2 * len(self.pins) + k] = self.angle_row(lock.pin)
        terms = []
        for k, p in enumerate(self.pins):
            for body, s, sign in ((p.a, p.sa, 1.0), (p.b, p.sb, -1.0)):
                _, u, i = self._point(body, s, q)
                if i is None:
                    continue
                J[2 * k:2 * k + 2, 3 * i:3 * i + 2] += sign * np.eye(2)
                J[2 * k:2 * k + 2, 3 * i + 2] += sign * (_PERP @ u)
                terms.append((k, i, sign, u))

        def gamma(qd):
            g = np.zeros(2 * len(self.pins) + len(self.locks))
            for k, i, sign, u in terms:
                g[2 * k:2 * k + 2] += sign * qd[3 * i + 2] ** 2 * u
            return g
        return J, gamma

    def mass(self) -> np.ndarray:
        return np.diag(np.concatenate([[b.mass, b.mass, b.inertia] for b in self.bodies]))

    def relative(self, pin: str, q) -> float:
        """θ_b − θ_a of a pin (rad; the ground's angle 0), from q or q̇."""
        p = next(p for p in self.pins if p.name == pin)
        angle = 0.0
        if p.b != GROUND:
            angle += q[3 * self.index[p.b] + 2]
        if p.a != GROUND:
            angle -= q[3 * self.index[p.a] + 2]
        return float(angle)

    def _point_velocity(self, body, s, q, qd):
        r, u, i = self._point(body, s, q)
        if i is None:
            return r, np.zeros(2), None, None
        return r, qd[3 * i:3 * i + 2] + qd[3 * i + 2] * (_PERP @ u), u, i

    def forces(self, t, q, qd) -> tuple[np.ndarray, float, float]:
        """Q, the torques' power (W) and the dampers' dissipation rate (W)."""
        Q = np.zeros(self.n)
        for i, b in enumerate(self.bodies):
            Q[3 * i + 1] -= b.mass * self.gravity
        power = 0.0
        pins = {p.name: p for p in self.pins}
        for torque in self.torques:
            p = pins[torque.pin]
            angle = rate = 0.0
            if p.b != GROUND:
                angle += q[3 * self.index[p.b] + 2]
                rate += qd[3 * self.index[p.b] + 2]
            if p.a != GROUND:
                angle -= q[3 * self.index[p.a] + 2]
                rate -= qd[3 * self.index[p.a] + 2]
            tau = torque.value(t, angle, rate) if torque.state else torque.value(t)
            if p.b != GROUND:
                Q[3 * self.index[p.b] + 2] += tau
            if p.a != GROUND:
                Q[3 * self.index[p.a] + 2] -= tau
            power += tau * rate
        for spring in self.springs:
            p = pins[spring.pin]
            tau = -spring.stiffness * (self.relative(spring.pin, q) - spring.rest)
            if p.b != GROUND:
                Q[3 * self.index[p.b] + 2] += tau
            if p.a != GROUND:
                Q[3 * self.index[p.a] + 2] -= tau
        dissipation = 0.0
        for d in self.dampers:
            ra, va, ua, ia = self._point_velocity(d.a, d.sa, q, qd)
            rb, vb, ub, ib = self._point_velocity(d.b, d.sb, q, qd)
            n = (rb - ra) / np.linalg.norm(rb - ra)
            ddot = float(n @ (vb - va))
            f = -d.coefficient * ddot  # on b along n, on a along −n
            for i, u, sign in ((ib, ub, 1.0), (ia, ua, -1.0)):
                if i is None:
                    continue
                Q[3 * i:3 * i + 2] += sign * f * n
                Q[3 * i + 2] += sign * f * float(n @ (_PERP @ u))
            dissipation += d.coefficient * ddot ** 2
        return Q, power, dissipation

    def accelerations(self, t, q, qd) -> tuple[np.ndarray, float, float]:
        qdd, _, power, dissipation = self.solve(t, q, qd)
        return qdd, power, dissipation

    def holding(self, t, q, qd) -> np.ndarray:
        """Each lock's holding torque τ = −μ (N·m, on the pin's relative angle)."""
        _, mu, _, _ = self.solve(t, q, qd)
        return -mu[len(mu) - len(self.locks):]

    def solve(self, t, q, qd) -> tuple[np.ndarray, np.ndarray, float, float]:
        """q̈, the multipliers μ, the torques' power and the dampers' dissipation."""
        M = self.mass()
        J, gamma = self.jacobian(q)
        Q, power, dissipation = self.forces(t, q, qd)
        m = J.shape[0]
        g = gamma(qd)
        if self.redundant:
            # dependent pin rows: Φ_q q̈ = γ on an orthonormal basis of Φ_q's row space instead (its
            # left singular vectors above 1e-8 of the largest singular value): the same q̈ for
            # consistent rows, and the KKT matrix square and regular
            U, sv, _ = np.linalg.svd(J, full_matrices=False)
            basis = U[:, sv > 1e-8 * sv[0]]
            J, g = basis.T @ J, basis.T @ g
            m = J.shape[0]
        A = np.block([[M, J.T], [J, np.zeros((m, m))]])
        sol = np.linalg.solve(A, np.concatenate([Q, g]))
        return sol[:self.n], sol[self.n:], power, dissipation

    def energy(self, q, qd) -> float:
        """Kinetic + gravity's and the torsion springs' potential (J)."""
        kinetic = 0.5 * qd @ self.mass() @ qd
        potential = sum(b.mass * self.gravity * q[3 * i + 1] for i, b in enumerate(self.bodies))
        potential += sum(0.5 * s.stiffness * (self.relative(s.pin, q) - s.rest) ** 2 for s in self.springs)
        return float(kinetic + potential)

    def angle_row(self, name: str) -> np.ndarray:
        """The row r with r·q = a body's angle, or a pin's relative angle θ_b − θ_a."""
        row = np.zeros(self.n)
        if name in self.index:
            row[3 * self.index[name] + 2] = 1.0
            return row
        p = next(p for p in self.pins if p.name == name)
        if p.b != GROUND:
            row[3 * self.index[p.b] + 2] += 1.0
        if p.a != GROUND:
            row[3 * self.index[p.a] + 2] -= 1.0
        return row

    def assemble(self, guess: dict, fixed: dict, rates: dict) -> tuple[np.ndarray, np.ndarray]:
        """A consistent (q, q̇): the body angles ``guess`` (rad, each body's), the angles named in
        ``fixed`` held (a body's angle, or a pin's relative angle θ_b − θ_a by the pin's name),
        positions by Newton on Φ = 0; q̇ from the rates of the angles named in ``rates`` (rad/s,
        bodies' or pins', as many as the mechanism's degrees of freedom) and Φ_q q̇ = 0."""
        q = np.zeros(self.n)
        for i, b in enumerate(self.bodies):
            q[3 * i + 2] = guess[b.name]
        rows = np.array([self.angle_row(name) for name in fixed]).reshape(len(fixed), self.n)
        values = np.array(list(fixed.values()), float)
        for _ in range(100):
            r = np.concatenate([self.residual(q), rows @ q - values])
            J, _ = self.jacobian(q)
            step = np.linalg.lstsq(np.vstack([J, rows]), -r, rcond=None)[0]
            q += step
            if np.max(np.abs(step)) < 1e-15 and np.max(np.abs(self.residual(q))) < 1e-14:
                break
        else:
            raise RuntimeError("the assembly did not converge")
        J, _ = self.jacobian(q)
        rows = np.array([self.angle_row(name) for name in rates]).reshape(len(rates), self.n)
        A = np.vstack([J, rows])
        b = np.concatenate([np.zeros(J.shape[0]), list(rates.values())])
        qd = np.linalg.solve(A, b) if A.shape[0] == A.shape[1] else np.linalg.lstsq(A, b, rcond=None)[0]
        return q, qd


@dataclass(frozen=True)
class Run:
    t: np.ndarray
    q: np.ndarray          # (samples, 3 × bodies)
    qd: np.ndarray
    work: np.ndarray       # J, the torques' work from t = 0
    dissipated: np.ndarray  # J, the dampers'
    energy: np.ndarray     # J, kinetic + potential

    def angle(self, model: Model, body: str) -> np.ndarray:
        return self.q[:, 3 * model.index[body] + 2]

    def rate(self, model: Model, body: str) -> np.ndarray:
        return self.qd[:, 3 * model.index[body] + 2]

    @property
    def balance(self) -> float:
        """|E(t) − E(0) − W + D| at its largest over the run, relative to max(|E|, W, D) (1)."""
        residual = self.energy - self.energy[0] - self.work + self.dissipated
        scale = max(np.max(np.abs(self.energy)), np.max(np.abs(self.work)), np.max(self.dissipated), 1e-300)
        return float(np.max(np.abs(residual)) / scale)


def integrate(model: Model, q0, qd0, t_eval, rtol: float = 1e-12) -> Run:
    """DOP853 from (q0, q̇0) through ``t_eval`` (restarted at every edge)."""
    t_eval = np.asarray(t_eval, float)
    n = model.n

    def rhs(t, y, t_load):
        q, qd = y[:n], y[n:2 * n]
        qdd, power, dissipation = model.accelerations(t_load, q, qd)
        return np.concatenate([qd, qdd, [power, dissipation]])

    y = np.concatenate([q0, qd0, [0.0, 0.0]])
    bounds = [t_eval[0], *[e for e in model.edges if t_eval[0] < e < t_eval[-1]], t_eval[-1]]
    out = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        last = hi == bounds[-1]
        inside = t_eval[(t_eval >= lo) & ((t_eval <= hi) if last else (t_eval < hi))]
        # the torques are constant between edges: read at the piece's middle, so that no stage at
        # an edge sees the next piece's value
        sol = solve_ivp(rhs, (lo, hi), y, method="DOP853", rtol=rtol, atol=rtol * 1e-2, dense_output=True,
                        args=(0.5 * (lo + hi),))
        if not sol.success:
            raise RuntimeError(sol.message)
        if inside.size:
            out.append(sol.sol(inside))
        y = sol.y[:, -1]
    Y = np.hstack(out)
    q, qd = Y[:n].T, Y[n:2 * n].T
    energy = np.array([model.energy(a, b) for a, b in zip(q, qd)])
    return Run(t_eval, q, qd, Y[2 * n], Y[2 * n + 1], energy)


def simulate(model: Model, q0, qd0, t_eval, rtol: float = 1e-12) -> tuple[Run, tuple[float, float]]:
    """The run at ``rtol`` and its accuracy: the largest difference of the bodies' angles (rad)
    and of their angular rates (rad/s) from the run at rtol / 2."""
    run = integrate(model, q0, qd0, t_eval, rtol)
    half = integrate(model, q0, qd0, t_eval, rtol / 2.0)
    angles = [3 * i + 2 for i in range(len(model.bodies))]
    accuracy = (float(np.max(np.abs(run.q[:, angles] - half.q[:, angles]))),
                float(np.max(np.abs(run.qd[:, angles] - half.qd[:, angles]))))
    return run, accuracy


@dataclass(frozen=True)
class FrictionRun:
    """A run with Coulomb friction on one pin (:func:`simulate_friction`): the state at the times
    asked, the events (time, "stick" or "slip", the way s it slips or 0) and, at each time, the
    holding torque where stuck (NaN where it slips)."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    events: list
    hold: np.ndarray


def simulate_friction(model: Model, pin: str, friction: float, q0, qd0, t_eval, rtol: float = 1e-12) -> FrictionRun:
    """Coulomb friction f on ``pin`` (static = kinetic), from the physics: while it slips in the
    way s = ±1, a torque −f s on the pin, until its rate u̇ crosses 0 (a terminal event of
    solve_ivp); while it sticks, a Lock row holds the pin, until its holding torque reaches ±f (an
    event: |τ| − f = 0), where it slips with s = −sign τ. At each rate zero it sticks where the
    hold needs |τ| < f, else it slips the way its acceleration takes it. At each load edge a stuck
    pin whose hold exceeds f slips. At the start it slips the way its rate goes (decided as at a
    rate zero where that is 0). The rates are projected (M-weighted) onto the lock at a stick."""
    t_eval = np.asarray(t_eval, float)
    n = model.n
    row = model.angle_row(pin)
    t, q, qd = float(t_eval[0]), np.array(q0, float), np.array(qd0, float)
    end = float(t_eval[-1])
    edges = [e for e in model.edges if t < e < end] + [end]

    def with_mode(s, value=None):
        if s == 0.0:
            return replace(model, locks=(Lock(pin, value),))
        return replace(model, torques=model.torques + (Torque(pin, lambda tt, s=s: -friction * s),))

    def decide(t_load, q, qd):
        """At a rate zero: 0 (stick) where |τ_hold| < f, else the way it accelerates."""
        held = with_mode(0.0, float(row @ q))
        tau = float(held.holding(t_load, q, _project(held, q, qd))[0])
        if abs(tau) < friction:
            return 0.0
        return -math.copysign(1.0, tau)

    rate0 = float(row @ qd)
    s = math.copysign(1.0, rate0) if rate0 != 0.0 else decide(0.5 * (t + edges[0]), q, qd)
    events = []
    ts, qs, qds, holds = [], [], [], []
    while t < end:
        hi = edges[0]
        t_load = 0.5 * (t + hi)
        m = with_mode(s, float(row @ q))
        if s == 0.0:
            qd = _project(m, q, qd)
            if abs(float(m.holding(t_load, q, qd)[0])) >= friction:  # a load edge breaks it loose
                s = -math.copysign(1.0, float(m.holding(t_load, q, qd)[0]))
                events.append((t, "slip", s))
                continue

        def rhs(tt, y, m=m):
            qdd, _, _ = m.accelerations(t_load, y[:n], y[n:])
            return np.concatenate([y[n:], qdd])

        if s == 0.0:
            def event(tt, y, m=m):
                return friction - abs(float(m.holding(t_load, y[:n], y[n:])[0]))
        else:
            def event(tt, y, s=s):
                return s * float(row @ y[n:])
        sol, stop, inside = _leg(rhs, t, hi, q, qd, [event], rtol, t_eval)
        if inside.size:
            Y = sol.sol(inside)
            ts.append(inside)
            qs.append(Y[:n].T)
            qds.append(Y[n:].T)
            holds.append([float(m.holding(t_load, y[:n], y[n:])[0]) if s == 0.0 else math.nan for y in Y.T])
        y = sol.y[:, -1]
        t, q, qd = stop, y[:n].copy(), y[n:].copy()
        if sol.status == 1:  # the event
            if s == 0.0:
                tau = float(m.holding(t_load, q, qd)[0])
                s = -math.copysign(1.0, tau)
                events.append((t, "slip", s))
            else:
                new = decide(t_load, q, qd)
                events.append((t, "stick" if new == 0.0 else "slip", new))
                s = new
        else:
            edges.pop(0)
    return FrictionRun(np.concatenate(ts), np.vstack(qs), np.vstack(qds), events, np.concatenate(holds))


@dataclass(frozen=True)
class FrictionsRun:
    """A run with Coulomb friction on several pins (:func:`simulate_frictions`): the state at the
    times asked, the events (time, pin, "stick" or "slip", the way s it slips or 0) and, at each
    time, the holding margin max min_e (f_e − |τ_e|) over the admissible holding torques of the
    stuck pins (inf where none is stuck)."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    events: list
    margin: np.ndarray


def hold_margin(model: Model, t_load, q, qd, frictions: dict) -> tuple[float, dict]:
    """The stuck pins' (``model.locks``) holding torques that leave the most margin: the multipliers
    μ of every row (pins' and locks') with Φ_qᵀ μ = Q − M q̈ (q̈ unique, ``redundant``'s SVD where
    the locks are dependent) are μ0 + N z (μ0 by least squares, N = scipy's null_space(Φ_qᵀ)), and
    scipy's linprog (HiGHS) maximizes t subject to t ≤ f_e − |τ_e(z)|, τ_e = −μ_lock,e, over z.
    Returns (t, {pin: τ}). A statically determinate hold (N empty) is the plain min_e f_e − |τ_e|."""
    from scipy.linalg import null_space
    from scipy.optimize import linprog

    qdd, _, _, _ = model.solve(t_load, q, qd)
    J, _ = model.jacobian(q)
    Q, _, _ = model.forces(t_load, q, qd)
    b = Q - model.mass() @ qdd
    mu0 = np.linalg.lstsq(J.T, b, rcond=None)[0]
    N = null_space(J.T)
    m = len(model.locks)
    first = J.shape[0] - m
    f = np.array([frictions[lock.pin] for lock in model.locks])
    tau0, Nt = -mu0[first:], -N[first:]
    if N.shape[1] == 0:
        tau = tau0
    else:
        d = N.shape[1]
        # variables (z, t): ±(τ0 + Nt z) + t ≤ f
        A = np.vstack([np.hstack([Nt, np.ones((m, 1))]), np.hstack([-Nt, np.ones((m, 1))])])
        ub = np.concatenate([f - tau0, f + tau0])
        lp = linprog(np.concatenate([np.zeros(d), [-1.0]]), A_ub=A, b_ub=ub, bounds=[(None, None)] * (d + 1),
                     method="highs-ds")
        if not lp.success:
            raise RuntimeError(lp.message)
        tau = tau0 + Nt @ lp.x[:d]
    return float(np.min(f - np.abs(tau))), {lock.pin: float(v) for lock, v in zip(model.locks, tau)}


def simulate_frictions(model: Model, frictions: dict, q0, qd0, t_eval, rtol: float = 1e-12,
                       rest_rate: float = 1e-9) -> FrictionsRun:
    """Coulomb friction f_p on each pin p of ``frictions`` (static = kinetic), from the physics: a
    slipping pin takes the torque −f s (s = ±1, the way it turns) until its rate crosses 0; the
    stuck pins are held by Lock rows while some admissible share of their holding torques keeps
    every |τ_e| < f_e (:func:`hold_margin`: the largest least margin, by a linear programme: a
    hold of more pins than the degrees of freedom is statically indeterminate, any admissible
    share holds it), until that margin reaches 0 (an event), where the pins at |τ| = f (to 1e-7 f)
    slip with s = −sign τ. At each such stop (and at the start, and at a load edge whose hold has
    no margin left) the pins at rest (|u̇| ≤ ``rest_rate``, or stuck) take the first consistent
    set of modes, fewest slipping first (the stuck ones with a positive margin, each slipping one
    accelerating its way, s ü > 0; a slip from rest tried +1 first). The rates are projected
    (M-weighted, least squares where the locks are dependent) onto the locks at a stick."""
    import itertools

    t_eval = np.asarray(t_eval, float)
    n = model.n
    pins = list(frictions)
    rows = {p: model.angle_row(p) for p in pins}
    t, q, qd = float(t_eval[0]), np.array(q0, float), np.array(qd0, float)
    end = float(t_eval[-1])
    edges = [e for e in model.edges if t < e < end] + [end]
    modes = {p: None for p in pins}

    def with_modes(modes, q):
        locks = tuple(Lock(p, model.relative(p, q)) for p in pins if modes[p] == 0.0)
        torques = tuple(Torque(p, lambda tt, v=-frictions[p] * modes[p]: v) for p in pins if modes[p])
        return replace(model, locks=locks, torques=model.torques + torques, redundant=True)

    def decide(t_load, q, qd, forced=()):
        new = dict(modes)
        rest = []
        for p in pins:
            rate = float(rows[p] @ qd)
            if p in forced:
                new[p] = forced[p]
            elif modes[p] != 0.0 and abs(rate) > rest_rate:
                new[p] = math.copysign(1.0, rate)
            else:
                rest.append(p)
        for combo in sorted(itertools.product((0.0, 1.0, -1.0), repeat=len(rest)),
                            key=lambda c: sum(m != 0.0 for m in c)):
            trial = dict(new, **dict(zip(rest, combo)))
            m = with_modes(trial, q)
            v = _project_any(m, q, qd)
            if any(trial[p] == 0.0 for p in pins) and hold_margin(m, t_load, q, v, frictions)[0] <= 0.0:
                continue
            qdd, _, _, _ = m.solve(t_load, q, v)
            if all(mode * float(rows[p] @ qdd) > 0.0 for p, mode in zip(rest, combo) if mode):
                return trial, v
        raise RuntimeError(f"no consistent modes at t = {t}")

    def log(t, old, new):
        for p in pins:
            if new[p] != old[p] and (t > t_eval[0] or new[p] == 0.0):
                events.append((t, p, "stick" if new[p] == 0.0 else "slip", new[p]))

    events = []
    ts, qs, qds, margins = [], [], [], []
    new, qd = decide(0.5 * (t + edges[0]), q, qd)
    log(t, modes, new)
    modes = new
    while t < end:
        hi = edges[0]
        t_load = 0.5 * (t + hi)
        m = with_modes(modes, q)
        stuck = any(modes[p] == 0.0 for p in pins)
        if stuck:
            qd = _project_any(m, q, qd)
            margin, tau = hold_margin(m, t_load, q, qd, frictions)
            if margin <= 0.0:  # a load edge breaks it loose
                forced = {p: -math.copysign(1.0, tau[p]) for p in tau if abs(tau[p]) >= (1 - 1e-7) * frictions[p]}
                new, qd = decide(t_load, q, qd, forced)
                log(t, modes, new)
                modes = new
                continue

        def rhs(tt, y, m=m):
            qdd, _, _, _ = m.solve(t_load, y[:n], y[n:])
            return np.concatenate([y[n:], qdd])

        evs = []
        for p in pins:
            if modes[p]:
                def slip_event(tt, y, p=p, s=modes[p]):
                    return s * float(rows[p] @ y[n:])
                evs.append(slip_event)
        if stuck:
            def hold_event(tt, y, m=m):
                return hold_margin(m, t_load, y[:n], y[n:], frictions)[0]
            evs.append(hold_event)
        sol, stop, inside = _leg(rhs, t, hi, q, qd, evs, rtol, t_eval)
        if inside.size:
            Y = sol.sol(inside)
            ts.append(inside)
            qs.append(Y[:n].T)
            qds.append(Y[n:].T)
            margins.append([hold_margin(m, t_load, y[:n], y[n:], frictions)[0] if stuck else math.inf
                            for y in Y.T])
        y = sol.y[:, -1]
        t, q, qd = stop, y[:n].copy(), y[n:].copy()
        if sol.status == 1:  # an event
            forced = {}
            if stuck:
                margin, tau = hold_margin(m, t_load, q, qd, frictions)
                if margin <= 1e-7 * max(frictions.values()):
                    forced = {p: -math.copysign(1.0, tau[p]) for p in tau
                              if abs(tau[p]) >= (1 - 1e-7) * frictions[p]}
            new, qd = decide(t_load, q, qd, forced)
            log(t, modes, new)
            modes = new
        else:
            edges.pop(0)
    return FrictionsRun(np.concatenate(ts), np.vstack(qs), np.vstack(qds), events, np.concatenate(margins))


def _leg(rhs, t: float, hi: float, q, qd, events: list, rtol: float, t_eval):
    """One leg of the friction oracles: solve_ivp's DOP853 from (t, q, q̇) towards ``hi``, stopped
    by the first of ``events`` to fall through zero. Returns (the solution, the time it stopped,
    the times of ``t_eval`` it covers: up to the stop, the stop itself only at the run's end)."""
    for ev in events:
        ev.terminal, ev.direction = True, -1
    sol = solve_ivp(rhs, (t, hi), np.concatenate([q, qd]), method="DOP853", rtol=rtol, atol=rtol * 1e-2,
                    dense_output=True, events=events)
    if not sol.success:
        raise RuntimeError(sol.message)
    stop = float(sol.t[-1])
    inside = t_eval[(t_eval >= t) & (t_eval < stop)] if sol.status == 1 or stop < float(t_eval[-1]) else \
        t_eval[(t_eval >= t) & (t_eval <= stop)]
    return sol, stop, inside


def _project_any(model: Model, q, qd) -> np.ndarray:
    """:func:`_project`, by least squares where the rows are dependent (several locks)."""
    J, _ = model.jacobian(q)
    Minv = np.diag(1.0 / np.diag(model.mass()))
    return qd - Minv @ J.T @ np.linalg.lstsq(J @ Minv @ J.T, J @ qd, rcond=None)[0]


def _project(model: Model, q, qd) -> np.ndarray:
    """q̇ projected onto Φ_q q̇ = 0 (the model's rows, its locks with them) in the mass metric."""
    J, _ = model.jacobian(q)
    Minv = np.diag(1.0 / np.diag(model.mass()))
    return qd - Minv @ J.T @ np.linalg.solve(J @ Minv @ J.T, J @ qd)


def pulse(value: float, start: float, duration: float) -> Callable[[float], float]:
    return lambda t: value if start <= t < start + duration else 0.0


__all__ = ["Body", "Damper", "FrictionRun", "FrictionsRun", "GROUND", "Lock", "Model", "Pin", "Run", "Torque",
           "TorsionSpring", "hold_margin", "integrate", "pulse", "simulate", "simulate_friction",
           "simulate_frictions"]
