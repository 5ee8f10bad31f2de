"""``loopcheck sweep``: a family of scenes through the engines, one summary row per variant.

A sweep (:mod:`loopcheck.compare.sweep_spec`) makes variants of one scene file. Each variant is built
with :func:`loopcheck.scenefile.scene_from_dict` and run through :func:`loopcheck.compare.run.compare_engines`
with the scene's own settings and tolerances (the same code path and settings as ``loopcheck run``
without engine flags). A variant that cannot be assembled is a row with status ``invalid``, one
whose engines fail numerically a row with status ``failed``; both are counted and the sweep goes
on.

Any list of engines (``spec.engines``, ``loopcheck sweep --engines reduced,mujoco,mjx``; the default
``both`` is the design card's pair): each variant runs the reference and every other engine of the
list, each judged against the reference at its own tolerances (:func:`_run_engines`, as ``loopcheck
check --engines``). One judged engine: the row's ``diff.*`` and ``gate.*`` columns (the pair's
sweep.csv and sweep.json are as they were); several: ``diff.ENGINE.*`` and ``gate.ENGINE.*`` for
each, sweep.json with ``schema_version`` 1 and the list of engines, the summary per engine. An
engine that declares a batch size (:func:`batch_sizes`: the registry's ``Engine.batch_size``, or
``--batch-size``) runs in this process in batches of consecutive variants of one structure
(:func:`structure`, :func:`run_batches`: the last chunk padded, a chunk split first to what the
device holds, each variant's failure its own), and the rest of each variant's row on the pool,
its workers started by ``spawn``.

Reduced-only sweeps (``spec.engines`` is the reference alone, ``loopcheck
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
:func:`loopcheck.compare.pool.ordered_map`), in chunks of consecutive variants per task (smaller
towards the end, so that the workers finish together; meanwhile this process imports matplotlib
for the plots in a thread: :func:`loopcheck.compare.plots.prefetch_matplotlib`); results
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

Several inputs (a scene of several degrees of freedom; docs/comparison.md, "Several inputs"): the
one-DOF columns hold the first input's figures (as report.json's ``diff``), but ``gate.passed`` and
``gate.worst_ratio``, which judge every input (:func:`loopcheck.compare.diff.gate_inputs`); each
later input NAME has its own columns after them, ``NAME:`` and the one-DOF column
(:func:`~loopcheck.compare.sweep_table.input_columns`: its differences, its gate ratios, every
engine's peak and its time). The journal checks them (:mod:`loopcheck.compare.sweep_journal`), the
summary's worst variant is the worst over every input, the peak plots have a panel per input and the
sensitivities a table per input. The reduced engine in several coordinates has no summary mode (a
reduced-only row is its full run); MJX's and MJWarp's batches carry every input as their single runs do.

This module runs a sweep: the row of one variant, the process pool, the order of the rows and the
estimate of a long sweep (:func:`run_sweep`). The rest has a module each: the Dask cluster
(:mod:`loopcheck.compare.sweep_dask`), the journal of finished rows (:mod:`loopcheck.compare.sweep_journal`),
the summary (:mod:`loopcheck.compare.sweep_summary`), sweep.csv and sweep.json
(:mod:`loopcheck.compare.sweep_table`), the plots (:mod:`loopcheck.compare.sweep_plots`) and
which engines run (:mod:`loopcheck.compare.sweep_engines`).
"""

from __future__ import annotations

import itertools
import math
import os
import time
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, NamedTuple

from .output import write_folder
from .pool import ignore_interrupts, ordered_map
from .sweep_dask import CHUNKS_IN_FLIGHT, dask_rows, dask_threads
from .sweep_journal import Journal
from .sweep_plots import PLOTS, WORST_PLOT, plot_files, plot_worst
from .sweep_summary import Summary
from .sweep_engines import judged_scene, sweep_engines
from .sweep_table import (CSV_FILE, DIFF_FIGURES, ENGINE_FIGURES, INPUT_DIFF_FIGURES, JSON_FILE, TRAJECTORY_FILE,
                          input_column, stream_rows, write_json)
from loopcheck.registry import ENGINES, REFERENCE
from loopcheck.sweep_spec import Engines, SweepSpec, count, engine_names, variant_values

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


def _input_ratios(d, tol) -> tuple[float | None, float | None]:
    """One input's difference ``d`` against the tolerances ``tol``: its peak ratio (peak_omega_abs
    over its bound) and its worst ratio (the largest of its ratios)."""
    peak_ratio = _ratio(d.peak_omega_abs, tol.peak_bound(abs(d.peak_omega_reference)))
    ratios = [peak_ratio, _ratio(d.q_max_abs, tol.q_atol), _ratio(d.omega_max_abs, tol.omega_atol),
              _ratio(d.omega_vs_q_max_abs, tol.omega_vs_q_atol)]
    ratios = [r for r in ratios if r is not None]
    return peak_ratio, max(ratios) if ratios else None


def comparison_row(c, engine: str | None = None, several: bool = False) -> dict[str, Any]:
    """The figures of one comparison (the ``diff`` and ``gate`` of report.json, both engines'
    peaks, times and residuals), keyed by sweep.csv column: ``diff.*``/``gate.*``, or with
    ``several`` (the sweep judges several engines) ``diff.ENGINE.*``/``gate.ENGINE.*``. ``engine``:
    the judged engine's name (default the result's).

    A scene of several degrees of freedom: the unprefixed figures are its first input's (as
    report.json's ``diff``), but ``gate.passed`` and ``gate.worst_ratio``, which judge every input
    (:func:`loopcheck.compare.diff.gate_inputs`); each later input NAME has its own figures in
    ``NAME:``-prefixed columns (:func:`~loopcheck.compare.sweep_table.input_columns`)."""
    from .report import report_dict

    engine = engine or c.other.engine
    col = (lambda table, k: f"{table}.{engine}.{k}") if several else (lambda table, k: f"{table}.{k}")  # noqa: E731
    report = report_dict(c, joints=())  # a row holds no joint coordinates
    row: dict[str, Any] = {col("diff", k): report["diff"][k] for k in DIFF_FIGURES}
    tol = c.gate.tolerances
    ratios = [_input_ratios(d, tol) for d in c.diffs]
    peak_ratio, worst = ratios[0]
    worsts = [w for _, w in ratios if w is not None]
    row.update({col("gate", "passed"): c.gate.passed,
                **{col("gate", k): v for k, v in report["gate"]["tolerances"].items()},
                col("gate", "peak_ratio"): peak_ratio, col("gate", "worst_ratio"): max(worsts) if worsts else None})
    row.update(engine_row(REFERENCE, c.reference, c.diff.peak_reference))
    row.update(engine_row(engine, c.other, c.diff.peak_other))
    gap = c.other.constraint_violation
    row[f"{engine}.max_constraint_violation"] = gap.max if gap is not None else None
    for name, d, (peak_k, worst_k) in list(zip(c.scene.inputs, c.diffs, ratios))[1:]:
        figures = {k: v for k, v in report_figures(d).items() if k in INPUT_DIFF_FIGURES}
        row.update({input_column(name, col("diff", k)): figures[k] for k in INPUT_DIFF_FIGURES})
        row.update({input_column(name, col("gate", "peak_ratio")): peak_k,
                    input_column(name, col("gate", "worst_ratio")): worst_k})
        for who, peak in ((REFERENCE, d.peak_reference), (engine, d.peak_other)):
            row.update({input_column(name, f"{who}.peak_omega"): peak.omega, input_column(name, f"{who}.t_peak"): peak.time})
    return row


def report_figures(d) -> dict[str, float | None]:
    """A difference's scalar figures as report.json writes them (NaN and inf as None)."""
    return {k: (float(v) if math.isfinite(v) else None) for k, v in d.figures().items()}


def engine_row(engine: str, result, peak=None, inputs: tuple[str, ...] = ()) -> dict[str, Any]:
    """One engine's figures (report.json's per-engine part, with the peak event ``peak``:
    default the run's own), keyed by sweep.csv column; with several inputs, each later input's
    own peak and its time too (``NAME:ENGINE.peak_omega``, ``NAME:ENGINE.t_peak``; ``inputs``: the
    scene's; a comparison's row sets them from its differences instead)."""
    from .report import engine_summary

    summary = engine_summary(result, peak)
    row = {f"{engine}.{k}": summary[k] for k in ENGINE_FIGURES}
    if inputs[1:] and len(result.other_inputs) != len(inputs) - 1:
        raise ValueError(f"the {result.engine} run records {len(result.other_inputs) + 1} input trajectories, the "
                         f"scene has {len(inputs)} inputs ({', '.join(inputs)})")
    for name, (_, p) in zip(inputs[1:], result.other_inputs):
        row.update({input_column(name, f"{engine}.peak_omega"): p.omega, input_column(name, f"{engine}.t_peak"): p.time})
    return row


def failure_text(exc: BaseException) -> str:
    """A failed run's reason, in one line, as a row says it."""
    from loopcheck.errors import NumericalFailure

    text = " ".join(str(exc).split())
    if isinstance(exc, NumericalFailure):
        return f"{exc.reason}: {text}"
    if isinstance(exc, ValueError):
        return f"refused: {text}"
    return f"{type(exc).__name__}: {text}"


def _run_engines(scene, engines, summary: bool = True,
                 batched: Mapping[str, Any] | None = None) -> tuple[dict[str, Any], str, str, dict[str, Any]]:
    """The figures, status, reason and results by engine name of ``scene`` run by ``engines``
    (names, the reference among them): each other engine compared with the reference and gated at
    its own tolerances (as ``loopcheck check --engines``; the pair as ``loopcheck run``), or the
    reduced engine alone with the settings the comparison would give it, as a summary run when
    ``summary`` (the row holds only summaries: :func:`loopcheck.reduced.engine.simulate`'s
    ``summary``; not when the trajectories are kept). ``batched``: the outcomes (EngineResult or
    exception) of the engines run in batches, by name. The reference's NumericalFailure
    propagates; so does the judged engine's when it is the only one (its row is ``failed``, as
    ``loopcheck run``'s); with several, a judged engine's failure is the row's, the others' figures kept."""
    from .settings import engine_settings

    names = sweep_engines(engine_names(engines))
    if len(names) == 1:  # the reference alone; no other engine is imported (loopcheck.compare.run would load one)
        result = ENGINES[REFERENCE].simulate(scene, engine_settings(REFERENCE, scene), summary=summary)
        return engine_row(REFERENCE, result, inputs=scene.inputs), "passed", "", {REFERENCE: result}
    from .run import judge

    reference = ENGINES[REFERENCE].simulate(scene, engine_settings(REFERENCE, scene))
    several = len(names) > 2
    figures: dict[str, Any] = {}
    failures: list[str] = []
    gates: list[str] = []
    results: dict[str, Any] = {REFERENCE: reference}
    for name in names[1:]:
        judged = judged_scene(scene, name)
        got = (batched or {}).get(name)
        if got is None:
            try:
                got = ENGINES[name].simulate(judged, engine_settings(name, scene))
            except Exception as exc:  # noqa: BLE001 - this engine's failure on this variant
                got = exc
        if isinstance(got, BaseException):
            if not several:
                raise got
            failures.append(f"{name}: {failure_text(got)}")
            continue
        c = judge(judged, reference, got, judged.tolerances)
        figures.update(comparison_row(c, name, several))
        gates += [f"{name}: {f}" if several else f for f in c.gate.failures]
        results[name] = got
    if not any(k.startswith(f"{REFERENCE}.") for k in figures):
        figures.update(engine_row(REFERENCE, reference, inputs=scene.inputs))
    status = "failed" if failures else "gate_failed" if gates else "passed"
    return figures, status, "; ".join(failures + gates), results


def run_variant(index: int, values: Mapping[str, float], data: Mapping[str, Any], source: str,
                keep_trajectories: bool = False, engines=Engines.BOTH,
                batched: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """One variant's row: built from ``data`` with ``values`` applied, run through ``engines`` (a
    word of :class:`~loopcheck.sweep_spec.Engines` or names) as :func:`_run_engines` says, with the
    outcomes ``batched`` of the engines run in batches; invalid and failed variants are rows too."""
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
            figures, status, reason, results = _run_engines(scene, engines, summary=not keep_trajectories,
                                                            batched=batched)
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
            row["_trajectories"] = {e: _trajectory(r, scene.inputs) for e, r in results.items()}
    row["variant_wall_s"] = time.perf_counter() - start + sum(
        r.wall_s for r in (batched or {}).values() if not isinstance(r, BaseException))
    return row


def _trajectory(result, inputs: tuple[str, ...] = ()) -> list:
    """The samples (t, q, q̇, q̈) of the run's input; with several ``inputs``, (name, samples) of each."""
    def samples(tr) -> list[tuple[float, float, float, float]]:
        return [tuple(map(float, r)) for r in zip(tr.t, tr.q, tr.qdot, tr.qddot)]

    if len(inputs) > 1:
        return [(name, samples(tr)) for name, (tr, _) in zip(inputs, result.inputs)]
    return samples(result.trajectory)


# -- the pool ---------------------------------------------------------------------------

_WORKER: dict[str, Any] = {}


def _init_worker(data, source, keep, engines) -> None:
    ignore_interrupts()
    _WORKER.update(data=data, source=source, keep=keep, engines=engines)


def _run_chunk(task: tuple) -> list[dict[str, Any]]:
    start, values, *rest = task
    batched = rest[0] if rest else [None] * len(values)
    return [run_variant(start + i, v, _WORKER["data"], _WORKER["source"], _WORKER["keep"], _WORKER["engines"], b)
            for i, (v, b) in enumerate(zip(values, batched))]


def chunk_size(n: int, workers: int) -> int:
    """Variants per task: about eight tasks per worker, at most :data:`MAX_CHUNK`."""
    return max(1, min(MAX_CHUNK, math.ceil(n / (8 * workers))))


def chunk_lengths(n: int, size: int, workers: int = 1) -> Iterator[int]:
    """How many of ``n`` variants each task takes, in order: ``size``; with several ``workers``,
    fewer towards the end (at most half of what is left per worker, at least one), so that the
    workers finish together instead of one waiting on the other's last chunk."""
    left = n
    while left > 0:
        take = size if workers <= 1 else max(1, min(size, math.ceil(left / (2 * workers))))
        yield take
        left -= take


def _chunks(spec: SweepSpec, size: int, start: int = 0,
            workers: int = 1) -> Iterator[tuple[int, list[dict[str, float]]]]:
    """The variants from ``start`` as tasks ``(start, values)`` of consecutive variants, as many
    as :func:`chunk_lengths` says."""
    it = itertools.islice(variant_values(spec), start, None)
    for take in chunk_lengths(count(spec) - start, size, workers):
        chunk = list(itertools.islice(it, take))
        if not chunk:
            return
        yield start, chunk
        start += len(chunk)


def _dask_chunk(start: int, values: list[dict[str, float]], data: Mapping[str, Any], source: str,
                keep: bool, engines) -> list[dict[str, Any]]:
    """One Dask task: the rows of the consecutive variants ``start``, ``start + 1``..."""
    return [run_variant(start + i, v, data, source, keep, engines) for i, v in enumerate(values)]


# -- batches ----------------------------------------------------------------------------

def batch_sizes(engines, batch_size: int | None = None) -> dict[str, int]:
    """The engines of a sweep that run in batches, and each one's batch size: the judged engines
    that declare a batch size over 1 (:attr:`loopcheck.registry.Engine.batch_size`), at that size
    or at ``batch_size`` (``--batch-size``; 1 puts them back on the process pool). The reference
    runs on the pool."""
    sizes = {}
    for name in sweep_engines(engine_names(engines))[1:]:
        declared = ENGINES[name].batch_size
        size = declared if batch_size is None else batch_size
        if declared > 1 and size > 1:
            sizes[name] = size
    return sizes


def structure(value: Any) -> Any:
    """``value`` (a scene, its parts, an engine's settings) with its real numbers stripped: what
    stays is its structure (types, names, counts, choices, integers), hashable. Two variants of a
    sweep whose scenes have one structure, whose engine settings are equal and whose horizons are
    equal have one model structure and step count (load edges that move the grid step aside,
    which a port's own check refuses: the batch then runs variant by variant)."""
    import dataclasses
    from enum import Enum

    import numpy as np

    if isinstance(value, bool) or value is None or isinstance(value, (int, str, Enum)):
        return value
    if isinstance(value, float):
        return None
    if isinstance(value, np.ndarray):
        return ("array", value.shape, str(value.dtype))
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__name__,) + tuple((f.name, structure(getattr(value, f.name)))
                                               for f in dataclasses.fields(value))
    if isinstance(value, Mapping):
        return tuple(sorted((str(k), structure(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple, frozenset, set)):
        return tuple(structure(v) for v in value)
    return type(value).__name__


class _Member(NamedTuple):
    index: int
    values: dict[str, float]
    runs: dict[str, tuple[Any, Any]]  # engine -> (judged scene, settings), or (None, exception)
    key: Any


def _member(index: int, values: dict[str, float], data: Mapping[str, Any], source: str,
            sizes: Mapping[str, int]) -> _Member:
    """A variant's scene and settings for each batched engine, keyed by its structure (an invalid
    variant: no runs, its row says why; a setting refused: that engine's outcome)."""
    from loopcheck.scenefile import scene_from_dict
    from loopcheck.sweep_spec import apply

    from .settings import engine_settings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = scene_from_dict(apply(data, values), source)
    except Exception:  # noqa: BLE001 - invalid: run_variant's row says why
        return _Member(index, values, {}, None)
    runs = {}
    for name in sizes:
        try:
            runs[name] = (judged_scene(scene, name), engine_settings(name, scene))
        except Exception as exc:  # noqa: BLE001 - this engine's outcome on this variant
            runs[name] = (None, exc)
    key = (structure(scene), scene.horizon,
           tuple((name, settings) for name, (_, settings) in runs.items() if not isinstance(settings, BaseException)))
    return _Member(index, values, runs, key)


_LIMITS: dict = {}  # (engine, structure key) -> its batch limit on this machine's device


def run_batches(members: list[_Member], sizes: Mapping[str, int]) -> list[dict[str, Any]]:
    """The outcomes of each batched engine on ``members`` (one structure), by member: each
    engine's ``simulate_batch`` per chunk of its batch size (split first to what the device holds:
    :meth:`loopcheck.registry.Engine.batch_limit`), the last chunk padded to the same size by
    repeating its last variant (the padding's results dropped), each variant's failure its own."""
    outcomes: list[dict[str, Any]] = [{} for _ in members]
    for name, size in sizes.items():
        ready = []
        for k, m in enumerate(members):
            if name not in m.runs:
                continue
            scene, settings = m.runs[name]
            if scene is None:
                outcomes[k][name] = settings
            else:
                ready.append((k, scene, settings))
        if not ready:
            continue
        engine = ENGINES[name]
        limit_key = (name, repr(members[0].key))
        if limit_key not in _LIMITS:
            try:
                _LIMITS[limit_key] = engine.batch_limit(ready[0][1], ready[0][2])
            except Exception:  # noqa: BLE001 - the variant's own run says what is wrong
                _LIMITS[limit_key] = None
        limit = _LIMITS[limit_key]
        chunk = min(size, limit) if limit else size
        for at in range(0, len(ready), chunk):
            part = ready[at:at + chunk]
            scenes = [scene for _, scene, _ in part]
            padded = scenes + [scenes[-1]] * (chunk - len(scenes))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                got = engine.simulate_batch(padded, part[0][2], each=True)
            for (k, _, _), outcome in zip(part, got):
                outcomes[k][name] = outcome
    return outcomes


def _batched_tasks(data: Mapping[str, Any], spec: SweepSpec, source: str, sizes: Mapping[str, int],
                   start: int = 0) -> Iterator[tuple[int, list[dict[str, float]], list[dict[str, Any]]]]:
    """The sweep's variants from ``start`` as tasks ``(start, values, outcomes)``: consecutive
    variants of one structure, as many as the largest batch, with the batched engines' outcomes
    (run here, in this process: JAX and warp find their device once)."""
    largest = max(sizes.values())
    group: list[_Member] = []

    def done():
        outcomes = run_batches([m for m in group if m.key is not None], sizes)
        it = iter(outcomes)
        batched = [next(it) if m.key is not None else None for m in group]
        return group[0].index, [m.values for m in group], batched

    for index, values in itertools.islice(enumerate(variant_values(spec)), start, None):
        m = _member(index, values, data, source, sizes)
        keys = [g.key for g in group if g.key is not None]
        if group and (len(group) >= largest or (m.key is not None and keys and m.key != keys[0])):
            yield done()
            group = []
        group.append(m)
    if group:
        yield done()


def run_rows(data: Mapping[str, Any], spec: SweepSpec, source: str, *, workers: int = 1,
             keep_trajectories: bool = False, client=None, start: int = 0,
             batch_size: int | None = None) -> Iterator[dict[str, Any]]:
    """Every variant's row from variant ``start`` on, in variant order, as they complete
    (``workers`` processes, or with ``client`` the Dask cluster's worker threads: the same
    chunks become Dask tasks). Engines that run in batches (:func:`batch_sizes`) run here, chunk
    by chunk, and the rest of each variant's row on the pool (started by ``spawn``: no fork of a
    process that holds JAX's or warp's threads)."""
    n = count(spec) - start
    if n <= 0:
        return
    sizes = batch_sizes(spec.engines, batch_size)
    if sizes:
        if client is not None:
            raise ValueError("engines run in batches (" + ", ".join(sizes) + ") run in this process, not on a Dask "
                             "cluster: give --batch-size 1 with --scheduler")
        tasks: Iterator = _batched_tasks(data, spec, source, sizes, start)
    else:
        if client is not None:
            workers = dask_threads(client)
        tasks = _chunks(spec, chunk_size(n, workers), start, workers)
    if client is not None:
        yield from dask_rows(client, _dask_chunk, data, (source, keep_trajectories, spec.engines), tasks,
                             CHUNKS_IN_FLIGHT * workers)
        return
    if workers <= 1:
        for task in tasks:
            _WORKER.update(data=data, source=source, keep=keep_trajectories, engines=spec.engines)
            yield from _run_chunk(task)
        return
    for rows in ordered_map(_run_chunk, tasks, workers, _init_worker,
                            (dict(data), source, keep_trajectories, spec.engines), lost=_lost_chunk,
                            start_method="spawn" if _holds_threads(spec.engines) else None):
        yield from rows


def _holds_threads(engines) -> bool:
    """Whether this process may hold a batch engine's runtime (JAX's, warp's threads: the engines
    declaring a batch size are loaded before any work), which a forked worker must not inherit."""
    return any(ENGINES[name].batch_size > 1 for name in sweep_engines(engine_names(engines)))


def _lost_chunk(task: tuple, reason: str) -> list[dict[str, Any]]:
    """The rows of a chunk whose worker died twice (:func:`loopcheck.compare.pool.ordered_map`):
    each variant ``failed`` with the reason ("worker killed by signal 9"), nothing measured."""
    start, values, *_ = task
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
              client=None, resume: bool = False, restart: bool = False, batch_size: int | None = None,
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
    two run here and the second one's time estimates the rest (:func:`_estimate`; not in a sweep
    with engines run in batches: ``batch_size`` overrides their own, :func:`batch_sizes`)."""
    from .cost import worker_count

    n = count(spec)
    used = dask_threads(client) if client is not None else worker_count(workers, n)
    if client is None and workers is not None and used < workers and used < n:
        warnings.warn(f"--workers {workers}: using {used} (at most one process per core: {os.cpu_count() or 1} cores)")
    from loopcheck.scenefile import scene_from_dict

    scene = scene_from_dict(data, source)
    speed_unit = f"{scene.input_unit}/s"
    inputs = scene.inputs if scene.dof > 1 else ()  # several: the later inputs' columns (sweep_table.input_columns)
    units = tuple(zip(scene.inputs, scene.input_units())) if scene.dof > 1 else ()
    sizes = batch_sizes(spec.engines, batch_size)
    summary = Summary(spec.keys, workers=used, engines=sweep_engines(spec.engines), speed_unit=speed_unit,
                      batch_sizes=sizes, inputs=units)
    bar = _Progress(n) if progress else None

    journal = Journal(out, data, spec, resume=resume, restart=restart, inputs=inputs)  # locked until closed

    def fresh_rows() -> Iterator[dict[str, Any]]:  # started once the journal's rows are replayed
        first = journal.kept
        timed = []
        for index, values in itertools.islice(enumerate(variant_values(spec)), first, first + (0 if sizes else 2)):
            began = time.perf_counter()
            yield run_variant(index, values, data, source, keep_trajectories, spec.engines)
            timed.append(time.perf_counter() - began)
        if len(timed) == 2:  # the second: imports and compiled code loaded by the first
            _estimate(n - first - 2, timed[1], used)
        # on a local pool this process waits on its workers: matplotlib is imported meanwhile (by a
        # thread, started once the workers are: loopcheck.compare.plots.prefetch_matplotlib)
        pooled = used > 1 and client is None and not sizes and bool(plot_files(spec))
        for k, row in enumerate(run_rows(data, spec, source, workers=used, keep_trajectories=keep_trajectories,
                                         client=client, start=first + len(timed), batch_size=batch_size)):
            if k == 0 and pooled:
                from .plots import prefetch_matplotlib

                prefetch_matplotlib()
            yield row

    def write_rows(path: Path) -> None:
        start = time.perf_counter()
        rows = itertools.chain(journal.replay(), fresh_rows())
        stream_rows(rows, spec, path, path.parent / TRAJECTORY_FILE if keep_trajectories else None, summary,
                    bar.step if bar else None, journal.write, inputs)
        summary.wall_s = time.perf_counter() - start

    def staged(path: Path) -> None:  # written with sweep.csv
        if not path.is_file():
            raise RuntimeError(f"{path.name} was not written with {CSV_FILE}")

    files: dict[str, Callable[[Path], None]] = {CSV_FILE: write_rows}
    if keep_trajectories:
        files[TRAJECTORY_FILE] = staged
    for name in plot_files(spec):  # from the staged sweep.csv, but the worst variant's (run again)
        files[name] = (lambda p: plot_worst(data, source, summary, p, sizes)) if name == WORST_PLOT else \
            (lambda p, name=name: PLOTS[name](p.parent / CSV_FILE, spec, source, p, speed_unit, inputs=units))
    files[JSON_FILE] = lambda p: write_json(p, p.parent / CSV_FILE, spec, source, summary, sensitivity, units)

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
