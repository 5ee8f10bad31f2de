"""`loopcheck check model.xml`: a user's MuJoCo model, as written, against the exact answer.

MuJoCo's own part of the check: the model is read as a scene (:func:`loopcheck.reference_models.mjcf_import.import_mjcf`),
the comparison runs the reduced reference on that scene and hands it here with its judge
(:func:`loopcheck.compare.model_check.check_model`), and MuJoCo runs the model with its own
options (:func:`loopcheck.reference_models.user_model.run_model`). Then each of the model's own
settings that can cause a difference is changed alone:

- the loops' softness: the same step, the loops as stiff as MuJoCo allows at it (solref
  (2·timestep, 1), solimp (0.9999, 0.9999, 0.001, 0.5, 2));
- the timestep: a tenth of it, the loops as written;
- where the model has dry friction (``frictionloss`` on a joint or tendon, which MuJoCo makes soft:
  it creeps while the exact solution sticks): the same step, the friction rows as stiff as the
  loops' (solreffriction (2·timestep, 1), solimpfriction (0.9999, 0.9999, 0.001, 0.5, 2)).

Each of these two has its own budget of TRIAL_STEPS steps (and a run's MAX_STEPS): past it, the
trial is skipped with a note, and the model as written still gets its verdict.

A model whose exact solution does not move (:class:`VacuousCheck`) is refused before MuJoCo runs:
nothing the gate compares could differ.

The one that removes more of the difference is named as its cause. Last, the cheapest options
that meet the tolerances with margin over the scene's horizon (every difference at most MARGIN,
half, of its tolerance) at their step and again at half of it: stiff loops at the model's step,
then at halved steps until a step and its half both do (or, when the model's own step does, at
doubled steps while they do, up to a tenth of the horizon), with the model's integrator and with
RK4; cheapest is fewest evaluations of the dynamics (RK4 makes four a step). The output states the
margin found.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.results import EngineResult
from loopcheck.scene import Scene, SceneError, Tolerances

from .mjcf_import import ImportedModel
from .settings import DEFAULT_SOLIMP
from .user_model import MAX_STEPS, ModelOptions, input_coordinate, run_model

# The comparison's judge (loopcheck.compare.run.judge): two runs of a scene and the tolerances -> their
# comparison (``.diff``, ``.gate``, ``.other``), handed in, since an engine imports nothing of the comparison.
Judge = Callable[[Scene, EngineResult, EngineResult, Tolerances], Any]

MAX_HALVINGS = 8  # the cheapest-options search tries steps down to timestep / 2⁸
SEARCH_STEPS = 1_000_000  # MuJoCo steps all the search's runs may take together (about 2 min at 150 µs a step)
MARGIN = 0.5  # a suggestion's differences are at most half their tolerances, at its step and at half of it
STEP_FACTOR = 10  # the timestep variant runs at timestep / 10
TRIAL_STEPS = SEARCH_STEPS  # the comparison trials' (stiff loops, timestep / 10) own budget each, in steps


class VacuousCheck(SceneError):
    """A check of a model whose exact solution does not move (max |q̇| ≤ omega_atol and
    max |q − q0| ≤ q_atol over the horizon): the gate could see no difference, so it would pass
    whatever MuJoCo did. Bad input (exit 2): the model has no load that moves it (``--ctrl``,
    ``--keyframe``)."""


def refuse_vacuous(reference: EngineResult, tolerances: Tolerances, where: str, unit: str) -> None:
    """Raise :class:`VacuousCheck` when the reference ``reference`` does not move by more than the
    gate's tolerances (with several inputs: none of them does); ``where`` names the model and the
    state it was read at."""
    moved = max(float(np.max(np.abs(trajectory.q - trajectory.q[0]))) for trajectory, _ in reference.inputs)
    fastest = max(float(np.max(np.abs(trajectory.qdot))) for trajectory, _ in reference.inputs)
    if fastest <= tolerances.omega_atol and moved <= tolerances.q_atol:
        raise VacuousCheck(f"{where}: the exact solution does not move (max |q̇| {fastest:.3g} {unit}/s ≤ omega_atol "
                           f"{tolerances.omega_atol:g}, max |q − q0| {moved:.3g} {unit} ≤ q_atol {tolerances.q_atol:g} "
                           f"over {reference.trajectory.t[-1]:g} s): the check could not fail; load the model with "
                           "--ctrl, or read a keyframe with rates or control with --keyframe")


def refuse_vacuous_model(imported: ImportedModel, reference: EngineResult, *, tolerances: Tolerances) -> None:
    """:func:`refuse_vacuous` for the user's model ``imported``, named by its file and the state it
    was read at (a keyframe or qpos0)."""
    scene = imported.scene
    read_at = f"keyframe '{imported.keyframe}'" if imported.keyframe else "qpos0"
    refuse_vacuous(reference, tolerances, f"{scene.source or scene.name} (read at {read_at})", scene.input_unit)


@dataclass(frozen=True)
class Trial:
    """One run of the model with ``options``: its comparison with the reference, or why it failed."""

    label: str
    options: ModelOptions
    comparison: Any  # the judge's comparison (loopcheck.compare.run.Comparison), None for a run that failed
    failure: NumericalFailure | None = None
    skipped: str | None = None  # why it was not run (a comparison trial past its budget)

    @property
    def passed(self) -> bool:
        return self.comparison is not None and self.comparison.gate.passed

    @property
    def excesses(self) -> tuple[float, ...]:
        """Each input's worst of |Δ peak|, max |Δq| and max |Δq̇| over its tolerance, in the scene's
        inputs order (one value with one input; inf each for a failed run)."""
        if self.comparison is None:
            return (math.inf,)
        t = self.comparison.gate.tolerances
        return tuple(max(d.peak_omega_abs / t.peak_bound(abs(d.peak_omega_reference)), d.q_max_abs / t.q_atol,
                         d.omega_max_abs / t.omega_atol) for d in self.comparison.diffs)

    @property
    def excess(self) -> float:
        """The worst of |Δ peak|, max |Δq| and max |Δq̇| over its tolerance, over every input (≤ 1
        passes those three; inf for a failed run)."""
        return max(self.excesses)

    def worst_input(self) -> int:
        """The index (in the scene's inputs order) of the input whose difference is the largest
        part of its tolerance (:attr:`excesses`)."""
        return int(np.argmax(self.excesses))

    @property
    def with_margin(self) -> bool:
        """Passes with every difference at most MARGIN of its tolerance."""
        return self.passed and self.excess <= MARGIN

    @property
    def evaluations(self) -> int:
        return self.comparison.other.n_evaluations if self.comparison is not None else 0


def _first_contact(trials) -> NumericalFailure | None:
    """The first of ``trials``' failures that is a contact (two geoms touched), or None."""
    return next((t.failure for t in trials
                 if t.failure is not None and t.failure.reason is FailureReason.CONTACT), None)


@dataclass(frozen=True)
class ModelCheck:
    """The model as written, each setting changed alone, the cause, and the cheapest options found."""

    imported: ImportedModel
    reference: EngineResult
    as_written: Trial
    stiff_loops: Trial
    smaller_step: Trial
    cheapest: Trial | None
    tried: tuple[Trial, ...]
    cheapest_half: Trial | None = None  # the suggestion checked again at half its step
    stiff_friction: Trial | None = None  # the dry friction's rows stiff (a model with frictionloss)

    @property
    def friction_is_the_cause(self) -> bool:
        """The model fails as written, and stiffer friction rows alone meet the tolerances where
        neither stiffer loops nor a smaller step does."""
        return (not self.as_written.passed and self.stiff_friction is not None and self.stiff_friction.passed
                and not self.stiff_loops.passed and not self.smaller_step.passed)

    @property
    def friction_removes_most(self) -> bool:
        """The model fails as written, no trial alone meets the tolerances, and stiffer friction
        rows leave the least of the difference (a friction that sticks in the exact solution, and
        creeps in MuJoCo, through events that the creep then shifts)."""
        trials = (self.stiff_loops, self.smaller_step)
        return (not self.as_written.passed and self.stiff_friction is not None and not self.stiff_friction.passed
                and self.stiff_friction.comparison is not None and not any(t.passed for t in trials)
                and all(self.stiff_friction.excess < t.excess for t in trials))

    @property
    def contact(self) -> NumericalFailure | None:
        """The first contact of any run (the as-written run first, then the trials): two geoms
        touched, which the exact reference cannot follow."""
        return _first_contact(self.tried)

    @property
    def passed(self) -> bool:
        return self.as_written.passed and self.contact is None

    @property
    def cause(self) -> str:
        """Which of the model's settings the difference comes from: the one whose change alone
        meets the tolerances; when neither or both do, both are named, the one that removes more
        of the difference first."""
        if self.contact is not None:
            return "a contact (above): the exact reference has none, so no options can meet the tolerances"
        if self.as_written.passed:
            return "none: the model as written meets the tolerances"
        if self.friction_is_the_cause:
            return FRICTION_CAUSE
        if self.friction_removes_most:
            return (f"mostly {FRICTION_CAUSE}; stiff friction rows alone remove the most of the difference but leave "
                    f"{self.stiff_friction.excess:.3g}× the tolerances (neither stiffer loops nor a smaller step "
                    "meets them either)")
        loops, step = "the loops' softness (the connects' and couplings' solref and solimp)", "the timestep"
        skipped = [t for t in (self.stiff_loops, self.smaller_step) if t.skipped]
        if skipped:
            ran = [t for t in (self.stiff_loops, self.smaller_step) if not t.skipped]
            if ran and ran[0].passed:
                return loops if ran[0] is self.stiff_loops else step
            names = " and ".join(f"the {t.label} trial ({t.skipped})" for t in skipped)
            return f"not found: {names}" + (f"; the {ran[0].label} trial alone does not meet the tolerances"
                                            if ran else "")
        more = {loops: "stiffer loops remove", step: "a smaller step removes"}
        if self.stiff_loops.passed != self.smaller_step.passed:
            return loops if self.stiff_loops.passed else step
        first, second = (loops, step) if self.stiff_loops.excess <= self.smaller_step.excess else (step, loops)
        if self.stiff_loops.passed:
            return f"{first} or {second}: changing either alone meets the tolerances"
        return (f"both {first} and {second}: neither changed alone meets the tolerances ({more[first]} "
                "more of the difference)")


FRICTION_CAUSE = ("the dry friction's softness (frictionloss: MuJoCo's friction rows creep where the exact solution "
                  "sticks): stiffen them with solreffriction and solimpfriction on the joints and tendons with "
                  "frictionloss")


def has_friction(model) -> bool:
    """Whether the model has dry friction (``frictionloss`` on a dof or a tendon)."""
    return bool(np.any(model.dof_frictionloss > 0.0) or np.any(model.tendon_frictionloss > 0.0))


def friction_snippet(timestep: float) -> str:
    """The MJCF that makes every joint's and tendon's friction rows as stiff as the stiff-friction
    trial's (a ``<default>`` of solreffriction and solimpfriction)."""
    solimp = " ".join(f"{v:g}" for v in DEFAULT_SOLIMP)
    values = f'solreffriction="{2.0 * timestep:g} 1" solimpfriction="{solimp}"'
    return f"<default><joint {values}/><tendon {values}/></default>"


def _stiff_friction(imported: ImportedModel, timestep: float) -> ImportedModel:
    """The imported model with its friction rows as stiff as the loops' stiff trial: solref
    (2·timestep, 1), solimp DEFAULT_SOLIMP on every dof and tendon with frictionloss."""
    model = copy.copy(imported.model)
    for d in np.flatnonzero(model.dof_frictionloss > 0.0):
        model.dof_solref[d] = (2.0 * timestep, 1.0)
        model.dof_solimp[d] = DEFAULT_SOLIMP
    for t in np.flatnonzero(model.tendon_frictionloss > 0.0):
        model.tendon_solref_fri[t] = (2.0 * timestep, 1.0)
        model.tendon_solimp_fri[t] = DEFAULT_SOLIMP
    return replace(imported, model=model)


def _trial(imported: ImportedModel, reference: EngineResult, judge: Judge, tolerances: Tolerances, label: str,
           options: ModelOptions, budget: int | None = None) -> Trial:
    """One run; with ``budget`` (a comparison trial's steps), a run of more steps than it, or than
    a run may take (MAX_STEPS), is skipped with a note instead."""
    if budget is not None:
        steps = options.steps(imported.scene.horizon)
        limit = min(budget, MAX_STEPS)
        if steps > limit:
            return Trial(label, options, None, skipped=f"skipped: {steps:.3g} steps at {options.timestep:.3g} s, "
                                                       f"more than this trial's budget of {limit:.3g} steps")
    try:
        result = run_model(imported, options)
    except NumericalFailure as failure:
        return Trial(label, options, None, failure)
    return Trial(label, options, judge(imported.scene, reference, result, tolerances))


def _cheapest_step(options: ModelOptions, horizon: float, trial, tried: list[Trial],
                   budget: float = math.inf) -> tuple[Trial, Trial] | None:
    """The longest step that passes with margin (:attr:`Trial.with_margin`) with stiff loops, and
    passes with margin again at half of it: from the model's step, halving until a step and its half
    both do (MAX_HALVINGS at most, and no step that would cost ``budget`` evaluations or more: a
    cheaper passing run is known); if the model's own step does, doubling while the longer step
    passes with margin (its half is the step before, which did), the step at most a tenth of the
    horizon. Returns the suggestion and its half-step run."""
    def at(h: float, label: str) -> Trial:
        candidate = replace(options, timestep=h).stiff_loops()
        found = next((t for t in tried if t.options == candidate), None)
        if found is None:
            found = trial(label, candidate)
            tried.append(found)
        return found

    def affordable(h: float) -> bool:
        steps = replace(options, timestep=h).steps(horizon)
        spent = sum(t.comparison.other.n_steps for t in tried if t.comparison is not None)
        return steps <= MAX_STEPS and spent + steps <= SEARCH_STEPS

    h = options.timestep
    for halvings in range(MAX_HALVINGS + 1):
        step = h / 2 ** halvings
        if not affordable(step) or replace(options, timestep=step).steps(horizon) * options.evaluations_per_step() >= budget:
            return None
        found = at(step, f"{options.integrator}, timestep / {2 ** halvings}")
        if not found.with_margin:
            continue
        if not affordable(step / 2):
            return None
        half = at(step / 2, f"{options.integrator}, timestep / {2 ** (halvings + 1)}")
        if half.with_margin:
            break
    else:
        return None
    if halvings == 0:
        doublings = 1
        while h * 2 ** doublings <= horizon / 10:
            longer = at(h * 2 ** doublings, f"{options.integrator}, timestep × {2 ** doublings}")
            if not longer.with_margin:
                break
            found, half = longer, found
            doublings += 1
    return found, half


def check_model(imported: ImportedModel, reference: EngineResult, judge: Judge, *,
                tolerances: Tolerances | None = None) -> ModelCheck:
    """Compare the model as written with ``reference``, the reduced solution of its scene, by
    ``judge`` (the comparison's), name the setting that causes the difference, and find the
    cheapest options that meet ``tolerances`` (module docstring).

    Raises
    ------
    VacuousCheck
        If the reference does not move (:func:`refuse_vacuous`): before MuJoCo runs.
    """
    scene = imported.scene
    tolerances = tolerances or scene.tolerances
    refuse_vacuous_model(imported, reference, tolerances=tolerances)
    written = ModelOptions.as_written(imported.model)

    def trial(label: str, options: ModelOptions, budget: int | None = None) -> Trial:
        return _trial(imported, reference, judge, tolerances, label, options, budget)

    as_written = trial("as written", written)  # a run beyond MAX_STEPS is refused (ValueError)
    stiff = trial("stiff loops", written.stiff_loops(), TRIAL_STEPS)
    smaller = trial(f"timestep / {STEP_FACTOR}", replace(written, timestep=written.timestep / STEP_FACTOR), TRIAL_STEPS)
    friction = None
    if has_friction(imported.model) and not as_written.passed:
        friction = _trial(_stiff_friction(imported, written.timestep), reference, judge, tolerances, "stiff friction",
                          written, TRIAL_STEPS)
    tried = [as_written, stiff, smaller]
    cheapest, half = (as_written, None) if as_written.passed else (None, None)
    # the friction the cause: its own snippet, no search of loops and steps (which cannot meet them)
    friction_cause = friction is not None and friction.passed and not (stiff.passed or smaller.passed)
    if cheapest is None and _first_contact(tried) is None and not friction_cause:  # a contact: no options can meet the tolerances
        for integrator in dict.fromkeys(("rk4", written.integrator)):  # RK4's answer bounds the other's search
            budget = cheapest.evaluations if cheapest is not None else math.inf
            found = _cheapest_step(replace(written, integrator=integrator), scene.horizon, trial, tried, budget)
            if found is not None and (cheapest is None or found[0].evaluations < cheapest.evaluations):
                cheapest, half = found
    return ModelCheck(imported=imported, reference=reference, as_written=as_written, stiff_loops=stiff,
                      smaller_step=smaller, cheapest=cheapest, tried=tuple(tried), cheapest_half=half,
                      stiff_friction=friction)


def _figures(trial: Trial, unit: str, names: tuple[str, ...] = (), units: tuple[str, ...] = ()) -> str:
    """A trial's figures: the peak and the largest differences (with several inputs, ``names``,
    the worst input's, named, in its unit of ``units``: the one whose difference is the largest part of its
    tolerance), the
    loops' opening and the energy balance."""
    if trial.skipped:
        return trial.skipped
    if trial.comparison is None:
        return f"failed: {trial.failure}"
    c = trial.comparison
    k = trial.worst_input() if len(names) > 1 else 0
    d = c.diffs[k]
    unit = units[k] if units else unit
    whose = f"worst input '{names[k]}': " if len(names) > 1 else ""
    gap = c.other.constraint_violation.max
    return (f"{whose}peak {d.peak_omega_other:.10g} {unit}/s ({d.peak_omega_rel:.2e} off), max |dq| {d.q_max_abs:.2e} "
            f"{unit}, max |dq/dt| {d.omega_max_abs:.2e} {unit}/s, loops open up to {gap:.2e} m, "
            f"energy balance {c.other.audit.relative_residual:.2e}")


def reference_failure_lines(imported: ImportedModel, failure: NumericalFailure, source: str) -> list[str]:
    """What ``check`` prints when the reduced reference of a user's model fails: the failure, and
    for a range reached, the range as the file writes it (the scene's bounds count from the joint's
    body frame, the file's from its qpos)."""
    lines = [f"FAIL  {source}: numerical failure of the reduced reference ({failure.reason}): {failure}"]
    if failure.joint in imported.range_sources:
        lines.append(f"      in the file: {imported.range_sources[failure.joint]}")
    return lines


def check_lines(check: ModelCheck, source: str) -> list[str]:
    """``loopcheck check``'s lines for one model."""
    scene, imported = check.imported.scene, check.imported
    unit = scene.input_unit
    t = check.as_written.comparison.gate.tolerances if check.as_written.comparison else scene.tolerances
    where = f"keyframe '{imported.keyframe}'" if imported.keyframe else "qpos0"
    status = "ok  " if check.passed else "FAIL"
    names = scene.inputs
    inputs = (f"inputs {', '.join(repr(n) for n in names)}" if len(names) > 1 else f"input '{names[0]}'")
    lines = [f"{status}  {source} ({where}, {inputs}): MuJoCo as written "
             f"({check.as_written.options.text()}) against the exact reduced solution, "
             f"peak {check.reference.peak.omega:.10g} {unit}/s",
             f"      read at {where}: loops closed to {imported.closure_residual:.3g} m, Newton moved the "
             f"configuration by {imported.polish:.3g} (rad or m); {'the first ' if len(names) > 1 else ''}input "
             f"{input_coordinate(imported).text()}",
             f"      horizon: every run simulates {scene.horizon:g} s (--horizon)",
             f"      tolerances: peak_omega_rtol {t.peak_omega_rtol:g}, q_atol {t.q_atol:g} {unit}, "
             f"omega_atol {t.omega_atol:g} {unit}/s",
             f"      as written:        {_figures(check.as_written, unit, names, scene.input_units())}"]
    if check.as_written.comparison is not None:
        lines += [f"      {failure}" for failure in check.as_written.comparison.gate.failures]
    if check.contact is not None and check.contact is not check.as_written.failure:
        lines.append(f"      contact: {check.contact}")
    return lines + diagnosis_lines(check)


def diagnosis_lines(check: ModelCheck) -> list[str]:
    """Each setting changed alone, the cause, and the cheapest options found (``loopcheck run`` prints
    these under its table)."""
    unit = check.imported.scene.input_unit
    names, units = check.imported.scene.inputs, check.imported.scene.input_units()
    lines = [f"      stiff loops:       {_figures(check.stiff_loops, unit, names, units)}",
             f"      timestep / {STEP_FACTOR}:     {_figures(check.smaller_step, unit, names, units)}"]
    if check.stiff_friction is not None:
        lines.append(f"      stiff friction:    {_figures(check.stiff_friction, unit, names, units)}")
    lines.append(f"      the difference comes from: {check.cause}")
    if len(names) > 1 and check.as_written.comparison is not None and not check.as_written.passed:
        failing = [n for n in names if any(f.startswith(f"{n}: ") for f in check.as_written.comparison.gate.failures)]
        worst = names[check.as_written.worst_input()]
        lines.append(f"      the coordinate whose difference fails: "
                     + (", ".join(f"'{n}'" for n in failing) if failing else f"'{worst}'")
                     + f" (the worst, '{worst}': {check.as_written.excesses[check.as_written.worst_input()]:.3g}× its "
                       "tolerance)")
    if check.contact is not None:
        pass  # no search: a contact leaves no options that meet the tolerances
    elif check.friction_is_the_cause:
        lines += ["      paste into the MJCF (the friction rows as stiff as the stiff-friction trial's, "
                  f"solreffriction at 2 × the timestep {check.as_written.options.timestep:g} s):",
                  f"        {friction_snippet(check.as_written.options.timestep)}"]
    elif check.cheapest is None:
        smallest = min(t.options.timestep for t in check.tried)
        lines.append(f"      no options tried meet the tolerances with margin (every difference at most {MARGIN:g} of its "
                     f"tolerance over {check.imported.scene.horizon:g} s, at the step and at half of it; stiff loops, "
                     f"RK4 and the model's integrator, steps down to {smallest:.3g} s, within the search's limit of "
                     f"{SEARCH_STEPS:.3g} steps): loosen the tolerances or shorten the horizon")
    elif check.cheapest is not check.as_written:
        c = check.cheapest
        written = check.as_written.options  # its work as planned (a failed run has no count)
        work = c.evaluations / (written.steps(check.imported.scene.horizon) * written.evaluations_per_step())
        snippet = c.options.mjcf(check.imported.connects)
        onto = (" (a <connect> line's attributes onto the model's connect of that name)" if "<connect " in snippet
                else "")
        margin = (f"margin: every difference at most {c.excess:.2g} of its tolerance over "
                  f"{check.imported.scene.horizon:g} s, {check.cheapest_half.excess:.2g} at half the step "
                  f"(required: {MARGIN:g})")
        lines += [f"      cheapest options that meet them with margin: {c.options.text()} ({c.comparison.other.n_steps} "
                  f"steps, {work:.3g}x the model's work as written); {margin}; paste into the MJCF{onto}:",
                  *(f"        {line}" for line in snippet.splitlines())]
    return lines


__all__ = ["FRICTION_CAUSE", "MARGIN", "MAX_HALVINGS", "SEARCH_STEPS", "TRIAL_STEPS", "ModelCheck", "Trial", "VacuousCheck",
           "check_lines", "check_model", "diagnosis_lines", "friction_snippet", "reference_failure_lines", "refuse_vacuous",
           "refuse_vacuous_model"]
