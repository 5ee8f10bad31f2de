"""What an engine run returns: trajectory, peak, energy audit, cost and settings."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from .errors import FailureReason, NumericalFailure
from .trajectory import JointTrajectory, Peak, Trajectory, freeze_arrays


@dataclass(frozen=True)
class EnergyAudit:
    """Energy balance along a run, all in J, each shape (n,) on the times ``t`` (s).

    residual = (T + V) − (T0 + V0) − W_torque + E_damper, zero for an exact solution. The residual
    and the scale are computed once, on first use (the arrays are read-only).
    """

    t: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    torque_work: np.ndarray
    damper_dissipation: np.ndarray

    def __post_init__(self) -> None:
        freeze_arrays(self, ("t", "kinetic", "potential", "torque_work", "damper_dissipation"), float)

    @cached_property
    def residual(self) -> np.ndarray:
        total = self.kinetic + self.potential
        residual = total - total[0] - self.torque_work + self.damper_dissipation
        residual.setflags(write=False)
        return residual

    @cached_property
    def scale(self) -> float:
        """Energy scale for relative figures: the largest of |W_torque|, T, |V − V0| (J)."""
        return float(max(np.max(np.abs(self.torque_work)), np.max(self.kinetic),
                         np.max(np.abs(self.potential - self.potential[0])), 1e-300))

    @cached_property
    def max_abs_residual(self) -> float:
        return float(np.max(np.abs(self.residual)))

    @property
    def relative_residual(self) -> float:
        """max |residual| / scale."""
        return self.max_abs_residual / self.scale

    def gate(self, bound: float, floor: float, who: str, setting: str) -> float:
        """The energy scale the run is judged against, max(:attr:`scale`, ``floor``) (J: a run in
        which almost nothing moves is judged against a floor, such as ½ 𝔍0 (1 unit/s)², never
        against a scale made of round-off); NumericalFailure (ENERGY_IMBALANCE) naming ``who``
        ran and the ``setting`` to change when max |residual| exceeds ``bound`` × it."""
        scale = max(self.scale, floor)
        if not self.max_abs_residual <= bound * scale:
            residual = np.abs(self.residual)
            k = int(np.argmax(np.nan_to_num(residual, nan=np.inf)))
            raise NumericalFailure(FailureReason.ENERGY_IMBALANCE,
                                   f"{who}'s energy balance is off by {residual[k]:.3g} J at t = {self.t[k]:.6g} s, "
                                   f"{residual[k] / scale:.3g} of the energy scale {scale:.6g} J, above {setting} "
                                   f"{bound:g}", float(self.t[k]))
        return scale


@dataclass(frozen=True)
class ConstraintViolation:
    """How far a run's loops open: at each time ``t`` (s), the largest ``gap`` (m) between the two
    points of a cut joint, over the cut joints."""

    t: np.ndarray
    gap: np.ndarray

    def __post_init__(self) -> None:
        freeze_arrays(self, ("t", "gap"), float)

    @property
    def max(self) -> float:
        """The largest gap over the run (m); NaN if a gap was not finite."""
        return float(np.max(self.gap)) if np.all(np.isfinite(self.gap)) else math.nan

    def gate(self, bound: float, who: str, setting: str) -> None:
        """NumericalFailure (CONSTRAINT_DRIFT) naming ``who`` ran, the gap's time and the ``setting``
        to change when a gap is above ``bound`` (m) or not finite."""
        if not self.max <= bound:
            k = int(np.argmax(np.nan_to_num(self.gap, nan=np.inf)))
            raise NumericalFailure(FailureReason.CONSTRAINT_DRIFT,
                                   f"{who}'s loops opened by {self.gap[k]:.3g} m at t = {self.t[k]:.6g} s, above "
                                   f"{setting} {bound:g} m", float(self.t[k]))


@dataclass(frozen=True)
class EngineResult:
    """One engine's run of one scene.

    engine : the engine's name (:data:`loopcheck.registry.ENGINES`: "reduced", "mujoco", "pin").
    trajectory : the input coordinate q (rad, or m for a prismatic input), q̇ and q̈ over time.
    joints : every joint's own coordinate and rate over time (:class:`JointTrajectory`); None for
        a reduced summary run (``loopcheck.reduced.engine.simulate``'s ``summary``: a sweep's row).
    peak : the largest |q̇| and its time.
    audit : the energy balance along the run.
    wall_s : s, the simulation only (no model building, no post-processing).
    n_steps, n_evaluations : the integrator's steps and evaluations of the dynamics.
    settings : the engine's ``Settings`` as the run used them (MuJoCo's automatic timestep
        resolved to the step it chose).
    effects : the physical effects simulated (:data:`loopcheck.scene.EFFECTS`).
    constraint_violation : the loops' opening over time; None for an engine whose loops are
        closed by construction (the reduced engine solves them by Newton to round-off).
    details : the engine's own record of the run (``loopcheck.reduced.engine.ReducedDetails``,
        ``loopcheck.reference_models.run.MujocoDetails``, ``loopcheck.pin.run.PinDetails``,
        ``loopcheck.mjx.run.MjxDetails``), each with ``as_dict()``.
    caveats : known defects of the engine that bear on this run, one line each (e.g. MJX 3.17's
        missing J̇·q̇ on a scene with loops); the comparison prints them beside the verdict.
    other_inputs : with several inputs (:attr:`loopcheck.scene.Scene.inputs`), the trajectories of the
        inputs after the first, in order, each with its peak; empty with one input. ``trajectory``
        and ``peak`` are the first input's; :attr:`inputs` gives them all.
    """

    engine: str
    trajectory: Trajectory
    joints: JointTrajectory | None
    peak: Peak
    audit: EnergyAudit
    wall_s: float
    n_steps: int
    n_evaluations: int
    settings: Any
    effects: tuple[str, ...] = ()
    constraint_violation: ConstraintViolation | None = None
    details: Any = None
    caveats: tuple[str, ...] = ()
    other_inputs: tuple[tuple[Trajectory, Peak], ...] = ()

    @property
    def inputs(self) -> tuple[tuple[Trajectory, Peak], ...]:
        """Every input's trajectory and peak, in the scene's inputs order (one for a one-DOF scene)."""
        return ((self.trajectory, self.peak), *self.other_inputs)
