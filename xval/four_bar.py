"""The seed's four-bar in closed form: position, velocity and acceleration analysis.

The seed notes solve the four-bar O1-A-B-O3 by hand; these are their formulas (with the
errata of the README), kept as the independent oracle of the general compiled path
(:mod:`xval.reduced.kernels.physics`) and to pick the ``four_bar`` shorthand's assembly branch.
The engine itself always runs the general path.

Coordinates x = (q, φ1, φ2): crank, coupler, and the vector B → O3, so the rocker's own angle
is φ2 + π (:meth:`FourBar.to_general` maps to the general coordinates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import NumericalFailure
from .scene import FourBarGeometry

# Below this |sin(φ2 − φ1)| the input cannot drive the four-bar: a dead-centre position.
SINGULAR_DETERMINANT = 1e-9
# A negative discriminant this small relative to A² + B² is round-off at a limit position.
ASSEMBLY_TOLERANCE = 1e-12


class AssemblyError(ValueError):
    """The linkage cannot be assembled at the requested input angle."""


class SingularPositionError(NumericalFailure):
    """The loop Jacobian is singular: a dead-centre (limit) position of the input."""

    def __init__(self, message: str):
        super().__init__("singular", message)


@dataclass(frozen=True)
class Kinematics:
    """All joint coordinates and their velocity and acceleration coefficients at one
    configuration: x (n,) rad or m, K = dx/dx_i, L = d²x/dx_i² for the coordinate x_i they
    are taken with respect to."""

    x: np.ndarray
    K: np.ndarray
    L: np.ndarray


class FourBar:
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
        self.geometry = geometry

    def loop_residual(self, x: np.ndarray) -> np.ndarray:
        """c1 e(q) + c2 e(φ1) + c3 e(φ2) − c4 e(0), shape (2,) (m)."""
        g = self.geometry
        q, p1, p2 = x
        return np.array([g.c1 * math.cos(q) + g.c2 * math.cos(p1) + g.c3 * math.cos(p2) - g.c4,
                         g.c1 * math.sin(q) + g.c2 * math.sin(p1) + g.c3 * math.sin(p2)])

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
        """The conditioning of each coordinate (:func:`xval.kinematics.conditioning`) for the four-bar:
        (|sin(φ2 − φ1)|, |sin(φ2 − q)|, |sin(φ1 − q)|) for q, φ1, φ2 independent."""
        q, p1, p2 = x[0], x[1], x[2]
        return np.array([abs(math.sin(p2 - p1)), abs(math.sin(p2 - q)), abs(math.sin(p1 - q))])

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


def _wrap(angle: float) -> float:
    """Angle in (−π, π]."""
    return math.atan2(math.sin(angle), math.cos(angle))
