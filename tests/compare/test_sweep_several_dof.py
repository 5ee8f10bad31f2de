"""``loopcheck sweep`` and its sensitivity on a scene of several degrees of freedom (the five-bar
robot, two inputs O1 and O5, cut to a 0.2 s horizon).

A row holds every input: the first input's figures in the one-DOF columns, each later input's in
``NAME:``-prefixed columns (sweep_table.input_columns). They are checked against runs made apart:
``loopcheck run`` of the same variant written as its own scene file (its report.json's ``inputs``)
and ``loopcheck.simulate``; the journal refuses a row whose input cells were tampered with; the
sensitivity of each input's peak is checked against a central difference of separate runs.

Plants that fail here (each tried, then removed): the later input's columns filled from the first
input's difference (sweep.comparison_row: ``c.diffs[0]`` for ``d``); the engines' per-input peaks
from the first input (sweep.engine_row: ``result.inputs[0]``); the journal's input check left out
(sweep_journal._checked without _inputs_problem); the sensitivity of every input taken from the
first input's peaks (sensitivity.sensitivities: ``at[k][0]``)."""

from __future__ import annotations

import json
import math
import re
import shutil

import pytest

import loopcheck
from loopcheck.compare import sweep as sweep_module
from loopcheck.compare.cli import main
from loopcheck.compare.sweep import run_sweep
from loopcheck.compare.sweep_journal import journal_path
from loopcheck.compare.sweep_scene import check, load_sweep
from loopcheck.compare.sweep_table import CSV_FILE, INPUT_DIFF_FIGURES, JSON_FILE, input_column, read_rows
from loopcheck.compare.sensitivity import sensitivities, sensitivity_lines
from loopcheck.sweep_spec import Engines, spec_from_args

from helpers import ROOT, plots_left_out

FIVE_BAR = ROOT / "scenes" / "mechanisms" / "five_bar_robot.toml"
MASSES = (1.5, 2.0, 2.5)
VARY = ("--vary", "bodies.left_crank.mass=1.5:2.5:3")


def _scene_text(mass: float | None = None) -> str:
    text = re.sub(r"(?m)^horizon = 0\.8$", "horizon = 0.2", FIVE_BAR.read_text())
    if mass is not None:  # the left crank's mass (its table's line "mass = 2.0", the first one)
        text = text.replace("mass = 2.0", f"mass = {mass!r}", 1)
    return text


@pytest.fixture
def five_bar(tmp_path):
    path = tmp_path / "five_bar.toml"
    path.write_text(_scene_text())
    assert "horizon = 0.2" in path.read_text()
    return path


def _rows(out):
    return list(read_rows(out / CSV_FILE))


def test_a_two_dof_sweep_s_rows_hold_every_input_as_loopcheck_run_of_each_variant(five_bar, tmp_path, capsys):
    with plots_left_out():
        status = main(["sweep", str(five_bar), "--out", str(tmp_path / "sw"), *VARY, "--workers", "1"])
    printed = capsys.readouterr().out
    assert status == 0, printed
    assert "studies one-DOF scenes only" not in printed  # the refusal is gone
    rows = _rows(tmp_path / "sw")
    assert [r["bodies.left_crank.mass"] for r in rows] == list(MASSES)
    header = (tmp_path / "sw" / CSV_FILE).read_text().splitlines()[0].split(",")
    assert [c for c in header if c.startswith("O5:")] == (
        [f"O5:diff.{k}" for k in INPUT_DIFF_FIGURES] + ["O5:gate.peak_ratio", "O5:gate.worst_ratio"]
        + [f"O5:{e}.{k}" for e in ("reduced", "mujoco") for k in ("peak_omega", "t_peak")])
    assert not any(c.startswith("O1:") for c in header)  # the first input's are the one-DOF columns
    for row, mass in zip(rows, MASSES):
        variant = tmp_path / f"variant_{mass}.toml"
        variant.write_text(_scene_text(mass))
        with plots_left_out():
            assert main(["run", str(variant), "--out", str(tmp_path / f"run_{mass}")]) == 0
        capsys.readouterr()
        report = json.loads((tmp_path / f"run_{mass}" / "report.json").read_text())
        assert [i["name"] for i in report["inputs"]] == ["O1", "O5"]
        assert row["gate.passed"] is report["gate"]["passed"] and row["status"] == "passed"
        for k, entry in enumerate(report["inputs"]):
            at = (lambda c: c) if k == 0 else (lambda c, n=entry["name"]: input_column(n, c))  # noqa: E731
            for figure in INPUT_DIFF_FIGURES:  # the same code path on the same scene: equal to the bit
                assert row[at(f"diff.{figure}")] == entry["diff"][figure], (mass, entry["name"], figure)
            for engine, role in (("reduced", "reference"), ("mujoco", "other")):
                assert row[at(f"{engine}.peak_omega")] == entry[role]["peak_omega"], (mass, entry["name"], engine)
                assert row[at(f"{engine}.t_peak")] == entry[role]["t_peak"], (mass, entry["name"], engine)
        # the two inputs' peaks are two events, not one copied: O1 turns one way, O5 the other
        assert row["reduced.peak_omega"] > 0 > row["O5:reduced.peak_omega"]
    worst = max((r[c], r["index"]) for r in rows for c in ("gate.peak_ratio", "O5:gate.peak_ratio"))
    data = json.loads((tmp_path / "sw" / JSON_FILE).read_text())
    assert data["inputs"] == [{"name": "O1", "unit": "rad"}, {"name": "O5", "unit": "rad"}]
    assert data["summary"]["worst"]["index"] == worst[1] and data["summary"]["worst"]["peak_ratio"] == worst[0]
    assert data["summary"]["worst"]["input"] in ("O1", "O5")
    assert f"peak-omega difference of {data['summary']['worst']['input']} " in printed
    for row in rows:  # the gate's worst ratio judges every input
        assert row["gate.worst_ratio"] == max(row["gate.worst_ratio"], row["O5:gate.worst_ratio"])
        assert row["gate.worst_ratio"] >= row["O5:gate.worst_ratio"]


def test_a_reduced_only_sweep_through_the_api_holds_each_input_s_peak_of_its_own_run(five_bar, tmp_path):
    data, _ = load_sweep(five_bar)
    spec = spec_from_args(["bodies.left_crank.mass=1.5:2.5:3"])
    spec = type(spec)(spec.varies, spec.samples, spec.seed, Engines.REDUCED.runs)
    check(data, spec, str(five_bar))  # a scene of two DOF is not refused
    with plots_left_out():
        summary, _ = run_sweep(data, spec, str(five_bar), tmp_path / "sw", workers=1, progress=False)
    rows = _rows(tmp_path / "sw")
    for row, mass in zip(rows, MASSES):
        variant = tmp_path / f"variant_{mass}.toml"
        variant.write_text(_scene_text(mass))
        result = loopcheck.simulate(loopcheck.load_scene(variant))  # the reduced engine, the scene's settings
        (_, p1), (_, p2) = result.inputs
        # the sweep's reduced runs of several inputs are full runs (the engine in k coordinates has no
        # summary mode): the same run, equal to the bit
        assert (row["reduced.peak_omega"], row["reduced.t_peak"]) == (p1.omega, p1.time), mass
        assert (row["O5:reduced.peak_omega"], row["O5:reduced.t_peak"]) == (p2.omega, p2.time), mass
    extremes = summary.as_dict()["input_peak_extremes"]
    o5 = [abs(r["O5:reduced.peak_omega"]) for r in rows]
    assert extremes["O5"]["highest"]["peak_omega"] == max(o5) and extremes["O5"]["lowest"]["peak_omega"] == min(o5)
    assert extremes["O1"]["highest"]["index"] != extremes["O5"]["highest"]["index"]  # they move opposite ways


def test_a_tampered_input_cell_in_the_journal_is_refused_and_its_variant_runs_again(five_bar, tmp_path, capsys,
                                                                                   monkeypatch):
    with plots_left_out():
        assert main(["sweep", str(five_bar), "--out", str(tmp_path / "ref"), *VARY, "--workers", "1"]) == 0
    reference = _rows(tmp_path / "ref")
    real = sweep_module.run_variant
    ran = []

    def interrupted(index, *args, **kwargs):
        if index == 2:
            raise KeyboardInterrupt
        ran.append(index)
        return real(index, *args, **kwargs)

    monkeypatch.setattr(sweep_module, "run_variant", interrupted)
    with plots_left_out():
        assert main(["sweep", str(five_bar), "--out", str(tmp_path / "sw"), *VARY, "--workers", "1"]) == 130
    journal = journal_path(tmp_path / "sw")
    lines = journal.read_bytes().splitlines(keepends=True)
    columns = lines[1].decode().rstrip("\n").split(",")
    assert len(lines) == 4  # the header, the columns, rows 0 and 1

    def tampered(line: bytes, swap: tuple[str, str]) -> bytes:  # two cells of row 1 swapped
        cells = line.decode().rstrip("\n").split(",")
        i, j = columns.index(swap[0]), columns.index(swap[1])
        cells[i], cells[j] = cells[j], cells[i]
        return (",".join(cells) + "\n").encode()

    monkeypatch.setattr(sweep_module, "run_variant", lambda index, *a, **k: (ran.append(index), real(index, *a, **k))[1])
    for swap in (("diff.peak_omega_abs", "O5:diff.peak_omega_abs"),  # the two inputs' differences
                 ("O5:reduced.peak_omega", "O5:mujoco.peak_omega")):  # the later input's two engines
        journal.write_bytes(b"".join(lines[:3]) + tampered(lines[3], swap))
        ran.clear()
        with plots_left_out():
            status = main(["sweep", str(five_bar), "--out", str(tmp_path / "sw"), *VARY, "--workers", "1", "--resume"])
        err = capsys.readouterr().err
        assert status == 0, err
        assert ran == [1, 2], (swap, err)
        assert f"{journal}: kept its first 1 row" in err and "(row 1: its " in err and " cell is not " in err, err
        drop = ("reduced.wall_s", "mujoco.wall_s", "variant_wall_s")
        assert [{k: v for k, v in r.items() if k not in drop} for r in _rows(tmp_path / "sw")] == \
            [{k: v for k, v in r.items() if k not in drop} for r in reference]
        shutil.rmtree(tmp_path / "sw")
    # the untampered journal: its two rows kept, only variant 2 runs
    journal.write_bytes(b"".join(lines))
    ran.clear()
    with plots_left_out():
        assert main(["sweep", str(five_bar), "--out", str(tmp_path / "sw"), *VARY, "--workers", "1", "--resume"]) == 0
    capsys.readouterr()
    assert ran == [2]


def test_each_input_s_peak_sensitivity_is_a_central_difference_of_runs_made_apart(five_bar, tmp_path):
    data, _ = load_sweep(five_bar)
    spec = spec_from_args(["bodies.left_crank.mass=1.5:2.5:3"])
    items = sensitivities(data, spec, str(five_bar))
    assert [s.input for s in items] == ["O1", "O5"]
    delta = 1e-3  # kg: the difference's truncation error, P''' delta²/6, is below 1e-6 of these slopes
    peaks = {}
    for sign in (-1, 1):
        variant = tmp_path / f"variant_{sign}.toml"
        variant.write_text(_scene_text(2.0 + sign * delta))
        peaks[sign] = [abs(p.omega) for _, p in loopcheck.simulate(loopcheck.load_scene(variant)).inputs]
    for k, s in enumerate(items):
        fd = (peaks[1][k] - peaks[-1][k]) / (2 * delta)
        # both estimate dP/dp; the runs' noise (rtol 1e-12 on peaks of 10 rad/s over 2e-3 kg) is
        # about 1e-8 rad/s/kg, the truncation of either difference below 1e-5 relative
        assert math.isclose(s.derivative, fd, rel_tol=1e-5), (s.input, s.derivative, fd)
        assert s.error < 1e-4 * abs(s.derivative)
    assert items[0].derivative < 0 < items[1].derivative  # two inputs, two slopes (-0.30 and 0.13 rad/s/kg)
    lines = sensitivity_lines(items, units={"O1": "rad/s", "O5": "rad/s"})
    assert lines[0] == "input O1 (rad/s):" and "input O5 (rad/s):" in lines
    assert items[1].as_dict()["input"] == "O5"


def test_a_key_of_one_input_is_labelled_in_that_input_s_unit():
    from loopcheck.compare.sweep_plots import key_label, key_unit

    mixed = ("rad", "m")  # the five-bar slider: a crank angle and a slide
    assert key_label("initial.qdot.1", "rad/s", mixed) == "initial.qdot.1 (m/s)"
    assert key_label("initial.q.0", "m/s", mixed) == "initial.q.0 (rad)"
    assert key_unit("tolerances.q_atol", "rad/s", mixed) == "m or rad"
    assert key_unit("initial.qdot.1", "rad/s") == "rad/s"  # one input: the scene's unit, as before
