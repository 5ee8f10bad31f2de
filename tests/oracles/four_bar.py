"""The seed's four-bar velocity and acceleration analysis in closed form: the tests' oracle.

The seed notes' formulas (with the errata of docs/physics.md) for K, L and the conditioning of
the four-bar O1-A-B-O3, checked against the general compiled path (the engine always runs that
one). The closed-form position analysis they build on is :class:`loopcheck.four_bar.FourBar`, which
production keeps to assemble a ``four_bar`` shorthand scene at q0 (docs/architecture.md says why).

Coordinates x = (q, φ1, φ2): crank, coupler, and the vector B → O3 (the rocker's own angle is
φ2 + π).
"""

from __future__ import annotations

import math

import numpy as np

from loopcheck import four_bar
from loopcheck.errors import NumericalFailure
from loopcheck.kinematics import SINGULAR_CONDITIONING, Kinematics


class FourBar(four_bar.FourBar):
    """:class:`loopcheck.four_bar.FourBar` with the seed's K and L and the conditioning."""

    def loop_residual(self, x: np.ndarray) -> np.ndarray:
        """c1 e(q) + c2 e(φ1) + c3 e(φ2) − c4 e(0), shape (2,) (m)."""
        g = self.geometry
        q, p1, p2 = x
        return np.array([g.c1 * math.cos(q) + g.c2 * math.cos(p1) + g.c3 * math.cos(p2) - g.c4,
                         g.c1 * math.sin(q) + g.c2 * math.sin(p1) + g.c3 * math.sin(p2)])

    def conditioning(self, x: np.ndarray) -> np.ndarray:
        """The conditioning of each coordinate (:func:`loopcheck.kinematics.conditioning`) for the four-bar:
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

        Raises NumericalFailure(SINGULAR) where |sin(φ2 − φ1)|, the crank's conditioning, is below
        the project's one threshold (:data:`loopcheck.kinematics.SINGULAR_CONDITIONING`).
        """
        g = self.geometry
        x = self.assemble(q, branch)
        _, p1, p2 = x
        s21 = math.sin(p2 - p1)
        if abs(s21) < SINGULAR_CONDITIONING:
            raise NumericalFailure("singular", f"dead-centre position at q = {q:.15g} rad: "
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
