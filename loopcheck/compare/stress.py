"""Hard cases: a catalogue of scenes under ``scenes/hard/`` and what each engine does with them.

Every case runs each engine of the list (by default :data:`loopcheck.registry.DEFAULT_ENGINES`, the
design card's pair) with the scene's own settings, each judged against the reference by
its own gate, as ``loopcheck check --engines`` judges it (:func:`loopcheck.compare.engines.check_engines`:
an engine's failure or refusal is its verdict in the case, and the catalogue goes on), plus the
checks its kind of difficulty calls for, engine by engine: coordinate switches at dead centres (the
reference's), each engine's declared probes where a case asks for them
(:meth:`loopcheck.registry.Engine.stress_probes`: a stiff damper's stability per integrator and
step), energy drift over long runs, and the error of a pulse edge off the step grid of every engine
that has one (:meth:`loopcheck.registry.Engine.fixed_step`). A case passes when every engine ran
and passed its gate and every check holds. Nothing is skipped and nothing is marked as expected to
fail.

A scene of several degrees of freedom (``five_bar_fold``: a two-DOF five-bar through a singular
configuration of its inputs' set) is judged the same way over every input: the gate judges each
input (:func:`loopcheck.compare.diff.gate_inputs`), an engine's figures are the worst input's
(:func:`_run_figures`), the switches are the reference's whatever its chart, the probes judge whole
runs, and the drift counts the revolutions of the input that turns most. The off-grid edge is
one input's pulse (``scene.load``): a case that asks for it on a scene of several DOF fails, saying so.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.loads import PulseLoad
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE, Rung
from loopcheck.results import EngineResult
from loopcheck.scene import Scene
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import scenes_dir

from .diff import compare_trajectories, worst_figures
from .engines import check_engines
from .run import Comparison
from .settings import engine_settings

SCHEMA_VERSION = 2  # stress.json: 2 holds each engine's outcome under "engines" (1: two engines' keys)


@dataclass(frozen=True)
class Case:
    """One hard case and what must happen.

    ``expect`` holds probe expectations, each (engine, probe, status): the engine's declared probe
    (``"SERIES@PARAMETER"``, e.g. ``"rkn4@0.001"``) must end with that status (``"unstable"``: the
    instability detected, not returned)."""

    name: str
    scene_file: str  # under the shipped scenes, or an absolute path
    must_switch: bool = False  # the reference must change coordinate and stay continuous
    probes: bool = False  # run and report every engine's stress probes
    expect: tuple[tuple[str, str, str], ...] = ()  # (engine, probe, status): a probe's expected status
    energy_drift: bool = False  # conservative: report each engine's drift per revolution, bound the reference's
    off_grid_edge: bool = False  # quantify the error of a pulse edge off each engine's step grid

    def __post_init__(self):
        for item in self.expect:
            if len(item) != 3 or not all(isinstance(part, str) and part for part in item):
                raise ValueError(f"case '{self.name}': expect holds (engine, probe, status) triples, got {item!r}")
        if self.expect and not self.probes:
            raise ValueError(f"case '{self.name}': a probe is expected but the case runs no probes")

    @property
    def path(self) -> Path:
        own = Path(self.scene_file)
        return own if own.is_absolute() else scenes_dir() / own


CATALOGUE = (
    Case("dead_centre", "hard/dead_centre.toml", must_switch=True),
    Case("start_dead_centre", "hard/start_dead_centre.toml"),
    Case("near_change_point", "hard/near_change_point.toml"),
    # The reference's explicit fixed-step method at 1 ms is far outside its stability region (h/τ ≈ 10):
    # it must say so.
    Case("stiff_damper", "hard/stiff_damper.toml", probes=True, expect=((REFERENCE, "rkn4@0.001", "unstable"),)),
    Case("long_conservative", "hard/long_conservative.toml", energy_drift=True),
    Case("fast_crank", "hard/fast_crank.toml"),
    Case("off_grid_edge", "hard/off_grid_edge.toml", off_grid_edge=True),
    Case("gravity", "hard/gravity.toml", energy_drift=True),
    # General linkages: a slider-driven slider-crank through its dead centres (the slide cannot
    # drive there: the reference must change coordinate), a six-bar near a toggle.
    Case("slider_dead_centres", "mechanisms/slider_crank_driven_slider.toml", must_switch=True),
    Case("sixbar_near_toggle", "mechanisms/stephenson3_near_toggle.toml"),
    # Two DOF: a five-bar whose arms fold parallel, a singular configuration of its inputs' set (the
    # reference must leave the inputs' coordinates and stay accurate on both inputs).
    Case("five_bar_fold", "hard/five_bar_fold.toml", must_switch=True),
)


class RunStatus(str, Enum):
    """How an engine's run ended in a case, besides a numerical failure (its
    :class:`~loopcheck.errors.FailureReason`)."""

    OK = "ok"
    REFUSED = "refused"  # the engine does not run this scene or these settings (a ValueError: its line)
    NOT_RUN = "not run"  # the reference failed: nothing to judge the engine against


@dataclass(frozen=True)
class EngineOutcome:
    """One engine in one case: how its run ended (``status``: :class:`RunStatus` or the numerical
    failure's reason, ``failure``: its line), the run (``result``, the reference's or the engine's;
    None when it did not run to the end), its comparison with the reference (None for the reference
    itself and for an engine that did not run) and its figures (wall time, energy residual, loop
    violation, the comparison's differences, drift, probes, the off-grid edge's errors)."""

    engine: str
    status: RunStatus | FailureReason
    failure: str | None = None
    result: EngineResult | None = field(default=None, repr=False)
    comparison: Comparison | None = field(default=None, repr=False)
    figures: Mapping[str, Any] = field(default_factory=dict)
    known_defects: tuple[str, ...] = ()  # the engine's known defects that bear on its run, as check prints them

    def __post_init__(self):
        if not isinstance(self.status, (RunStatus, FailureReason)):
            raise ValueError(f"EngineOutcome.status must be a RunStatus or a FailureReason, got {self.status!r}")
        if (self.status is RunStatus.OK) != (self.failure is None):
            raise ValueError(f"EngineOutcome of '{self.engine}': a failure line goes with a status other than ok")

    @property
    def passed(self) -> bool:
        """It ran, and passed its gate (the reference: it ran)."""
        return self.status is RunStatus.OK and (self.comparison is None or self.comparison.gate.passed)


@dataclass(frozen=True)
class CaseResult:
    """What happened to one case: each engine's outcome (the reference's first), why the case did
    not pass (``problems``, empty when it did), the case's own figures and what it showed in words."""

    name: str
    passed: bool
    outcomes: tuple[EngineOutcome, ...]
    problems: tuple[str, ...]
    figures: Mapping[str, Any] = field(default_factory=dict)  # the case's: switches, the reference's drift bound, wall
    notes: tuple[str, ...] = ()

    def __post_init__(self):
        if not self.outcomes or self.outcomes[0].engine != REFERENCE:
            raise ValueError(f"CaseResult '{self.name}': the reference '{REFERENCE}' comes first")

    @property
    def engines(self) -> tuple[str, ...]:
        return tuple(o.engine for o in self.outcomes)

    def outcome(self, engine: str) -> EngineOutcome:
        """The outcome of the engine named ``engine`` (KeyError naming the engines run otherwise)."""
        for o in self.outcomes:
            if o.engine == engine:
                return o
        raise KeyError(f"'{engine}' was not run in case '{self.name}' (engines: {', '.join(self.engines)})")


def _attempt(call):
    """``call()``'s run, ``(result, RunStatus.OK, None)``, or how it ended: ``(None, reason, line)``."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return call(), RunStatus.OK, None
    except NumericalFailure as exc:
        return None, exc.reason, str(exc)
    except ValueError as exc:  # what the engine does not run: its one line
        return None, RunStatus.REFUSED, str(exc)


def _failure_status(line: str) -> RunStatus | FailureReason:
    """An :class:`~loopcheck.compare.engines.EngineVerdict`'s failure line's status: it reads
    ``refused: ...`` or ``numerical failure (REASON): ...`` (check_engines writes them so)."""
    if line.startswith("refused:"):
        return RunStatus.REFUSED
    return FailureReason(line.split("(", 1)[1].split(")", 1)[0])


def _revolutions(result: EngineResult) -> float:
    """The turns of the input that turns most (each input's |q(T) − q(0)| / 2π), at least 1: a
    swing, or a slide, counts as one."""
    return max(1.0, *(abs(tr.q[-1] - tr.q[0]) / (2 * math.pi) for tr, _ in result.inputs))


def _drift_per_revolution(result) -> float:
    """|E(T) − E(0)| / E(0) per revolution of the input that turns most (conservative scenes)."""
    a = result.audit
    energy = a.kinetic + a.potential
    scale = max(a.scale, abs(energy[0]), 1e-300)
    return float(abs(energy[-1] - energy[0]) / scale / _revolutions(result))


def _run_figures(result: EngineResult, comparison: Comparison | None) -> dict:
    """An engine's figures in a case; its differences from the reference are the worst input's,
    each figure over every input (:attr:`~loopcheck.compare.run.Comparison.diffs`: one for a
    one-DOF scene: :func:`loopcheck.compare.diff.worst_figures`), in that input's unit."""
    figures = dict(wall_s=result.wall_s, energy_residual=result.audit.relative_residual)
    if result.constraint_violation is not None:
        figures["constraint_violation"] = result.constraint_violation.max
    if comparison is not None:
        worst = worst_figures(comparison.diffs)
        figures.update({key: worst[key] for key in ("peak_omega_rel", "peak_omega_abs", "t_peak_abs", "q_max_abs",
                                                    "omega_max_abs", "omega_vs_q_max_abs")})
        figures.update(span_end=comparison.diff.span_end, mode_mismatches=comparison.modes.total)
    return figures


def _run_engines(scene: Scene, engines: tuple[str, ...]) -> list[EngineOutcome]:
    """Every engine on ``scene``, judged as ``loopcheck check --engines`` judges it (the same call):
    the reference's outcome first."""
    settings, refused = {}, {}
    for name in engines:
        try:
            settings[name] = engine_settings(name, scene)
        except ValueError as exc:  # the scene's table refused for this engine: its verdict
            refused[name] = str(exc)
    ordered = (REFERENCE, *(n for n in engines if n != REFERENCE))
    if REFERENCE in refused:
        return [EngineOutcome(name, RunStatus.REFUSED if name == REFERENCE else RunStatus.NOT_RUN,
                              refused.get(name, f"the reference did not run: {refused[REFERENCE]}"))
                for name in ordered]
    runnable = tuple(name for name in engines if name not in refused)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            check = check_engines(scene, runnable, settings) if len(runnable) > 1 else None
            reference = check.reference if check else ENGINES[REFERENCE].simulate(scene, settings[REFERENCE])
    except (NumericalFailure, ValueError) as exc:  # the reference's failure (another engine's is its verdict)
        status = exc.reason if isinstance(exc, NumericalFailure) else RunStatus.REFUSED
        return [EngineOutcome(name, status, str(exc)) if name == REFERENCE else
                EngineOutcome(name, RunStatus.REFUSED, refused[name]) if name in refused else
                EngineOutcome(name, RunStatus.NOT_RUN, f"the reference failed: {exc}") for name in ordered]
    outcomes = [EngineOutcome(REFERENCE, RunStatus.OK, result=reference, figures=_run_figures(reference, None))]
    for name in (n for n in engines if n != REFERENCE):
        if name in refused:
            outcomes.append(EngineOutcome(name, RunStatus.REFUSED, refused[name]))
            continue
        v = check.verdict(name)
        if v.comparison is None:
            outcomes.append(EngineOutcome(name, _failure_status(v.failure), v.failure,
                                          known_defects=v.known_defects))
        else:
            outcomes.append(EngineOutcome(name, RunStatus.OK, result=v.comparison.other, comparison=v.comparison,
                                          figures=_run_figures(v.comparison.other, v.comparison),
                                          known_defects=v.known_defects))
    return outcomes


def run_case(case: Case, engines: tuple[str, ...] = DEFAULT_ENGINES) -> CaseResult:
    """Run one case: every engine of ``engines`` (the reference among them), its gate and the
    case's own checks."""
    if REFERENCE not in engines:
        raise ValueError(f"the engines must include '{REFERENCE}', the reference every engine is judged against")
    scene = load_scene(case.path)
    outcomes = _run_engines(scene, tuple(engines))
    problems, notes, figures = [], [], {}
    others = [o for o in outcomes if o.engine != REFERENCE]
    for o in outcomes:
        label = ENGINES[o.engine].label
        if o.status is not RunStatus.OK:
            problems.append(f"{label} failed: {o.failure}" if o.status is not RunStatus.REFUSED
                            else f"{label} refused: {o.failure}")
        elif o.comparison is not None:
            where = "gate" if len(others) == 1 else f"gate ({o.engine})"
            problems += [f"{where}: {f}" for f in o.comparison.gate.failures]
        notes += [f"{label} known defect: {defect}" for defect in o.known_defects]

    reference = outcomes[0].result
    if reference is not None:
        switches = getattr(reference.details, "switches", None)
        if switches is not None:
            figures["switches"] = len(switches)
        if case.must_switch:
            problems += _check_switches(reference, notes)
    extra = {o.engine: {} for o in outcomes}  # each engine's figures from the case's checks
    if case.probes:
        problems += _run_probes(scene, case, outcomes, extra, notes)
    if case.energy_drift:
        problems += _report_drift(outcomes, extra, notes)
    if case.off_grid_edge and scene.dof > 1:
        problems.append(f"the off-grid edge is one input's pulse: scene '{scene.name}' has {scene.dof} degrees of "
                        "freedom (its loads are actuators)")
    elif case.off_grid_edge and reference is not None:
        on_grid_references: dict[float, EngineResult] = {}
        for o in others:
            if o.result is not None:
                problems += _quantify_off_grid_edge(scene, o, on_grid_references, len(others) > 1, extra[o.engine],
                                                    notes)
    outcomes = tuple(replace(o, figures={**o.figures, **extra[o.engine]}) for o in outcomes)
    return CaseResult(case.name, not problems, outcomes, tuple(problems), figures, tuple(notes))


def _check_switches(reference: EngineResult, notes: list) -> list[str]:
    switches = reference.details.switches
    joints = reference.joints
    if not switches:
        return [f"{ENGINES[REFERENCE].label} never switched coordinate"]
    same_time = np.diff(joints.t) == 0.0
    jump_x = float(np.max(np.abs(np.diff(joints.x, axis=0))[same_time])) if same_time.any() else 0.0
    jump_v = float(np.max(np.abs(np.diff(joints.xdot, axis=0))[same_time])) if same_time.any() else 0.0
    changes = int(np.sum(np.any(joints.mode[1:] != joints.mode[:-1], axis=-1)))
    notes.append(f"{len(switches)} coordinate switches ({', '.join(sorted({s.new for s in switches}))}), "
                 f"{changes} assembly-mode changes tracked; largest jump across a switch: "
                 f"{jump_x:.1e} (rad or m), {jump_v:.1e} (rad or m)/s")
    # Across a switch the state is the same instant seen in two charts: only round-off differs.
    return [] if jump_x < 1e-12 and jump_v < 1e-9 else [f"discontinuity across a switch: {jump_x:.2e} (rad or m), "
                                                        f"{jump_v:.2e} (rad or m)/s"]


def probe_key(rung: Rung) -> str:
    """A probe's name in stress.json and in a case's ``expect``: ``SERIES@PARAMETER`` (``rk4@0.001``)."""
    return rung.series if math.isnan(rung.parameter) else f"{rung.series}@{rung.parameter:g}"


def _run_probes(scene: Scene, case: Case, outcomes: list[EngineOutcome], extra: dict, notes: list) -> list[str]:
    """Each engine's declared probes, run on the scene judged by its tolerances; their statuses go
    into the engine's figures (``stability``); a case's expectations are checked."""
    problems = []
    for o in outcomes:
        engine = ENGINES[o.engine]
        judged = replace(scene, tolerances=scene.tolerances_for(o.engine)) if o.engine != REFERENCE else scene
        try:
            probes = engine.stress_probes(judged, engine_settings(o.engine, scene))
        except ValueError as exc:  # the engine's settings refused for this scene: said by its outcome
            probes = ()
            notes.append(f"{engine.label}: no probes ({exc})")
        table, stable = {}, {}
        for rung in probes:
            _, status, _ = _attempt(lambda rung=rung: engine.simulate(judged, rung.settings))
            table[probe_key(rung)] = status.value
            stable.setdefault(rung.series, [])
            if status is RunStatus.OK:
                stable[rung.series].append(rung.parameter)
        if table:
            extra[o.engine]["stability"] = table
            failed = [f"{key} {status}" for key, status in table.items() if status != RunStatus.OK.value]
            notes.append(f"{engine.label} stable at: " + "; ".join(
                f"{series} {', '.join(f'{p:g}' for p in ps) or 'none'}" for series, ps in stable.items()) + " s"
                + (f" (not: {', '.join(failed)})" if failed else ""))
    for name, key, expected in case.expect:
        got = extra.get(name, {}).get("stability", {}).get(key)
        if got is None:
            if name in extra:
                problems.append(f"{ENGINES[name].label} has no probe '{key}' (case '{case.name}' expects one)")
        elif got != expected:
            problems.append(f"{ENGINES[name].label}'s probe {key} ended '{got}', expected '{expected}'")
    return problems


def _report_drift(outcomes: list[EngineOutcome], extra: dict, notes: list) -> list[str]:
    """Each engine's energy drift per revolution (its figures' ``drift_per_revolution``); the
    reference's bounded (its ``drift_bound``: :func:`_check_reference_drift`)."""
    ran = [o for o in outcomes if o.result is not None]
    for o in ran:
        extra[o.engine]["drift_per_revolution"] = _drift_per_revolution(o.result)
    if not ran or ran[0].engine != REFERENCE:
        return []
    reference = ran[0].result
    revolutions = _revolutions(reference)
    problems, bound = _check_reference_drift(reference, extra[REFERENCE]["drift_per_revolution"], revolutions)
    extra[REFERENCE]["drift_bound"] = bound
    span = f"{revolutions:.0f} revolutions" if revolutions > 1.0 else "swinging, under one revolution"
    drifts = [f"{ENGINES[o.engine].label} {extra[o.engine]['drift_per_revolution']:.1e}"
              + (f" (bound {bound:.1e})" if o.engine == REFERENCE else "") for o in ran]
    notes.append(f"{span}; energy drift per revolution (or over the run): {', '.join(drifts)}")
    return problems


def _check_reference_drift(reference: EngineResult, drift: float, revolutions: float) -> tuple[list[str], float]:
    """Bound: an adaptive method keeps each step's local error below rtol (relative to the
    state), so energy can drift by at most about rtol per step; per revolution the bound is
    rtol × (steps per revolution). For a fixed-step method the same reasoning with its own error
    is not a bound, so only adaptive references are held to it."""
    settings = reference.settings
    bound = settings.rtol * reference.n_steps / revolutions
    if ENGINES[REFERENCE].fixed_step(settings) is None and not drift <= bound:
        label = ENGINES[REFERENCE].label
        return [f"{label} energy drift {drift:.2e} per revolution exceeds its bound {bound:.2e}"], bound
    return [], bound


def _quantify_off_grid_edge(scene: Scene, outcome: EngineOutcome, on_grid_references: dict, named: bool,
                            figures: dict, notes: list) -> list[str]:
    """The engine's error with the edge off its step grid against the same scene with the edge
    moved onto the grid (each against its own reference run), at the step its run used; nothing
    for an engine whose steps adapt (:meth:`loopcheck.registry.Engine.fixed_step` None)."""
    engine = ENGINES[outcome.engine]
    h = engine.fixed_step(outcome.result.settings)
    if h is None:
        return []
    torque = scene.load
    if not isinstance(torque, PulseLoad):
        return ["off-grid case needs a pulse torque"]
    judged = replace(scene, tolerances=scene.tolerances_for(outcome.engine))
    on_grid = replace(judged, load=replace(torque, duration=round(torque.duration / h) * h))

    def error(s: Scene, reference: EngineResult | None = None):
        if reference is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                reference = ENGINES[REFERENCE].simulate(s, engine_settings(REFERENCE, s))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            other = engine.simulate(s, outcome.result.settings)
        return (compare_trajectories(reference.trajectory, other.trajectory, horizon=s.horizon), reference,
                {str(w.message) for w in caught})

    off, _, off_warnings = error(judged)
    on, on_grid_references[h], on_warnings = error(on_grid, on_grid_references.get(h))
    warned = bool(off_warnings - on_warnings)  # a warning the edge off the grid raised, and only it
    figures.update(off_grid_peak_rel=off.peak_omega_rel, on_grid_peak_rel=on.peak_omega_rel,
                           off_grid_q_max=off.q_max_abs, on_grid_q_max=on.q_max_abs)
    who = f"{engine.label}: " if named else ""
    notes.append(f"{who}edge {torque.start + torque.duration:g} s off the {h:g} s grid: peak error "
                 f"{off.peak_omega_rel:.1e} (on grid {on.peak_omega_rel:.1e}), max |dq| {off.q_max_abs:.1e} "
                 f"{scene.input_unit} (on grid {on.q_max_abs:.1e}); warned: {'yes' if warned else 'NO'}")
    problems = [] if warned else [f"{who}no warning for the off-grid pulse edge"]
    if not off.q_max_abs > on.q_max_abs:
        problems.append(f"{who}the off-grid edge shows no extra error: the quantification is not measuring it")
    return problems


def run_catalogue(cases=CATALOGUE, progress=None, engines: tuple[str, ...] = DEFAULT_ENGINES) -> list[CaseResult]:
    results = []
    for case in cases:
        start = time.perf_counter()
        result = run_case(case, engines)
        results.append(replace(result, figures={**result.figures, "case_wall_s": time.perf_counter() - start}))
        if progress:
            progress(result)
    return results


def _f(x, fmt=".1e"):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def table_lines(results: list[CaseResult]) -> list[str]:
    """The table: a case a line with each engine's status; with one engine beside the reference its
    differences, loop violation, drift per revolution and wall times on the same line, with several
    one line per engine under the case's."""
    engines = results[0].engines if results else DEFAULT_ENGINES
    w = max([9, *(len(o.status.value) for r in results for o in r.outcomes)])  # a status column's width
    statuses = " ".join(f"{name:>{w}s}" for name in engines)
    pair = len(engines) == 2
    if pair:
        lines = [f"{'case':18s} {statuses} {'peak rel':>8s} {'max|dq|':>8s} {'loop (m)':>8s} {'drift/rev':>17s} "
                 f"{'wall (s)':>11s}  verdict"]
    else:
        lines = [f"{'case':18s} {statuses}  verdict",
                 f"{'':18s} {'engine':>9s} {'peak rel':>8s} {'max|dq|':>8s} {'loop (m)':>8s} {'drift/rev':>9s} "
                 f"{'wall (s)':>8s}"]
    for r in results:
        row = " ".join(f"{o.status.value:>{w}s}" for o in r.outcomes)
        verdict = "PASS" if r.passed else "FAIL"
        if pair:
            ref, other = (o.figures for o in r.outcomes)
            drift = (f"{_f(ref.get('drift_per_revolution'))}/{_f(other.get('drift_per_revolution'))}"
                     if "drift_per_revolution" in ref else "-")
            walls = f"{_f(ref.get('wall_s'), '.2f')}/{_f(other.get('wall_s'), '.2f')}"
            lines.append(f"{r.name:18s} {row} {_f(other.get('peak_omega_rel')):>8s} {_f(other.get('q_max_abs')):>8s} "
                         f"{_f(other.get('constraint_violation')):>8s} {drift:>17s} {walls:>11s}  {verdict}")
        else:
            lines.append(f"{r.name:18s} {row}  {verdict}")
            for o in r.outcomes:
                g = o.figures
                lines.append(f"{'':18s} {o.engine:>9s} {_f(g.get('peak_omega_rel')):>8s} {_f(g.get('q_max_abs')):>8s} "
                             f"{_f(g.get('constraint_violation')):>8s} {_f(g.get('drift_per_revolution')):>9s} "
                             f"{_f(g.get('wall_s'), '.2f'):>8s}")
        for note in r.notes:
            lines.append(f"{'':18s}   {note}")
        for problem in r.problems:
            lines.append(f"{'':18s}   problem: {problem}")
    lines.append(f"{sum(r.passed for r in results)} passed, {sum(not r.passed for r in results)} failed")
    return lines


STRESS_FILES = ("stress.json",)


def stress_data(results: list[CaseResult]) -> dict:
    """stress.json's content (schema :data:`SCHEMA_VERSION`): the engines, and per case its verdict,
    each engine's outcome (status, failure line, figures, known defects), problems, notes and the case's figures."""
    return {"schema_version": SCHEMA_VERSION, "engines": list(results[0].engines if results else DEFAULT_ENGINES),
            "cases": [{"case": r.name, "passed": r.passed,
                       "engines": {o.engine: {"status": o.status.value, "failure": o.failure,
                                              "figures": dict(o.figures), "known_defects": list(o.known_defects)}
                                   for o in r.outcomes},
                       "problems": list(r.problems), "notes": list(r.notes), "figures": dict(r.figures)}
                      for r in results]}


def write_stress(results: list[CaseResult], out_dir, committed=None) -> list:
    """stress.json (:func:`stress_data`) into ``out_dir``, through
    :func:`loopcheck.compare.output.write_folder`."""
    from .output import json_text, write_folder

    data = stress_data(results)
    return write_folder(out_dir, {"stress.json": lambda p: p.write_text(json_text(data), encoding="utf-8")},
                        one_run=True, committed=committed)
