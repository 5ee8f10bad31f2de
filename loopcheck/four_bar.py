"""The seed's four-bar in closed form: its assembly at q0, for the ``four_bar`` shorthand.

The seed notes solve the four-bar O1-A-B-O3 by hand. The one part of their closed form that
production uses is the position analysis, to assemble a shorthand scene at q0 on its branch:
the scene file polishes it with the general Newton (:func:`loopcheck.scenefile._assemble_four_bar`)
and the MuJoCo model is authored at it (:func:`loopcheck.mujoco_model.build.assembled_angles`).
Newton alone, from a guess on the branch, gives other last bits and moved the shipped runs by up
to 1.7e-6 (and could not reach a start exactly at a limit position, a double root:
``scenes/hard/start_dead_centre.toml``); docs/architecture.md gives the measurements. The
velocity and acceleration closed forms (K, L, the conditioning) are the tests' independent
oracle (``tests/oracles/four_bar.py``); the engine always runs the general path.

Coordinates x = (q, φ1, φ2): crank, coupler, and the vector B → O3, so the rocker's own angle
is φ2 + π (:meth:`FourBar.to_general` maps to the general coordinates).
"""

from __future__ import annotations

import math

import numpy as np

from .scene import FourBarGeometry

# A negative discriminant this small relative to A² + B² is round-off at a limit position.
ASSEMBLY_TOLERANCE = 1e-12


class AssemblyError(ValueError):
    """The linkage cannot be assembled at the requested input angle."""


class FourBar:
    """The four-bar O1-A-B-O3 of the seed: c1 e(q) + c2 e(φ1) + c3 e(φ2) − c4 e(0) = 0.

    Coordinates x = (q, φ1, φ2); φ2 is the angle of the vector B→O3, so the rocker's own
    angle (O3→B) is φ2 + π.
    """

    coordinate_names = ("q", "phi1", "phi2")

    def __init__(self, geometry: FourBarGeometry):
        self.geometry = geometry

    def to_general(self, X: np.ndarray) -> np.ndarray:
        """(q, φ1, φ2) → the general frame angles (crank, coupler, rocker) = (q, φ1, φ2 + π)."""
        out = np.array(X, dtype=float, copy=True)
        out[..., 2] += math.pi
        return out

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


def _wrap(angle: float) -> float:
    """Angle in (−π, π]."""
    return math.atan2(math.sin(angle), math.cos(angle))
