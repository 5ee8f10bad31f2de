"""Kinematics of one-degree-of-freedom planar linkages: the four-bar closed form and the
general loop system.

:class:`GeneralLinkage` drives any :class:`reduced.loops.LoopSystem` (plain arrays, Newton's
method with branch continuity); :class:`FourBar` is the seed's closed form, kept as a checked
fast path for scenes that use the ``four_bar`` shorthand. Both offer the interface that
:mod:`reduced.partition` uses (:class:`LoopLinkage`). What follows describes the closed form.

Coordinates are joint angles x = (q, φ1, …, φm): q is the independent one, the φ are
fixed by m loop-closure equations Φ(x) = 0. Every position that matters (the loop,
a body's centre of mass, a damper's attachment point) is a *phasor sum*

    r(x) = r0 + Σ_t a_t e(x[i_t] + α_t),    e(θ) = (cos θ, sin θ),

so its velocity and acceleration coefficients follow generically:

    K_r = dr/dq = Σ a_t K[i_t] e⊥(x[i_t] + α_t),             e⊥(θ) = (−sin θ, cos θ)
    L_r = dK_r/dq = Σ a_t (L[i_t] e⊥(·) − K[i_t]² e(·)).

The φ rates come from the loop's velocity equations Φ_φ K_φ = −Φ_q, and their
derivatives from its acceleration equations Φ_φ L_φ = −γ, with γ the part of
d²Φ/dq² that is quadratic in K (no finite differences). A new linkage type only
supplies its loop phasors, its bodies, and a position solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import loops
from .errors import NumericalFailure
from .scene import FourBarGeometry

# Below this conditioning (|sin| of the angle between the dependent Jacobian columns) a
# coordinate is treated as unable to drive the linkage: a dead-centre position.
SINGULAR_DETERMINANT = 1e-9
# A negative discriminant this small relative to A² + B² is round-off at a limit position.
ASSEMBLY_TOLERANCE = 1e-12


class AssemblyError(ValueError):
    """The linkage cannot be assembled at the requested input angle."""


class SingularPositionError(NumericalFailure):
    """The loop Jacobian Φ_φ is singular: a dead-centre (limit) position of the input."""

    def __init__(self, message: str):
        super().__init__("singular", message)


@dataclass(frozen=True)
class PhasorSum:
    """r(x) = offset + Σ_t lengths[t] · e(x[index[t]] + phase[t]), a point of the plane (m)."""

    offset: tuple[float, float]
    lengths: tuple[float, ...]
    index: tuple[int, ...]
    phase: tuple[float, ...]

    @staticmethod
    def fixed(point: tuple[float, float]) -> "PhasorSum":
        return PhasorSum(tuple(point), (), (), ())

    def plus(self, other: "PhasorSum") -> "PhasorSum":
        return PhasorSum((self.offset[0] + other.offset[0], self.offset[1] + other.offset[1]),
                         self.lengths + other.lengths, self.index + other.index,
                         self.phase + other.phase)

    def _terms(self, x) -> list[tuple[float, float, int]]:
        """(length, angle, coordinate index) of each term; scalar maths, these are hot."""
        return [(a, x[i] + p, i) for a, i, p in zip(self.lengths, self.index, self.phase)]

    def evaluate(self, x, K, L=None) -> tuple[float, ...]:
        """r, K_r = dr/dq and (if L is given) L_r = d²r/dq² in one pass: (rx, ry, kx, ky, lx, ly).

        x, K, L are sequences indexed by coordinate (plain lists are fastest). Units m, m/rad,
        m/rad².
        """
        rx, ry = self.offset
        kx = ky = lx = ly = 0.0
        for a, i, p in zip(self.lengths, self.index, self.phase):
            th = x[i] + p
            c, s = math.cos(th), math.sin(th)
            rx += a * c
            ry += a * s
            w = a * K[i]
            kx -= w * s
            ky += w * c
            if L is not None:
                wl, wk = a * L[i], w * K[i]
                lx += -wl * s - wk * c
                ly += wl * c - wk * s
        return rx, ry, kx, ky, lx, ly

    def position(self, x) -> tuple[float, float]:
        """r(x) (m)."""
        rx, ry = self.offset
        for a, th, _ in self._terms(x):
            rx += a * math.cos(th)
            ry += a * math.sin(th)
        return rx, ry

    def velocity_coefficient(self, x, K) -> tuple[float, float]:
        """K_r = dr/dq (m/rad)."""
        return self.evaluate(x, K)[2:4]

    def acceleration_coefficient(self, x, K, L) -> tuple[float, float]:
        """L_r = d²r/dq² (m/rad²)."""
        return self.evaluate(x, K, L)[4:6]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂r/∂x, shape (2, len(x))."""
        J = np.zeros((2, len(x)))
        for a, t, i in self._terms(x):
            J[0, i] -= a * math.sin(t)
            J[1, i] += a * math.cos(t)
        return J


@dataclass(frozen=True)
class Body:
    """A rigid link: its angle is x[angle_index] + angle_offset, its frame origin a phasor sum."""

    name: str
    angle_index: int
    angle_offset: float
    origin: PhasorSum
    pivoted: bool  # the frame origin is fixed to the ground

    def point(self, local: tuple[float, float]) -> PhasorSum:
        """A point fixed in the body, given in the body frame (m)."""
        u, v = local
        if u == 0.0 and v == 0.0:
            return self.origin
        rotating = PhasorSum((0.0, 0.0), (math.hypot(u, v),), (self.angle_index,),
                             (self.angle_offset + math.atan2(v, u),))
        return self.origin.plus(rotating)


@dataclass(frozen=True)
class Kinematics:
    """Joint angles and their velocity and acceleration coefficients at one q.

    x, K = dx/dq, L = d²x/dq²: arrays of shape (n,), with x[0] = q, K[0] = 1, L[0] = 0.
    """

    x: np.ndarray
    K: np.ndarray
    L: np.ndarray


class LoopLinkage:
    """A one-DOF planar linkage: loop phasors that must sum to zero, and its bodies.

    Any joint angle can serve as the independent coordinate (generalized coordinate
    partitioning, Wehage & Haug): :meth:`solve` closes the loop with x[i] held and returns
    K = dx/dx_i and L = d²x/dx_i²; :meth:`conditioning` says how well each choice is posed.
    """

    coordinate_names: tuple[str, ...]
    loops: tuple[PhasorSum, ...]  # each loop gives two scalar equations
    bodies: dict[str, Body]
    has_closed_form: bool = False  # kinematics(q, branch) is a closed form with q independent
    input_index: int = 0  # the input q is x[input_index] (closed forms); see input_rate
    input_coordinate: int | None = 0  # index of q among the coordinates, None when q is not one

    def input_value(self, x: np.ndarray) -> float:
        """q = drive·x (rad or m)."""
        return float(x[self.input_index])

    def input_rate(self, K: np.ndarray) -> float:
        """dq/dx_i = drive·K for K = dx/dx_i."""
        return float(K[self.input_index])

    def input_curvature(self, L: np.ndarray) -> float:
        """d²q/dx_i² = drive·L."""
        return float(L[self.input_index])

    def to_general(self, X: np.ndarray) -> np.ndarray:
        """Configurations (samples, n) in the coordinates of :class:`reduced.loops.LoopSystem`."""
        return X

    def angle_columns(self) -> np.ndarray:
        """Boolean mask (n,) of the coordinates that are angles (unwrapped along a run)."""
        return np.ones(len(self.coordinate_names), dtype=bool)

    # -- position ---------------------------------------------------------
    def assemble(self, q: float) -> np.ndarray:
        """All joint angles x at input angle q on the declared branch, shape (n,)."""
        raise NotImplementedError

    def branch_of(self, x: np.ndarray) -> int:
        """The assembly branch (±1) of a loop-consistent configuration."""
        raise NotImplementedError

    def branches(self, x: np.ndarray) -> np.ndarray:
        """:meth:`branch_of` of each row of x, shape (n, len(coordinates))."""
        return np.array([self.branch_of(row) for row in x])

    def loop_residual(self, x: np.ndarray) -> np.ndarray:
        """Φ(x), shape (2·len(loops),) (m)."""
        return np.array([r for loop in self.loops for r in loop.position(x)])

    def loop_jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂Φ/∂x, shape (2·len(loops), n)."""
        return np.vstack([loop.jacobian(x) for loop in self.loops])

    def refine(self, x_guess: np.ndarray, independent: int = 0, tol: float = 1e-13,
               max_iter: int = 25) -> np.ndarray:
        """Newton's method on Φ(x) = 0 with x[independent] held fixed, from a nearby guess."""
        x = np.array(x_guess, dtype=float)
        dep = [j for j in range(len(x)) if j != independent]
        for _ in range(max_iter):
            r = self.loop_residual(x)
            if np.max(np.abs(r)) < tol:
                return x
            x[dep] -= np.linalg.solve(self.loop_jacobian(x)[:, dep], r)
        if np.max(np.abs(self.loop_residual(x))) > 1e3 * tol:
            raise SingularPositionError(
                f"Newton's method did not close the loop with {self.coordinate_names[independent]} = "
                f"{x[independent]:.15g} rad held: the position is singular or unreachable")
        return x

    # -- conditioning and coordinate choice --------------------------------
    def conditioning(self, x: np.ndarray) -> np.ndarray:
        """For each coordinate as the independent one, |det J_dep| / Π ‖columns of J_dep‖.

        1 when the dependent columns of the loop Jacobian are orthogonal, 0 at a position
        where that coordinate cannot drive the linkage (for the four-bar with q independent,
        |sin(φ2 − φ1)|: 0 at the input link's dead centre). Shape (n,).
        """
        J = self.loop_jacobian(x)
        n = J.shape[1]
        out = np.empty(n)
        for i in range(n):
            Jd = J[:, [j for j in range(n) if j != i]]
            norms = np.prod(np.linalg.norm(Jd, axis=0))
            out[i] = abs(np.linalg.det(Jd)) / norms if norms > 0 else 0.0
        return out

    # -- velocity and acceleration coefficients (generic path) ------------
    def kinematics(self, q: float) -> Kinematics:
        """x, K and L at input angle q on the declared branch; may be overridden by closed forms."""
        return self.kinematics_generic(q)

    def kinematics_generic(self, q: float) -> Kinematics:
        """K and L of every coordinate with q independent, from the loop's equations."""
        return self.coefficients_at(self.assemble(q), independent=0)

    def chart_sign(self, x: np.ndarray, independent: int) -> int:
        """Sign of det J_dep at x: constant inside a chart, it names the assembly branch there."""
        J = self.loop_jacobian(x)
        dep = [j for j in range(len(x)) if j != independent]
        return 1 if np.linalg.det(J[:, dep]) >= 0.0 else -1

    def solve(self, x_guess: np.ndarray, independent: int, value: float, sign: int) -> Kinematics:
        """Close the loop with x[independent] = value on the branch where sign(det J_dep) = sign.

        Generic path: Newton's method from ``x_guess``; a result on the other branch is
        refused (the guess was too far from the chart's branch).
        """
        x = np.array(x_guess, dtype=float)
        x[independent] = value
        x = self.refine(x, independent)
        if self.chart_sign(x, independent) != sign:
            raise SingularPositionError(f"Newton's method left the assembly branch at "
                                        f"{self.coordinate_names[independent]} = {value:.15g} rad")
        return self.coefficients_at(x, independent)

    def coefficients_at(self, x: np.ndarray, independent: int) -> Kinematics:
        """K = dx/dx_i and L = d²x/dx_i² at a loop-consistent x, i = ``independent``.

        Velocity: J_dep K_dep = −J_i.  Acceleration: J_dep L_dep = −γ, with
        γ = Σ_t −a_t K[i_t]² e(θ_t) the part of d²Φ/dx_i² that is quadratic in K.
        """
        J = self.loop_jacobian(x)
        n = len(x)
        dep = [j for j in range(n) if j != independent]
        Jd = J[:, dep]
        if self.conditioning(x)[independent] < SINGULAR_DETERMINANT:
            raise SingularPositionError(
                f"dead-centre position: {self.coordinate_names[independent]} = {x[independent]:.15g} rad "
                f"cannot drive the linkage (the loop Jacobian of the other coordinates is singular)")
        K = np.zeros(n)
        K[independent] = 1.0
        K[dep] = np.linalg.solve(Jd, -J[:, independent])
        gamma = np.array([g for loop in self.loops
                          for g in loop.acceleration_coefficient(x, K, np.zeros(n))])
        L = np.zeros(n)
        L[dep] = np.linalg.solve(Jd, -gamma)
        return Kinematics(x=x, K=K, L=L)


class FourBar(LoopLinkage):
    """The four-bar O1-A-B-O3 of the seed: c1 e(q) + c2 e(φ1) + c3 e(φ2) − c4 e(0) = 0.

    Coordinates x = (q, φ1, φ2); φ2 is the angle of the vector B→O3, so the rocker's own
    angle (O3→B) is φ2 + π.
    """

    coordinate_names = ("q", "phi1", "phi2")
    has_closed_form = True

    def to_general(self, X: np.ndarray) -> np.ndarray:
        """(q, φ1, φ2) → the general frame angles (crank, coupler, rocker) = (q, φ1, φ2 + π)."""
        out = np.array(X, dtype=float, copy=True)
        out[..., 2] += math.pi
        return out

    def __init__(self, geometry: FourBarGeometry):
        g = self.geometry = geometry
        self.loops = (PhasorSum((-g.c4, 0.0), (g.c1, g.c2, g.c3), (0, 1, 2), (0.0, 0.0, 0.0)),)
        a = PhasorSum((0.0, 0.0), (g.c1,), (0,), (0.0,))
        self.bodies = {
            "crank": Body("crank", 0, 0.0, PhasorSum.fixed((0.0, 0.0)), pivoted=True),
            "coupler": Body("coupler", 1, 0.0, a, pivoted=False),
            "rocker": Body("rocker", 2, math.pi, PhasorSum.fixed((g.c4, 0.0)), pivoted=True),
        }

    def discriminant(self, q: float) -> float:
        """A² + B² − C² of the seed's φ1 formula (m⁴); negative: cannot be assembled."""
        A, B, C = self._abc(q)
        return A * A + B * B - C * C

    def _abc(self, q: float) -> tuple[float, float, float]:
        g = self.geometry
        A = 2.0 * g.c1 * g.c2 * math.sin(q)
        B = 2.0 * g.c2 * (g.c1 * math.cos(q) - g.c4)
        C = g.c1**2 + g.c2**2 - g.c3**2 + g.c4**2 - 2.0 * g.c1 * g.c4 * math.cos(q)
        return A, B, C

    def assemble(self, q: float, branch: int | None = None) -> np.ndarray:
        """Closed-form position analysis on the scene's branch (or the given one).

        A sin φ1 + B cos φ1 + C = 0 is solved as φ1 = β − branch·acos(−C/R), with
        R = √(A²+B²), β = atan2(A, B): the same root as the seed's half-angle formula
        with the ± sign equal to ``branch``, without its division by C − B (erratum 4).
        φ2 uses atan2 on both loop components (erratum 3).
        """
        g = self.geometry
        A, B, C = self._abc(q)
        disc = A * A + B * B - C * C
        if disc < -ASSEMBLY_TOLERANCE * (A * A + B * B):
            raise AssemblyError(f"the linkage cannot be assembled (discriminant A²+B²−C² = {disc:.6g} m⁴ < 0)")
        R = math.hypot(A, B)
        sign = g.branch if branch is None else branch
        phi1 = math.atan2(A, B) - sign * math.acos(max(-1.0, min(1.0, -C / R)))
        phi2 = math.atan2(-(g.c1 * math.sin(q) + g.c2 * math.sin(phi1)),
                          g.c4 - g.c1 * math.cos(q) - g.c2 * math.cos(phi1))
        return np.array([q, _wrap(phi1), phi2])


    def conditioning(self, x: np.ndarray) -> np.ndarray:
        """Closed form of :meth:`LoopLinkage.conditioning` for the four-bar:
        (|sin(φ2 − φ1)|, |sin(φ2 − q)|, |sin(φ1 − q)|) for q, φ1, φ2 independent."""
        q, p1, p2 = x[0], x[1], x[2]
        return np.array([abs(math.sin(p2 - p1)), abs(math.sin(p2 - q)), abs(math.sin(p1 - q))])

    def solve(self, x_guess: np.ndarray, independent: int, value: float, sign: int) -> Kinematics:
        """Closed form for any independent angle: the other two links form a dyad.

        With x_i known, c_a e(a) + c_b e(b) = P = (c4, 0) − c_i e(x_i), so a = ψ ± α with
        ψ = atan2(P), cos α = (c_a² + |P|² − c_b²) / (2 c_a |P|), and b from the remainder;
        of the two roots, the one with sign(det J_dep) = sign(sin(b − a)) = ``sign``.
        The root does not depend on ``x_guess``; the dependent angles are returned in the
        turn (2π multiple) nearest to it (when given), as the generic path's Newton iteration
        does, so that a chart's angles continue the configuration it started from.
        """
        g = self.geometry
        lengths = (g.c1, g.c2, g.c3)
        ia, ib = [j for j in range(3) if j != independent]
        ca, cb = lengths[ia], lengths[ib]
        px = g.c4 - lengths[independent] * math.cos(value)
        py = -lengths[independent] * math.sin(value)
        d = math.hypot(px, py)
        cos_alpha = (ca * ca + d * d - cb * cb) / (2.0 * ca * d)
        if abs(cos_alpha) > 1.0 + 1e-12:
            raise SingularPositionError(f"the linkage cannot be closed with {self.coordinate_names[independent]} "
                                        f"= {value:.15g} rad")
        alpha = math.acos(max(-1.0, min(1.0, cos_alpha)))
        psi = math.atan2(py, px)
        # det J_dep = det [c_a e⊥(a), c_b e⊥(b)] = c_a c_b sin(b − a)   (a before b in x).
        for a in (psi + alpha, psi - alpha):
            b = math.atan2(py - ca * math.sin(a), px - ca * math.cos(a))
            if (1 if math.sin(b - a) >= 0.0 else -1) == sign:
                break
        x = np.empty(3)
        x[independent], x[ia], x[ib] = value, a, b
        for j in (ia, ib) if x_guess is not None else ():
            x[j] += 2.0 * math.pi * np.round((x_guess[j] - x[j]) / (2.0 * math.pi))  # NaN stays NaN
        return self.coefficients_at(x, independent)

    def branch_of(self, x: np.ndarray) -> int:
        """+1 or −1: the closed-form branch whose φ1 is nearest the configuration's."""
        return int(self.branches(np.asarray(x)[None, :])[0])

    def branches(self, x: np.ndarray) -> np.ndarray:
        """:meth:`branch_of` for many configurations at once, x of shape (n, 3)."""
        g = self.geometry
        q, phi1 = x[:, 0], x[:, 1]
        A = 2.0 * g.c1 * g.c2 * np.sin(q)
        B = 2.0 * g.c2 * (g.c1 * np.cos(q) - g.c4)
        C = g.c1**2 + g.c2**2 - g.c3**2 + g.c4**2 - 2.0 * g.c1 * g.c4 * np.cos(q)
        half = np.arccos(np.clip(-C / np.hypot(A, B), -1.0, 1.0))
        beta = np.arctan2(A, B)

        def gap(root):
            return np.abs(np.angle(np.exp(1j * (root - phi1))))
        return np.where(gap(beta - half) <= gap(beta + half), 1, -1)

    def kinematics(self, q: float, branch: int | None = None) -> Kinematics:
        """Closed-form K and L of the seed (the generic path checks them in the tests).

        K_φ1 = c1 sin(q − φ2) / (c2 sin(φ2 − φ1)),  K_φ2 = c1 sin(φ1 − q) / (c3 sin(φ2 − φ1)),
        L_φ1 = (X cos φ2 + Y sin φ2) / (c2 sin(φ2 − φ1)),  L_φ2 = (X cos φ1 + Y sin φ1) / (c3 sin(φ1 − φ2)),
        X = c1 cos q + K_φ1² c2 cos φ1 + K_φ2² c3 cos φ2,  Y likewise with sines.
        """
        g = self.geometry
        x = self.assemble(q, branch)
        _, p1, p2 = x
        s21 = math.sin(p2 - p1)
        if abs(s21) < SINGULAR_DETERMINANT:
            raise SingularPositionError(f"dead-centre position at q = {q:.15g} rad: "
                                        f"sin(φ2 − φ1) = {s21:.3g}")
        k1 = g.c1 * math.sin(q - p2) / (g.c2 * s21)
        k2 = g.c1 * math.sin(p1 - q) / (g.c3 * s21)
        c1c, c1s = math.cos(p1), math.sin(p1)
        c2c, c2s = math.cos(p2), math.sin(p2)
        X = g.c1 * math.cos(q) + k1 * k1 * g.c2 * c1c + k2 * k2 * g.c3 * c2c
        Y = g.c1 * math.sin(q) + k1 * k1 * g.c2 * c1s + k2 * k2 * g.c3 * c2s
        l1 = (X * c2c + Y * c2s) / (g.c2 * s21)
        l2 = -(X * c1c + Y * c1s) / (g.c3 * s21)
        return Kinematics(x=x, K=np.array([1.0, k1, k2]), L=np.array([0.0, l1, l2]))


class GeneralLinkage(LoopLinkage):
    """Any one-DOF loop system (:mod:`reduced.loops`), with any coordinate independent.

    Coordinates are those of the :class:`~reduced.loops.LoopSystem` (body frame angles in
    rad, then slider displacements in m); the input q = drive·x need not be a coordinate.
    Everything evaluated here is on the system's plain arrays (term tables, linear rows and
    the driving rows of :meth:`LoopSystem.driven_by`), so a compiled kernel can replace it.

    Position: Newton's method on the loops with x_i held, from the predictor
    x + K Δ + ½ L Δ² of the chart's last configuration (branch continuity), checked to keep
    the sign of det [Φ_x; e_i] (the chart's assembly branch, which cannot change inside a
    chart: it ends before its own singularity).
    """

    has_closed_form = False

    def __init__(self, system: "loops.LoopSystem", x0):
        self.system = system
        self.x0 = np.array(x0, dtype=float)
        self.coordinate_names = system.coordinate_names
        self.drive = np.array(system.drive, dtype=float)
        unit_rows = np.flatnonzero(self.drive)
        self.input_coordinate = (int(unit_rows[0]) if len(unit_rows) == 1 and self.drive[unit_rows[0]] == 1.0
                                 else None)  # a revolute between two moving bodies drives θ_b − θ_a
        unit = np.array([name.endswith(".angle") for name in system.coordinate_names])
        self._angles = unit
        self._driven = tuple(system.driven_by(i) for i in range(system.n))
        self.loops = ()
        self.bodies = {}

    def input_value(self, x: np.ndarray) -> float:
        return float(self.drive @ x)

    def input_rate(self, K: np.ndarray) -> float:
        return float(self.drive @ K)

    def input_curvature(self, L: np.ndarray) -> float:
        return float(self.drive @ L)

    def angle_columns(self) -> np.ndarray:
        return self._angles

    def assemble(self, q: float) -> np.ndarray:
        """The scene's assembled configuration when q is its q0; else Newton from it."""
        if q == self.input_value(self.x0):
            return self.x0.copy()
        try:
            return loops.assemble(self.system, q, self.x0)
        except loops.AssemblyError as exc:
            raise AssemblyError(str(exc)) from None

    def loop_residual(self, x: np.ndarray) -> np.ndarray:
        return loops.constraint_residual(self.system, x)

    def loop_jacobian(self, x: np.ndarray) -> np.ndarray:
        return loops.constraint_jacobian(self.system, x)

    def conditioning(self, x: np.ndarray) -> np.ndarray:
        return loops.conditioning(self.system, x)

    def chart_sign(self, x: np.ndarray, independent: int) -> int:
        """Sign of det [Φ_x; e_i] (= ± det Φ_dep): constant inside a chart."""
        A = np.vstack([loops.constraint_jacobian(self.system, x), self._driven[independent].drive])
        return 1 if np.linalg.det(A) >= 0.0 else -1

    def branch_of(self, x: np.ndarray) -> int:
        return 0  # the general path tracks assembly modes (loops.assembly_modes), not a ±1

    def solve(self, x_guess: np.ndarray, independent: int, value: float, sign: int) -> Kinematics:
        """Close the loops with x_i = value by Newton's method from ``x_guess``, on the chart's
        branch (``sign`` of det [Φ_x; e_i]); K, L with respect to x_i.

        Newton on Φ(x) = 0 with x_i held until every residual is ≤ ``NEWTON_TOL`` (m or rad),
        then one more step (round-off), at most ``NEWTON_MAX_ITER`` iterations; the last
        Jacobian gives K and L (:func:`reduced.loops.coefficients`' equations).
        """
        system, name = self.system, self.coordinate_names[independent]
        x = np.array(x_guess, dtype=float)
        x[independent] = value
        e_i = self._driven[independent].drive
        polished = False
        for _ in range(NEWTON_MAX_ITER):
            F, J = loops.residual_and_jacobian(system, x)
            A = np.vstack([J, e_i])
            if polished:
                break
            if not np.all(np.isfinite(F)):
                break
            polished = float(np.max(np.abs(F))) <= NEWTON_TOL
            try:
                x = x - np.linalg.solve(A, np.append(F, 0.0))
            except np.linalg.LinAlgError:
                break
        else:
            polished = False
        if not polished or not np.all(np.isfinite(x)):
            raise SingularPositionError(f"Newton's method did not close the loops with {name} = {value:.15g} "
                                        f"held: the position is singular or unreachable from the predictor")
        return self._coefficients(A, x, independent, sign)

    def _coefficients(self, A: np.ndarray, x: np.ndarray, independent: int, sign: int | None) -> Kinematics:
        """K, L from A = [Φ_x; e_i] at x; refuses a singular A and, with ``sign``, another branch."""
        det = np.linalg.det(A)
        norms = np.prod(np.linalg.norm(A[:-1], axis=0)[np.arange(len(x)) != independent])
        name = self.coordinate_names[independent]
        if not (norms > 0.0 and abs(det) / norms >= SINGULAR_DETERMINANT):
            raise SingularPositionError(f"dead-centre position: {name} = {x[independent]:.15g} cannot drive the "
                                        "linkage (the loop Jacobian of the other coordinates is singular)")
        if sign is not None and (1 if det >= 0.0 else -1) != sign:
            raise SingularPositionError(f"Newton's method left the assembly branch at {name} = {x[independent]:.15g}")
        n = len(x)
        rhs = np.zeros(n)
        rhs[-1] = 1.0
        K = np.linalg.solve(A, rhs)
        _, gamma = loops.rates(self.system.loops, x, K)
        rhs = np.zeros(n)
        rhs[:gamma.size] = -gamma.ravel()
        L = np.linalg.solve(A, rhs)
        return Kinematics(x=x, K=K, L=L)

    def coefficients_at(self, x: np.ndarray, independent: int) -> Kinematics:
        """K = dx/dx_i and L = d²x/dx_i² at an assembled x (the equations of
        :func:`reduced.loops.coefficients`, with x_i driving)."""
        x = np.asarray(x, dtype=float)
        A = np.vstack([loops.constraint_jacobian(self.system, x), self._driven[independent].drive])
        return self._coefficients(A, x, independent, None)


# General path's Newton iteration: converged at residuals ≤ 1e-12 (m or rad) plus one step,
# as loops.assemble; from the chart's quadratic predictor it takes 2–3 iterations.
NEWTON_TOL = 1e-12
NEWTON_MAX_ITER = 20


def _wrap(angle: float) -> float:
    """Angle in (−π, π]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def unwrap_continuous(angles: np.ndarray) -> np.ndarray:
    """Remove 2π jumps along a sampled trajectory of joint angles, shape (n_samples, n)."""
    return np.unwrap(angles, axis=0)
