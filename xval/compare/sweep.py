"""``xval sweep``: a family of scenes through both engines, one summary row per variant.

A sweep (:mod:`xval.compare.sweep_spec`) makes variants of one scene file. Each variant is built
with :func:`xval.scenefile.scene_from_dict` and run through :func:`xval.compare.run.compare_engines`
with the scene's own settings and tolerances (the same code path and settings as ``xval run``
without engine flags). A variant that cannot be assembled is a row with status ``invalid``, one
whose engines fail numerically a row with status ``failed``; both are counted and the sweep goes
on.

Reduced-only sweeps (``spec.engines`` is :attr:`~xval.compare.sweep_spec.Engines.REDUCED`, ``xval
sweep --engines reduced`` or ``engines = "reduced"`` in the ``[sweep]`` table): each variant runs
only :func:`xval.reduced.engine.simulate` with the scene's reduced settings as the comparison resolves
them (:func:`xval.compare.settings.reduced_settings`); MuJoCo is neither run nor imported. ``passed``
then means the reduced engine's own checks (error estimate, energy balance) passed; there is no
gate, so no ``gate_failed``. Their sweep.csv has only the columns of what ran:
:data:`FIXED_COLUMNS`, the varied keys, then :data:`REDUCED_ONLY_COLUMNS` (the ``reduced.*``
figures and ``variant_wall_s``); the ``diff.*``, ``gate.*`` and ``mujoco.*`` columns are left
out rather than left empty, since nothing was compared (empty cells would read like variants that
failed, and their nulls would make each row of sweep.json 3.4 times longer: 1270 characters for
374 on the seed). The mode is in sweep.json (``"engines"``) and readable from the header.

Variants run in a process pool (``workers`` processes, default all cores), in chunks of
consecutive variants per task; results come back in variant order (``Pool.imap``) and each row is
written to ``sweep.csv`` as soon as it arrives, so memory stays flat with the number of variants
(only a bounded summary is kept: counts, the worst variant, per key the range of the failing
variants' values).

With a Dask scheduler (``xval sweep --scheduler ADDRESS``, the optional ``distributed`` extra;
nothing here imports Dask otherwise) the same chunks are Dask tasks: the scene data is scattered
once to every worker, at most :data:`CHUNKS_IN_FLIGHT` chunks per worker thread are in flight, and
the futures are read back in submission order, so the rows are the same, in the same order, as a
local run's (only the wall times differ).

Files (written through :func:`xval.compare.output.write_folder`: all or nothing). The rows are
streamed into the staged ``sweep.csv`` inside write_folder's hidden staging folder: the sweep
itself is the writer of ``sweep.csv``, so a failed or interrupted sweep leaves the output folder as
it was (nothing appears until the whole set is committed). The plots and ``sweep.json`` are then
made from the staged ``sweep.csv`` read back row by row.

- ``sweep.csv``: one row per variant, in variant order (:data:`FIXED_COLUMNS`, then the varied
  keys by name, then :data:`FIGURE_COLUMNS`, reduced-only :data:`REDUCED_ONLY_COLUMNS`); empty cells are figures not measured; list figures
  (``diff.mode_mismatches``...) are JSON text.
- ``sweep.json``: the specification, the summary and the rows (strict JSON, null for NaN).
- plots: ``sweep_peak_omega.png`` (peak ω of each engine run against the first varied key, a
  grid), ``sweep_gate_map.png`` (the gate's worst ratio over the first two keys of a grid of two
  or more keys), ``sweep_peak_omega_hist.png`` (Monte Carlo: histogram of each engine's peak ω),
  ``sweep_worst_differences.png`` (``xval run``'s differences plot of the worst variant, run
  again: the one whose peak-ω difference is the largest multiple of its tolerance). A
  reduced-only sweep draws the first or the third, with the reduced engine only: no gate map
  and no worst differences, as nothing was compared (:func:`plot_files`).
- ``trajectories.csv`` with ``keep_trajectories``: index, engine, t, q, qdot, qddot of every
  variant that ran (for small sweeps).
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import json
import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping

from .output import json_text, plain, portable_source, write_folder
from .pool import ignore_interrupts, ordered_map
from xval.sweep_spec import Engines, SweepSpec, count, variant_values

STATUSES = ("passed", "gate_failed", "failed", "invalid")
"""A variant's status: every check that ran passed (both engines and the gate; reduced-only:
the reduced engine's own checks) / both engines ran and the gate failed; an engine failed
numerically; the variant could not be assembled (its scene is invalid)."""

FIXED_COLUMNS = ("index", "status", "reason")
DIFF_FIGURES = ("peak_omega_abs", "peak_omega_rel", "t_peak_abs", "q_max_abs", "q_rms", "omega_max_abs",
                "omega_rms", "omega_vs_q_max_abs", "peak_omega_reference", "peak_omega_other",
                "t_peak_reference", "t_peak_other", "span_start", "span_end", "horizon",
                "mode_mismatches", "mode_mismatch_first_times", "mode_mismatches_total")
GATE_FIGURES = ("passed", "peak_omega_rtol", "q_atol", "omega_atol", "omega_vs_q_atol", "peak_ratio",
                "worst_ratio")
ENGINE_FIGURES = ("peak_omega", "t_peak", "wall_s", "n_steps", "energy_residual", "energy_residual_rel")
FIGURE_COLUMNS = (tuple(f"diff.{k}" for k in DIFF_FIGURES) + tuple(f"gate.{k}" for k in GATE_FIGURES)
                  + tuple(f"reduced.{k}" for k in ENGINE_FIGURES) + tuple(f"mujoco.{k}" for k in ENGINE_FIGURES)
                  + ("mujoco.max_constraint_violation", "variant_wall_s"))
REDUCED_ONLY_COLUMNS = tuple(f"reduced.{k}" for k in ENGINE_FIGURES) + ("variant_wall_s",)
"""The figure columns of a reduced-only sweep (module docstring)."""
LIST_COLUMNS = ("diff.mode_mismatches", "diff.mode_mismatch_first_times")

CSV_FILE, JSON_FILE, TRAJECTORY_FILE = "sweep.csv", "sweep.json", "trajectories.csv"
PEAK_PLOT, MAP_PLOT, HIST_PLOT = "sweep_peak_omega.png", "sweep_gate_map.png", "sweep_peak_omega_hist.png"
WORST_PLOT = "sweep_worst_differences.png"
MAX_CHUNK = 32


def columns(spec: SweepSpec) -> tuple[str, ...]:
    """The columns of sweep.csv for ``spec``."""
    return FIXED_COLUMNS + spec.keys + (REDUCED_ONLY_COLUMNS if spec.engines is Engines.REDUCED else FIGURE_COLUMNS)


def plot_files(spec: SweepSpec) -> tuple[str, ...]:
    """The plots a sweep of ``spec`` draws (a reduced-only sweep: no gate map, no worst differences)."""
    compared = spec.engines is Engines.BOTH
    if not spec.is_grid:
        plots = (HIST_PLOT,)
    else:
        plots = (PEAK_PLOT,) + ((MAP_PLOT,) if compared and len(spec.keys) >= 2 else ())
    return plots + ((WORST_PLOT,) if compared else ())


def sweep_files(spec: SweepSpec, keep_trajectories: bool = False) -> tuple[str, ...]:
    """Every file a sweep of ``spec`` writes, in the order they are committed."""
    return ((CSV_FILE,) + ((TRAJECTORY_FILE,) if keep_trajectories else ()) + plot_files(spec)
            + (JSON_FILE,))


# -- one variant ------------------------------------------------------------------------

def _finite(x: Any) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


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
    row.update(engine_row("reduced", c.reduced, c.diff.peak_reference))
    row.update(engine_row("mujoco", c.mujoco, c.diff.peak_other))
    row["mujoco.max_constraint_violation"] = c.mujoco.constraint_violation.max
    return row


def engine_row(engine: str, result, peak=None) -> dict[str, Any]:
    """One engine's figures (report.json's per-engine part, with the peak event ``peak``:
    default the run's own), keyed by sweep.csv column."""
    from .report import engine_summary

    summary = engine_summary(result, peak)
    return {f"{engine}.{k}": summary[k] for k in ENGINE_FIGURES}


def _run_engines(scene, engines: Engines) -> tuple[dict[str, Any], str, str, dict[str, Any]]:
    """The figures, status, reason and results by engine name of ``scene`` run as ``engines``
    says: both engines compared and gated (as ``xval run``), or the reduced engine alone with the
    settings the comparison would give it. NumericalFailure propagates."""
    if engines is Engines.REDUCED:  # MuJoCo is not imported: xval.compare.run would load it
        from xval.reduced.engine import simulate

        from .settings import reduced_settings

        result = simulate(scene, reduced_settings(scene))
        return engine_row("reduced", result), "passed", "", {"reduced": result}
    from .run import compare_engines

    c = compare_engines(scene)
    return (comparison_row(c), "passed" if c.gate.passed else "gate_failed", "; ".join(c.gate.failures),
            {"reduced": c.reduced, "mujoco": c.mujoco})


def run_variant(index: int, values: Mapping[str, float], data: Mapping[str, Any], source: str,
                keep_trajectories: bool = False, engines: Engines = Engines.BOTH) -> dict[str, Any]:
    """One variant's row: built from ``data`` with ``values`` applied, run through both engines
    and gated (as ``xval run``), or with ``engines`` REDUCED through the reduced engine alone;
    invalid and failed variants are rows too."""
    from xval.errors import NumericalFailure
    from xval.scene import SceneError
    from xval.scenefile import scene_from_dict

    from xval.sweep_spec import apply

    row: dict[str, Any] = {"index": index, "status": "", "reason": "", **values}
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():  # off-grid edges and ignored settings: the same for many variants
            warnings.simplefilter("ignore")
            scene = scene_from_dict(apply(data, values), source)
            figures, status, reason, results = _run_engines(scene, engines)
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


# -- a Dask cluster (the optional ``distributed`` extra) ------------------------------------

DASK_EXTRA = "pip install 'xval[distributed]'"
CONNECT_TIMEOUT_S = 10.0
CHUNKS_IN_FLIGHT = 4
"""Dask tasks (chunks) submitted at a time per worker thread: enough to keep each busy while the
earliest is read back, few enough that results waiting their turn stay a bounded handful."""


class SchedulerError(ValueError):
    """``--scheduler``: Dask is not installed, the scheduler cannot be reached, or the cluster lost a
    chunk (one line, exit status 2)."""


def require_dask() -> None:
    """Refuse ``--scheduler`` without the ``distributed`` extra (checked before any work)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise SchedulerError(f"--scheduler needs Dask, which is not installed: {DASK_EXTRA}") from None


HANDSHAKE_MAX_BYTES = 1 << 20  # a Dask handshake is ~100 bytes; more is some other service's data


def _probe_scheduler(address: str, host: str, port: int, deadline: float, timeout: float) -> None:
    """Refuse a TCP address that is not a Dask scheduler before Dask talks to it, by ``deadline``.

    A Dask server sends its handshake as soon as it accepts a connection: an 8-byte length,
    then that many bytes. Dask's own client waits for it without a time limit (a silent
    service hung ``xval sweep`` for 681 s) and allocates whatever length it reads (an HTTP
    server's reply made it a MemoryError). Here the wait is bounded and the length checked."""
    import socket
    import struct

    def fail(why: str):
        return SchedulerError(f"--scheduler {address}: {why}")

    def left() -> float:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise fail(f"no Dask scheduler there (no handshake within {timeout:g} s)")
        return remaining

    def read(sock, n: int) -> bytes:
        data = b""
        while len(data) < n:
            sock.settimeout(left())
            try:
                chunk = sock.recv(n - len(data))
            except socket.timeout:
                continue  # left() raises once the deadline has passed
            if not chunk:
                raise fail("not a Dask scheduler (the service closed the connection)")
            data += chunk
        return data

    try:
        sock = socket.create_connection((host, port), timeout=left())
    except OSError as exc:
        raise fail(f"cannot connect ({exc.strerror or ' '.join(str(exc).split())})") from None
    with sock:
        try:
            (size,) = struct.unpack("<Q", read(sock, 8))
            if not 0 < size <= HANDSHAKE_MAX_BYTES:
                raise fail("not a Dask scheduler (it did not answer with a Dask handshake)")
            read(sock, size)
        except OSError as exc:
            raise fail(f"cannot connect ({exc.strerror or ' '.join(str(exc).split())})") from None


def connect(address: str, timeout: float | None = None):
    """A :class:`distributed.Client` of the scheduler at ``address`` with at least one worker,
    or :class:`SchedulerError` within about ``timeout`` seconds (default :data:`CONNECT_TIMEOUT_S`)."""
    require_dask()
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    from distributed import Client
    from distributed.comm import get_address_host_port

    try:  # a malformed address first: a Client that fails on one hangs in its __del__
        host, port = get_address_host_port(address)
    except ValueError as exc:
        raise SchedulerError(f"--scheduler {address}: not a scheduler address like tcp://host:8786 "
                             f"({' '.join(str(exc).split())})") from None
    deadline = time.monotonic() + timeout
    if address.startswith("tcp://") or "://" not in address:
        _probe_scheduler(address, host, port, deadline, timeout)
    try:
        client = Client(address, timeout=max(deadline - time.monotonic(), 1.0), set_as_default=False)
    except Exception as exc:  # noqa: BLE001 - OSError, TimeoutError...
        raise SchedulerError(f"--scheduler {address}: cannot connect "
                             f"({type(exc).__name__}: {' '.join(str(exc).split())})") from None
    try:
        client.wait_for_workers(1, timeout=timeout)
    except Exception:  # noqa: BLE001
        client.close()
        raise SchedulerError(f"--scheduler {address}: the scheduler has no workers "
                             f"(none joined within {timeout:g} s)") from None
    return client


def dask_threads(client) -> int:
    """Worker threads of a Dask cluster (what the chunk size and the tasks in flight scale with)."""
    return max(1, sum(client.nthreads().values()))


def _dask_chunk(start: int, values: list[dict[str, float]], data: Mapping[str, Any], source: str,
                keep: bool, engines: Engines) -> list[dict[str, Any]]:
    """One Dask task: the rows of the consecutive variants ``start``, ``start + 1``..."""
    return [run_variant(start + i, v, data, source, keep, engines) for i, v in enumerate(values)]


def _dask_rows(client, data: Mapping[str, Any], source: str, keep: bool, engines: Engines,
               tasks: Iterator[tuple[int, list[dict[str, float]]]], in_flight: int) -> Iterator[dict[str, Any]]:
    """The rows of ``tasks`` run on ``client``'s cluster, in variant order: the futures are read
    in submission order, at most ``in_flight`` submitted at a time, the next submitted as the
    earliest comes back (so the CSV streams and memory stays flat)."""
    from collections import deque

    [shared] = client.scatter([dict(data)], broadcast=True)  # the scene data: sent once to every worker
    pending: deque = deque()

    def submit() -> bool:
        task = next(tasks, None)
        if task is None:
            return False
        start, values = task
        pending.append(client.submit(_dask_chunk, start, values, shared, source, keep, engines, pure=False))
        return True

    try:
        while len(pending) < in_flight and submit():
            pass
        while pending:
            future = pending.popleft()
            try:
                rows = future.result()
            except Exception as exc:  # noqa: BLE001 - the cluster's (a variant's own errors are rows)
                raise SchedulerError(f"a chunk of variants failed on the Dask cluster ({type(exc).__name__}: "
                                     f"{' '.join(str(exc).split())})") from exc
            submit()
            yield from rows
    finally:
        try:  # interrupted or failed: nothing left running for this sweep
            client.cancel(list(pending) + [shared])
        except Exception:  # noqa: BLE001 - the scheduler is gone: nothing to cancel
            pass


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
        yield from _dask_rows(client, data, source, keep_trajectories, spec.engines, tasks,
                              CHUNKS_IN_FLIGHT * workers)
        return
    if workers <= 1:
        for start, values in tasks:
            for i, v in enumerate(values):
                yield run_variant(start + i, v, data, source, keep_trajectories, spec.engines)
        return
    for rows in ordered_map(_run_chunk, tasks, workers, _init_worker,
                            (dict(data), source, keep_trajectories, spec.engines)):
        yield from rows


# -- the bounded summary ------------------------------------------------------------------

@dataclass
class Summary:
    """What a sweep prints and keeps in memory: counts, the worst variant (compared sweeps),
    the variants of the lowest and highest peak |ω| of the reduced engine, and per key the range
    of values of the variants that failed (the gate or numerically)."""

    keys: tuple[str, ...]
    total: int = 0
    counts: dict[str, int] = field(default_factory=lambda: {s: 0 for s in STATUSES})
    worst: dict[str, Any] | None = None  # index, values, peak_ratio, status
    peak_extremes: dict[str, dict[str, Any]] = field(default_factory=dict)  # lowest/highest: index, values, peak
    failing_ranges: dict[str, list[float]] = field(default_factory=dict)  # key -> [min, max]
    ranges: dict[str, list[float]] = field(default_factory=dict)
    wall_s: float = 0.0
    workers: int = 1
    engines: Engines = Engines.BOTH
    speed_unit: str = "rad/s"

    def add(self, row: Mapping[str, Any]) -> None:
        self.total += 1
        status = row["status"]
        self.counts[status] += 1
        values = {k: row[k] for k in self.keys}
        for k, v in values.items():
            _extend(self.ranges, k, v)
        if status in ("gate_failed", "failed"):
            for k, v in values.items():
                _extend(self.failing_ranges, k, v)
        ratio = row.get("gate.peak_ratio")
        if ratio is not None and not math.isnan(ratio) and (self.worst is None or ratio > self.worst["peak_ratio"]):
            self.worst = {"index": row["index"], "values": values, "peak_ratio": ratio, "status": status,
                          "peak_omega_rel": row.get("diff.peak_omega_rel")}
        peak = row.get("reduced.peak_omega")
        if peak is not None and math.isfinite(peak):
            entry = {"index": row["index"], "values": values, "peak_omega": abs(peak)}
            low, high = self.peak_extremes.get("lowest"), self.peak_extremes.get("highest")
            if low is None or abs(peak) < low["peak_omega"]:
                self.peak_extremes["lowest"] = entry
            if high is None or abs(peak) > high["peak_omega"]:
                self.peak_extremes["highest"] = entry

    @property
    def none_valid(self) -> bool:
        """No variant could be assembled: the sweep checked nothing."""
        return self.total > 0 and self.counts["invalid"] == self.total

    @property
    def failed_any(self) -> bool:
        """A variant failed the gate or numerically, or none was valid (exit status 1)."""
        return bool(self.counts["gate_failed"] or self.counts["failed"]) or self.none_valid

    def as_dict(self) -> dict[str, Any]:
        return {"variants": self.total, "engines": self.engines, "counts": dict(self.counts), "worst": self.worst,
                "peak_extremes": self.peak_extremes, "ranges": self.ranges, "failing_ranges": self.failing_ranges,
                "wall_s": self.wall_s, "workers": self.workers}


def _values_text(values: Mapping[str, float]) -> str:
    return ", ".join(f"{k} = {v:.6g}" for k, v in values.items())


def _extend(ranges: dict[str, list[float]], key: str, value: float) -> None:
    lo_hi = ranges.setdefault(key, [value, value])
    lo_hi[0], lo_hi[1] = min(lo_hi[0], value), max(lo_hi[1], value)


def summary_lines(summary: Summary) -> list[str]:
    """The printed summary of a sweep."""
    c = summary.counts
    workers = f"{summary.workers} worker{'s' if summary.workers != 1 else ''}, {summary.wall_s:.1f} s"
    if summary.engines is Engines.REDUCED:
        lines = [f"{summary.total} variants, reduced engine only, no gate ({workers}): {c['passed']} passed its "
                 f"own checks, {c['failed']} failed numerically, {c['invalid']} invalid"]
        low, high = summary.peak_extremes.get("lowest"), summary.peak_extremes.get("highest")
        if low is not None:
            lines.append(f"peak |omega| from {low['peak_omega']:.6g} {summary.speed_unit} (#{low['index']}: "
                         f"{_values_text(low['values'])}) to {high['peak_omega']:.6g} {summary.speed_unit} "
                         f"(#{high['index']}: {_values_text(high['values'])})")
    else:
        lines = [f"{summary.total} variants ({workers}): {c['passed']} passed, {c['gate_failed']} failed the gate, "
                 f"{c['failed']} failed numerically, {c['invalid']} invalid"]
    if summary.none_valid:
        lines.append("no variant is valid: the sweep checked nothing (sweep.csv's reason column says why)")
    w = summary.worst
    if w is not None:
        lines.append(f"worst variant: #{w['index']} ({_values_text(w['values'])}): peak-omega difference "
                     f"{w['peak_ratio']:.3g}x its tolerance (peak_omega_rel {w['peak_omega_rel']:.3e}), {w['status']}")
    if summary.failing_ranges:
        parts = []
        for k, (lo, hi) in summary.failing_ranges.items():
            all_lo, all_hi = summary.ranges[k]
            parts.append(f"{k} in [{lo:.6g}, {hi:.6g}] (swept [{all_lo:.6g}, {all_hi:.6g}])")
        lines.append("failing variants have: " + "; ".join(parts))
    return lines


# -- plots (drawn like xval/compare/plots.py: new_figure, no pyplot) ----------------------------

def _column(csv_path: Path, names: tuple[str, ...]) -> dict[str, list]:
    """Some columns of a sweep.csv (None where not measured)."""
    out: dict[str, list] = {n: [] for n in names}
    for row in read_rows(csv_path):
        for n in names:
            out[n].append(row[n])
    return out


def _nan(values: list) -> "np.ndarray":
    import numpy as np

    return np.array([math.nan if v is None else float(v) for v in values], dtype=float)


def _title(source: str, what: str) -> str:
    from .plots import short_name

    return f"{short_name(Path(source).stem if not source.startswith('<') else source)}: {what}"


def _peaks(csv_path: Path, spec: SweepSpec, names: tuple[str, ...] = ()) -> tuple[dict[str, list], dict]:
    """The columns ``names`` of a sweep.csv, and the peak |ω| of each engine the sweep ran (by
    engine name, in :attr:`Engines.runs` order, NaN where not measured)."""
    cols = _column(csv_path, names + tuple(f"{e}.peak_omega" for e in spec.engines.runs))
    return cols, {e: abs(_nan(cols[f"{e}.peak_omega"])) for e in spec.engines.runs}


def _engine_styles() -> dict[str, dict[str, Any]]:
    """How each engine is drawn in the sweep's plots: its colour, label, marker, line style."""
    from .plots import MUJOCO_STYLE, REDUCED_STYLE

    return {"reduced": {**REDUCED_STYLE, "marker": "o", "markersize": 3, "linestyle": "-"},
            "mujoco": {**MUJOCO_STYLE, "marker": "x", "markersize": 4, "linestyle": "--"}}


def _what(spec: SweepSpec, what: str) -> str:
    """A plot's title text; a reduced-only sweep says so on a second line (one line would not
    fit over the axes with a long key)."""
    return what + ("\n(reduced engine only: no MuJoCo, no gate)" if spec.engines is Engines.REDUCED else "")


def _title_margins(spec: SweepSpec) -> dict[str, float]:
    """new_figure's margins for :func:`_what`'s title (inches)."""
    from .plots import MARGINS

    return {"top": MARGINS["top"] + (0.25 if spec.engines is Engines.REDUCED else 0.0)}


def plot_peak_omega(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str) -> None:
    """Peak |ω| of each engine run against the first varied key (other keys: one line each value)."""
    import numpy as np

    from .plots import PLAIN, new_figure

    key = spec.keys[0]
    cols, peaks = _peaks(csv_path, spec, spec.keys + ("status",))
    x = _nan(cols[key])
    red = peaks["reduced"]
    styles = _engine_styles()
    fig, ax = new_figure((7.0, 4.2), margins=_title_margins(spec))
    others = spec.keys[1:]
    groups: dict[tuple, list[int]] = {}
    for i in range(len(x)):
        groups.setdefault(tuple(cols[k][i] for k in others), []).append(i)
    for n, (label, idx) in enumerate(groups.items()):
        idx = np.array(idx)
        suffix = (" (" + ", ".join(f"{k}={v:g}" for k, v in zip(others, label)) + ")") if others else ""
        for engine, peak in peaks.items():
            style = styles[engine]
            ax.plot(x[idx], peak[idx], marker=style["marker"], markersize=style["markersize"], color=style["color"],
                    linestyle=style["linestyle"], label=style["label"] if n == 0 else None,
                    alpha=1.0 if len(groups) == 1 else 0.6)
        ok = np.flatnonzero(np.isfinite(red[idx]))
        if others and ok.size and (len(groups) <= 10 or n in (0, len(groups) - 1)):
            # name each line by the other keys' values (of many lines, the first and the last)
            last = idx[ok[-1]]
            ax.annotate(suffix.strip(" ()"), (x[last], red[last]), textcoords="offset points", xytext=(-4, 4),
                        ha="right", fontsize=7, **PLAIN)
    bad = np.array([s in ("invalid", "failed") for s in cols["status"]])
    if bad.any():
        for xv in x[bad]:
            ax.axvline(xv, color="tab:red", alpha=0.3, linewidth=1)
        ax.plot([], [], color="tab:red", alpha=0.3, label="invalid / failed variant")
    ax.set_xlabel(key, **PLAIN)
    ax.set_ylabel(f"peak |ω| of the input ({speed_unit})")
    ax.set_title(_title(source, _what(spec, f"peak speed against {key}")), **PLAIN)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


def plot_gate_map(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str) -> None:
    """The gate's worst ratio (largest figure over its tolerance) over the first two grid keys
    (the others: the largest ratio over their values); gray where no comparison ran."""
    import numpy as np
    from matplotlib.colors import LogNorm

    from .plots import PLAIN, new_figure, plain_log_axis

    kx, ky = spec.keys[1], spec.keys[0]
    xs, ys = list(spec.varies[1].values), list(spec.varies[0].values)
    cols = _column(csv_path, (kx, ky, "gate.worst_ratio"))
    grid = np.full((len(ys), len(xs)), np.nan)
    for xv, yv, r in zip(cols[kx], cols[ky], cols["gate.worst_ratio"]):
        if r is None:
            continue
        i, j = ys.index(yv), xs.index(xv)
        grid[i, j] = r if math.isnan(grid[i, j]) else max(grid[i, j], r)
    fig, ax = new_figure((7.0, 5.0), margins={"right": 1.3})
    finite = grid[np.isfinite(grid) & (grid > 0)]
    norm = LogNorm(vmin=min(finite.min(), 0.1), vmax=max(finite.max(), 10.0)) if finite.size else None
    masked = np.ma.masked_invalid(np.where(grid > 0, grid, np.nan))
    mesh = ax.pcolormesh(np.arange(len(xs) + 1), np.arange(len(ys) + 1), masked, cmap="RdYlGn_r", norm=norm,
                         shading="flat")
    ax.set_facecolor("0.8")
    ax.set_xticks(np.arange(len(xs)) + 0.5, [f"{v:.4g}" for v in xs], fontsize=7, rotation=45 if len(xs) > 6 else 0)
    ax.set_yticks(np.arange(len(ys)) + 0.5, [f"{v:.4g}" for v in ys], fontsize=7)
    ax.set_xlabel(kx, **PLAIN)
    ax.set_ylabel(ky, **PLAIN)
    ax.set_title(_title(source, "gate's worst figure / tolerance (> 1 fails)"), **PLAIN)
    bar = fig.colorbar(mesh, ax=ax, label="worst ratio")
    if norm is not None:
        plain_log_axis(bar.ax.yaxis)  # the project's plain-text log labels (no mathtext)
    fig.savefig(path)


def plot_worst(data: Mapping[str, Any], source: str, summary: Summary, path: Path) -> None:
    """The differences plot of ``xval run`` (:func:`xval.compare.plots.plot_differences`) for the
    worst variant, the one whose peak-ω difference is the largest multiple of its tolerance, run
    again through both engines (the same scene and settings as its row); a note instead when no
    variant ran through both."""
    from .plots import PLAIN, _save, new_figure, plot_differences
    from .run import compare_engines
    from xval.sweep_spec import apply
    from xval.scenefile import scene_from_dict

    worst = summary.worst
    if worst is None:
        fig, ax = new_figure((8, 2))
        ax.axis("off")
        ax.text(0.5, 0.5, f"{_title(source, 'no variant ran through both engines: no differences to plot')}",
                ha="center", va="center", **PLAIN)
        _save(fig, path)
        return
    with warnings.catch_warnings():  # as run_variant: its warnings were the sweep's to ignore
        warnings.simplefilter("ignore")
        c = compare_engines(scene_from_dict(apply(data, worst["values"]), source))
    values = _values_text(worst["values"])
    plot_differences(c, path, subtitle=f"worst of {summary.total} variants: #{worst['index']}, peak-ω difference "
                                       f"{worst['peak_ratio']:.3g}× its tolerance\n{values}")


def plot_peak_histogram(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str) -> None:
    """Histogram of each engine run's peak |ω| over a Monte Carlo sample (the reduced engine's
    filled, MuJoCo's outlined)."""
    import numpy as np

    from .plots import PLAIN, new_figure

    _, peaks = _peaks(csv_path, spec)
    peaks = {e: p[np.isfinite(p)] for e, p in peaks.items()}
    styles = _engine_styles()
    fig, ax = new_figure((7.0, 4.2), margins=_title_margins(spec))
    every = np.concatenate(list(peaks.values()))
    if every.size:
        bins = np.histogram_bin_edges(every, bins=min(50, max(5, int(math.sqrt(every.size)))))
        for engine, peak in peaks.items():
            style = styles[engine]
            look = {"alpha": 0.6} if engine == "reduced" else {"histtype": "step", "linestyle": "--", "linewidth": 1.5}
            ax.hist(peak, bins=bins, color=style["color"], label=style["label"], **look)
        ax.legend(fontsize=8)
    ax.set_xlabel(f"peak |ω| of the input ({speed_unit})")
    ax.set_ylabel("variants")
    ax.set_title(_title(source, _what(spec, f"peak speed over {len(peaks['reduced'])} samples (seed {spec.seed})")),
                 **PLAIN)
    ax.grid(True, alpha=0.3)
    fig.savefig(path)


PLOTS = {PEAK_PLOT: plot_peak_omega, MAP_PLOT: plot_gate_map, HIST_PLOT: plot_peak_histogram}


# -- files ------------------------------------------------------------------------------

def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, (list, tuple)):
        return json.dumps([_finite(v) if isinstance(v, float) else v for v in value])
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return value


def _parse(column: str, text: str) -> Any:
    if column in ("status", "reason"):
        return text
    if column == "index":
        return int(text)
    if text == "":
        return None
    if column in LIST_COLUMNS:
        return json.loads(text)
    if text in ("true", "false"):
        return text == "true"
    value = float(text)
    return int(value) if column.endswith(("n_steps", "mode_mismatches_total")) else value


def read_rows(path: str | Path) -> Iterator[dict[str, Any]]:
    """The rows of a sweep.csv, one at a time, with their types (None: not measured)."""
    with open(path, newline="", encoding="utf-8") as f:
        for raw in csv.DictReader(f):
            yield {k: _parse(k, v) for k, v in raw.items()}


class _Progress:
    def __init__(self, total: int):
        from .cost import Progress

        self.bar = Progress(total, label="sweep")

    def step(self, row):
        self.bar.step(f"#{row['index']} {row['status']}")


def _stream(rows: Iterable[dict[str, Any]], spec: SweepSpec, csv_path: Path, trajectory_path: Path | None,
            summary: Summary, progress: Callable | None, journal: Callable[[list], None] | None = None,
            replayed: int = 0) -> None:
    """Write ``rows`` into sweep.csv (and trajectories), count them in ``summary``; each row
    after the first ``replayed`` (read back from the journal) also goes to ``journal``."""
    cols = columns(spec)
    traj = open(trajectory_path, "w", newline="", encoding="utf-8") if trajectory_path else None
    try:
        tw = csv.writer(traj) if traj else None
        if tw:
            tw.writerow(("index", "engine", "t_s", "q", "qdot", "qddot"))
        with open(csv_path, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f)
            writer.writerow(cols)
            for i, row in enumerate(rows):
                trajectories = row.pop("_trajectories", None)
                cells = [_cell(row.get(k)) for k in cols]
                writer.writerow(cells)
                if journal and i >= replayed:
                    journal(cells)
                if tw and trajectories:
                    for engine, samples in trajectories.items():
                        tw.writerows((row["index"], engine, *map(repr, s)) for s in samples)
                summary.add(row)
                if progress:
                    progress(row)
    finally:
        if traj:
            traj.close()


def _write_json(path: Path, csv_path: Path, spec: SweepSpec, source: str, summary: Summary,
                sensitivity: list[dict] | None = None) -> None:
    """sweep.json: the specification, summary and sensitivities, then the rows read back one by one."""
    head = {"source": portable_source(source), "engines": spec.engines, "keys": list(spec.keys),
            "kind": "grid" if spec.is_grid else "monte_carlo", "samples": spec.samples, "seed": spec.seed,
            "varies": [str(v) if not spec.is_grid else {"key": v.key, "values": list(v.values)}
                       for v in spec.varies],
            "summary": summary.as_dict()}
    if sensitivity is not None:
        head["sensitivity"] = sensitivity
    text = json_text(head)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text.rstrip().rstrip("}").rstrip() + ',\n  "rows": [')
        for i, row in enumerate(read_rows(csv_path)):
            f.write(("," if i else "") + "\n    " + json.dumps(plain(row), allow_nan=False))
        f.write("\n  ]\n}\n")


# -- the journal of finished rows, and the estimate of a long sweep ------------------------

JOURNAL_SUFFIX = ".sweep-journal.csv"
JOURNAL_MAGIC = "# xval sweep journal "
LONG_SWEEP_S = 600.0  # a sweep estimated to take longer says so (one warning line) before it runs on


class JournalError(ValueError):
    """--resume without a journal of this very sweep beside --out (exit status 2)."""


def journal_path(out: str | os.PathLike) -> Path:
    """The journal of a sweep into ``out``: beside it, never inside (``<out>.sweep-journal.csv``)."""
    folder = Path(os.path.abspath(out))
    return folder.parent / f"{folder.name}{JOURNAL_SUFFIX}"


def _identity(data: Mapping[str, Any], spec: SweepSpec) -> str:
    """A digest of what decides a sweep's rows: the scene data and the specification."""
    import hashlib

    text = json.dumps({"data": data, "spec": repr(spec)}, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def journaled_rows(out: str | os.PathLike, data: Mapping[str, Any], spec: SweepSpec) -> int:
    """How many rows the journal beside ``out`` holds for this sweep (checked before any work).

    Raises
    ------
    JournalError
        No journal, or the journal of another sweep (scene, keys, values or engines differ).
    """
    path = journal_path(out)
    try:
        with open(path, encoding="utf-8", newline="") as f:
            first = f.readline()
            if first != f"{JOURNAL_MAGIC}{_identity(data, spec)}\n":
                raise JournalError(f"--resume: {path} is the journal of another sweep (its scene file, keys, values "
                                   "or engines differ): run without --resume to start afresh")
            return sum(1 for _ in _complete_rows(f)) if f.readline() else 0
    except FileNotFoundError:
        raise JournalError(f"--resume: no journal {path} of an interrupted sweep into "
                           f"{os.fspath(out)!r}: nothing to resume") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise JournalError(f"--resume: cannot read {path}: {exc}") from None


def _complete_rows(f) -> Iterator[str]:
    """The complete lines (the last one, cut by a kill, is not) of the journal after its header."""
    for line in f:
        if line.endswith("\n"):
            yield line


class _Journal:
    """The rows of a sweep written as they finish, beside its output folder; removed once the
    sweep's files are committed. A journal that cannot be written is a warning, not an error."""

    def __init__(self, out, data: Mapping[str, Any], spec: SweepSpec, resume: bool):
        self.path, self.file = journal_path(out), None
        self.replayed = journaled_rows(out, data, spec) if resume else 0
        try:
            if resume:
                self._truncate_partial_line()
                self.file = open(self.path, "a", newline="", encoding="utf-8")
            else:
                if self.path.exists():
                    warnings.warn(f"{self.path}: the rows of an interrupted sweep are replaced by this one's "
                                  "(--resume continues a sweep)")
                self.file = open(self.path, "w", newline="", encoding="utf-8")
                self.file.write(f"{JOURNAL_MAGIC}{_identity(data, spec)}\n")
                csv.writer(self.file).writerow(columns(spec))
                self.file.flush()
        except OSError as exc:
            warnings.warn(f"no journal of finished rows ({self.path}: {exc.strerror or exc}): an interrupted "
                          "sweep cannot be resumed")
            self.file = None
        self.writer = csv.writer(self.file) if self.file else None
        self.written = 0

    def _truncate_partial_line(self) -> None:
        with open(self.path, "rb+") as f:
            data = f.read()
            keep = data.rfind(b"\n") + 1
            if keep < len(data):
                f.truncate(keep)

    def replay(self, spec: SweepSpec) -> Iterator[dict[str, Any]]:
        """The journaled rows, in order, with their types (as read back from sweep.csv)."""
        if not self.replayed:
            return
        with open(self.path, encoding="utf-8", newline="") as f:
            f.readline()
            for i, row in enumerate(csv.DictReader(_complete_rows(f), fieldnames=next(csv.reader([f.readline()])))):
                if i >= self.replayed:
                    return
                yield {k: _parse(k, v) for k, v in row.items()}

    def write(self, cells: list) -> None:
        if self.writer:
            self.writer.writerow(cells)
            self.file.flush()
            self.written += 1

    def close(self, done: bool) -> None:
        """Close the journal; remove it when the sweep's files are committed, or when it holds
        no row (a sweep stopped before its first one leaves nothing to resume)."""
        if self.file:
            self.file.close()
        if done or (self.file and not self.replayed and not self.written):
            with contextlib.suppress(OSError):
                os.unlink(self.path)


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
              client=None, resume: bool = False) -> tuple[Summary, list[Path]]:
    """Run every variant and write the sweep's files into ``out`` (module docstring). The
    caller has checked ``spec`` against the scene and ``out`` (:func:`xval.compare.output.check_folder`);
    ``sensitivity`` (:meth:`xval.compare.sensitivity.Sensitivity.as_dict` of each key) goes into sweep.json.
    With ``client`` (:func:`connect`) the variants run on that Dask cluster instead of a local pool.

    Each finished row also goes to the journal beside ``out`` (:func:`journal_path`), which the
    commit of the files removes: an interrupted sweep leaves ``out`` as it was and its rows
    there; with ``resume`` they are read back instead of run again (the caller checked the
    journal with :func:`journaled_rows`). Before the bulk of the variants, the next two run
    here and the second one's time estimates the rest (:func:`_estimate`)."""
    from .cost import worker_count

    n = count(spec)
    used = dask_threads(client) if client is not None else worker_count(workers, n)
    if client is None and workers is not None and used < workers and used < n:
        warnings.warn(f"--workers {workers}: using {used} (at most one process per core: {os.cpu_count() or 1} cores)")
    from xval.scenefile import scene_from_dict

    speed_unit = f"{scene_from_dict(data, source).input_unit}/s"
    summary = Summary(spec.keys, workers=used, engines=spec.engines, speed_unit=speed_unit)
    bar = _Progress(n) if progress else None

    journal = _Journal(out, data, spec, resume)

    def fresh_rows() -> Iterator[dict[str, Any]]:
        first = journal.replayed
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
        rows = itertools.chain(journal.replay(spec), fresh_rows())
        _stream(rows, spec, path, path.parent / TRAJECTORY_FILE if keep_trajectories else None, summary,
                bar.step if bar else None, journal.write, journal.replayed)
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
    files[JSON_FILE] = lambda p: _write_json(p, p.parent / CSV_FILE, spec, source, summary, sensitivity)
    done = False
    try:
        paths = write_folder(out, files, one_run=True)
        done = True
    finally:
        journal.close(done)
    return summary, paths
