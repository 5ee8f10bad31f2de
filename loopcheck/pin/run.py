"""Run a scene's Pinocchio model (:mod:`loopcheck.pin.model`) and return an :class:`EngineResult`.

The state y = (q, v, W, D): Pinocchio's joint positions and rates (one each per tree joint), and
the work W of the external loads and the energy D the dampers dissipate, integrated alongside
from their rates at every stage (the audit evaluates nothing again). The acceleration is
Pinocchio's ``constraintDynamics`` (the KKT system of M, the loop constraints' Jacobian and
their Baumgarte-corrected drift, solved by its proximal Cholesky) under the generalized forces

    τ = τ_input e_input + Σ_dampers −b ḋ g + Σ_springs −k (d − d0) g
        + Σ_joint elements −(c u̇ + k (u − u0)) coef + Σ_forces F (J_pᵀ e)

(g = (J_b − J_a)ᵀ n the line's Jacobian, n its unit vector, d its length; J_p a point's
in-plane translational Jacobian, e the force's ground direction; gravity is Pinocchio's own).

Joint couplings (:class:`loopcheck.pin.model.CouplingRow`) are rows beside the loops: φ = u_y −
y_ref − p(u_x − x_ref), its Jacobian row C = c_y − p'(s) c_x over v, and C a = γ − Kp φ − Kd C v
with γ = p''(s) (c_x·v)² and the loops' Baumgarte gains. Pinocchio's ``constraintDynamics`` takes
only its own constraint models, and its solution is affine in τ: a(τ + Cᵀλ) = a(τ) + G Cᵀλ, G the
loop-constrained inverse inertia. So a0 = a(τ), each column of G Cᵀ from one more solve (the
difference of a(τ + s Cₖᵀ) and a0, s scaling the probe to the largest of |τ| and Pinocchio's
nonlinear effects so that the difference keeps its digits), λ from (C G Cᵀ) λ = γ − Kp φ − Kd C v
− C a0, and a = a0 + G Cᵀλ: the KKT system of the loops and the couplings together, the loops
still Pinocchio's. A coupling's residual counts in the loop gap as a length (φ × the
mechanism's size for a revolute coupled joint, φ for a prismatic one).

scipy's ``solve_ivp`` integrates each piece between load edges with the load of that piece
(restarted at every edge, as the reduced engine's DOP853 is); every solver step is cut into at
least four parts no longer than ``sample_interval``, sampled from the dense output, and each
step's end state is kept exactly.

With several inputs (``scene.dof`` > 1) every input starts at its rate (ẋ0 = K q̇0,
:func:`loopcheck.kinematics.input_rates`), their loads are actuators on their joints (above), and
every input's q is read from Pinocchio's q through its joint's row (``PinModel.input_rows``): the
first is the result's trajectory, the others ``EngineResult.other_inputs``, each with its peak.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from loopcheck import kinematics as loops
from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.loads import TabulatedForce
from loopcheck.results import ConstraintViolation, EnergyAudit, EngineResult
from loopcheck.scene import Scene
from loopcheck.trajectory import JointTrajectory, Trajectory
from loopcheck.tree_coordinates import initial_rates

from .model import PinModel, build, pin  # pin: Pinocchio, or one line saying how to install it
from .settings import MAX_SAMPLES, SCIPY_NAMES, PinSettings

# The initial state's loop residuals (gap, m, and its rate, m/s) relative to the mechanism's
# size and its point-speed scale: the model is placed at the assembled x0 (a gap of ~1e-16 m on
# the catalogue), so 1e-12 is round-off with a wide margin.
INITIAL_RESIDUAL_REL = 1e-12
PARTS_PER_STEP = 4  # each solver step is sampled at least this many parts (and at its end)


class _OutOfBudget(Exception):
    """The run used its ``max_evaluations``."""


@dataclass(frozen=True)
class PinDetails:
    """The Pinocchio engine's own record of a run (:attr:`EngineResult.details`).

    solver : scipy's method ("DOP853", ...).
    pieces : the integrated pieces between load edges.
    n_steps_per_piece : the solver's accepted steps in each piece.
    constraint_rows : the rows of the loop constraints (3 per cut joint, CONTACT_3D) and the
        joint couplings' (one each).
    baumgarte : (Kp 1/s², Kd 1/s).
    proximal : (μ, accuracy, iterations) of ``constraintDynamics``.
    largest_gap_rate : m/s, the largest |d gap/dt| at the samples.
    energy_scale : J, what the energy residual is relative to.
    energy_bound : the largest relative residual allowed.
    initial_residuals : the loops' gap (m) and its rate (m/s) at the start.
    pinocchio_version : the Pinocchio that ran.
    """

    solver: str
    pieces: int
    n_steps_per_piece: tuple[int, ...]
    constraint_rows: int
    baumgarte: tuple[float, float]
    proximal: tuple[float, float, int]
    largest_gap_rate: float
    energy_scale: float
    energy_bound: float
    initial_residuals: tuple[float, float]
    pinocchio_version: str

    def as_dict(self) -> dict:
        return {"solver": self.solver, "pieces": self.pieces, "n_steps_per_piece": list(self.n_steps_per_piece),
                "constraint_rows": self.constraint_rows, "baumgarte": list(self.baumgarte),
                "proximal": list(self.proximal), "largest_gap_rate_m_per_s": self.largest_gap_rate,
                "energy_scale_J": self.energy_scale, "energy_bound": self.energy_bound,
                "initial_residuals": list(self.initial_residuals), "pinocchio_version": self.pinocchio_version}


class _Dynamics:
    """The right-hand side f(t, y) and the read-outs at a state, of one scene's model."""

    def __init__(self, scene: Scene, pm: PinModel, settings: PinSettings):
        self.pm, self.scene = pm, scene
        mech = scene.mechanism
        self.nq = pm.model.nq
        self.prox = pin.ProximalSettings(settings.proximal_accuracy, settings.proximal_mu,
                                         settings.proximal_iterations)
        self.input_dof = pm.joint_names.index(mech.linkage.input_joint)
        f = pm.frames
        self.dampers = [(f[(e.body_a, e.point_a)], f[(e.body_b, e.point_b)], e.coefficient) for e in mech.dampers]
        self.springs = [(f[(e.body_a, e.point_a)], f[(e.body_b, e.point_b)], e.coefficient, e.rest_length)
                        for e in mech.springs]
        self.joint_dampers = [(*pm.joint_coef[e.joint], e.coefficient) for e in mech.joint_dampers]
        self.joint_springs = [(*pm.joint_coef[e.joint], e.coefficient, e.rest) for e in mech.joint_springs]
        self.point_forces = [(f[(p.body, p.point)], np.array([math.cos(p.direction), math.sin(p.direction)]),
                              TabulatedForce(p.coordinate, p.values, p.period)) for p in mech.point_forces]
        self.timed_forces = [(f[(p.body, p.point)], np.array([math.cos(p.direction), math.sin(p.direction)]),
                              p.profile) for p in mech.timed_forces]
        # actuators: (actuator, coef, l0) with its transmission's length l = l0 + coef·q
        self.actuators = [(a, sum(c * pm.joint_coef[j][0] for j, c in a.terms),
                           sum(c * pm.joint_coef[j][1] for j, c in a.terms)) for a in mech.actuators]
        self.cut_frames = [(f[(j.body_a, j.point_a)], f[(j.body_b, j.point_b)])
                           for j in (mech.linkage.joint_map[n] for n in mech.linkage.cut_joints)]
        self.q_input0 = float(pm.system.drive @ pm.x0)
        self.evaluations = 0
        self.budget = settings.max_evaluations
        self.kp, self.kd = settings.baumgarte_kp, settings.kd  # the couplings' Baumgarte gains: the loops'

    def _kinematics(self, q: np.ndarray) -> None:
        pin.computeJointJacobians(self.pm.model, self.pm.data, q)

    def _point(self, frame: int):
        """The frame's position (2,) and in-plane Jacobian (2, nv) at the last :meth:`_kinematics`."""
        model, data = self.pm.model, self.pm.data
        return (pin.updateFramePlacement(model, data, frame).translation[:2],
                pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:2])

    def forces(self, q: np.ndarray, v: np.ndarray, load: float, timed: tuple[float, ...]):
        """(τ, load power W', dissipation D') at (q, v) with the input load and timed forces'
        values of the piece, then the actuators' clamped controls (``timed``); Pinocchio's kinematics at q are computed here."""
        self._kinematics(q)
        tau = np.zeros(self.nq)
        tau[self.input_dof] = load
        if self.pm.compensation is not None:  # gravcomp: the compensated weight's generalized gravity, held up
            tau += pin.computeGeneralizedGravity(self.pm.compensation, self.pm.compensation_data, q)
        power = load * v[self.input_dof]
        dissipation = 0.0
        for a, b, c in self.dampers:
            (pa, Ja), (pb, Jb) = self._point(a), self._point(b)
            d = pb - pa
            n = d / math.hypot(d[0], d[1])
            g = n @ (Jb - Ja)
            rate = float(g @ v)
            tau -= (c * rate) * g
            dissipation += c * rate * rate
        for a, b, k, rest in self.springs:
            (pa, Ja), (pb, Jb) = self._point(a), self._point(b)
            d = pb - pa
            length = math.hypot(d[0], d[1])
            tau -= (k * (length - rest)) * ((d / length) @ (Jb - Ja))
        for coef, _, c in self.joint_dampers:
            rate = float(coef @ v)
            tau -= (c * rate) * coef
            dissipation += c * rate * rate
        for coef, u0, k, rest in self.joint_springs:
            tau -= (k * (u0 + float(coef @ q) - rest)) * coef
        if self.point_forces:
            q_in = self.q_input0 + float(self.pm.input_row @ q)
            for frame, e, table in self.point_forces:
                _, J = self._point(frame)
                gen = (float(table(q_in)) * e) @ J
                tau += gen
                power += float(gen @ v)
        for (frame, e, _), value in zip(self.timed_forces, timed):
            _, J = self._point(frame)
            gen = (value * e) @ J
            tau += gen
            power += float(gen @ v)
        # the actuators' clamped controls follow the timed forces' values in ``timed``
        for (a, coef, l0), ctrl in zip(self.actuators, timed[len(self.timed_forces):]):
            rate = float(coef @ v)
            f = float(a.force(ctrl, l0 + float(coef @ q), rate))
            tau += (a.gear * f) * coef
            power += a.gear * f * rate
        return tau, power, dissipation

    def acceleration(self, q, v, tau) -> np.ndarray:
        """The constrained acceleration: Pinocchio's ``constraintDynamics`` (the loops), and with
        joint couplings their rows beside it (the module's docstring says how)."""
        pm = self.pm
        a = self._loops(q, v, tau)
        if not pm.couplings:
            return a
        rows, target = [], []
        for c in pm.couplings:
            phi, row, rate, gamma = c.state(q, v)
            rows.append(row)
            target.append(gamma - self.kp * phi - self.kd * rate)  # row·a = γ, Baumgarte-corrected as the loops
        C = np.array(rows)
        # the loops' dynamics is affine in τ: its response to a generalized force Cᵀλ is G Cᵀλ,
        # G the loop-constrained inverse inertia; each column of G Cᵀ from one more solve, the
        # probe scaled to the forces at hand so that the difference keeps its digits
        scale = max(float(np.max(np.abs(tau))), float(np.max(np.abs(pm.data.nle))), 1e-300)
        response = np.empty((self.nq, len(rows)))
        for k, row in enumerate(rows):
            probe = scale / float(np.max(np.abs(row)))
            response[:, k] = (self._loops(q, v, tau + probe * row) - a) / probe
        # least squares: a coupling dependent on the loops (or another) is a dependent row, as the
        # proximal solver takes the loops' own (its cut singular values below 1e-12 of the largest)
        lam = np.linalg.lstsq(C @ response, np.array(target) - C @ a, rcond=1e-12)[0]
        return a + response @ lam

    def _loops(self, q, v, tau) -> np.ndarray:
        pm = self.pm
        return pin.constraintDynamics(pm.model, pm.data, q, v, tau, pm.constraints, pm.constraint_datas,
                                      self.prox).copy()

    def rhs(self, load: float, timed: tuple[float, ...]):
        n = self.nq

        def f(t, y):
            self.evaluations += 1
            if self.evaluations > self.budget:
                raise _OutOfBudget
            q, v = y[:n], y[n:2 * n]
            tau, power, dissipation = self.forces(q, v, load, timed)
            out = np.empty_like(y)
            out[:n] = v
            out[n:2 * n] = self.acceleration(q, v, tau)
            out[2 * n] = power
            out[2 * n + 1] = dissipation
            return out
        return f

    def gaps(self, q: np.ndarray, v: np.ndarray, *, kinematics: bool = True) -> tuple[float, float]:
        """The largest loop gap (m) and its rate (m/s) over the cut joints at (q, v)
        (``kinematics=False``: at the kinematics already computed at q), and over the couplings: a
        coupling's residual φ and its rate as a length (:attr:`CouplingRow.length` × φ: a residual
        of δ rad moves a point at the mechanism's size by δ·size)."""
        gap = rate = 0.0
        for c in self.pm.couplings:
            phi, _, phi_rate, _ = c.state(q, v)
            gap, rate = max(gap, c.length * abs(phi)), max(rate, c.length * abs(phi_rate))
        if not self.cut_frames:
            return gap, rate
        if kinematics:
            self._kinematics(q)
        for a, b in self.cut_frames:
            (pa, Ja), (pb, Jb) = self._point(a), self._point(b)
            gap = max(gap, math.hypot(*(pb - pa)))
            rate = max(rate, float(np.linalg.norm((Jb - Ja) @ v)))
        return gap, rate

    def energy(self, q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
        """Kinetic ½ vᵀ M v (M with the joint inertias' armature) and potential (gravity from
        Pinocchio, springs ½ k (d − d0)² and ½ k (u − u0)²), J; Pinocchio's kinematics at q
        are computed here."""
        model, data = self.pm.model, self.pm.data
        M = pin.crba(model, data, q)  # the whole symmetric M (Pinocchio 4's binding), armature included
        kinetic = 0.5 * float(v @ M @ v)
        potential = float(pin.computePotentialEnergy(model, data, q))
        if self.pm.compensation is not None:  # gravcomp: the compensated weight's potential is not the body's
            potential -= float(pin.computePotentialEnergy(self.pm.compensation, self.pm.compensation_data, q))
        if self.springs:
            self._kinematics(q)
        for a, b, k, rest in self.springs:
            d = self._point(b)[0] - self._point(a)[0]
            potential += 0.5 * k * (math.hypot(d[0], d[1]) - rest) ** 2
        for coef, u0, k, rest in self.joint_springs:
            potential += 0.5 * k * (u0 + float(coef @ q) - rest) ** 2
        return kinetic, potential

    def unit_rate_inertia(self) -> float:
        """𝔍(q0): vᵀ M v for the loop-consistent joint rates with the input at unit rate (at a
        dead centre of the input, the largest rate 1), kg·m² or kg. With several inputs, the
        smallest diagonal term of the k×k 𝔍(q0): each input at unit rate with the others held
        (:func:`loopcheck.kinematics.input_rates`), the lightest input's (MuJoCo's floor, too)."""
        system = self.pm.system
        x0 = self.pm.x0
        M = pin.crba(self.pm.model, self.pm.data, np.zeros(self.nq))
        if system.dof > 1:
            units = np.eye(system.dof)
            return min(float(u @ M @ u) for u in (self.pm.P @ loops.input_rates(system, x0, e) for e in units))
        best = int(np.argmax(loops.conditioning(system, x0)))
        K, _ = loops.coefficients(system.driven_by(best), x0)
        rate = float(system.drive @ K)
        K = K / rate if abs(rate) > 1e-6 * np.max(np.abs(K)) else K / np.max(np.abs(K))
        u = self.pm.P @ K
        return float(u @ M @ u)


def _pieces(scene: Scene) -> list[tuple[float, float]]:
    edges = [0.0] + [e for e in scene.load_edges if 0.0 < e < scene.horizon] + [scene.horizon]
    return list(zip(edges[:-1], edges[1:]))


def _initial_rates(scene: Scene, pm: PinModel) -> np.ndarray:
    """ẋ0 consistent with the loops at the assembled x0: the input at its rate
    (:func:`loopcheck.tree_coordinates.initial_rates`); with several inputs, every input at its
    rate, ẋ0 = K q̇0 (:func:`loopcheck.kinematics.input_rates`)."""
    if scene.dof > 1:
        try:
            return loops.input_rates(pm.system, pm.x0, scene.initial_qdot())
        except loops.AssemblyError as exc:
            raise NumericalFailure(FailureReason.INITIAL_STATE, f"the initial rates: {exc}", 0.0) from None
    return initial_rates(scene.mechanism.linkage, scene.x0, scene.qdot0)


def simulate_pin(scene: Scene, settings: PinSettings = PinSettings()) -> EngineResult:
    """Integrate the scene's Pinocchio model to the horizon (the module's docstring says how).

    Raises
    ------
    ValueError
        What the model cannot hold (:func:`loopcheck.pin.model.build`), or a run of more than
        MAX_SAMPLES samples (naming ``[pin] sample_interval`` and ``simulation.horizon``).
    NumericalFailure
        INITIAL_STATE: the loops' gap or its rate at the start above round-off; STEP_SIZE: the
        solver failed or used ``max_evaluations``; SINGULAR: Pinocchio could not solve the
        constrained dynamics; NON_FINITE; CONSTRAINT_DRIFT: a loop gap above
        ``max_constraint_violation``; ENERGY_IMBALANCE: an energy residual above
        ``max_energy_residual`` of the energy scale.
    """
    if scene.horizon / settings.sample_interval > MAX_SAMPLES:
        raise ValueError(f"a Pinocchio run of {scene.horizon / settings.sample_interval:.3g} samples "
                         f"(simulation.horizon {scene.horizon:g} s / [pin] sample_interval "
                         f"{settings.sample_interval:g} s) exceeds {MAX_SAMPLES:.3g}: raise [pin] sample_interval "
                         "(--sample-interval) or shorten simulation.horizon")
    pm = build(scene, settings)
    dyn = _Dynamics(scene, pm, settings)
    n = pm.model.nq
    q0 = np.zeros(n)
    v0 = pm.P @ _initial_rates(scene, pm)
    gap0, rate0 = dyn.gaps(q0, v0)
    speed = pm.size * max(1.0, float(np.max(np.abs(v0), initial=0.0)))
    if not (gap0 <= INITIAL_RESIDUAL_REL * pm.size and rate0 <= INITIAL_RESIDUAL_REL * speed):
        raise NumericalFailure(FailureReason.INITIAL_STATE,
                               f"the Pinocchio model's loops (and couplings, as lengths) are open by {gap0:.3g} m (rate "
                               f"{rate0:.3g} m/s) at the initial state: the assembled (q0, q̇0) does not close them", 0.0)

    start = time.perf_counter()
    y = np.concatenate([q0, v0, [0.0, 0.0]])
    times, states, loads, timed_at, steps = [], [], [], [], []
    for t0, t1 in _pieces(scene):
        mid = 0.5 * (t0 + t1)
        load = 0.0 if scene.load is None else float(scene.load(mid))
        timed = (tuple(float(p.profile(mid)) for p in scene.mechanism.timed_forces)
                 + tuple(float(a.control_values(np.array([mid]))[0]) for a in scene.mechanism.actuators))
        try:
            sol = solve_ivp(dyn.rhs(load, timed), (t0, t1), y, method=SCIPY_NAMES[settings.method],
                            rtol=settings.rtol, atol=settings.atol, dense_output=True)
        except _OutOfBudget:
            raise NumericalFailure(FailureReason.STEP_SIZE,
                                   f"the Pinocchio run used its {settings.max_evaluations} evaluations before "
                                   f"t = {t1:g} s: loosen [pin] rtol or raise [pin] max_evaluations", t0) from None
        except (RuntimeError, ValueError) as exc:  # Pinocchio's refusals (a singular KKT system)
            raise NumericalFailure(FailureReason.SINGULAR, f"Pinocchio's constraintDynamics failed in "
                                   f"[{t0:g}, {t1:g}] s: {str(exc).strip().splitlines()[0]}", t0) from None
        if sol.status != 0:
            raise NumericalFailure(FailureReason.STEP_SIZE, f"scipy's {SCIPY_NAMES[settings.method]} stopped at "
                                   f"t = {sol.t[-1]:.6g} s: {sol.message}", float(sol.t[-1]))
        if not np.all(np.isfinite(sol.y)):
            raise NumericalFailure(FailureReason.NON_FINITE, "the Pinocchio run's state became NaN or infinite")
        steps.append(len(sol.t) - 1)
        before = sum(len(a) for a in times)
        for k in range(len(sol.t) - 1):
            a, b = sol.t[k], sol.t[k + 1]
            parts = max(PARTS_PER_STEP, math.ceil((b - a) / settings.sample_interval))
            inner = a + (b - a) * np.arange(1, parts) / parts
            if k == 0:
                times.append(np.array([a]))
                states.append(sol.y[:, :1].T)
            times += [inner, np.array([b])]
            states += [sol.sol(inner).T, sol.y[:, k + 1:k + 2].T]
        count = sum(len(a) for a in times) - before
        loads.append(np.full(count, load))
        timed_at.append(np.tile(timed, (count, 1)).reshape(count, len(timed)))
        y = sol.y[:, -1].copy()
    wall = time.perf_counter() - start
    n_evaluations = dyn.evaluations

    t = np.concatenate(times)
    Y = np.concatenate(states)
    load_at = np.concatenate(loads)
    timed_values = np.concatenate(timed_at)
    Q, V = Y[:, :n], Y[:, n:2 * n]
    acc = np.empty((len(t), n))
    kinetic, potential = np.empty(len(t)), np.empty(len(t))
    gap, gap_rate = np.empty(len(t)), np.empty(len(t))
    for i in range(len(t)):
        tau, _, _ = dyn.forces(Q[i], V[i], load_at[i], tuple(timed_values[i]))
        gap[i], gap_rate[i] = dyn.gaps(Q[i], V[i], kinematics=False)
        acc[i] = dyn.acceleration(Q[i], V[i], tau)
        kinetic[i], potential[i] = dyn.energy(Q[i], V[i])
    row = pm.input_row
    trajectory = Trajectory(t, pm.system.drive @ pm.x0 + Q @ row, V @ row, acc @ row)
    others = [Trajectory(t, r0 @ pm.x0 + Q @ row, V @ row, acc @ row)  # with several inputs, each later one's
              for r0, row in zip(pm.system.input_rows[1:], pm.input_rows[1:])]
    x, xdot = pm.x(Q), pm.xdot(V)
    joints = JointTrajectory(pm.system.coordinate_names, t, x, xdot, np.full(len(t), -1),
                             loops.assembly_modes(pm.system, x))
    violation = ConstraintViolation(t, gap)
    violation.gate(settings.max_constraint_violation, "the Pinocchio run", "[pin] max_constraint_violation")
    audit = EnergyAudit(t=t, kinetic=kinetic, potential=potential, torque_work=Y[:, 2 * n],
                        damper_dissipation=Y[:, 2 * n + 1])
    scale = audit.gate(settings.max_energy_residual, 0.5 * dyn.unit_rate_inertia(), "the Pinocchio run",
                       "[pin] max_energy_residual")
    details = PinDetails(solver=SCIPY_NAMES[settings.method], pieces=len(steps), n_steps_per_piece=tuple(steps),
                         constraint_rows=3 * len(pm.constraints) + len(pm.couplings),
                         baumgarte=(settings.baumgarte_kp, settings.kd),
                         proximal=(settings.proximal_mu, settings.proximal_accuracy, settings.proximal_iterations),
                         largest_gap_rate=float(np.max(gap_rate)), energy_scale=scale,
                         energy_bound=settings.max_energy_residual, initial_residuals=(gap0, rate0),
                         pinocchio_version=pin.__version__)
    return EngineResult(engine="pin", trajectory=trajectory, joints=joints, peak=trajectory.peak_rate(), audit=audit,
                        wall_s=wall, n_steps=sum(steps), n_evaluations=n_evaluations, settings=settings,
                        effects=tuple(scene.effects), constraint_violation=violation, details=details,
                        other_inputs=tuple((tr, tr.peak_rate()) for tr in others))
