"""The figures that README.md and docs/*.md quote from the shipped results files match those files.

A figure taken from a results file carries a marker right after it (after its unit, if any):

    7.6e-6 in 88 ms <!-- from benchmarks/results/cost.json#measurements[label=MuJoCo rk4 (hard) h=1.0e-03].wall_median_s *1e3 -->

naming the file (relative to the repository root) and the key:

- ``.json``: a dotted path; ``[N]`` indexes a list, ``[key=value]`` picks the list's one element
  whose ``key`` is ``value``;
- ``.csv``: ``[column=value].column``, the one row whose ``column`` is ``value``, then the column;
- ``.md``, ``.txt``: ``/regex/``, whose first group is the figure (it must match once).

A trailing `` *F`` multiplies the file's value by F (e.g. ``*1e3`` for s quoted in ms).

The figure is the last number in the text between the previous marker (or the line's start) and
this marker, written as ``12``, ``1 394`` (thin or plain space between thousands), ``3.18`` or
``3.2e-2``. Rounding rule: the file's value must lie within half a unit of the figure's last
written digit (a tie, such as 5.85e-6 written 5.9e-6 or 5.8e-6, passes either way: the file's
own figure may be rounded already). So ``3.2e-2`` matches 0.0318, ``22.6`` matches 22.57,
``10`` matches 9.97; ``2.6e-2`` does not match 0.0318, nor ``22`` 22.57.

Constants and settings (tolerances, steps, defaults) need no marker. A figure that no file holds
says when and where it was measured: "(measured 2026-11-28 at 925d050)".
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

MARKER = re.compile(r"<!--\s*from\s+(?P<file>\S+?)#(?P<key>.+?)(?:\s+\*(?P<scale>[0-9.eE+-]+))?\s*-->")
NUMBER = re.compile(r"(?<![\w.])[-+−]?\d{1,3}(?:[ \u2009\u202f]\d{3})+(?:\.\d+)?(?![\d])"
                    r"|(?<![\w.])[-+−]?\d+(?:\.\d+)?(?:[eE][-+−]?\d+)?(?![\d])")


def written_value(text: str) -> tuple[float, float]:
    """The number ``text`` and the unit of its last written digit (3.18e-2: 1e-4; 22.6: 0.1; 1 394: 1)."""
    plain = text.replace("−", "-").replace("\u2009", "").replace("\u202f", "").replace(" ", "")
    mantissa, _, exponent = plain.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return float(plain), 10.0 ** (int(exponent or 0) - decimals)


def matches(written: str, value: float) -> bool:
    """The rounding rule (module docstring): within half a unit of the figure's last digit."""
    figure, unit = written_value(written)
    return abs(figure - value) <= 0.5 * unit * (1.0 + 1e-9)


def _json_path(data, key: str):
    for part in re.findall(r"\[[^\]]*\]|[^.\[\]]+", key):
        if part.startswith("["):
            inner = part[1:-1]
            if "=" in inner:
                field, want = inner.split("=", 1)
                found = [item for item in data if str(item.get(field)) == want]
                if len(found) != 1:
                    raise KeyError(f"{len(found)} elements with {field}={want}")
                data = found[0]
            else:
                data = data[int(inner)]
        else:
            data = data[part]
    return data


def file_value(file: str, key: str) -> float:
    """The value the marker names (KeyError/ValueError saying why when there is none)."""
    path = ROOT / file
    if not path.is_file():
        raise KeyError(f"no file {file}")
    if path.suffix == ".json":
        return float(_json_path(json.loads(path.read_text(encoding="utf-8")), key))
    if path.suffix == ".csv":
        m = re.fullmatch(r"\[(?P<col>[^=\]]+)=(?P<want>[^\]]*)\]\.(?P<field>.+)", key)
        if not m:
            raise KeyError(f"a CSV key is [column=value].column, got {key!r}")
        with open(path, newline="", encoding="utf-8") as f:
            rows = [r for r in csv.DictReader(f) if r[m["col"]] == m["want"]]
        if len(rows) != 1:
            raise KeyError(f"{len(rows)} rows with {m['col']}={m['want']}")
        return float(rows[0][m["field"]])
    m = re.fullmatch(r"/(?P<re>.+)/", key)
    if not m:
        raise KeyError(f"a text file's key is /regex/, got {key!r}")
    found = re.findall(m["re"], path.read_text(encoding="utf-8"), flags=re.MULTILINE)
    if len(found) != 1:
        raise KeyError(f"/{m['re']}/ matches {len(found)} times in {file}")
    return written_value(found[0] if isinstance(found[0], str) else found[0][0])[0]


def figures(text: str):
    """(line number, written figure or None, file, key, scale) for every marker in ``text``."""
    for n, line in enumerate(text.splitlines(), 1):
        start = 0
        for m in MARKER.finditer(line):
            numbers = NUMBER.findall(line[start:m.start()])
            yield n, (numbers[-1] if numbers else None), m["file"], m["key"].strip(), float(m["scale"] or 1.0)
            start = m.end()


def problems(text: str, name: str) -> list[str]:
    """One line for each marker whose figure does not match its file, or names nothing."""
    out = []
    for n, written, file, key, scale in figures(text):
        where = f"{name}:{n}"
        if written is None:
            out.append(f"{where}: no figure before the marker for {file}#{key}")
            continue
        try:
            value = file_value(file, key) * scale
        except (KeyError, IndexError, ValueError, TypeError) as exc:
            out.append(f"{where}: {file}#{key}: {exc}")
            continue
        if not matches(written, value):
            out.append(f"{where}: the text says {written}, {file}#{key} holds {value:.6g}")
    return out


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_marked_figure_matches_its_results_file(doc):
    found = problems(doc.read_text(encoding="utf-8"), doc.relative_to(ROOT).as_posix())
    assert not found, "\n".join(found)


def test_the_docs_mark_figures_from_the_results_files():
    """The check has something to check: the cost section's headline among them."""
    marked = [f for doc in DOCS for f in figures(doc.read_text(encoding="utf-8"))]
    assert len(marked) >= 10
    assert any(f[2] == "benchmarks/results/cost.json" and "mujoco_over_reduced_wall" in f[3] for f in marked)


COST = "benchmarks/results/cost.json"


def test_a_planted_wrong_figure_is_caught():
    """The issue's stale figure: the soft constraint's error written 2.6e-2 against 3.18e-2 in the
    file. The right figure passes, the stale one fails, at the rounding rule's precision."""
    key = "measurements[label=MuJoCo rk4 (mujoco-default) h=1.0e-03].peak_omega_rel"
    value = file_value(COST, key)
    right = f"{value:.2e}"
    assert problems(f"the error ({right}) <!-- from {COST}#{key} -->", "planted") == []
    assert problems(f"the error ({value:.1e}) <!-- from {COST}#{key} -->", "planted") == []
    (wrong,) = problems(f"the error (2.6e-2) <!-- from {COST}#{key} -->", "planted")
    assert "says 2.6e-2" in wrong
    assert problems(f"{float(right) * 1.02:.2e} <!-- from {COST}#{key} -->", "planted")  # last digit off
    assert problems(f"1.0 <!-- from {COST}#no.such.key -->", "planted")  # a key that names nothing


@pytest.mark.parametrize("written, value, ok", [
    ("3.2e-2", 0.0318, True), ("3.18e-2", 0.0318, True), ("2.6e-2", 0.0318, False),
    ("22.6", 22.57, True), ("22.57", 22.572, True), ("23", 22.57, True), ("22", 22.57, False),
    ("1 394", 1394, True), ("1 395", 1394, False), ("88", 87.58, True), ("0.0039", 0.00388, True),
    ("5.9e-6", 5.85e-6, True), ("5.8e-6", 5.85e-6, True), ("5.7e-6", 5.85e-6, False), ("10", 9.967, True),
])
def test_the_rounding_rule(written, value, ok):
    assert matches(written, value) is ok


def test_markers_in_csv_and_text_files():
    label = "MuJoCo rk4 (hard) h=1.0e-03"
    csv_value = file_value("benchmarks/results/cost.csv", f"[label={label}].wall_median_s")
    assert csv_value == file_value(COST, f"measurements[label={label}].wall_median_s")
    text = f"{csv_value * 1e3:.1f} ms <!-- from benchmarks/results/cost.csv#[label={label}].wall_median_s *1e3 -->"
    assert problems(text, "planted") == []
