"""One comparison: the same scene through both engines, their differences and the gate."""

from __future__ import annotations

from dataclasses import dataclass, replace

from typing import Any

from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE
from loopcheck.results import EngineResult
from loopcheck.scene import Scene
from loopcheck.scene import Tolerances

from .settings import mujoco_settings, reduced_settings
from .diff import (Difference, GateResult, ModeCheck, compare_modes, compare_trajectories, gate_inputs,
                   peak_floor_of)


@dataclass(frozen=True)
class Comparison:
    """Two engines' results for one scene by role, how far apart they are, and the verdict:
    ``reference`` (the reduced engine's run, :data:`loopcheck.registry.REFERENCE`) and ``other``
    (the run judged against it: MuJoCo's in the default comparison, any engine's with
    ``--engines``; ``other.engine`` names it).

    ``diff`` is the first input's difference (the one input's); with several inputs
    (:attr:`loopcheck.scene.Scene.inputs`), ``other_diffs`` holds each later input's, in order,
    and :attr:`diffs` all of them; the gate judges every input."""

    scene: Scene
    reference: EngineResult
    other: EngineResult
    diff: Difference
    modes: ModeCheck  # assembly mode of each loop, the other engine's against the reference's
    gate: GateResult
    other_diffs: tuple[Difference, ...] = ()

    @property
    def diffs(self) -> tuple[Difference, ...]:
        """Every input's difference, in the scene's inputs order (one for a one-DOF scene)."""
        return (self.diff, *self.other_diffs)


def compare_engines(scene: Scene, *, reduced: Any = None, mujoco: Any = None,
                    tolerances: Tolerances | None = None) -> Comparison:
    """Run the default comparison's engines on ``scene`` (:data:`loopcheck.registry.DEFAULT_ENGINES`:
    the reduced reference, settings ``reduced``, and MuJoCo, settings ``mujoco``) and compare
    MuJoCo against the reference.

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
    other_engine = ENGINES[next(name for name in DEFAULT_ENGINES if name != REFERENCE)]
    tolerances = tolerances or scene.tolerances_for(other_engine.name)
    reference = ENGINES[REFERENCE].simulate(scene, reduced or reduced_settings(scene))
    other = other_engine.simulate(replace(scene, tolerances=tolerances), mujoco or mujoco_settings(scene))
    return judge(scene, reference, other, tolerances)


def judge(scene: Scene, reference: EngineResult, other: EngineResult, tolerances: Tolerances) -> Comparison:
    """Compare two finished runs of ``scene`` over its whole horizon and gate them: every input's
    trajectory (:attr:`loopcheck.results.EngineResult.inputs`), each judged by the gate
    (:func:`loopcheck.compare.diff.gate_inputs`).

    Raises
    ------
    ValueError
        When a run does not record one trajectory per input of the scene."""
    for run in (reference, other):
        if len(run.inputs) != scene.dof:
            raise ValueError(f"the {run.engine} run of '{scene.name}' records {len(run.inputs)} input trajectories, "
                             f"the scene has {scene.dof} inputs ({', '.join(scene.inputs)})")
    diffs = tuple(compare_trajectories(ref, oth, horizon=scene.horizon, peak_floor=peak_floor_of(tolerances))
                  for (ref, _), (oth, _) in zip(reference.inputs, other.inputs))
    modes = compare_modes(reference.joints, other.joints)
    verdict = gate_inputs(diffs, tolerances, modes, units=scene.input_units(), names=scene.inputs)
    verdict = _name_the_fixed_step(scene, other, verdict)
    return Comparison(scene=scene, reference=reference, other=other, diff=diffs[0], modes=modes,
                      gate=verdict, other_diffs=diffs[1:])


def _name_the_fixed_step(scene: Scene, run: EngineResult, verdict: GateResult) -> GateResult:
    """A failed gate also carries what the run's engine says about it
    (:meth:`loopcheck.registry.Engine.gate_notes`: MuJoCo at a fixed timestep names where the step
    came from)."""
    if verdict.passed or run.engine not in ENGINES:
        return verdict
    notes = ENGINES[run.engine].gate_notes(scene, run, verdict.failures)
    return replace(verdict, failures=(*verdict.failures, *notes)) if notes else verdict
