"""One comparison: the same scene through both engines, their differences and the gate."""

from __future__ import annotations

from dataclasses import dataclass, replace

from loopcheck.results import EngineResult
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scene import Scene
from loopcheck.scene import Tolerances
from loopcheck.reference_models import MujocoSettings, simulate_mujoco

from .settings import mujoco_settings, reduced_settings
from .diff import (Difference, GateResult, ModeCheck, compare_modes, compare_trajectories, gate,
                   peak_floor_of)


@dataclass(frozen=True)
class Comparison:
    """Two engines' results for one scene by role, how far apart they are, and the verdict:
    ``reference`` (the reduced engine's run, :data:`loopcheck.registry.REFERENCE`) and ``other``
    (the run judged against it: MuJoCo's in the default comparison, any engine's with
    ``--engines``; ``other.engine`` names it)."""

    scene: Scene
    reference: EngineResult
    other: EngineResult
    diff: Difference
    modes: ModeCheck  # assembly mode of each loop, the other engine's against the reference's
    gate: GateResult


def compare_engines(scene: Scene, *, reduced: ReducedSettings | None = None,
                    mujoco: MujocoSettings | None = None,
                    tolerances: Tolerances | None = None) -> Comparison:
    """Run both engines on ``scene`` and compare MuJoCo against the reduced reference.

    Settings default to the scene's [reduced] and [mujoco] tables over the defaults;
    ``tolerances`` to MuJoCo's in the scene (``[tolerances.mujoco]`` over ``[tolerances]``:
    :meth:`loopcheck.scene.Scene.tolerances_for`). MuJoCo's automatic timestep (without a timestep in
    the settings) is chosen for these tolerances, the ones the gate applies. The comparison covers the scene's horizon:
    if either run stops short of it, the gate fails and names the span compared.

    Raises
    ------
    NumericalFailure
        If either engine fails.
    """
    tolerances = tolerances or scene.tolerances_for("mujoco")
    reference = simulate(scene, reduced or reduced_settings(scene))
    other = simulate_mujoco(replace(scene, tolerances=tolerances), mujoco or mujoco_settings(scene))
    return judge(scene, reference, other, tolerances)


def judge(scene: Scene, reference: EngineResult, other: EngineResult, tolerances: Tolerances) -> Comparison:
    """Compare two finished runs of ``scene`` over its whole horizon and gate them."""
    diff = compare_trajectories(reference.trajectory, other.trajectory, horizon=scene.horizon,
                                peak_floor=peak_floor_of(tolerances))
    modes = compare_modes(reference.joints, other.joints)
    verdict = _name_the_fixed_step(scene, other, gate(diff, tolerances, modes, unit=scene.input_unit))
    return Comparison(scene=scene, reference=reference, other=other, diff=diff, modes=modes,
                      gate=verdict)


def _name_the_fixed_step(scene: Scene, run: EngineResult, verdict: GateResult) -> GateResult:
    """A failed gate of a MuJoCo run at a fixed timestep also names where the step came from:
    the automatic step would have been chosen for the gate's tolerances, a fixed one was not."""
    accuracy = ("peak_omega_abs", "q_max_abs", "omega_max_abs", "omega_vs_q_max_abs")
    if (run.engine != "mujoco" or run.details.timestep_automatic
            or not any(f.startswith(accuracy) for f in verdict.failures)):
        return verdict
    h = run.settings.timestep
    source = ("the scene's [mujoco] timestep" if scene.engine_table("mujoco").get("timestep") == h
              else "the settings (--timestep)")
    note = (f"MuJoCo ran at the fixed timestep {h:g} s from {source}, not a step chosen for these tolerances: "
            f"without it the step is chosen automatically for them")
    return replace(verdict, failures=(*verdict.failures, note))
