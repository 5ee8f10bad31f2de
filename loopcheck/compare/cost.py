"""What accuracy costs in time: work-precision sweeps of both engines on one scene.

Ground truth is the reduced adaptive solver (DOP853) at rtol 1e-12; a second run at rtol
1e-11 measures how accurate that truth is. Every configuration runs to the scene's
horizon; its errors are measured against the truth with :func:`compare_trajectories`,
its cost is the median wall time of the simulation alone (no model building, audit or
plotting) over repeated runs, plus its step and force-evaluation counts.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

from loopcheck.errors import NumericalFailure
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scene import Scene
from loopcheck.trajectory import Trajectory
from loopcheck.reference_models import INTEGRATORS, MujocoSettings, simulate_mujoco

from .diff import compare_trajectories
from .output import json_text, portable_source, write_folder
from .pool import ordered_map

COST_FILES = ("cost.png", "cost.csv", "cost.json")

HARD = {"solimp": (0.9999, 0.9999, 0.001, 0.5, 2.0)}  # solref (2·timestep, 1): loopcheck's default
MUJOCO_DEFAULT_SOFTNESS = {"solref": (0.02, 1.0), "solimp": (0.9, 0.95, 0.001, 0.5, 2.0)}
SOFTNESS = {"hard": HARD, "mujoco-default": MUJOCO_DEFAULT_SOFTNESS}
SWEEP_VIOLATION_LIMIT = 0.1  # m: a sweep measures soft constraints rather than rejecting them
SWEEP_ENERGY_LIMIT = 1.0  # of the energy scale: likewise for first-order integrators' energy error


@dataclass(frozen=True)
class Config:
    """One point of a sweep."""

    engine: str  # "reduced" or "mujoco"
    series: str  # e.g. "RKN4", "DOP853", "MuJoCo rk4 (hard)"
    parameter: float  # step (s), rtol, or timestep (s)
    reduced: ReducedSettings | None = None
    mujoco: MujocoSettings | None = None

    @property
    def label(self) -> str:
        name = "rtol" if self.series == "DOP853" else "h"
        return f"{self.series} {name}={self.parameter:.1e}"


@dataclass(frozen=True)
class Measurement:
    """Errors against the truth and the cost of one configuration."""

    config: Config
    status: str  # "ok" or a failure reason
    message: str = ""
    peak_omega_rel: float = math.nan
    q_max_abs: float = math.nan
    omega_max_abs: float = math.nan
    omega_vs_q_max_abs: float = math.nan
    constraint_violation: float = math.nan
    wall_median_s: float = math.nan
    repeats: int = 0
    n_steps: int = 0
    n_evaluations: int = 0

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def row(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k != "config"}
        d.update(engine=self.config.engine, series=self.config.series, parameter=self.config.parameter,
                 label=self.config.label)
        return d


@dataclass(frozen=True)
class Truth:
    """The reference trajectory and how far it is from a second, looser tight run."""

    trajectory: Trajectory
    peak_omega: float
    error: dict = field(default_factory=dict)


def ground_truth(scene: Scene) -> Truth:
    """DOP853 at rtol 1e-12, checked against rtol 1e-11."""
    tight = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12))
    check = simulate(scene, ReducedSettings(method="dop853", rtol=1e-11))
    d = compare_trajectories(tight.trajectory, check.trajectory)
    return Truth(tight.trajectory, tight.peak.omega,
                 {"against": "DOP853 rtol 1e-11", **d.figures()})


def ladder(quick: bool = False, integrators=INTEGRATORS) -> list[Config]:
    """The configurations of a sweep (a small ladder with ``quick``)."""
    if quick:
        steps, rtols, timesteps = (1e-2, 3e-3, 1e-3), (1e-4, 1e-7, 1e-10), (1e-3, 2.5e-4)
    else:
        steps = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)
        rtols = tuple(10.0 ** -k for k in range(3, 13))
        timesteps = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)
    configs = [Config("reduced", "RKN4", h, reduced=ReducedSettings(method="rkn4", step=h, check_error=False))
               for h in steps]
    configs += [Config("reduced", "DOP853", r, reduced=ReducedSettings(method="dop853", rtol=r, check_error=False))
                for r in rtols]
    for integrator in integrators:
        for softness, extra in SOFTNESS.items():
            for h in timesteps:
                settings = MujocoSettings(integrator=integrator, timestep=h,
                                          max_constraint_violation=SWEEP_VIOLATION_LIMIT,
                                          max_energy_residual=SWEEP_ENERGY_LIMIT, **extra)
                configs.append(Config("mujoco", f"MuJoCo {integrator} ({softness})", h, mujoco=settings))
    return configs


def measure(scene: Scene, config: Config, truth: Trajectory, repeats: int) -> Measurement:
    """Run one configuration ``repeats`` times; errors from the first run, median wall time."""
    walls = []
    result = None
    try:
        for _ in range(repeats):
            if config.engine == "reduced":
                result = simulate(scene, config.reduced)
            else:
                with warnings.catch_warnings():  # off-grid edges: measured here, not warned about
                    warnings.simplefilter("ignore")
                    result = simulate_mujoco(scene, config.mujoco)
            walls.append(result.wall_s)
    except NumericalFailure as exc:
        return Measurement(config, status=exc.reason, message=str(exc))
    d = compare_trajectories(truth, result.trajectory)
    return Measurement(
        config, status="ok", peak_omega_rel=d.peak_omega_rel, q_max_abs=d.q_max_abs,
        omega_max_abs=d.omega_max_abs, omega_vs_q_max_abs=d.omega_vs_q_max_abs,
        constraint_violation=(math.nan if result.constraint_violation is None
                              else result.constraint_violation.max),
        wall_median_s=statistics.median(walls), repeats=len(walls), n_steps=result.n_steps,
        n_evaluations=result.n_evaluations)


def _measure_args(args):
    return measure(*args)


def _lost_job(args, reason: str) -> Measurement:
    """The measurement of a configuration whose worker died twice (killed from outside, as the
    OOM killer does): status ``failed``, the reason ("worker killed by signal 9") its message."""
    return Measurement(args[1], status="failed", message=reason)


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


def sweep(scene: Scene, configs: list[Config], truth: Truth, *, repeats: int = 3,
          workers: int | None = None) -> list[Measurement]:
    """Measure every configuration, ``workers`` processes at a time (see :func:`worker_count`).

    An exception in the parent (Ctrl-C, SIGTERM raised as an exception) ends the workers.
    """
    workers = worker_count(workers, len(configs))
    progress = Progress(len(configs))
    jobs = [(scene, c, truth.trajectory, repeats) for c in configs]
    results: list[Measurement] = []
    if workers == 1:
        for job in jobs:
            results.append(_measure_args(job))
            progress.step(job[1].label)
        return results
    for m in ordered_map(_measure_args, jobs, workers, lost=_lost_job):
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
        return self.confirmed is not None and self.confirmed.ok and self.confirmed.peak_omega_rel <= self.target


def cheapest_meeting(measurements: list[Measurement], engine: str, target: float) -> Measurement | None:
    """The successful measurement of ``engine`` with the smallest median wall time among those
    whose peak-ω relative error is at most ``target`` (None if there is none)."""
    meeting = [m for m in measurements if m.config.engine == engine and m.ok and m.peak_omega_rel <= target]
    return min(meeting, key=lambda m: m.wall_median_s) if meeting else None


def recommend(scene: Scene, measurements: list[Measurement], truth: Truth, target: float,
              repeats: int = 3) -> dict[str, Recommendation]:
    """Per engine, the cheapest measured configuration with peak-ω relative error ≤ target."""
    out = {}
    for engine in ("reduced", "mujoco"):
        best = cheapest_meeting(measurements, engine, target)
        if best is None:
            out[engine] = Recommendation(engine, target, None)
            continue
        confirmed = measure(scene, best.config, truth.trajectory, repeats)
        out[engine] = Recommendation(engine, target, best, confirmed)
    return out


def pareto_front(measurements: list[Measurement]) -> list[Measurement]:
    """Configurations that no other one beats on both peak-ω error and wall time."""
    ok = sorted((m for m in measurements if m.ok and m.peak_omega_rel > 0),
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


def cost_report(scene: Scene, truth: Truth, measurements: list[Measurement],
                recommendations: dict[str, Recommendation], repeats: int) -> dict:
    """The study as JSON-serialisable data."""
    def rec(r: Recommendation) -> dict:
        if not r.reached:
            return {"reached": False, "target": r.target}
        return {"reached": True, "target": r.target, "label": r.measurement.config.label,
                "wall_median_s": r.measurement.wall_median_s, "peak_omega_rel": r.measurement.peak_omega_rel,
                "confirmed_peak_omega_rel": r.confirmed.peak_omega_rel if r.confirmed else None,
                "confirmed": r.confirmed_ok}

    red, mj = recommendations["reduced"], recommendations["mujoco"]
    ratio = (mj.measurement.wall_median_s / red.measurement.wall_median_s
             if red.reached and mj.reached else None)
    return {
        "scene": scene.name, "source": portable_source(scene.source), "input_unit": scene.input_unit,
        "truth": {"method": "DOP853 rtol 1e-12", "peak_omega": truth.peak_omega, "accuracy": truth.error},
        "timing": {"what": "simulation only (integration or rollout); no model building, audit or plots",
                   "repeats": repeats, "statistic": "median"},
        "measurements": [m.row() for m in measurements],
        "recommendation": {"reduced": rec(red), "mujoco": rec(mj), "mujoco_over_reduced_wall": ratio},
    }


def write_cost_outputs(report: dict, measurements: list[Measurement], out_dir, target: float,
                       committed=None) -> list[Path]:
    """cost.png, cost.csv and cost.json into ``out_dir``, as a set (:func:`loopcheck.compare.output.write_folder`).

    cost.json is strict JSON: figures that were not measured (NaN) are null.
    """
    import csv

    from .plots import plot_work_precision

    def write_csv(path: Path) -> None:
        rows = [m.row() for m in measurements]
        with open(path, "w", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["status"])
            writer.writeheader()
            writer.writerows(rows)

    files = {
        "cost.png": lambda p: plot_work_precision(measurements, pareto_front(measurements), target,
                                                  report["scene"], p),
        "cost.csv": write_csv,
        "cost.json": lambda p: p.write_text(json_text(report), encoding="utf-8"),
    }
    return write_folder(out_dir, files, one_run=True, committed=committed)


def summary_lines(report: dict, measurements: list[Measurement]) -> list[str]:
    """A printed summary: the table, the truth's accuracy and the recommendation."""
    unit = report.get("input_unit", "rad")
    lines = [f"truth: DOP853 rtol 1e-12, peak qdot {report['truth']['peak_omega']:+.12g} {unit}/s; "
             f"against rtol 1e-11: peak {report['truth']['accuracy']['peak_omega_rel']:.1e} rel, "
             f"max |dq| {report['truth']['accuracy']['q_max_abs']:.1e} {unit}",
             f"wall time: median of {report['timing']['repeats']} runs, simulation only",
             f"{'configuration':46s} {'status':>8s} {'peak rel':>9s} {'max|dq|':>9s} {'max|dw|':>9s} "
             f"{'dw at q':>9s} {'loop (m)':>9s} {'wall (s)':>9s} {'steps':>7s}"]
    for m in measurements:
        if m.ok:
            lines.append(f"{m.config.label:46s} {'ok':>8s} {m.peak_omega_rel:9.2e} {m.q_max_abs:9.2e} "
                         f"{m.omega_max_abs:9.2e} {m.omega_vs_q_max_abs:9.2e} {m.constraint_violation:9.2e} "
                         f"{m.wall_median_s:9.4f} {m.n_steps:7d}")
        else:
            lines.append(f"{m.config.label:46s} {m.status:>8s} {m.message[:70]}")
    rec = report["recommendation"]
    for engine in ("reduced", "mujoco"):
        r = rec[engine]
        if r["reached"]:
            lines.append(f"cheapest {engine} configuration with peak error <= {r['target']:g}: {r['label']} "
                         f"({r['wall_median_s']:.4f} s, error {r['peak_omega_rel']:.2e}; re-run: "
                         f"{r['confirmed_peak_omega_rel']:.2e}, {'confirmed' if r['confirmed'] else 'NOT confirmed'})")
        else:
            lines.append(f"{engine}: the target {r['target']:g} was not reached at any setting tried")
    if rec["mujoco_over_reduced_wall"] is not None:
        lines.append(f"at that accuracy MuJoCo costs {rec['mujoco_over_reduced_wall']:.2f}x "
                     "the reduced solver's wall time")
    return lines


def study(scene: Scene, *, quick: bool = False, target: float | None = None, repeats: int | None = None,
          workers: int | None = None) -> tuple[dict, list[Measurement], float]:
    """The whole cost pipeline: truth, sweep, recommendation and report.

    ``target`` defaults to the scene's peak_omega_rtol, ``repeats`` to 3, ``workers`` to
    one process per core (a request above that warns and is capped). Returns the report
    (cost.json's data), the measurements and the target used.
    """
    target = target if target is not None else scene.tolerances.peak_omega_rtol
    repeats = repeats if repeats is not None else 3
    configs = ladder(quick=quick)
    used = worker_count(workers, len(configs))
    if workers is not None and used < workers:
        warnings.warn(f"--workers {workers}: using {used} "
                      f"(at most one process per core: {os.cpu_count() or 1} cores)")
    truth = ground_truth(scene)
    measurements = sweep(scene, configs, truth, repeats=repeats, workers=used)
    recommendations = recommend(scene, measurements, truth, target, repeats)
    return cost_report(scene, truth, measurements, recommendations, repeats), measurements, target
