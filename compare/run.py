"""One comparison: the same scene through both engines, their differences and the gate."""

from __future__ import annotations

from dataclasses import dataclass, replace

from reduced import EngineResult, ReducedSettings, Scene, simulate
from reduced.scene import Tolerances
from reference_models import MujocoSettings, simulate_mujoco

from .diff import Difference, GateResult, compare_trajectories, gate


@dataclass(frozen=True)
class Comparison:
    """Both engines' results for one scene, how far apart they are, and the verdict."""

    scene: Scene
    reduced: EngineResult
    mujoco: EngineResult
    diff: Difference
    gate: GateResult


def compare_engines(scene: Scene, *, reduced: ReducedSettings = ReducedSettings(),
                    mujoco: MujocoSettings = MujocoSettings(),
                    tolerances: Tolerances | None = None) -> Comparison:
    """Run both engines on ``scene`` and compare MuJoCo against the reduced reference.

    ``tolerances`` defaults to the scene's own table.

    Raises
    ------
    NumericalFailure
        If either engine fails.
    """
    reference = simulate(scene, reduced)
    other = simulate_mujoco(scene, mujoco)
    diff = compare_trajectories(reference.trajectory, other.trajectory)
    verdict = gate(diff, tolerances or scene.tolerances)
    return Comparison(scene=scene, reduced=reference, mujoco=other, diff=diff, gate=verdict)


def override_tolerances(base: Tolerances, **overrides: float | None) -> Tolerances:
    """The scene's tolerances with any non-None override applied."""
    return replace(base, **{k: v for k, v in overrides.items() if v is not None})
