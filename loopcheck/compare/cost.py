"""What accuracy costs in time: work-precision sweeps of engines on one scene.

Each engine runs its accuracy ladder (:meth:`loopcheck.registry.Engine.ladder`: its settings
module's ``accuracy_ladder``, by default one point at the scene's settings); the default list is
:data:`loopcheck.registry.DEFAULT_ENGINES`. Ground truth is the reference engine's
(:meth:`loopcheck.registry.Engine.truth`: its adaptive DOP853 at rtol 1e-12); a
second run (rtol 1e-11) measures how accurate that truth is. Every configuration runs to the scene's
horizon; its errors are measured against the truth with :func:`compare_trajectories`,
its cost is the wall time of the simulation alone (no model building, audit or plotting)
over repeated runs (median, with the repeats' min and max), plus its step and
force-evaluation counts.

Every point also carries the verdict ``loopcheck run`` / ``check`` would give it
(:class:`Verdict`): the engine's own limits at ``run``'s defaults (a ladder may loosen them, a
loop gap, an energy balance, an error estimate, to measure what ``run`` would refuse: the rung's
``run_settings`` are run's) and the agreement gate against the truth,
:func:`loopcheck.compare.run.judge` at the scene's tolerances for the engine. One rule, the one
``run`` applies; none of this module's own. An engine that fails a point (a numerical failure, or
a refusal of what it does not run) has that point's verdict: the study goes on.

Wall times move with the machine's load: the report records the load average at the start
and end, and the headline ratio of each engine against the reference is an interval from the
repeats' spread (:class:`CostRatio`), with a warning when it is too wide to read.

A scene of several degrees of freedom: a run's errors are the worst input's, each figure at its
largest over the inputs (:func:`loopcheck.compare.diff.worst_figures`: the peak error relative to
each input's own peak, the trajectory differences in each input's unit), and the truth's accuracy
likewise; so the work-precision curve, the verdicts and the recommendation hold for every input.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import warnings
from dataclasses import asdict, dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, Sequence

from loopcheck.errors import NumericalFailure
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE, Rung
from loopcheck.results import EngineResult
from loopcheck.scene import Scene
from loopcheck.trajectory import Trajectory

from .diff import compare_trajectories, worst_figures
from .output import json_text, portable_source, write_folder
from .pool import ordered_map
from .run import judge
from .settings import engine_settings

COST_FILES = ("cost.png", "cost.csv", "cost.json")
FRESH_WORKERS = "forkserver"  # pool.ordered_map's start method for a sweep with an engine beyond the default
# pair: fresh processes, not forks of a parent that loaded the engine's library (JAX runs threads, and
# warns that a fork of them may deadlock). The default pair's workers are forks, as they always were.


@dataclass(frozen=True)
class Config:
    """One point of a sweep: a rung of ``engine``'s accuracy ladder (:class:`loopcheck.registry.Rung`:
    ``series``, ``parameter`` (a step in s, a tolerance; NaN for a single point), ``settings`` the
    sweep runs, ``symbol`` the parameter's name in labels, ``run_settings`` ``loopcheck run``'s,
    None where they are ``settings``)."""

    engine: str  # a registered engine's name (loopcheck.registry.ENGINES)
    series: str  # e.g. "RKN4", "DOP853", "<engine> rk4 (hard)"
    parameter: float  # step (s), rtol, or timestep (s); NaN for an engine's single point
    settings: Any  # the engine's Settings, as the sweep runs them
    symbol: str = "h"
    run_settings: Any = None

    @classmethod
    def of(cls, engine: str, rung: Rung) -> "Config":
        return cls(engine, rung.series, rung.parameter, rung.settings, rung.symbol, rung.run_settings)

    @property
    def rung(self) -> Rung:
        return Rung(self.series, self.parameter, self.settings, self.symbol, self.run_settings)

    @property
    def label(self) -> str:
        return self.rung.label


class Verdict(str, Enum):
    """What ``loopcheck run`` / ``check`` would say of a configuration (compares equal to its value)."""

    PASS = "pass"
    FAIL = "fail"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Measurement:
    """Errors against the truth, the cost and the verdict of one configuration.

    ``status`` is "ok" when the sweep could measure the configuration (with its loose limits),
    else the failure's reason; ``verdict`` and ``verdict_reasons`` are what ``loopcheck run``
    would say (module docstring): FAIL with the reasons, PASS with none. Wall times in s over
    ``repeats`` runs: ``wall_min_s`` ≤ ``wall_median_s`` ≤ ``wall_max_s``. ``constraint_violation``
    (m) is NaN for an engine whose loops are exact (its results have none).
    """

    config: Config
    status: str  # "ok" or a failure reason
    message: str = ""
    verdict: Verdict = Verdict.FAIL
    verdict_reasons: tuple[str, ...] = ()
    peak_omega_rel: float = math.nan
    q_max_abs: float = math.nan
    omega_max_abs: float = math.nan
    omega_vs_q_max_abs: float = math.nan
    constraint_violation: float = math.nan
    wall_min_s: float = math.nan
    wall_median_s: float = math.nan
    wall_max_s: float = math.nan
    repeats: int = 0
    n_steps: int = 0
    n_evaluations: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.verdict, Verdict):
            object.__setattr__(self, "verdict", Verdict(self.verdict))
        if (self.verdict is Verdict.PASS) == bool(self.verdict_reasons):
            raise ValueError(f"{self.config.label}: a verdict fails with its reasons and passes without any, "
                             f"got {self.verdict} with {len(self.verdict_reasons)} reason(s)")
        walls = (self.wall_min_s, self.wall_median_s, self.wall_max_s)
        if not all(math.isnan(w) for w in walls) and not walls[0] <= walls[1] <= walls[2]:
            raise ValueError(f"{self.config.label}: wall times must satisfy min <= median <= max, got {walls}")

    @property
    def ok(self) -> bool:
        """Whether the sweep measured it (errors and times are figures, not NaN)."""
        return self.status == "ok"

    @property
    def passed(self) -> bool:
        """Whether ``loopcheck run`` would pass it."""
        return self.verdict is Verdict.PASS

    def row(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k not in ("config", "verdict", "verdict_reasons")}
        d.update(engine=self.config.engine, series=self.config.series, parameter=self.config.parameter,
                 label=self.config.label, verdict=self.verdict.value,
                 verdict_reasons="; ".join(self.verdict_reasons))
        return d


@dataclass(frozen=True)
class Truth:
    """The reference run and how far it is from a second, looser tight run."""

    result: EngineResult
    error: dict = field(default_factory=dict)

    @property
    def trajectory(self) -> Trajectory:
        return self.result.trajectory

    @property
    def peak_omega(self) -> float:
        return self.result.peak.omega


def _rung_text(rung: Rung) -> str:
    """``"DOP853 rtol 1e-12"``: a rung in prose."""
    return rung.series if math.isnan(rung.parameter) else f"{rung.series} {rung.symbol} {rung.parameter:g}"


def truth_text() -> str:
    """The ground truth in prose (the reference's declaration): ``"DOP853 rtol 1e-12"``."""
    return _rung_text(ENGINES[REFERENCE].truth()[0])


def ground_truth(scene: Scene) -> Truth:
    """The reference engine's truth (DOP853 at rtol 1e-12), checked against its looser run (rtol 1e-11)."""
    reference = ENGINES[REFERENCE]
    tight_rung, check_rung = reference.truth()
    tight = reference.simulate(scene, tight_rung.settings)
    check = reference.simulate(scene, check_rung.settings)
    diffs = tuple(compare_trajectories(a, b) for (a, _), (b, _) in zip(tight.inputs, check.inputs))
    # several inputs: the worst input's errors, and no one input's peaks or peak times
    figures = diffs[0].figures() if len(diffs) == 1 else {k: getattr(diffs[0], k) for k in
                                                          ("span_start", "span_end", "horizon")}
    return Truth(tight, {"against": _rung_text(check_rung), **figures, **worst_figures(diffs)})


def ladder(scene: Scene, engines: Sequence[str] = DEFAULT_ENGINES, quick: bool = False) -> list[Config]:
    """The configurations of a sweep: each engine's accuracy ladder (a short one with ``quick``),
    from the scene's settings of that engine (its table over its defaults), in the list's order."""
    configs = []
    for name in engines:
        engine = ENGINES[name]
        configs += [Config.of(name, rung) for rung in engine.ladder(scene, engine_settings(name, scene), quick)]
    return configs


def run_settings(config: Config) -> Any:
    """The configuration's settings with the limits ``loopcheck run`` applies (the rung's
    ``run_settings``; the sweep's own may be looser, so that it can measure what ``run`` refuses)."""
    return config.settings if config.run_settings is None else config.run_settings


def _simulate(scene: Scene, config: Config, settings) -> EngineResult:
    with warnings.catch_warnings():  # off-grid edges and the like: measured here, not warned about
        warnings.simplefilter("ignore")
        return ENGINES[config.engine].simulate(scene, settings)


def measure(scene: Scene, config: Config, truth: Truth, repeats: int) -> Measurement:
    """Run one configuration ``repeats`` times: errors and verdict from the first run, wall
    times (min, median, max) from all.

    The first run has ``loopcheck run``'s limits (:func:`run_settings`): a failure there is
    the verdict's first reason, and the configuration is then measured with the sweep's own.
    The verdict's other reasons are the agreement gate's against the truth,
    :func:`loopcheck.compare.run.judge` at the scene's tolerances for the engine. A point the
    engine refuses (a ValueError: what it does not run) has status ``refused``, as
    ``loopcheck check --engines`` says it.
    """
    own_failures: list[str] = []
    walls, first = [], None
    try:
        try:
            first = _simulate(scene, config, run_settings(config))
            walls.append(first.wall_s)
        except NumericalFailure as exc:
            own_failures.append(f"{exc.reason}: {exc}")
        while len(walls) < repeats:
            result = _simulate(scene, config, config.settings)
            first = first or result
            walls.append(result.wall_s)
    except NumericalFailure as exc:
        return Measurement(config, status=str(exc.reason), message=str(exc),
                           verdict_reasons=tuple(own_failures) or (f"{exc.reason}: {exc}",))
    except ValueError as exc:  # what the engine does not run (an MJX refusal, ...): one line, its verdict
        return Measurement(config, status="refused", message=str(exc), verdict_reasons=(f"refused: {exc}",))
    comparison = judge(scene, truth.result, first, scene.tolerances_for(config.engine))
    d = worst_figures(comparison.diffs)  # every input's: the worst (one input: its own)
    reasons = (*own_failures, *comparison.gate.failures)
    return Measurement(
        config, status="ok", verdict=Verdict.FAIL if reasons else Verdict.PASS, verdict_reasons=reasons,
        peak_omega_rel=d["peak_omega_rel"], q_max_abs=d["q_max_abs"],
        omega_max_abs=d["omega_max_abs"], omega_vs_q_max_abs=d["omega_vs_q_max_abs"],
        constraint_violation=(math.nan if first.constraint_violation is None
                              else first.constraint_violation.max),
        wall_min_s=min(walls), wall_median_s=statistics.median(walls), wall_max_s=max(walls),
        repeats=len(walls), n_steps=first.n_steps, n_evaluations=first.n_evaluations)


def _measure_args(args):
    return measure(*args)


def _lost_job(args, reason: str) -> Measurement:
    """The measurement of a configuration whose worker died twice (killed from outside, as the
    OOM killer does): status ``failed``, the reason ("worker killed by signal 9") its message."""
    return Measurement(args[1], status="failed", message=reason, verdict_reasons=(reason,))


class Progress:
    """A one-line progress bar on stderr (only when stderr is a terminal)."""

    def __init__(self, total: int, label: str = "cost"):
        self.total, self.done, self.label = total, 0, label
        self.live = sys.stderr.isatty()

    def step(self, text: str = "") -> None:
        self.done += 1
        if self.live:
            filled = int(30 * self.done / self.total)
            sys.stderr.write(f"\r{self.label} [{'#' * filled}{'.' * (30 - filled)}] "
                             f"{self.done}/{self.total} {text[:40]:<40}")
            if self.done == self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()


def worker_count(requested: int | None, jobs: int) -> int:
    """Processes for ``jobs`` configurations: the request (default: all cores), at most one
    per core and one per job."""
    cores = os.cpu_count() or 1
    return max(1, min(requested or cores, cores, jobs))


def start_method(engines: Sequence[str]) -> str | None:
    """The workers' start method for a sweep of ``engines``: forks (None, the platform's default)
    for the default pair, else :data:`FRESH_WORKERS` (they find the engines as the registry does)."""
    return None if set(engines) <= set(DEFAULT_ENGINES) else FRESH_WORKERS


def sweep(scene: Scene, configs: list[Config], truth: Truth, *, repeats: int = 3,
          workers: int | None = None) -> list[Measurement]:
    """Measure every configuration, ``workers`` processes at a time (see :func:`worker_count`
    and :func:`start_method`).

    An exception in the parent (Ctrl-C, SIGTERM raised as an exception) ends the workers.
    """
    workers = worker_count(workers, len(configs))
    progress = Progress(len(configs))
    jobs = [(scene, c, truth, repeats) for c in configs]
    results: list[Measurement] = []
    if workers == 1:
        for job in jobs:
            results.append(_measure_args(job))
            progress.step(job[1].label)
        return results
    method = start_method([c.engine for c in configs])
    for m in ordered_map(_measure_args, jobs, workers, lost=_lost_job, start_method=method):
        results.append(m)
        progress.step(m.config.label)
    return results


@dataclass(frozen=True)
class Recommendation:
    """The cheapest configuration of one engine that meets the target, re-run to confirm."""

    engine: str
    target: float
    measurement: Measurement | None  # None: the target was not reached at any setting tried
    confirmed: Measurement | None = None

    @property
    def reached(self) -> bool:
        return self.measurement is not None

    @property
    def confirmed_ok(self) -> bool:
        return (self.confirmed is not None and self.confirmed.ok and self.confirmed.passed
                and self.confirmed.peak_omega_rel <= self.target)


def cheapest_meeting(measurements: list[Measurement], engine: str, target: float) -> Measurement | None:
    """The measurement of ``engine`` that ``loopcheck run`` passes with the smallest median wall
    time among those whose peak-ω relative error is at most ``target`` (None if there is none)."""
    meeting = [m for m in measurements
               if m.config.engine == engine and m.ok and m.passed and m.peak_omega_rel <= target]
    return min(meeting, key=lambda m: m.wall_median_s) if meeting else None


RATIO_SPREAD_LIMIT = 2.0  # a headline interval wider than this factor is too wide to read


@dataclass(frozen=True)
class CostRatio:
    """An engine's wall time over the reference's at the recommended configurations: the
    ratio of the medians and the interval the repeats allow (the engine's fastest over the
    reference's slowest, its slowest over the reference's fastest)."""

    low: float
    median: float
    high: float

    def __post_init__(self) -> None:
        if not 0.0 < self.low <= self.median <= self.high < math.inf:
            raise ValueError(f"a cost ratio needs 0 < low <= median <= high < inf, got "
                             f"{self.low!r}, {self.median!r}, {self.high!r}")

    @classmethod
    def of(cls, other: Measurement, reference: Measurement) -> CostRatio:
        return cls(other.wall_min_s / reference.wall_max_s, other.wall_median_s / reference.wall_median_s,
                   other.wall_max_s / reference.wall_min_s)

    @property
    def spread(self) -> float:
        return self.high / self.low

    def warnings(self) -> tuple[str, ...]:
        """Why the interval cannot be read as one figure: it spans more than
        ``RATIO_SPREAD_LIMIT``x, or it contains 1 (which engine is cheaper is not measured)."""
        out = []
        if self.spread > RATIO_SPREAD_LIMIT:
            out.append(f"the repeats' spread makes the ratio uncertain by {self.spread:.1f}x (more than "
                       f"{RATIO_SPREAD_LIMIT:g}x): the machine's load moved the timings; rerun on an idle "
                       "machine or with more --repeats")
        if self.low <= 1.0 <= self.high:
            out.append("the interval contains 1: which engine is cheaper at this accuracy is not measured")
        return tuple(out)

    def text(self) -> str:
        return f"{self.median:.2f}x (between {self.low:.2f}x and {self.high:.2f}x over the repeats)"

    def as_dict(self) -> dict:
        return {"low": self.low, "median": self.median, "high": self.high, "spread": self.spread,
                "warnings": list(self.warnings())}


@dataclass(frozen=True)
class LoadAverage:
    """The machine's load average (os.getloadavg: 1, 5 and 15 min) at the start and end of a
    study, with its core count; None where the platform has none."""

    start: tuple[float, float, float] | None
    end: tuple[float, float, float] | None
    cores: int

    def __post_init__(self) -> None:
        for name in ("start", "end"):
            value = getattr(self, name)
            if value is not None and (len(value) != 3 or not all(0.0 <= x < math.inf for x in value)):
                raise ValueError(f"load average {name} must be three finite numbers >= 0 (1, 5, 15 min), got {value!r}")
        if isinstance(self.cores, bool) or not isinstance(self.cores, int) or self.cores < 1:
            raise ValueError(f"cores must be a whole number >= 1, got {self.cores!r}")

    @staticmethod
    def now() -> tuple[float, float, float] | None:
        try:
            return tuple(os.getloadavg())
        except (AttributeError, OSError):
            return None

    def as_dict(self) -> dict:
        return {"start": list(self.start) if self.start else None, "end": list(self.end) if self.end else None,
                "cores": self.cores, "what": "os.getloadavg(): 1, 5 and 15 min"}


def engines_of(measurements: list[Measurement]) -> tuple[str, ...]:
    """The engines measured, in the sweep's order."""
    return tuple(dict.fromkeys(m.config.engine for m in measurements))


def recommend(scene: Scene, measurements: list[Measurement], truth: Truth, target: float,
              repeats: int = 3, engines: Sequence[str] | None = None) -> dict[str, Recommendation]:
    """Per engine (``engines``, default those measured), the cheapest measured configuration with
    peak-ω relative error ≤ target."""
    out = {}
    for engine in (engines if engines is not None else engines_of(measurements)):
        best = cheapest_meeting(measurements, engine, target)
        if best is None:
            out[engine] = Recommendation(engine, target, None)
            continue
        confirmed = measure(scene, best.config, truth, repeats)
        out[engine] = Recommendation(engine, target, best, confirmed)
    return out


def pareto_front(measurements: list[Measurement]) -> list[Measurement]:
    """Configurations that ``loopcheck run`` passes and that no other such one beats on both
    peak-ω error and wall time."""
    ok = sorted((m for m in measurements if m.ok and m.passed and m.peak_omega_rel > 0),
                key=lambda m: (m.wall_median_s, m.peak_omega_rel))
    front, best_error = [], math.inf
    for m in ok:
        if m.peak_omega_rel < best_error:
            front.append(m)
            best_error = m.peak_omega_rel
    return front


def converges(series: list[Measurement], floor: float, attr: str = "peak_omega_rel") -> bool:
    """Whether the error falls as the step or tolerance falls, above ``floor``.

    Points are ordered from the largest parameter down; once an error is within 10x of
    ``floor`` (the truth's own error or round-off) the rest are not judged. A rise of up to
    2x between neighbours is allowed (peak-ω errors can cross zero and dip).
    """
    errors = [getattr(m, attr) for m in sorted(series, key=lambda m: -m.config.parameter) if m.ok]
    judged = [e for e in errors if e > 10 * floor]
    if len(judged) < 2:
        return True
    return all(b <= 2.0 * a for a, b in zip(judged, judged[1:])) and judged[-1] < judged[0]


def ratio_key(engine: str) -> str:
    """cost.json's key of ``engine``'s ratio to the reference: ``recommendation.ENGINE_over_REFERENCE_wall``."""
    return f"{engine}_over_{REFERENCE}_wall"


def cost_report(scene: Scene, truth: Truth, measurements: list[Measurement],
                recommendations: dict[str, Recommendation], repeats: int, load: LoadAverage | None = None) -> dict:
    """The study as JSON-serialisable data. ``engines`` lists the engines in the sweep's order
    (``reference`` the one the truth is from); ``recommendation.ENGINE`` is each engine's cheapest
    configuration meeting the target, and ``recommendation.ENGINE_over_REFERENCE_wall``
    (:func:`ratio_key`) each other engine's headline ratio to the
    reference (:class:`CostRatio`: low, median, high and its warnings), null when either did not reach
    the target."""
    def rec(r: Recommendation) -> dict:
        if not r.reached:
            return {"reached": False, "target": r.target}
        m = r.measurement
        return {"reached": True, "target": r.target, "label": m.config.label,
                "wall_min_s": m.wall_min_s, "wall_median_s": m.wall_median_s, "wall_max_s": m.wall_max_s,
                "peak_omega_rel": m.peak_omega_rel,
                "confirmed_peak_omega_rel": r.confirmed.peak_omega_rel if r.confirmed else None,
                "confirmed": r.confirmed_ok}

    engines = tuple(recommendations)
    reference = recommendations.get(REFERENCE)
    recommendation: dict = {name: rec(r) for name, r in recommendations.items()}
    for name, r in recommendations.items():
        if name != REFERENCE:
            ratio = (CostRatio.of(r.measurement, reference.measurement)
                     if reference is not None and reference.reached and r.reached else None)
            recommendation[ratio_key(name)] = ratio.as_dict() if ratio else None
    load = load or LoadAverage(None, None, os.cpu_count() or 1)
    units = scene.input_units()
    return {
        "scene": scene.name, "source": portable_source(scene.source),
        "input_unit": units[0] if len(set(units)) == 1 else "rad or m",
        "inputs": [{"name": name, "unit": unit, "truth_peak_omega": peak.omega}
                   for name, unit, (_, peak) in zip(scene.inputs, units, truth.result.inputs)],
        "engines": list(engines), "reference": REFERENCE,
        "truth": {"method": truth_text(), "peak_omega": truth.peak_omega, "accuracy": truth.error},
        "timing": {"what": "simulation only (integration or rollout); no model building, audit or plots",
                   "repeats": repeats, "statistic": "median, with the repeats' min and max",
                   "load_average": load.as_dict()},
        "verdict": {"what": "loopcheck run's: the engine's own limits at run's defaults and the agreement gate "
                            "(loopcheck.compare.run.judge) against the truth at the scene's tolerances for the engine",
                    "passed": sum(m.passed for m in measurements), "failed": sum(not m.passed for m in measurements)},
        "measurements": [m.row() for m in measurements],
        "recommendation": recommendation,
    }


def write_cost_outputs(report: dict, measurements: list[Measurement], out_dir, target: float,
                       committed=None) -> list[Path]:
    """cost.png, cost.csv and cost.json into ``out_dir``, as a set (:func:`loopcheck.compare.output.write_folder`).

    cost.json is strict JSON: figures that were not measured (NaN) are null.
    """
    import csv

    from .cost_plot import plot_cost

    def write_csv(path: Path) -> None:
        rows = [m.row() for m in measurements]
        with open(path, "w", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["status"])
            writer.writeheader()
            writer.writerows(rows)

    files = {
        "cost.png": lambda p: plot_cost(measurements, pareto_front(measurements), target, report["scene"], p,
                                        truth=report["truth"]["method"], headline="\n".join(headline_lines(report))),
        "cost.csv": write_csv,
        "cost.json": lambda p: p.write_text(json_text(report), encoding="utf-8"),
    }
    return write_folder(out_dir, files, one_run=True, committed=committed)


LOOP_EXACT = "n/a (exact)"  # the loop column of an engine whose loops are closed by construction


def _headline(report: dict, engine: str) -> str | None:
    """``engine``'s cost over the reference's at the target, an interval, one line (None: no ratio)."""
    rec = report["recommendation"]
    ratio = rec.get(ratio_key(engine)) if engine != REFERENCE else None
    if ratio is None:
        return None
    return (f"at peak error <= {rec[engine]['target']:g} {ENGINES[engine].label} costs "
            f"{CostRatio(ratio['low'], ratio['median'], ratio['high']).text()} {ENGINES[REFERENCE].label}'s wall time")


def headline_lines(report: dict) -> list[str]:
    """The headlines, one line per engine beside the reference where both reached the target."""
    return [line for line in (_headline(report, name) for name in report["engines"]) if line]


def _loop_cell(m: Measurement) -> str:
    if math.isnan(m.constraint_violation):  # the engine's results have no loop gap: loops closed by construction
        return LOOP_EXACT
    return f"{m.constraint_violation:.2e}"


def summary_lines(report: dict, measurements: list[Measurement]) -> list[str]:
    """A printed summary: the table, the truth's accuracy and the recommendation."""
    unit = report.get("input_unit", "rad")
    timing = report["timing"]
    load = timing.get("load_average") or {}
    loads = " ; ".join(f"{when} {' '.join(f'{x:.2f}' for x in load[when])}" for when in ("start", "end")
                       if load.get(when))
    inputs = report.get("inputs") or []
    if len(inputs) > 1:  # several DOF: every input's peak; the errors below are the worst input's
        peaks = ", ".join(f"{i['name']} {i['truth_peak_omega']:+.12g} {i['unit']}/s" for i in inputs)
        worst = " (the worst input's, as every error below)"
    else:
        peaks, worst = f"{report['truth']['peak_omega']:+.12g} {unit}/s", ""
    lines = [f"truth: {report['truth']['method']}, peak qdot {peaks}; "
             f"against {report['truth']['accuracy']['against'].split(' ', 1)[-1]}: peak "
             f"{report['truth']['accuracy']['peak_omega_rel']:.1e} rel, "
             f"max |dq| {report['truth']['accuracy']['q_max_abs']:.1e} {unit}{worst}",
             f"wall time: median of {timing['repeats']} runs [min-max], simulation only; load average "
             f"(1, 5, 15 min) {loads or 'not available'} on {load.get('cores', '?')} cores",
             "verdict: what `loopcheck run` says (its own limits, and its gate against the truth at the "
             "scene's tolerances)",
             f"{'configuration':46s} {'verdict':>7s} {'peak rel':>9s} {'max|dq|':>9s} {'max|dw|':>9s} "
             f"{'dw at q':>9s} {'loop (m)':>11s} {'wall (s) [min-max]':>26s} {'steps':>7s}"]
    for m in measurements:
        if m.ok:
            walls = f"{m.wall_median_s:.4f} [{m.wall_min_s:.4f}-{m.wall_max_s:.4f}]"
            lines.append(f"{m.config.label:46s} {m.verdict.value:>7s} {m.peak_omega_rel:9.2e} {m.q_max_abs:9.2e} "
                         f"{m.omega_max_abs:9.2e} {m.omega_vs_q_max_abs:9.2e} {_loop_cell(m):>11s} "
                         f"{walls:>26s} {m.n_steps:7d}")
        else:
            lines.append(f"{m.config.label:46s} {m.verdict.value:>7s} {m.status}: {m.message[:70]}")
    failing = [m for m in measurements if m.ok and not m.passed]
    for m in failing:
        lines.append(f"  {m.config.label}: fails run: {m.verdict_reasons[0][:110]}")
    rec = report["recommendation"]
    for engine in report["engines"]:
        r = rec[engine]
        if r["reached"]:
            lines.append(f"cheapest {engine} configuration that run passes with peak error <= {r['target']:g}: "
                         f"{r['label']} ({r['wall_median_s']:.4f} s [{r['wall_min_s']:.4f}-{r['wall_max_s']:.4f}], "
                         f"error {r['peak_omega_rel']:.2e}; re-run: "
                         f"{r['confirmed_peak_omega_rel']:.2e}, {'confirmed' if r['confirmed'] else 'NOT confirmed'})")
        else:
            lines.append(f"{engine}: the target {r['target']:g} was not reached at any setting tried that run passes")
    for engine in report["engines"]:
        headline = _headline(report, engine)
        if headline:
            lines.append(headline)
            lines += [f"warning: {w}" for w in rec[ratio_key(engine)]["warnings"]]
    return lines


def study(scene: Scene, *, quick: bool = False, target: float | None = None, repeats: int | None = None,
          workers: int | None = None, engines: Sequence[str] = DEFAULT_ENGINES) -> tuple[dict, list[Measurement], float]:
    """The whole cost pipeline: truth, sweep, recommendation and report, over ``engines``
    (names of :data:`loopcheck.registry.ENGINES`; default the design card's pair).

    ``target`` defaults to the scene's peak_omega_rtol, ``repeats`` to 3, ``workers`` to
    one process per core (a request above that warns and is capped). Returns the report
    (cost.json's data), the measurements and the target used.

    Raises
    ------
    ImportError
        In one line, before any work, when an engine's optional extra is missing.
    ValueError
        In one line, before any work: a scene table an engine's settings refuse.
    """
    target = target if target is not None else scene.tolerances.peak_omega_rtol
    repeats = repeats if repeats is not None else 3
    for name in engines:
        ENGINES[name].load()
    configs = ladder(scene, engines, quick=quick)
    used = worker_count(workers, len(configs))
    if workers is not None and used < workers:
        warnings.warn(f"--workers {workers}: using {used} "
                      f"(at most one process per core: {os.cpu_count() or 1} cores)")
    load_start = LoadAverage.now()
    truth = ground_truth(scene)
    measurements = sweep(scene, configs, truth, repeats=repeats, workers=used)
    recommendations = recommend(scene, measurements, truth, target, repeats, engines=engines)
    load = LoadAverage(load_start, LoadAverage.now(), os.cpu_count() or 1)
    return cost_report(scene, truth, measurements, recommendations, repeats, load), measurements, target
