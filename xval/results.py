"""What an engine run returns: trajectory, peak, energy audit, cost and settings."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .trajectory import Peak, Trajectory


@dataclass(frozen=True)
class EnergyAudit:
    """Energy balance along a run, all in J, each shape (n,) on the times ``t`` (s).

    residual = (T + V) − (T0 + V0) − W_torque + E_damper, zero for an exact solution.
    """

    t: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    torque_work: np.ndarray
    damper_dissipation: np.ndarray

    def __post_init__(self) -> None:
        for name in ("t", "kinetic", "potential", "torque_work", "damper_dissipation"):  # read-only results
            a = np.array(getattr(self, name), dtype=float, copy=True)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def residual(self) -> np.ndarray:
        total = self.kinetic + self.potential
        return total - total[0] - self.torque_work + self.damper_dissipation

    @property
    def scale(self) -> float:
        """Energy scale for relative figures: the largest of |W_torque|, T, |V − V0| (J)."""
        return float(max(np.max(np.abs(self.torque_work)), np.max(self.kinetic),
                         np.max(np.abs(self.potential - self.potential[0])), 1e-300))

    @property
    def max_abs_residual(self) -> float:
        return float(np.max(np.abs(self.residual)))

    @property
    def relative_residual(self) -> float:
        """max |residual| / scale."""
        return self.max_abs_residual / self.scale


@dataclass(frozen=True)
class EngineResult:
    """One engine's run of one scene."""

    engine: str  # "reduced" or "mujoco"
    trajectory: Trajectory
    peak: Peak
    audit: EnergyAudit
    wall_s: float  # simulation only: no model building, no post-processing
    n_steps: int
    n_evaluations: int
    settings: dict
    diagnostics: dict = field(default_factory=dict)
