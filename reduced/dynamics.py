"""Eksergian's equation for a one-DOF linkage, built only from the effects a scene declares.

    𝔍(q) q̈ + ζ(q) q̇² + dV/dq = Q_nc(t, q, q̇)

    𝔍 = Σ M_i |K_Gi|² + Σ I_Gi K_ωi²       (a pivoted body may use I_O K_ω² instead)
    ζ = ½ d𝔍/dq = Σ M_i K_Gi·L_Gi + Σ I_Gi K_ωi L_ωi
    V = −Σ M_i g·r_Gi + Σ ½ k_s (D_s − D0_s)²
    Q_nc = T(t) − Σ b_d K_Dd² q̇           (K_D = dD/dq, D the damper length)

The same equation holds in any joint angle x_i as the coordinate (for passing the input
link's dead centres): every K and L is then a derivative with respect to x_i, and the
torque on the input link contributes T · dq/dx_i to the generalized force.

Units: 𝔍 in kg·m², ζ in kg·m², dV/dq and Q in N·m (per rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable


from .linkage import FourBar, Kinematics, LoopLinkage, PhasorSum
from .scene import Scene


@dataclass(frozen=True)
class _MassTerm:
    """One link's share of 𝔍: mass M at a point G, plus a rotational inertia about it."""

    mass: float  # 0 for a pivoted body described by its pivot inertia
    centre: PhasorSum
    rotational_inertia: float  # I_G, or I_O when centre is the fixed pivot
    angle_index: int


@dataclass(frozen=True)
class _LineElement:
    """A damper or spring along the line from a fixed point to a body point."""

    ground_point: tuple[float, float]
    attachment: PhasorSum
    coefficient: float  # b (N·s/m) or k (N/m)
    rest_length: float = 0.0


@dataclass(frozen=True)
class Coefficients:
    """The reduced model's coefficients at one configuration."""

    kinematics: Kinematics
    generalized_inertia: float  # 𝔍 (kg·m²)
    centrifugal: float  # ζ (kg·m²)
    potential_gradient: float  # dV/dq (N·m)
    damping: float  # Σ b K_D² (N·m·s)
    potential: float  # V (J)
    input_rate: float = 1.0  # dq/dx_i: 1 when the input angle q is the coordinate

    def acceleration(self, torque: float, rate: float) -> float:
        """ẍ_i from Eksergian's equation at coordinate rate ẋ_i (rad/s) and input torque (N·m)."""
        Q = torque * self.input_rate - self.damping * rate
        return (Q - self.centrifugal * rate * rate - self.potential_gradient) / self.generalized_inertia


class MechanismModel:
    """Eksergian's equation for one scene; knows which effects it contains.

    Parameters
    ----------
    scene : Scene
        The validated scene.
    linkage : LoopLinkage, optional
        Kinematics to use; a :class:`FourBar` of the scene's geometry by default.
    """

    def __init__(self, scene: Scene, linkage: LoopLinkage | None = None):
        self.scene = scene
        self.linkage = linkage if linkage is not None else FourBar(scene.linkage)
        self.effects: tuple[str, ...] = scene.effects
        self._mass_terms = tuple(self._mass_term(name, b) for name, b in scene.bodies.items())
        self._dampers = tuple(
            _LineElement(d.ground_point, self.linkage.bodies[d.body].point(d.body_point),
                         d.coefficient) for d in scene.dampers)
        self._springs = tuple(
            _LineElement(s.ground_point, self.linkage.bodies[s.body].point(s.body_point),
                         s.stiffness, s.rest_length) for s in scene.springs)
        self._gravity = scene.gravity
        self._gravity_terms = () if scene.gravity is None else tuple(
            (b.mass, self.linkage.bodies[name].point(b.com)) for name, b in scene.bodies.items())
        self.torque = scene.torque

    def _mass_term(self, name: str, inertia) -> _MassTerm:
        body = self.linkage.bodies[name]
        if body.pivoted:
            return _MassTerm(0.0, body.origin, inertia.pivot_inertia, body.angle_index)
        return _MassTerm(inertia.mass, body.point(inertia.com), inertia.centroidal_inertia,
                         body.angle_index)

    # -- coefficients -------------------------------------------------------
    def coefficients(self, q: float) -> Coefficients:
        """𝔍, ζ, dV/dq, damping and V at input angle q (rad), with q as the coordinate."""
        return self.coefficients_from(self.linkage.kinematics(q))

    def coefficients_from(self, kin: Kinematics) -> Coefficients:
        """The coefficients for kinematics whose K, L are derivatives w.r.t. any one coordinate."""
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

    def generalized_inertia(self, q: float) -> float:
        """𝔍(q) in kg·m²."""
        return self.coefficients(q).generalized_inertia

    # -- the equation of motion ----------------------------------------------
    def acceleration_on_piece(self, start: float, end: float) -> Callable[[float, float, float], float]:
        """q̈ = f(t, q, q̇) on one smooth piece [start, end] of the load history.

        The torque is taken from the open interval (start, end) even at its ends, so a
        step that ends on a pulse edge sees only one side of it (seed-notes erratum 5, README).
        """
        torque = self.torque_on_piece(start, end)

        def f(t: float, q: float, qdot: float) -> float:
            return self.coefficients(q).acceleration(torque(t), qdot)

        return f

    def torque_on_piece(self, start: float, end: float) -> Callable[[float], float]:
        """T(t) on one smooth piece of the load history (N·m), zero without a torque."""
        return self.torque.on_piece(start, end) if self.torque is not None else (lambda t: 0.0)

    @property
    def load_edges(self) -> tuple[float, ...]:
        """Times (s) where the applied loads jump."""
        return self.torque.edges if self.torque is not None else ()


def _length_and_rate(element: _LineElement, x, K) -> tuple[float, float]:
    """Length D (m) of a line element and K_D = dD/dq (m/rad)."""
    px, py, kx, ky, _, _ = element.attachment.evaluate(x, K)
    dx, dy = px - element.ground_point[0], py - element.ground_point[1]
    length = math.hypot(dx, dy)
    k_d = (dx * kx + dy * ky) / length
    return length, k_d
