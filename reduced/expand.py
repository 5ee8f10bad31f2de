"""The ``type = "four_bar"`` scene shorthand expanded into the general linkage description.

Bodies and their frames are those of :class:`reduced.scene.BodyInertia` (the same frames as
:class:`reduced.linkage.FourBar`): ground holds O1 = (0, 0) and O3 = (c4, 0); the crank has
its origin at O1 and A = (c1, 0); the coupler its origin at A and B = (c2, 0); the rocker its
origin at O3 and B = (c3, 0). So the general coordinates are the absolute frame angles
(crank, coupler, rocker) = (q, φ1, φ2 + π) of the closed form. Point names added to the
bodies:

- ``"G"`` (:data:`COM`): a moving body's centre of mass, when the scene gives one;
- ``"damper<k>"`` / ``"spring<k>"``: the two ends of the k-th damper or spring, one on ground
  and one on its body (k counts from 0 in the scene's order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .linkage import FourBar
from .loops import AssemblyError, LoopSystem, assemble, compile_linkage
from .mechanism import GROUND, Body, Linkage, MechanismError, RevoluteJoint
from .scene import Scene

COM = "G"
INPUT_JOINT = "O1"
# The Newton assembly must land on the closed form's configuration: both are exact to
# round-off (~1e-15 rad), so anything above this is another assembly, not noise.
SAME_ASSEMBLY_RAD = 1e-9


@dataclass(frozen=True)
class LineElement:
    """A damper or spring between two named points of the expanded linkage.

    ``coefficient`` is b (N·s/m) for a damper, k (N/m) for a spring; ``rest_length`` (m) is
    the spring's D0 (0 for a damper).
    """

    kind: str
    name: str
    body_a: str
    point_a: str
    body_b: str
    point_b: str
    coefficient: float
    rest_length: float = 0.0

    def __post_init__(self):
        if self.kind not in ("damper", "spring"):
            raise MechanismError(f"line element {self.name!r}: kind must be 'damper' or "
                                 f"'spring', got {self.kind!r}")
        if not (math.isfinite(self.coefficient) and self.coefficient > 0.0):
            raise MechanismError(f"line element {self.name!r}: coefficient must be positive "
                                 f"and finite, got {self.coefficient}")
        if not (math.isfinite(self.rest_length) and self.rest_length >= 0.0):
            raise MechanismError(f"line element {self.name!r}: rest_length must be ≥ 0 m, "
                                 f"got {self.rest_length}")


@dataclass(frozen=True)
class MassPoint:
    """A body's share of 𝔍: ``mass`` (kg) at ``point`` and ``inertia`` (kg·m²) about it.

    A pivoted link given only by its pivot inertia has mass 0 at its pivot.
    """

    body: str
    point: str
    mass: float
    inertia: float

    def __post_init__(self):
        for f in ("mass", "inertia"):
            v = getattr(self, f)
            if not (math.isfinite(v) and v >= 0.0):
                raise MechanismError(f"body {self.body!r}: {f} must be ≥ 0 and finite, got {v}")


def four_bar_elements(scene: Scene) -> tuple[LineElement, ...]:
    """The scene's dampers, then its springs, between the points the expansion names."""
    out = [LineElement("damper", f"damper{k}", GROUND, f"damper{k}", d.body, f"damper{k}",
                       d.coefficient) for k, d in enumerate(scene.dampers)]
    out += [LineElement("spring", f"spring{k}", GROUND, f"spring{k}", s.body, f"spring{k}",
                        s.stiffness, s.rest_length) for k, s in enumerate(scene.springs)]
    return tuple(out)


def four_bar_masses(scene: Scene) -> tuple[MassPoint, ...]:
    """Mass at the centre of mass with the centroidal inertia where the scene gives them,
    else the pivot inertia at the link's fixed pivot (crank O1, rocker O3)."""
    pivots = {"crank": "O1", "rocker": "O3"}
    out = []
    for name, b in scene.bodies.items():
        if b.has_mass_distribution and b.centroidal_inertia is not None:
            out.append(MassPoint(name, COM, b.mass, b.centroidal_inertia))
        else:
            out.append(MassPoint(name, pivots[name], 0.0, b.pivot_inertia))
    return tuple(out)


def four_bar_description(scene: Scene) -> Linkage:
    """The general :class:`~reduced.mechanism.Linkage` of a four-bar scene (no assembly)."""
    g = scene.linkage
    points = {GROUND: {"O1": (0.0, 0.0), "O3": (g.c4, 0.0)},
              "crank": {"O1": (0.0, 0.0), "A": (g.c1, 0.0)},
              "coupler": {"A": (0.0, 0.0), "B": (g.c2, 0.0)},
              "rocker": {"O3": (0.0, 0.0), "B": (g.c3, 0.0)}}
    for name, b in scene.bodies.items():
        if b.com is not None:
            points[name][COM] = tuple(b.com)
    for kind, items in (("damper", scene.dampers), ("spring", scene.springs)):
        for k, item in enumerate(items):
            points[GROUND][f"{kind}{k}"] = tuple(item.ground_point)
            points[item.body][f"{kind}{k}"] = tuple(item.body_point)
    return Linkage(
        bodies=[Body(name, pts) for name, pts in points.items()],
        joints=[RevoluteJoint("O1", GROUND, "O1", "crank", "O1"),
                RevoluteJoint("A", "crank", "A", "coupler", "A"),
                RevoluteJoint("B", "coupler", "B", "rocker", "B"),
                RevoluteJoint("O3", GROUND, "O3", "rocker", "O3")],
        input_joint=INPUT_JOINT)


def four_bar_linkage(scene: Scene) -> tuple[Linkage, LoopSystem, np.ndarray]:
    """The four-bar shorthand as the general description, assembled at the scene's q0.

    Returns
    -------
    linkage : Linkage
    system : LoopSystem
        Its compiled loop kinematics; coordinates (crank, coupler, rocker) angles (rad).
    x0 : ndarray, shape (3,)
        The configuration at q0 on the scene's branch, found by Newton's method from the
        closed form's (:meth:`FourBar.assemble`) and checked to be that one.

    Raises
    ------
    AssemblyError
        If Newton's method lands elsewhere than the closed form's assembly.
    """
    linkage = four_bar_description(scene)
    system = compile_linkage(linkage)
    q, phi1, phi2 = FourBar(scene.linkage).assemble(scene.q0)
    guess = np.array([q, phi1, phi2 + math.pi])
    x0 = assemble(system, scene.q0, guess)
    gap = np.max(np.abs(np.angle(np.exp(1j * (x0 - guess)))))
    if not gap <= SAME_ASSEMBLY_RAD:
        raise AssemblyError(f"the general description assembles {gap:.3g} rad away from the "
                            f"four-bar closed form at q = {scene.q0:.15g} rad (branch "
                            f"{scene.linkage.branch})")
    return linkage, system, x0
