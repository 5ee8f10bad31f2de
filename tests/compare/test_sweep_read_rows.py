"""read_rows chooses each column's parser once (sweep_table.cell_parser) and reads every row as
csv.DictReader with parse_cell cell by cell reads it: the same values of the same types, the same
keys in the same order, and the same error where a cell is not one of its column's."""

from __future__ import annotations

import csv
import json

import pytest

from loopcheck.compare.sweep_table import parse_cell, read_rows

HEADER = ["index", "status", "reason", "damper.c", "reduced.peak_omega", "reduced.n_steps",
          "diff.mode_mismatches_total", "diff.mode_mismatches", "reduced.passed"]
ROWS = [
    ["0", "passed", "", "40.0", "12.5", "336", "0", "[]", "true"],
    ["1", "failed", "singular: x", "41.0", "", "", "", "", "false"],
    ["2", "passed", "true", "1e-300", "-0.0", "3.0", "2", "[1, 2]", ""],
    ["3", "gate_failed", "a, b", "inf", "nan", "true", "false", "true", "1"],
]


def _cell(column, text):  # parse_cell as it was written before cell_parser
    if column in ("status", "reason"):
        return text
    if column == "index":
        return int(text)
    if text == "":
        return None
    if column.startswith("diff.") and column.rsplit(".", 1)[-1] in ("mode_mismatches", "mode_mismatch_first_times"):
        return json.loads(text)
    if text in ("true", "false"):
        return text == "true"
    value = float(text)
    return int(value) if column.endswith(("n_steps", "mode_mismatches_total")) else value


def _reference(path):  # what read_rows did before it chose its parsers once
    with open(path, newline="", encoding="utf-8") as f:
        for raw in csv.DictReader(f):
            yield {k: _cell(k, v) for k, v in raw.items()}


def test_parse_cell_is_as_it_was():
    for row in ROWS:
        for column, text in zip(HEADER, row):
            assert repr(parse_cell(column, text)) == repr(_cell(column, text)), (column, text)


def _typed(rows):  # values and their types: True == 1 == 1.0 must not pass for one another
    return [[(k, type(v).__name__, repr(v)) for k, v in row.items()] for row in rows]


def _write(path, header, rows, blank=False):
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow(r)
            if blank:
                f.write("\r\n")


def test_rows_are_read_as_cell_by_cell(tmp_path):
    path = tmp_path / "sweep.csv"
    _write(path, HEADER, ROWS, blank=True)
    got = list(read_rows(path))
    assert len(got) == len(ROWS)
    assert _typed(got) == _typed(_reference(path))


def test_a_header_that_names_a_column_twice_reads_as_before(tmp_path):
    path = tmp_path / "sweep.csv"
    _write(path, ["index", "x.n_steps", "x.n_steps"], [["0", "oops", "3"]])
    assert _typed(read_rows(path)) == _typed(_reference(path)) == [[("index", "int", "0"), ("x.n_steps", "int", "3")]]


@pytest.mark.parametrize("row", [["0", "passed"], ["0", "passed", "", "1", "2", "3", "4", "[]", "true", "extra"],
                                 ["zero", "passed", "", "1", "2", "3", "4", "[]", "true"],
                                 ["0", "passed", "", "1", "2", "3", "4", "[oops", "true"]])
def test_a_row_that_is_not_one_fails_as_before(tmp_path, row):
    path = tmp_path / "sweep.csv"
    _write(path, HEADER, [row])
    with pytest.raises(Exception) as before:
        list(_reference(path))
    with pytest.raises(type(before.value)):
        list(read_rows(path))
