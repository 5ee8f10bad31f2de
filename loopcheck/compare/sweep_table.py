"""A sweep's table: the columns of ``sweep.csv``, its cells as text and back, the rows streamed
into it (with ``trajectories.csv``), and ``sweep.json`` made from it (the module docstring of
:mod:`loopcheck.compare.sweep` says what each file holds)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator

from .output import json_text, plain, portable_source
from .sweep_engines import engines_value, judged, sweep_engines
from .sweep_summary import INPUT_SEPARATOR, input_column  # noqa: F401 - a column's name: its home is the summary's
from loopcheck.registry import REFERENCE
from loopcheck.sweep_spec import SweepSpec

if TYPE_CHECKING:
    from .sweep_summary import Summary

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

INPUT_DIFF_FIGURES = DIFF_FIGURES[:12]
"""The figures of :data:`DIFF_FIGURES` that each input of a scene of several degrees of freedom has
its own of (peak_omega_abs … t_peak_other); the span, horizon and assembly modes are the linkage's."""
INPUT_GATE_FIGURES = ("peak_ratio", "worst_ratio")
INPUT_ENGINE_FIGURES = ("peak_omega", "t_peak")


def input_columns(spec: SweepSpec, inputs: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The columns of the inputs after the first (``inputs``: the scene's, in order; none for one
    input): for each, every judged engine's :data:`INPUT_DIFF_FIGURES` and
    :data:`INPUT_GATE_FIGURES`, then every engine's :data:`INPUT_ENGINE_FIGURES`."""
    names = sweep_engines(spec.engines)
    others = names[1:]
    out: list[str] = []
    for name in inputs[1:]:
        out += [input_column(name, diff_column(others, x, k)) for x in others for k in INPUT_DIFF_FIGURES]
        out += [input_column(name, diff_column(others, x, k, "gate")) for x in others for k in INPUT_GATE_FIGURES]
        out += [input_column(name, f"{e}.{k}") for e in names for k in INPUT_ENGINE_FIGURES]
    return tuple(out)


def input_of(column: str, inputs: tuple[str, ...]) -> tuple[int, str]:
    """Which input a column is of (its index in ``inputs``; 0 for an unprefixed one) and the
    column's figure without the input's prefix."""
    for k, name in enumerate(inputs[1:], 1):
        prefix = name + INPUT_SEPARATOR
        if column.startswith(prefix):
            return k, column[len(prefix):]
    return 0, column

CSV_FILE, JSON_FILE, TRAJECTORY_FILE = "sweep.csv", "sweep.json", "trajectories.csv"


SCHEMA_VERSION = 1
"""sweep.json's ``schema_version`` (written for a list of engines other than the two words;
the files of ``both`` and ``reduced`` are as before, without it)."""


def diff_column(spec_or_judged, engine: str, figure: str, table: str = "diff") -> str:
    """The column of ``engine``'s ``figure`` of its comparison (``table`` "diff" or "gate"):
    ``diff.FIGURE`` when the sweep judges one engine (the pair's layout), ``diff.ENGINE.FIGURE``
    when it judges several."""
    names = judged(spec_or_judged) if isinstance(spec_or_judged, SweepSpec) else tuple(spec_or_judged)
    return f"{table}.{engine}.{figure}" if len(names) > 1 else f"{table}.{figure}"


def columns(spec: SweepSpec, inputs: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The columns of sweep.csv for ``spec``: the fixed ones, the varied keys, then the figures,
    then with several ``inputs`` (the scene's) the later inputs' own (:func:`input_columns`).
    The reference alone: its own figures (:data:`REDUCED_ONLY_COLUMNS`). One judged engine (the
    default pair among them, :data:`FIGURE_COLUMNS`): ``diff.*``, ``gate.*``, both engines'
    figures, the judged engine's loop gap. Several: each judged engine's ``diff.ENGINE.*`` and
    ``gate.ENGINE.*``, then every engine's figures, then each judged engine's loop gap."""
    names = sweep_engines(spec.engines)
    others = names[1:]
    mine = lambda name: tuple(f"{name}.{k}" for k in ENGINE_FIGURES)  # noqa: E731
    if not others:
        figures = mine(REFERENCE) + ("variant_wall_s",)
    else:
        figures = (tuple(diff_column(others, x, k) for x in others for k in DIFF_FIGURES)
                   + tuple(diff_column(others, x, k, "gate") for x in others for k in GATE_FIGURES)
                   + sum((mine(n) for n in names), ())
                   + tuple(f"{x}.max_constraint_violation" for x in others) + ("variant_wall_s",))
    return FIXED_COLUMNS + spec.keys + figures + input_columns(spec, inputs)


def is_list_column(column: str) -> bool:
    """A column whose cells are JSON lists (:data:`LIST_COLUMNS`, or an engine's of them)."""
    return column.startswith("diff.") and column.rsplit(".", 1)[-1] in ("mode_mismatches",
                                                                        "mode_mismatch_first_times")


def _finite(x: Any) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


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


def parse_cell(column: str, text: str) -> Any:
    """The value of a cell of ``column`` written as ``text`` (None: not measured)."""
    return cell_parser(column)(text)


def _text(text: str) -> Any:
    return text


def _measured(read: Callable[[str], Any]) -> Callable[[str], Any]:
    def parse(text: str) -> Any:
        return None if text == "" else read(text)
    return parse


def _number(text: str) -> Any:
    return text == "true" if text in ("true", "false") else float(text)


def _count(text: str) -> Any:
    return text == "true" if text in ("true", "false") else int(float(text))


_TEXT, _LIST, _NUMBER, _COUNT = _text, _measured(json.loads), _measured(_number), _measured(_count)


def cell_parser(column: str) -> Callable[[str], Any]:
    """:func:`parse_cell` of ``column``, chosen once for all its cells (:func:`read_rows`)."""
    if column in ("status", "reason"):
        return _TEXT
    if column == "index":
        return int
    if is_list_column(column):
        return _LIST
    return _COUNT if column.endswith(("n_steps", "mode_mismatches_total")) else _NUMBER


def read_rows(path: str | Path) -> Iterator[dict[str, Any]]:
    """The rows of a sweep.csv, one at a time, with their types (None: not measured): each
    column's :func:`parse_cell`, chosen once (a row of another length, as ``csv.DictReader``
    reads it: a cell past the header under the key None, a missing one as None; so a header
    that names a column twice)."""
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            return
        parsers = [cell_parser(k) for k in header]
        unique = len(set(header)) == len(header)  # else as DictReader: the last cell of a name, alone parsed
        for cells in reader:
            if not cells:  # a blank line (DictReader skips it)
                continue
            if len(cells) == len(header) and unique:
                yield {k: parse(v) for k, parse, v in zip(header, parsers, cells)}
                continue
            raw: dict[Any, Any] = dict(zip(header, cells))
            if len(cells) < len(header):
                raw.update((k, None) for k in header[len(cells):])
            elif len(cells) > len(header):
                raw[None] = cells[len(header):]
            yield {k: parse_cell(k, v) for k, v in raw.items()}


def stream_rows(rows: Iterable[dict[str, Any]], spec: SweepSpec, csv_path: Path, trajectory_path: Path | None,
            summary: Summary, progress: Callable | None, journal: Callable[[list], None] | None = None,
            inputs: tuple[str, ...] = ()) -> None:
    """Write ``rows`` into sweep.csv (and trajectories), count them in ``summary``; each row but
    those read back from the journal (marked ``_journaled``) also goes to ``journal``. ``inputs``:
    the scene's (:func:`columns`); with several, trajectories.csv has an ``input`` column."""
    cols = columns(spec, inputs)
    several = len(inputs) > 1
    traj = open(trajectory_path, "w", newline="", encoding="utf-8") if trajectory_path else None
    try:
        tw = csv.writer(traj) if traj else None
        if tw:
            tw.writerow(("index", "engine") + (("input",) if several else ()) + ("t_s", "q", "qdot", "qddot"))
        with open(csv_path, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f)
            writer.writerow(cols)
            for row in rows:
                trajectories = row.pop("_trajectories", None)
                journaled = row.pop("_journaled", False)
                cells = [_cell(row.get(k)) for k in cols]
                writer.writerow(cells)
                if journal and not journaled:
                    journal(cells)
                if tw and trajectories:
                    for engine, samples in trajectories.items():
                        if several:  # by input: (name, samples) each
                            for name, part in samples:
                                tw.writerows((row["index"], engine, name, *map(repr, s)) for s in part)
                        else:
                            tw.writerows((row["index"], engine, *map(repr, s)) for s in samples)
                summary.add(row)
                if progress:
                    progress(row)
    finally:
        if traj:
            traj.close()


def write_json(path: Path, csv_path: Path, spec: SweepSpec, source: str, summary: Summary,
                sensitivity: list[dict] | None = None, inputs: tuple[tuple[str, str], ...] = ()) -> None:
    """sweep.json: the specification, summary and sensitivities, then the rows read back one by one.
    ``inputs``: with several, each input's name and unit (rad or m), as ``inputs``."""
    engines = engines_value(spec.engines)
    head = {**({"schema_version": SCHEMA_VERSION} if isinstance(engines, list) else {}),
            "source": portable_source(source), "engines": engines, "keys": list(spec.keys),
            **({"inputs": [{"name": n, "unit": u} for n, u in inputs]} if len(inputs) > 1 else {}),
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
