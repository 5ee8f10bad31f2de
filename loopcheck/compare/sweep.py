"""``loopcheck sweep``: a family of scenes through both engines, one summary row per variant.

A sweep (:mod:`loopcheck.compare.sweep_spec`) makes variants of one scene file. Each variant is built
with :func:`loopcheck.scenefile.scene_from_dict` and run through :func:`loopcheck.compare.run.compare_engines`
with the scene's own settings and tolerances (the same code path and settings as ``loopcheck run``
without engine flags). A variant that cannot be assembled is a row with status ``invalid``, one
whose engines fail numerically a row with status ``failed``; both are counted and the sweep goes
on.

Reduced-only sweeps (``spec.engines`` is :attr:`~loopcheck.compare.sweep_spec.Engines.REDUCED`, ``loopcheck
sweep --engines reduced`` or ``engines = "reduced"`` in the ``[sweep]`` table): each variant runs
only :func:`loopcheck.reduced.engine.simulate` with the scene's reduced settings as the comparison resolves
them (:func:`loopcheck.compare.settings.reduced_settings`); MuJoCo is neither run nor imported. Their rows
hold summaries only, so each variant is a summary run (``simulate``'s ``summary``: the compiled DOP853
sampled at its steps, and finely only beside the peak; unless ``keep_trajectories``): the full
run's peak and its time to round-off (within 4e-12 relative on the seed's variants), its steps to
round-off (within 1 %), q̈ evaluated only at the samples cut beside the peaks (about 140 on the
seed) and the dense output made only for their steps (on the seed at rtol 1e-12: 9 187 evaluations
of q̈ for a full run's 10 864 + 2 887 at its samples), and the energy residual taken at the step
ends, where the flows are the solver's own (0.2 to 1.2 times the full run's, which also counts the
dense output's error between steps; tests/reduced/test_summary_runs.py states the bounds: near the
energy bound a row can pass where ``loopcheck run`` of the variant fails on that error, as 12 of the
seed's 1 000 benchmark variants do at rtol 1e-9, none at 1e-10 or 1e-12). ``passed``
then means the reduced engine's own checks (error estimate, energy balance) passed; there is no
gate, so no ``gate_failed``. Their sweep.csv has only the columns of what ran:
:data:`~loopcheck.compare.sweep_table.FIXED_COLUMNS`, the varied keys, then
:data:`~loopcheck.compare.sweep_table.REDUCED_ONLY_COLUMNS` (the ``reduced.*``
figures and ``variant_wall_s``); the ``diff.*``, ``gate.*`` and ``mujoco.*`` columns are left
out rather than left empty, since nothing was compared (empty cells would read like variants that
failed, and their nulls would make each row of sweep.json 3.4 times longer: 1270 characters for
374 on the seed). The mode is in sweep.json (``"engines"``) and readable from the header.

Variants run in a process pool (``workers`` processes, default all cores,
:func:`loopcheck.compare.pool.ordered_map`), in chunks of consecutive variants per task; results
come back in variant order and each row is
written to ``sweep.csv`` as soon as it arrives, so memory stays flat with the number of variants
(only a bounded summary is kept: counts, the worst variant, per key the range of the failing
variants' values). A worker that dies (killed from outside, as the OOM killer does) is replaced
and its chunk runs once more; a chunk whose worker dies twice becomes rows of status ``failed``
with the reason "worker killed by signal N" (exit status 1), and the sweep goes on.

With a Dask scheduler (``loopcheck sweep --scheduler ADDRESS``, the optional ``distributed`` extra;
nothing here imports Dask otherwise) the same chunks are Dask tasks: the scene data is scattered
once to every worker, at most :data:`~loopcheck.compare.sweep_dask.CHUNKS_IN_FLIGHT` chunks per worker
thread are in flight, and the futures are read back in submission order, so the rows are the same,
in the same order, as a local run's (only the wall times differ).

Files (written through :func:`loopcheck.compare.output.write_folder`: all or nothing). The rows are
streamed into the staged ``sweep.csv`` inside write_folder's hidden staging folder: the sweep
itself is the writer of ``sweep.csv``, so a failed or interrupted sweep leaves the output folder as
it was (nothing appears until the whole set is committed). The plots and ``sweep.json`` are then
made from the staged ``sweep.csv`` read back row by row.

- ``sweep.csv``: one row per variant, in variant order (:data:`~loopcheck.compare.sweep_table.FIXED_COLUMNS`,
  then the varied keys by name, then :data:`~loopcheck.compare.sweep_table.FIGURE_COLUMNS`, reduced-only
  :data:`~loopcheck.compare.sweep_table.REDUCED_ONLY_COLUMNS`); empty cells are figures not measured;
  list figures (``diff.mode_mismatches``...) are JSON text.
- ``sweep.json``: the specification, the summary and the rows (strict JSON, null for NaN).
- plots: ``sweep_peak_omega.png`` (peak ω of each engine run against the first varied key, a
  grid), ``sweep_gate_map.png`` (the gate's worst ratio over the first two keys of a grid of two
  or more keys), ``sweep_peak_omega_hist.png`` (Monte Carlo: histogram of each engine's peak ω),
  ``sweep_worst_differences.png`` (``loopcheck run``'s differences plot of the worst variant, run
  again: the one whose peak-ω difference is the largest multiple of its tolerance). A
  reduced-only sweep draws the first or the third, with the reduced engine only: no gate map
  and no worst differences, as nothing was compared (:func:`~loopcheck.compare.sweep_plots.plot_files`).
- ``trajectories.csv`` with ``keep_trajectories``: index, engine, t, q, qdot, qddot of every
  variant that ran (for small sweeps).

This module runs a sweep: the row of one variant, the process pool, the order of the rows and the
estimate of a long sweep (:func:`run_sweep`). The rest has a module each: the Dask cluster
(:mod:`loopcheck.compare.sweep_dask`), the journal of finished rows (:mod:`loopcheck.compare.sweep_journal`),
the summary (:mod:`loopcheck.compare.sweep_summary`), sweep.csv and sweep.json
(:mod:`loopcheck.compare.sweep_table`) and the plots (:mod:`loopcheck.compare.sweep_plots`).
"""

from __future__ import annotations

import itertools
import math
import os
import time
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

from .output import write_folder
from .pool import ignore_interrupts, ordered_map
from .sweep_dask import CHUNKS_IN_FLIGHT, dask_rows, dask_threads
from .sweep_journal import Journal
from .sweep_plots import PLOTS, WORST_PLOT, plot_files, plot_worst
from .sweep_summary import Summary
from .sweep_table import (CSV_FILE, DIFF_FIGURES, ENGINE_FIGURES, JSON_FILE, TRAJECTORY_FILE, stream_rows,
                          write_json)
from loopcheck.sweep_spec import Engines, SweepSpec, count, variant_values

MAX_CHUNK = 32


def sweep_files(spec: SweepSpec, keep_trajectories: bool = False) -> tuple[str, ...]:
    """Every file a sweep of ``spec`` writes, in the order they are committed."""
    return ((CSV_FILE,) + ((TRAJECTORY_FILE,) if keep_trajectories else ()) + plot_files(spec)
            + (JSON_FILE,))


# -- one variant ------------------------------------------------------------------------

def _ratio(value: float, bound: float | None) -> float | None:
    if bound is None or value is None or not math.isfinite(value):
        return None
    return value / bound if bound > 0 else math.inf


def comparison_row(c) -> dict[str, Any]:
    """The figures of one comparison (the ``diff`` and ``gate`` of report.json, both engines'
    peaks, times and residuals), keyed by sweep.csv column."""
    from .report import report_dict

    report = report_dict(c, joints=())  # a row holds no joint coordinates
    row: dict[str, Any] = {f"diff.{k}": report["diff"][k] for k in DIFF_FIGURES}
    tol = c.gate.tolerances
    peak_ratio = _ratio(c.diff.peak_omega_abs, tol.peak_bound(abs(c.diff.peak_omega_reference)))
    ratios = [peak_ratio, _ratio(c.diff.q_max_abs, tol.q_atol), _ratio(c.diff.omega_max_abs, tol.omega_atol),
              _ratio(c.diff.omega_vs_q_max_abs, tol.omega_vs_q_atol)]
    ratios = [r for r in ratios if r is not None]
    row.update({"gate.passed": c.gate.passed, **{f"gate.{k}": v for k, v in report["gate"]["tolerances"].items()},
                "gate.peak_ratio": peak_ratio, "gate.worst_ratio": max(ratios) if ratios else None})
    row.update(engine_row("reduced", c.reference, c.diff.peak_reference))
    row.update(engine_row("mujoco", c.other, c.diff.peak_other))
    row["mujoco.max_constraint_violation"] = c.other.constraint_violation.max
    return row


def engine_row(engine: str, result, peak=None) -> dict[str, Any]:
    """One engine's figures (report.json's per-engine part, with the peak event ``peak``:
    default the run's own), keyed by sweep.csv column."""
    from .report import engine_summary

    summary = engine_summary(result, peak)
    return {f"{engine}.{k}": summary[k] for k in ENGINE_FIGURES}


def _run_engines(scene, engines: Engines, summary: bool = True) -> tuple[dict[str, Any], str, str, dict[str, Any]]:
    """The figures, status, reason and results by engine name of ``scene`` run as ``engines``
    says: both engines compared and gated (as ``loopcheck run``), or the reduced engine alone with the
    settings the comparison would give it, as a summary run when ``summary`` (the row holds only
    summaries: :func:`loopcheck.reduced.engine.simulate`'s ``summary``; not when the trajectories
    are kept). NumericalFailure propagates."""
    if engines is Engines.REDUCED:  # MuJoCo is not imported: loopcheck.compare.run would load it
        from loopcheck.reduced.engine import simulate

        from .settings import reduced_settings

        result = simulate(scene, reduced_settings(scene), summary=summary)
        return engine_row("reduced", result), "passed", "", {"reduced": result}
    from .run import compare_engines

    c = compare_engines(scene)
    return (comparison_row(c), "passed" if c.gate.passed else "gate_failed", "; ".join(c.gate.failures),
            {"reduced": c.reference, "mujoco": c.other})


def run_variant(index: int, values: Mapping[str, float], data: Mapping[str, Any], source: str,
                keep_trajectories: bool = False, engines: Engines = Engines.BOTH) -> dict[str, Any]:
    """One variant's row: built from ``data`` with ``values`` applied, run through both engines
    and gated (as ``loopcheck run``), or with ``engines`` REDUCED through the reduced engine alone;
    invalid and failed variants are rows too."""
    from loopcheck.errors import NumericalFailure
    from loopcheck.scene import SceneError
    from loopcheck.scenefile import scene_from_dict

    from loopcheck.sweep_spec import apply

    row: dict[str, Any] = {"index": index, "status": "", "reason": "", **values}
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():  # off-grid edges and ignored settings: the same for many variants
            warnings.simplefilter("ignore")
            scene = scene_from_dict(apply(data, values), source)
            figures, status, reason, results = _run_engines(scene, engines, summary=not keep_trajectories)
    except (SceneError, ValueError) as exc:  # as main() does: the variant's scene or settings are bad input
        row.update(status="invalid", reason=" ".join(str(exc).split()))
    except NumericalFailure as exc:
        row.update(status="failed", reason=f"{exc.reason}: {' '.join(str(exc).split())}")
    except Exception as exc:  # noqa: BLE001 - an engine's own error is this variant's, not the sweep's
        row.update(status="failed", reason=f"{type(exc).__name__}: {' '.join(str(exc).split())}")
    else:
        row.update(figures)
        row.update(status=status, reason=reason)
        if keep_trajectories:
            row["_trajectories"] = {e: _trajectory(r) for e, r in results.items()}
    row["variant_wall_s"] = time.perf_counter() - start
    return row


def _trajectory(result) -> list[tuple[float, float, float, float]]:
    tr = result.trajectory
    return [tuple(map(float, r)) for r in zip(tr.t, tr.q, tr.qdot, tr.qddot)]


# -- the pool ---------------------------------------------------------------------------

_WORKER: dict[str, Any] = {}


def _init_worker(data, source, keep, engines) -> None:
    ignore_interrupts()
    _WORKER.update(data=data, source=source, keep=keep, engines=engines)


def _run_chunk(task: tuple[int, list[dict[str, float]]]) -> list[dict[str, Any]]:
    start, values = task
    return [run_variant(start + i, v, _WORKER["data"], _WORKER["source"], _WORKER["keep"], _WORKER["engines"])
            for i, v in enumerate(values)]


def chunk_size(n: int, workers: int) -> int:
    """Variants per task: about eight tasks per worker, at most :data:`MAX_CHUNK`."""
    return max(1, min(MAX_CHUNK, math.ceil(n / (8 * workers))))


def _chunks(spec: SweepSpec, size: int, start: int = 0) -> Iterator[tuple[int, list[dict[str, float]]]]:
    it = itertools.islice(variant_values(spec), start, None)
    while True:
        chunk = list(itertools.islice(it, size))
        if not chunk:
            return
        yield start, chunk
        start += len(chunk)


def _dask_chunk(start: int, values: list[dict[str, float]], data: Mapping[str, Any], source: str,
                keep: bool, engines: Engines) -> list[dict[str, Any]]:
    """One Dask task: the rows of the consecutive variants ``start``, ``start + 1``..."""
    return [run_variant(start + i, v, data, source, keep, engines) for i, v in enumerate(values)]


def run_rows(data: Mapping[str, Any], spec: SweepSpec, source: str, *, workers: int = 1,
             keep_trajectories: bool = False, client=None, start: int = 0) -> Iterator[dict[str, Any]]:
    """Every variant's row from variant ``start`` on, in variant order, as they complete
    (``workers`` processes, or with ``client`` the Dask cluster's worker threads: the same
    chunks become Dask tasks)."""
    n = count(spec) - start
    if n <= 0:
        return
    if client is not None:
        workers = dask_threads(client)
    size = chunk_size(n, workers)
    tasks = _chunks(spec, size, start)
    if client is not None:
        yield from dask_rows(client, _dask_chunk, data, (source, keep_trajectories, spec.engines), tasks,
                             CHUNKS_IN_FLIGHT * workers)
        return
    if workers <= 1:
        for start, values in tasks:
            for i, v in enumerate(values):
                yield run_variant(start + i, v, data, source, keep_trajectories, spec.engines)
        return
    for rows in ordered_map(_run_chunk, tasks, workers, _init_worker,
                            (dict(data), source, keep_trajectories, spec.engines), lost=_lost_chunk):
        yield from rows


def _lost_chunk(task: tuple[int, list[dict[str, float]]], reason: str) -> list[dict[str, Any]]:
    """The rows of a chunk whose worker died twice (:func:`loopcheck.compare.pool.ordered_map`):
    each variant ``failed`` with the reason ("worker killed by signal 9"), nothing measured."""
    start, values = task
    return [{"index": start + i, "status": "failed", "reason": reason, **v} for i, v in enumerate(values)]


# -- progress and the estimate of a long sweep ----------------------------------------------

LONG_SWEEP_S = 600.0  # a sweep estimated to take longer says so (one warning line) before it runs on


class _Progress:
    def __init__(self, total: int):
        from .cost import Progress

        self.bar = Progress(total, label="sweep")

    def step(self, row):
        self.bar.step(f"#{row['index']} {row['status']}")


def _estimate(n_left: int, seconds_each: float, workers: int) -> None:
    """One warning line when the variants left are estimated to take over :data:`LONG_SWEEP_S`."""
    total = n_left * seconds_each / workers
    if total > LONG_SWEEP_S:
        shown = f"{total / 3600:.1f} h" if total >= 3600 else f"{total / 60:.0f} min"
        warnings.warn(f"this sweep is estimated to take {shown} ({n_left} variants at {seconds_each:.3g} s each "
                      f"on {workers} worker{'s' if workers != 1 else ''}); Ctrl-C keeps the finished rows for "
                      "--resume")


def run_sweep(data: Mapping[str, Any], spec: SweepSpec, source: str, out: str | os.PathLike, *,
              workers: int | None = None, keep_trajectories: bool = False,
              progress: bool = True, sensitivity: list[dict] | None = None,
              client=None, resume: bool = False, restart: bool = False,
              committed: Callable[[Summary, list[Path]], None] | None = None) -> tuple[Summary, list[Path]]:
    """Run every variant and write the sweep's files into ``out`` (module docstring). The
    caller has checked ``spec`` against the scene and ``out`` (:func:`loopcheck.compare.output.check_folder`);
    ``sensitivity`` (:meth:`loopcheck.compare.sensitivity.Sensitivity.as_dict` of each key) goes into sweep.json.
    With ``client`` (:func:`loopcheck.compare.sweep_dask.connect`) the variants run on that Dask cluster
    instead of a local pool. ``committed`` (the command's lines) is called with the summary and the
    files once they are in place, while signals are held (:func:`loopcheck.compare.output.write_folder`).

    Each finished row also goes to the journal beside ``out``
    (:func:`loopcheck.compare.sweep_journal.journal_path`), which the commit of the files removes: an
    interrupted sweep leaves ``out`` as it was and its rows there; with ``resume`` those that check
    are read back instead of run again, with ``restart`` they are discarded, and with neither an
    existing journal is refused (:class:`loopcheck.compare.sweep_journal.JournalError`; the caller
    checks first with :func:`loopcheck.compare.sweep_journal.check_journal`). Before the bulk of the variants, the next
    two run here and the second one's time estimates the rest (:func:`_estimate`)."""
    from .cost import worker_count

    n = count(spec)
    used = dask_threads(client) if client is not None else worker_count(workers, n)
    if client is None and workers is not None and used < workers and used < n:
        warnings.warn(f"--workers {workers}: using {used} (at most one process per core: {os.cpu_count() or 1} cores)")
    from loopcheck.scenefile import scene_from_dict

    speed_unit = f"{scene_from_dict(data, source).input_unit}/s"
    summary = Summary(spec.keys, workers=used, engines=spec.engines, speed_unit=speed_unit)
    bar = _Progress(n) if progress else None

    journal = Journal(out, data, spec, resume=resume, restart=restart)  # locked until closed

    def fresh_rows() -> Iterator[dict[str, Any]]:  # started once the journal's rows are replayed
        first = journal.kept
        timed = []
        for index, values in itertools.islice(enumerate(variant_values(spec)), first, first + 2):
            began = time.perf_counter()
            yield run_variant(index, values, data, source, keep_trajectories, spec.engines)
            timed.append(time.perf_counter() - began)
        if len(timed) == 2:  # the second: imports and compiled code loaded by the first
            _estimate(n - first - 2, timed[1], used)
        yield from run_rows(data, spec, source, workers=used, keep_trajectories=keep_trajectories, client=client,
                            start=first + len(timed))

    def write_rows(path: Path) -> None:
        start = time.perf_counter()
        rows = itertools.chain(journal.replay(), fresh_rows())
        stream_rows(rows, spec, path, path.parent / TRAJECTORY_FILE if keep_trajectories else None, summary,
                    bar.step if bar else None, journal.write)
        summary.wall_s = time.perf_counter() - start

    def staged(path: Path) -> None:  # written with sweep.csv
        if not path.is_file():
            raise RuntimeError(f"{path.name} was not written with {CSV_FILE}")

    files: dict[str, Callable[[Path], None]] = {CSV_FILE: write_rows}
    if keep_trajectories:
        files[TRAJECTORY_FILE] = staged
    for name in plot_files(spec):  # from the staged sweep.csv, but the worst variant's (run again)
        files[name] = (lambda p: plot_worst(data, source, summary, p)) if name == WORST_PLOT else \
            (lambda p, name=name: PLOTS[name](p.parent / CSV_FILE, spec, source, p, speed_unit))
    files[JSON_FILE] = lambda p: write_json(p, p.parent / CSV_FILE, spec, source, summary, sensitivity)

    def in_place(paths: list[Path]) -> None:
        journal.close(True)  # the set is committed: nothing is left to resume
        if committed is not None:
            committed(summary, paths)

    done = False
    try:
        paths = write_folder(out, files, one_run=True, committed=in_place)
        done = True
    finally:
        journal.close(done)
    return summary, paths
