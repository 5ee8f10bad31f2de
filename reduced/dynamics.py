"""Eksergian's equation for a one-DOF linkage, built only from the effects a scene declares.

    𝔍(x_i) ẍ_i + ζ(x_i) ẋ_i² + dV/dx_i = Q_i(t, x_i, ẋ_i)

    𝔍 = Σ m |K_G|² + I_G K_θ²                (a pivoted body: mass 0, I about its pivot)
    ζ = ½ d𝔍/dx_i = Σ m K_G·L_G + I_G K_θ L_θ
    V = −Σ m g·r_G + Σ ½ k_s (D_s − D0_s)²    (D = |r_a − r_b| between the element's points)
    Q_i = load(t)·dq/dx_i + Σ F_p(q) e_p·K_P − Σ b_d K_Dd² ẋ_i   (K_D = dD/dx_i)

x_i is the chart's independent coordinate (any joint coordinate: a body angle or a slider
displacement, :mod:`reduced.partition`); every K and L is a derivative with respect to it.
The input q = drive·x; dq/dx_i = drive·K. Units: with x_i an angle 𝔍, ζ in kg·m², dV/dx_i and
Q_i in N·m; with a displacement, kg and N.

Two evaluations of the same equation: the general one on the loop system's plain arrays
(:mod:`reduced.loops`), and the seed's four-bar closed form (:class:`reduced.linkage.FourBar`,
phasor sums) for scenes given with the ``four_bar`` shorthand and no point forces — a fast
path, checked against the general one in the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import loops
from .linkage import FourBar, GeneralLinkage, Kinematics, LoopLinkage, PhasorSum
from .loads import TabulatedForce
from .mechanism import GROUND
from .scene import Scene


@dataclass(frozen=True)
class _MassTerm:
    """One link's share of 𝔍 (closed-form path): mass at a point G, plus an inertia about it."""

    mass: float  # 0 for a pivoted body described by its pivot inertia
    centre: PhasorSum
    rotational_inertia: float  # I_G, or I_O when centre is the fixed pivot
    angle_index: int


@dataclass(frozen=True)
class _LineElement:
    """A damper or spring between two points (closed-form path)."""

    end_a: PhasorSum
    end_b: PhasorSum
    coefficient: float  # b (N·s/m) or k (N/m)
    rest_length: float = 0.0


@dataclass(frozen=True)
class Coefficients:
    """The reduced model's coefficients at one configuration, with respect to the chart's
    coordinate x_i (rad or m)."""

    kinematics: Kinematics
    generalized_inertia: float  # 𝔍 (kg·m² or kg)
    centrifugal: float  # ζ
    potential_gradient: float  # dV/dx_i (N·m or N)
    damping: float  # Σ b K_D² (N·m·s or N·s/m)
    potential: float  # V (J)
    input_rate: float = 1.0  # dq/dx_i: 1 when the input q is the coordinate
    point_force: float = 0.0  # Σ F(q) e·K_P, the point forces' generalized force (N·m or N)

    def acceleration(self, load: float, rate: float) -> float:
        """ẍ_i from Eksergian's equation at coordinate rate ẋ_i and input load (N·m or N)."""
        Q = load * self.input_rate - self.damping * rate
        if self.point_force:
            Q += self.point_force
        return (Q - self.centrifugal * rate * rate - self.potential_gradient) / self.generalized_inertia


def _select(table: loops.TermTable, rows: list[int]) -> loops.TermTable:
    """The rows ``rows`` of a term table, in that order (plain arrays)."""
    index = {r: k for k, r in enumerate(rows)}
    keep = np.array([r in index for r in table.row.tolist()], dtype=bool)
    return loops.TermTable(offset=table.offset[rows].reshape(-1, 2),
                           row=np.array([index[r] for r in table.row[keep].tolist()], dtype=np.intp),
                           coef=table.coef[keep], mag=table.mag[keep], angle=table.angle[keep],
                           phase=table.phase[keep])


class MechanismModel:
    """Eksergian's equation for one scene; knows which effects it contains.

    Parameters
    ----------
    scene : Scene
        The validated scene.
    closed_form : bool, optional
        Use the four-bar closed form (default: when the scene used the ``four_bar`` shorthand
        and has no point forces). False forces the general path.
    """

    def __init__(self, scene: Scene, closed_form: bool | None = None):
        self.scene = scene
        mech = scene.mechanism
        linkage = mech.linkage
        self.system = loops.compile_linkage(linkage)
        self.effects: tuple[str, ...] = scene.effects
        self.load = scene.load
        self._gravity = scene.gravity
        can_close = scene.four_bar is not None and not mech.point_forces
        if closed_form is None:
            closed_form = can_close
        if closed_form and not can_close:
            raise ValueError("the closed form needs a four_bar shorthand scene without point forces")
        self.closed_form = bool(closed_form)
        self.general = GeneralLinkage(self.system, scene.x0)
        bodies = linkage.body_map
        self._masses = np.array([bodies[b].mass for b in linkage.moving])
        self._inertias = np.array([bodies[b].inertia for b in linkage.moving])
        self._nb = len(linkage.moving)
        # element ends and point-force points as a small term table (rows 2k, 2k+1: ends of k)
        elements = list(mech.dampers) + list(mech.springs)
        self._n_dampers = len(mech.dampers)
        ends = []
        for e in elements:
            ends += [self.system.point_index(e.body_a, e.point_a), self.system.point_index(e.body_b, e.point_b)]
        self._ends = _select(self.system.points, ends) if ends else None
        self._coefficient = np.array([e.coefficient for e in elements])
        self._rest = np.array([e.rest_length for e in elements])
        pf = mech.point_forces
        self._forces = tuple(TabulatedForce(p.coordinate, p.values, p.period) for p in pf)
        self._force_points = (_select(self.system.points, [self.system.point_index(p.body, p.point) for p in pf])
                              if pf else None)
        self._force_dirs = np.array([[math.cos(p.direction), math.sin(p.direction)] for p in pf]).reshape(-1, 2)
        if self.closed_form:
            self.linkage: LoopLinkage = FourBar(scene.four_bar)
            self._build_closed_form()
        else:
            self.linkage = self.general

    # -- the closed-form path (the seed's four-bar; same arithmetic as before the general port)
    def _build_closed_form(self) -> None:
        mech = self.scene.mechanism
        fb = self.linkage.bodies
        bodies = mech.linkage.body_map

        def point(body: str, name: str) -> PhasorSum:
            p = bodies[body].points[name]
            return PhasorSum.fixed(p) if body == GROUND else fb[body].point(p)
        terms = []
        for name in mech.linkage.moving:
            b, body = bodies[name], fb[name]
            if body.pivoted:  # its inertia about the fixed pivot, the frame origin (as before the port)
                cx, cy = b.com
                pivot = b.inertia + b.mass * (cx ** 2 + cy ** 2) if b.mass else b.inertia
                terms.append(_MassTerm(0.0, body.origin, pivot, body.angle_index))
            else:
                terms.append(_MassTerm(b.mass, body.point(b.com), b.inertia, body.angle_index))
        self._mass_terms = tuple(terms)
        self._dampers = tuple(_LineElement(point(d.body_a, d.point_a), point(d.body_b, d.point_b), d.coefficient)
                              for d in mech.dampers)
        self._springs = tuple(_LineElement(point(s.body_a, s.point_a), point(s.body_b, s.point_b), s.coefficient,
                                           s.rest_length) for s in mech.springs)
        self._gravity_terms = () if self._gravity is None else tuple(
            (bodies[name].mass, fb[name].point(bodies[name].com)) for name in mech.linkage.moving)

    def _closed_form_coefficients(self, kin: Kinematics) -> Coefficients:
        x, K, L = kin.x.tolist(), kin.K.tolist(), kin.L.tolist()  # scalar maths: lists are fastest
        J = zeta = 0.0
        for term in self._mass_terms:
            k_w, l_w = K[term.angle_index], L[term.angle_index]
            J += term.rotational_inertia * k_w * k_w
            zeta += term.rotational_inertia * k_w * l_w
            if term.mass:
                _, _, kx, ky, lx, ly = term.centre.evaluate(x, K, L)
                J += term.mass * (kx * kx + ky * ky)
                zeta += term.mass * (kx * lx + ky * ly)
        dV = V = 0.0
        for mass, centre in self._gravity_terms:
            gx, gy = self._gravity
            rx, ry, kx, ky, _, _ = centre.evaluate(x, K)
            dV -= mass * (gx * kx + gy * ky)
            V -= mass * (gx * rx + gy * ry)
        for spring in self._springs:
            length, k_d = _length_and_rate(spring, x, K)
            stretch = length - spring.rest_length
            dV += spring.coefficient * stretch * k_d
            V += 0.5 * spring.coefficient * stretch * stretch
        damping = 0.0
        for damper in self._dampers:
            _, k_d = _length_and_rate(damper, x, K)
            damping += damper.coefficient * k_d * k_d
        return Coefficients(kin, J, zeta, dV, damping, V, input_rate=K[0])

    # -- the general path (plain arrays) -------------------------------------
    def _general_coefficients(self, kin: Kinematics) -> Coefficients:
        """𝔍, ζ, dV/dx_i, damping, V and the point forces at general coordinates x."""
        x, K, L = kin.x, kin.K, kin.L
        system, nb = self.system, self._nb
        kc, lc = loops.rates(system.centres, x, K, L)
        kt, lt = K[:nb], L[:nb]
        m, inertia = self._masses, self._inertias
        J = float(m @ np.einsum("ij,ij->i", kc, kc) + inertia @ (kt * kt))
        zeta = float(m @ np.einsum("ij,ij->i", kc, lc) + inertia @ (kt * lt))
        dV = V = damping = force = 0.0
        if self._gravity is not None:
            g = np.asarray(self._gravity, dtype=float)
            rc = loops.positions(system.centres, x)
            dV -= float(m @ (kc @ g))
            V -= float(m @ (rc @ g))
        if self._ends is not None:
            r = loops.positions(self._ends, x)
            kr, _ = loops.rates(self._ends, x, K)
            d = r[0::2] - r[1::2]
            kd_vec = kr[0::2] - kr[1::2]
            length = np.hypot(d[:, 0], d[:, 1])
            k_d = np.einsum("ij,ij->i", d, kd_vec) / length
            nd = self._n_dampers
            damping = float(self._coefficient[:nd] @ (k_d[:nd] * k_d[:nd]))
            stretch = length[nd:] - self._rest[nd:]
            dV += float(self._coefficient[nd:] @ (stretch * k_d[nd:]))
            V += float(0.5 * self._coefficient[nd:] @ (stretch * stretch))
        if self._forces:
            q = float(self.system.drive @ x)
            kp, _ = loops.rates(self._force_points, x, K)
            along = np.einsum("ij,ij->i", kp, self._force_dirs)
            force = float(sum(f(q) * a for f, a in zip(self._forces, along.tolist())))
        return Coefficients(kin, J, zeta, dV, damping, V, input_rate=float(self.system.drive @ K),
                            point_force=force)

    # -- coefficients -------------------------------------------------------
    def coefficients_from(self, kin: Kinematics) -> Coefficients:
        """The coefficients for kinematics (in :attr:`linkage`'s coordinates) whose K, L are
        derivatives with respect to any one coordinate."""
        if self.closed_form:
            return self._closed_form_coefficients(kin)
        return self._general_coefficients(kin)

    def coefficients(self, q: float) -> Coefficients:
        """The coefficients at input q (rad or m) on the scene's assembly, with q as the
        coordinate (closed form: the scene's branch; general: Newton from x0)."""
        if self.closed_form:
            return self._closed_form_coefficients(self.linkage.kinematics(q))
        return self.coefficients_at(self.general.assemble(q))

    def coefficients_at(self, x) -> Coefficients:
        """The coefficients at an assembled configuration x (general coordinates,
        :class:`reduced.loops.LoopSystem`, shape (n,)) with the input q as the coordinate:
        ½ 𝔍 q̇² is the kinetic energy there. Always the general path.

        Raises NumericalFailure(SINGULAR) where q cannot drive the linkage.
        """
        x = np.asarray(x, dtype=float)
        K, L = loops.coefficients(self.system, x)
        return self._general_coefficients(Kinematics(x=x, K=K, L=L))

    def generalized_inertia(self, q: float) -> float:
        """𝔍(q) (kg·m² or kg)."""
        return self.coefficients(q).generalized_inertia

    # -- the equation of motion ----------------------------------------------
    def acceleration_on_piece(self, start: float, end: float) -> Callable[[float, float, float], float]:
        """q̈ = f(t, q, q̇) on one smooth piece [start, end] of the load history (q the coordinate).

        The load is taken from the open interval (start, end) even at its ends, so a
        step that ends on a pulse edge sees only one side of it (seed-notes erratum 5, README).
        """
        load = self.load_on_piece(start, end)

        def f(t: float, q: float, qdot: float) -> float:
            return self.coefficients(q).acceleration(load(t), qdot)

        return f

    def load_on_piece(self, start: float, end: float) -> Callable[[float], float]:
        """The input load on one smooth piece of its history (N·m or N), zero without one."""
        return self.load.on_piece(start, end) if self.load is not None else (lambda t: 0.0)

    @property
    def load_edges(self) -> tuple[float, ...]:
        """Times (s) where the applied loads jump."""
        return self.load.edges if self.load is not None else ()


def _length_and_rate(element: _LineElement, x, K) -> tuple[float, float]:
    """Length D (m) of a line element and K_D = dD/dx_i."""
    bx, by, kbx, kby, _, _ = element.end_b.evaluate(x, K)
    ax, ay, kax, kay, _, _ = element.end_a.evaluate(x, K)
    dx, dy = bx - ax, by - ay
    length = math.hypot(dx, dy)
    k_d = (dx * (kbx - kax) + dy * (kby - kay)) / length
    return length, k_d
