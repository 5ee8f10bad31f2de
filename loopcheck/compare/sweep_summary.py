"""What a sweep keeps of its rows and prints: the counts by status, the worst variant, the
extremes of the reduced engine's peak |ω|, the ranges of the failing variants' values."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from .sweep_engines import engines_value
from loopcheck.registry import ENGINES, REFERENCE
from loopcheck.sweep_spec import Engines

STATUSES = ("passed", "gate_failed", "failed", "invalid")
"""A variant's status: every check that ran passed (both engines and the gate; reduced-only:
the reduced engine's own checks) / both engines ran and the gate failed; an engine failed
numerically; the variant could not be assembled (its scene is invalid)."""


INPUT_SEPARATOR = ":"


def input_column(name: str, column: str) -> str:
    """The column of a later input ``name``'s own ``column`` (``O5:diff.peak_omega_abs``,
    ``O5:reduced.peak_omega``): a scene of several degrees of freedom (module docstring of
    :mod:`loopcheck.compare.sweep`, "Several inputs"; sweep.csv's columns:
    :func:`loopcheck.compare.sweep_table.input_columns`)."""
    return f"{name}{INPUT_SEPARATOR}{column}"


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
    engines: tuple[str, ...] = Engines.BOTH.runs  # the reference first (sweep_table.sweep_engines)
    speed_unit: str = "rad/s"
    # several judged engines: per engine, its gate's counts and its worst peak ratio
    per_engine: dict[str, dict[str, Any]] = field(default_factory=dict)
    batch_sizes: dict[str, int] = field(default_factory=dict)  # engines run in batches: their batch size
    # several degrees of freedom: each input's name and unit (rad or m), in the scene's order; the
    # worst variant is the worst over every input (its "input" named), and each input has its
    # peak extremes (input_peak_extremes; peak_extremes stays the first input's)
    inputs: tuple[tuple[str, str], ...] = ()
    input_peak_extremes: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict)

    def __post_init__(self):
        self.inputs = tuple((str(n), str(u)) for n, u in self.inputs) if len(self.inputs) > 1 else ()
        self.engines = tuple(Engines(self.engines).runs if isinstance(self.engines, str) else self.engines)
        if len(self.engines) > 2:
            self.per_engine = {x: {"passed": 0, "gate_failed": 0, "failed": 0, "worst_peak_ratio": None}
                               for x in self.engines[1:]}

    @property
    def judged(self) -> tuple[str, ...]:
        return self.engines[1:]

    def _add_engine(self, row: Mapping[str, Any], status: str, values: dict) -> None:
        """Several judged engines: each one's gate and failure, and the worst variant over all."""
        for x, counts in self.per_engine.items():
            passed = row.get(f"gate.{x}.passed")
            if passed is None and status == "failed":
                counts["failed"] += 1
            elif passed is not None:
                counts["passed" if passed else "gate_failed"] += 1
            for at, name in self._columns():
                ratio = row.get(at(f"gate.{x}.peak_ratio"))
                if ratio is None or math.isnan(ratio):
                    continue
                if counts["worst_peak_ratio"] is None or ratio > counts["worst_peak_ratio"]:
                    counts["worst_peak_ratio"] = ratio
                if self.worst is None or ratio > self.worst["peak_ratio"]:
                    self.worst = {"index": row["index"], "values": values, "peak_ratio": ratio, "status": status,
                                  "peak_omega_rel": row.get(at(f"diff.{x}.peak_omega_rel")), "engine": x,
                                  **({"input": name} if name else {})}

    def _columns(self):
        """Each input's column of a figure (a function) and its name ("" for the one input)."""
        if not self.inputs:
            return [((lambda c: c), "")]
        first = self.inputs[0][0]
        return [((lambda c: c), first)] + [((lambda c, n=n: input_column(n, c)), n) for n, _ in self.inputs[1:]]

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
        for at, name in self._columns():
            ratio = row.get(at("gate.peak_ratio"))
            if ratio is not None and not math.isnan(ratio) and (self.worst is None or ratio > self.worst["peak_ratio"]):
                self.worst = {"index": row["index"], "values": values, "peak_ratio": ratio, "status": status,
                              "peak_omega_rel": row.get(at("diff.peak_omega_rel")), **({"input": name} if name else {})}
        if self.per_engine:
            self._add_engine(row, status, values)
        for at, name in self._columns():
            extremes = self.input_peak_extremes.setdefault(name, {}) if name else self.peak_extremes
            peak = row.get(at(f"{REFERENCE}.peak_omega"))
            if peak is not None and math.isfinite(peak):
                entry = {"index": row["index"], "values": values, "peak_omega": abs(peak)}
                low, high = extremes.get("lowest"), extremes.get("highest")
                if low is None or abs(peak) < low["peak_omega"]:
                    extremes["lowest"] = entry
                if high is None or abs(peak) > high["peak_omega"]:
                    extremes["highest"] = entry
        if self.inputs:
            self.peak_extremes = self.input_peak_extremes.get(self.inputs[0][0], {})

    @property
    def none_valid(self) -> bool:
        """No variant could be assembled: the sweep checked nothing."""
        return self.total > 0 and self.counts["invalid"] == self.total

    @property
    def failed_any(self) -> bool:
        """A variant failed the gate or numerically, or none was valid (exit status 1)."""
        return bool(self.counts["gate_failed"] or self.counts["failed"]) or self.none_valid

    def as_dict(self) -> dict[str, Any]:
        out = {"variants": self.total, "engines": engines_value(self.engines), "counts": dict(self.counts),
               "worst": self.worst, "peak_extremes": self.peak_extremes, "ranges": self.ranges,
               "failing_ranges": self.failing_ranges, "wall_s": self.wall_s, "workers": self.workers}
        if self.per_engine:
            out["per_engine"] = {x: dict(c) for x, c in self.per_engine.items()}
        if self.batch_sizes:
            out["batch_sizes"] = dict(self.batch_sizes)
        if self.inputs:
            out["input_peak_extremes"] = {n: self.input_peak_extremes.get(n, {}) for n, _ in self.inputs}
        return out


def values_text(values: Mapping[str, float]) -> str:
    """A variant's varied values as text: ``key = value, ...``."""
    return ", ".join(f"{k} = {v:.6g}" for k, v in values.items())


def _extend(ranges: dict[str, list[float]], key: str, value: float) -> None:
    lo_hi = ranges.setdefault(key, [value, value])
    lo_hi[0], lo_hi[1] = min(lo_hi[0], value), max(lo_hi[1], value)


def summary_lines(summary: Summary) -> list[str]:
    """The printed summary of a sweep."""
    c = summary.counts
    workers = f"{summary.workers} worker{'s' if summary.workers != 1 else ''}, {summary.wall_s:.1f} s"
    if summary.batch_sizes:
        workers += ", " + ", ".join(f"{ENGINES[x].label} in batches of {b}" for x, b in summary.batch_sizes.items())
    if not summary.judged:
        lines = [f"{summary.total} variants, {REFERENCE} engine only, no gate ({workers}): {c['passed']} passed its "
                 f"own checks, {c['failed']} failed numerically, {c['invalid']} invalid"]
        each = ([(f" of {n}", summary.input_peak_extremes.get(n, {}), f"{u}/s") for n, u in summary.inputs]
                or [("", summary.peak_extremes, summary.speed_unit)])
        for of, extremes, unit in each:
            low, high = extremes.get("lowest"), extremes.get("highest")
            if low is not None:
                lines.append(f"peak |omega|{of} from {low['peak_omega']:.6g} {unit} (#{low['index']}: "
                             f"{values_text(low['values'])}) to {high['peak_omega']:.6g} {unit} "
                             f"(#{high['index']}: {values_text(high['values'])})")
    else:
        lines = [f"{summary.total} variants ({workers}): {c['passed']} passed, {c['gate_failed']} failed the gate, "
                 f"{c['failed']} failed numerically, {c['invalid']} invalid"]
        for x, e in summary.per_engine.items():
            worst = "" if e["worst_peak_ratio"] is None else f" (worst peak-omega difference {e['worst_peak_ratio']:.3g}x its tolerance)"
            lines.append(f"  {ENGINES[x].label}: {e['passed']} passed its gate, {e['gate_failed']} failed it, "
                         f"{e['failed']} failed numerically{worst}")
    if summary.none_valid:
        lines.append("no variant is valid: the sweep checked nothing (sweep.csv's reason column says why)")
    w = summary.worst
    if w is not None:
        by = f" of {ENGINES[w['engine']].label}" if "engine" in w else ""
        of = f" of {w['input']}" if "input" in w else ""
        lines.append(f"worst variant{by}: #{w['index']} ({values_text(w['values'])}): peak-omega difference{of} "
                     f"{w['peak_ratio']:.3g}x its tolerance (peak_omega_rel {w['peak_omega_rel']:.3e}), {w['status']}")
    if summary.failing_ranges:
        parts = []
        for k, (lo, hi) in summary.failing_ranges.items():
            all_lo, all_hi = summary.ranges[k]
            parts.append(f"{k} in [{lo:.6g}, {hi:.6g}] (swept [{all_lo:.6g}, {all_hi:.6g}])")
        lines.append("failing variants have: " + "; ".join(parts))
    return lines
