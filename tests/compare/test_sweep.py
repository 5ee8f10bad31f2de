"""loopcheck sweep (loopcheck.compare.sweep): rows equal to loopcheck run's report on the same variant scene, rows in
variant order from a pool, Monte Carlo reproducible with its seed, bad specifications refused up
front naming the key, invalid and failed variants counted without stopping the sweep, exit status,
and the output folder left as it was by an interrupted sweep. Reduced-only sweeps (``--engines
reduced``): rows equal to loopcheck.reduced.engine.simulate with the settings the comparison would give it,
MuJoCo neither run nor imported, exit status 1 on a variant failing the reduced engine's own
checks, exactly the files sweep_files lists, the [sweep] table's engines and the flag over it, and
bad values refused. Short scenes (the seed with a 0.3 s horizon) and 2-4 variants."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
from dataclasses import replace

import pytest

from loopcheck.compare import sweep as sweep_module
from loopcheck.compare.cli import main
from loopcheck.compare.output import MANIFEST_FILE
from loopcheck.compare.sweep import sweep_files
from loopcheck.compare.sweep_journal import journal_path
from loopcheck.compare.sweep_table import CSV_FILE, JSON_FILE, REDUCED_ONLY_COLUMNS, TRAJECTORY_FILE, read_rows
from loopcheck.sweep_spec import Engines, spec_from_args, variant_values
from loopcheck.shipped_scenes import default_scene_path

from helpers import ROOT, interruptible, plots_left_out, short_seed_file  # noqa: F401 - fixture

SEED_TEXT = default_scene_path().read_text()
SHORT_TEXT = re.sub(r"(?m)^horizon = 2\.0.*$", "horizon = 0.3", SEED_TEXT)
FIXED_STEP = "\n[mujoco]\ntimestep = 1e-3\n"  # an explicit step: the gate is not met by shrinking it
WALL = ("reduced.wall_s", "mujoco.wall_s", "variant_wall_s")
RKN4 = '\n[reduced]\nmethod = "rkn4"\n'  # its error estimate fails at steps of 2e-2 s on the short seed


@pytest.fixture
def short_scene(tmp_path):
    return short_seed_file(tmp_path)


@pytest.fixture
def without_plots():
    """The sweep (and ``loopcheck run``) without their plots: for a test that reads only the rows."""
    with plots_left_out():
        yield


def _sweep(capsys, scene, out, *args):
    status = main(["sweep", str(scene), "--out", str(out), *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _rows(out):
    return list(read_rows(out / CSV_FILE))


def _without_wall(row):
    return {k: v for k, v in row.items() if k not in WALL}


def test_a_row_equals_loopcheck_run_on_the_same_variant_scene(short_scene, tmp_path, capsys):
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "dampers.0.coefficient=[50, 60.5]",
                                "--workers", "2")
    assert status == 0, printed
    rows = _rows(tmp_path / "sw")
    assert [r["index"] for r in rows] == [0, 1] and [r["status"] for r in rows] == ["passed", "passed"]
    row = rows[1]
    assert row["dampers.0.coefficient"] == 60.5
    variant = tmp_path / "variant.toml"
    variant.write_text(SHORT_TEXT.replace("coefficient = 55.0", "coefficient = 60.5"))
    with plots_left_out():  # its report.json is read
        assert main(["run", str(variant), "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    for key, value in report["diff"].items():
        assert row[f"diff.{key}"] == value, key
    assert row["gate.passed"] is report["gate"]["passed"]
    for key, value in report["gate"]["tolerances"].items():
        assert row[f"gate.{key}"] == value, key
    for engine in ("reduced", "mujoco"):
        for key in ("peak_omega", "t_peak", "n_steps", "energy_residual", "energy_residual_rel"):
            assert row[f"{engine}.{key}"] == report[engine][key], (engine, key)
    assert row["mujoco.max_constraint_violation"] == report["mujoco"]["max_constraint_violation"]
    assert math.isclose(row["gate.peak_ratio"], report["diff"]["peak_omega_abs"]
                        / (report["gate"]["tolerances"]["peak_omega_rtol"] * abs(report["diff"]["peak_omega_reference"])
                           + 1e-9))
    data = json.loads((tmp_path / "sw" / JSON_FILE).read_text())  # sweep.json: the same rows
    assert [_without_wall(r) for r in data["rows"]] == [_without_wall(r) for r in rows]
    assert data["summary"]["counts"] == {"passed": 2, "gate_failed": 0, "failed": 0, "invalid": 0}
    assert sorted(p.name for p in (tmp_path / "sw").iterdir()) == sorted(["sweep.csv", "sweep.json",
                                                                         "sweep_peak_omega.png",
                                                                         "sweep_worst_differences.png", MANIFEST_FILE])


def test_rows_come_in_variant_order_from_the_pool(short_scene, tmp_path, capsys):
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "bodies.coupler.mass=[41, 39]",
                                "--vary", "dampers.0.coefficient=50:60:2", "--workers", "2")
    assert status == 0, printed
    rows = _rows(tmp_path / "sw")
    assert [r["index"] for r in rows] == [0, 1, 2, 3]
    assert [(r["bodies.coupler.mass"], r["dampers.0.coefficient"]) for r in rows] == [
        (41, 50), (41, 60), (39, 50), (39, 60)]
    # the peak moves the physical way: heavier coupler, slower crank; more damping, slower crank
    peaks = [r["reduced.peak_omega"] for r in rows]
    assert peaks[2] > peaks[0] and peaks[0] > peaks[1] and peaks[2] > peaks[3]
    assert (tmp_path / "sw" / "sweep_gate_map.png").is_file()
    assert "4 variants (2 workers" in printed and "4 passed" in printed


def test_the_pool_s_chunks_hold_every_variant_once_in_order_and_shrink_at_the_end():
    """Chunks of at most chunk_size; with two workers the last ones smaller, down to one variant
    (the workers end together); one worker: chunks of the size. (Planted: no shrink: fails here.)"""
    spec = spec_from_args(["dampers.0.coefficient=40:70:25", "bodies.coupler.mass=35:45:40"])
    size = sweep_module.chunk_size(998, 2)
    for workers in (1, 2):
        chunks = list(sweep_module._chunks(spec, size, 2, workers))
        starts = [start for start, _ in chunks]
        assert starts == [2 + sum(len(v) for _, v in chunks[:k]) for k in range(len(chunks))]
        assert [v for _, values in chunks for v in values] == list(variant_values(spec))[2:]
        sizes = [len(v) for _, v in chunks]
        assert max(sizes) == size == sizes[0]
        if workers == 1:
            assert sizes[:-1] == [size] * (len(sizes) - 1)
        else:
            assert sizes == sorted(sizes, reverse=True) and sizes[-1] == 1 and len(chunks) < 2 * 998 / size


def test_monte_carlo_is_reproducible_with_its_seed(short_scene, tmp_path, capsys):
    runs = {}
    for name, seed in (("a", "7"), ("b", "7"), ("c", "8")):
        with contextlib.nullcontext() if name == "a" else plots_left_out():  # b's and c's rows are read
            status, printed, _ = _sweep(capsys, short_scene, tmp_path / name,
                                        "--vary", "bodies.coupler.mass=normal(40, 1)",
                                        "--vary", "dampers.0.coefficient=uniform(50, 60)", "--samples", "2",
                                        "--seed", seed, "--workers", "1")
        assert status == 0, printed
        runs[name] = [_without_wall(r) for r in _rows(tmp_path / name)]
    assert runs["a"] == runs["b"] and len(runs["a"]) == 2
    values = lambda rows: [(r["bodies.coupler.mass"], r["dampers.0.coefficient"]) for r in rows]
    assert values(runs["a"]) != values(runs["c"])
    assert all(a != c for a, c in zip(values(runs["a"]), values(runs["c"])))
    assert (tmp_path / "a" / "sweep_peak_omega_hist.png").is_file()


@pytest.mark.parametrize("args, key", [
    (["--vary", "bodies.coupler.mas=38:42:2"], "bodies.coupler.mas"),
    (["--vary", "linkage.type=1:2:2"], "linkage.type"),
    (["--vary", "dampers.0.coefficient=70:40:3"], "dampers.0.coefficient"),
    (["--vary", "dampers.0.coefficient=40:70:0"], "dampers.0.coefficient"),
    (["--vary", "bodies.coupler.mass=normal(40, -1)", "--samples", "2"], "bodies.coupler.mass"),
    (["--vary", "bodies.coupler.mass=-1:40:2"], "bodies.coupler.mass"),
    (["--vary", "linkage.c2=0.9:5:2"], "linkage.c2"),  # a coupler of 5 m cannot close the loop
    (["--vary", "dampers.0.coefficient=normal(50, 1)"], "dampers.0.coefficient"),  # no --samples
    (["--vary", "dampers.3.coefficient=1:2:2"], "dampers.3.coefficient"),
], ids=["unknown", "not-a-number", "lo>hi", "n<1", "negative-sigma", "invalid-value", "invalid-extreme",
        "no-samples", "no-such-entry"])
def test_bad_specs_exit_2_naming_the_key_and_write_nothing(args, key, short_scene, tmp_path, capsys, monkeypatch):
    ran = []
    monkeypatch.setattr(sweep_module, "run_variant", lambda *a, **k: ran.append(a))
    status, printed, err = _sweep(capsys, short_scene, tmp_path / "sw", *args)
    assert status == 2
    assert printed == "" and err.count("\n") == 1 and err.startswith("loopcheck: error:")
    assert f"'{key}'" in err, err
    assert not (tmp_path / "sw").exists() and not ran


def test_nothing_to_sweep_and_a_bad_folder_are_refused(short_scene, tmp_path, capsys):
    status, _, err = _sweep(capsys, short_scene, tmp_path / "sw")
    assert status == 2 and "nothing to sweep" in err
    status, _, err = _sweep(capsys, short_scene, tmp_path / "no" / "sw", "--vary", "torque.value=200:250:2")
    assert status == 2 and "does not exist" in err


def test_an_invalid_variant_is_a_counted_row_and_the_others_run(short_scene, tmp_path, capsys):
    # c1 = 0.62 makes the four-bar non-Grashof: with the crank at 3.1 rad it cannot close; each
    # key's extremes with the other nominal assemble, so check() lets the sweep through
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "linkage.c1=[0.62, 0.5]",
                                "--vary", "initial.q=[0.2, 3.1]", "--workers", "2")
    assert status == 0, printed  # invalid variants are counted, not failures of the gate
    rows = _rows(tmp_path / "sw")
    assert [r["status"] for r in rows] == ["passed", "invalid", "passed", "passed"]
    assert "cannot be assembled" in rows[1]["reason"]
    assert rows[1]["reduced.peak_omega"] is None and rows[3]["reduced.peak_omega"] > 0
    assert "3 passed, 0 failed the gate, 0 failed numerically, 1 invalid" in printed


def test_a_variant_failing_the_gate_exits_1_and_names_the_failing_values(tmp_path, capsys):
    scene = tmp_path / "fixed.toml"
    scene.write_text(SHORT_TEXT + FIXED_STEP)
    status, printed, _ = _sweep(capsys, scene, tmp_path / "sw", "--vary", "tolerances.peak_omega_rtol=[1e-4, 1e-12]",
                                "--workers", "1")
    assert status == 1
    rows = _rows(tmp_path / "sw")
    assert [r["status"] for r in rows] == ["passed", "gate_failed"]
    assert "peak_omega_abs" in rows[1]["reason"] and rows[1]["gate.peak_ratio"] > 1
    assert "1 passed, 1 failed the gate" in printed
    assert "worst variant: #1 (tolerances.peak_omega_rtol = 1e-12)" in printed
    assert "failing variants have: tolerances.peak_omega_rtol in [1e-12, 1e-12]" in printed


def test_the_worst_variant_is_plotted_from_a_run_equal_to_its_row(short_scene, tmp_path, capsys, monkeypatch):
    """sweep_worst_differences.png: loopcheck run's differences plot of the row with the largest
    peak-ω difference against its tolerance, from a run again of that variant (the plot's
    comparison has the row's peaks) and named in the plot's subtitle."""
    import loopcheck.compare.plots

    drawn = []
    real = loopcheck.compare.plots.plot_differences
    monkeypatch.setattr(loopcheck.compare.plots, "plot_differences",
                        lambda c, path, subtitle=None: (drawn.append((c, subtitle)), real(c, path, subtitle))[1])
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "bodies.coupler.mass=[35, 45, 40]",
                                "--workers", "2")
    assert status == 0, printed
    rows = _rows(tmp_path / "sw")
    worst = max(rows, key=lambda r: r["gate.peak_ratio"])
    assert len(drawn) == 1 and (tmp_path / "sw" / "sweep_worst_differences.png").is_file()
    c, subtitle = drawn[0]
    assert f"worst of 3 variants: #{worst['index']}," in subtitle
    assert f"bodies.coupler.mass = {worst['bodies.coupler.mass']:g}" in subtitle
    # The row's peaks are the compared event of each engine (report.json's)
    assert c.diff.peak_omega_reference == worst["reduced.peak_omega"]
    assert c.diff.peak_omega_other == worst["mujoco.peak_omega"]


def test_without_a_compared_variant_the_worst_plot_says_so(tmp_path):
    from loopcheck.compare.sweep_plots import plot_worst
    from loopcheck.compare.sweep_summary import Summary

    plot_worst({}, "<none>", Summary(keys=()), tmp_path / "worst.png")
    assert (tmp_path / "worst.png").stat().st_size > 0


def test_a_failed_variant_is_a_row_and_the_sweep_goes_on(short_scene, tmp_path, capsys, monkeypatch):
    from loopcheck.errors import NumericalFailure

    import loopcheck.compare.run

    original, calls = loopcheck.compare.run.judge, []

    def flaky(scene, *args, **kwargs):  # the second variant's comparison fails
        calls.append(scene)
        if len(calls) == 2:
            raise NumericalFailure("unstable", "planted")
        return original(scene, *args, **kwargs)

    monkeypatch.setattr(loopcheck.compare.run, "judge", flaky)
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "torque.value=[250, 240, 245]",
                                "--workers", "1")
    rows = _rows(tmp_path / "sw")
    assert [r["status"] for r in rows] == ["passed", "failed", "passed"], [r["reason"] for r in rows]
    assert status == 1 and "1 failed numerically" in printed


@pytest.mark.usefixtures("without_plots")  # rows and the trajectories file are read
def test_the_scene_files_sweep_table_and_vary_winning(short_scene, tmp_path, capsys):
    scene = tmp_path / "table.toml"
    scene.write_text(SHORT_TEXT + '\n[sweep]\n[sweep.vary]\n"torque.value" = [240, 250]\n')
    status, printed, _ = _sweep(capsys, scene, tmp_path / "a", "--workers", "1", "--keep-trajectories")
    assert status == 0, printed
    rows = _rows(tmp_path / "a")
    assert [r["torque.value"] for r in rows] == [240, 250]
    traj = (tmp_path / "a" / "trajectories.csv").read_text().splitlines()
    assert traj[0] == "index,engine,t_s,q,qdot,qddot"
    assert {tuple(line.split(",")[:2]) for line in traj[1:]} == {(i, e) for i in "01" for e in ("reduced", "mujoco")}
    status, printed, _ = _sweep(capsys, scene, tmp_path / "b", "--vary", "torque.value=[230]", "--workers", "1")
    assert status == 0
    assert [r["torque.value"] for r in _rows(tmp_path / "b")] == [230]


def test_an_interrupted_sweep_leaves_the_folder_as_it_was(short_scene, tmp_path, capsys, monkeypatch):
    out = tmp_path / "sw"
    out.mkdir()
    (out / CSV_FILE).write_text("old\n")
    real = sweep_module.run_variant

    def interrupted(index, *args, **kwargs):
        if index == 1:
            raise KeyboardInterrupt
        return real(index, *args, **kwargs)

    monkeypatch.setattr(sweep_module, "run_variant", interrupted)
    status, _, err = _sweep(capsys, short_scene, out, "--vary", "torque.value=[240, 250]", "--workers", "1")
    assert status == 130 and "interrupted" in err
    assert sorted(p.name for p in out.iterdir()) == [CSV_FILE] and (out / CSV_FILE).read_text() == "old\n"
    assert len(journal_path(out).read_text().splitlines()) == 2 + 1  # variant 0's row, beside
    monkeypatch.setattr(sweep_module, "run_variant", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    status, _, err = _sweep(capsys, short_scene, out, "--vary", "torque.value=[240, 250]", "--workers", "1",
                            "--restart")
    assert status == 130 and not journal_path(out).exists()  # no row: no journal left


def test_the_pool_yields_rows_in_variant_order_whatever_finishes_first(monkeypatch):
    """The first variant is the slowest (forked workers inherit the patched function): rows
    still come back 0, 1, 2, 3."""
    import multiprocessing
    import time

    from loopcheck.compare.sweep import run_rows
    from loopcheck.sweep_spec import spec_from_args

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("needs forked workers to see the patched variant runner")

    def slow_first(index, values, data, source, keep=False, engines=None, batched=None):
        time.sleep(0.5 if index == 0 else 0.01)
        return {"index": index, "status": "passed", "reason": "", **values, "pid": multiprocessing.current_process().pid}

    monkeypatch.setattr(sweep_module, "run_variant", slow_first)
    spec = spec_from_args(["torque.value=1:4:4"])
    rows = list(run_rows({}, spec, "<memory>", workers=2))
    assert [r["index"] for r in rows] == [0, 1, 2, 3]
    assert [r["torque.value"] for r in rows] == [1, 2, 3, 4]
    assert len({r["pid"] for r in rows}) == 2  # both workers took part


# -- reduced-only sweeps (--engines reduced) ------------------------------------------------

def _header(out):
    return (out / CSV_FILE).read_text().splitlines()[0].split(",")


def test_rows_equal_the_reduced_engine_on_the_same_variant_scene(short_scene, tmp_path, capsys, monkeypatch):
    """Each row's reduced figures are those of loopcheck.reduced.engine.simulate with the scene's reduced
    settings as loopcheck.compare.settings resolves them, as a summary run (the row's figures equal a full
    run's within the bounds of tests/reduced/test_summary_runs.py); MuJoCo and the comparison are not run
    (the comparison is planted to fail: a variant that ran it would be a failed row)."""
    import loopcheck.compare.run
    from loopcheck.compare.settings import reduced_settings
    from loopcheck.reduced.engine import simulate
    from loopcheck.scenefile import load_scene

    def no_comparison(*args, **kwargs):
        raise AssertionError("a reduced-only sweep ran the comparison")

    monkeypatch.setattr(loopcheck.compare.run, "compare_engines", no_comparison)
    short_scene.write_text(short_scene.read_text() + '\n[reduced]\nrtol = 1e-10\n')  # its own settings, used
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "dampers.0.coefficient=[50, 60.5]",
                                "--engines", "reduced", "--workers", "1")
    assert status == 0, printed
    rows = _rows(tmp_path / "sw")
    assert _header(tmp_path / "sw") == ["index", "status", "reason", "dampers.0.coefficient", *REDUCED_ONLY_COLUMNS]
    assert [(r["index"], r["status"], r["reason"]) for r in rows] == [(0, "passed", ""), (1, "passed", "")]
    for row in rows:
        variant = tmp_path / f"variant{row['index']}.toml"
        variant.write_text(short_scene.read_text().replace("coefficient = 55.0",
                                                           f"coefficient = {row['dampers.0.coefficient']!r}"))
        scene = load_scene(variant)
        result = simulate(scene, reduced_settings(scene), summary=True)
        assert result.settings.rtol == 1e-10
        assert row["reduced.peak_omega"] == result.peak.omega
        assert row["reduced.t_peak"] == result.peak.time
        assert row["reduced.energy_residual"] == result.audit.max_abs_residual
        assert row["reduced.energy_residual_rel"] == result.audit.relative_residual
        assert row["reduced.n_steps"] == result.n_steps
        assert row["variant_wall_s"] > 0
    assert rows[0]["reduced.peak_omega"] > rows[1]["reduced.peak_omega"]  # more damping, slower crank
    data = json.loads((tmp_path / "sw" / JSON_FILE).read_text())
    assert data["engines"] == "reduced" and data["summary"]["engines"] == "reduced"
    assert data["summary"]["counts"] == {"passed": 2, "gate_failed": 0, "failed": 0, "invalid": 0}
    assert data["summary"]["worst"] is None
    assert data["summary"]["peak_extremes"]["highest"]["index"] == 0
    lines = printed.splitlines()
    assert lines[0].startswith("2 variants, reduced engine only, no gate (1 worker,")
    assert "2 passed its own checks, 0 failed numerically, 0 invalid" in lines[0]
    assert lines[1].startswith("peak |omega| from ") and "(#1: dampers.0.coefficient = 60.5)" in lines[1]
    assert "(#0: dampers.0.coefficient = 50)" in lines[1]
    assert not any(line.startswith("worst variant") for line in lines)


def test_a_reduced_only_variant_does_not_import_mujoco(tmp_path):
    """The memory target's premise: a worker running reduced-only variants never loads MuJoCo."""
    code = ("import sys\nfrom loopcheck.compare.sweep import run_variant\nfrom loopcheck.sweep_spec import Engines\nfrom loopcheck.compare.sweep_scene import load_sweep\n"
            f"data, _ = load_sweep({str(short_seed_file(tmp_path))!r})\n"
            "row = run_variant(0, {'torque.value': 240.0}, data, 'short.toml', engines=Engines.REDUCED)\n"
            "print(row['status'], 'mujoco' in sys.modules, 'reference_models' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["passed", "False", "False"]


def test_a_variant_failing_the_reduced_engines_checks_exits_1(tmp_path, capsys):
    scene = tmp_path / "rkn4.toml"
    scene.write_text(short_seed_file(tmp_path).read_text() + RKN4)
    status, printed, _ = _sweep(capsys, scene, tmp_path / "sw", "--vary", "reduced.step=[1e-3, 2e-2, 2e-3]",
                                "--engines", "reduced", "--workers", "1")
    assert status == 1
    rows = _rows(tmp_path / "sw")
    assert [r["status"] for r in rows] == ["passed", "failed", "passed"]
    assert rows[1]["reason"].startswith("inaccurate: RKN4 at step 0.02 s")
    assert rows[1]["reduced.peak_omega"] is None and rows[1]["variant_wall_s"] > 0
    assert "2 passed its own checks, 1 failed numerically, 0 invalid" in printed
    assert "failing variants have: reduced.step in [0.02, 0.02]" in printed


@pytest.mark.parametrize("varies, samples, keep", [
    (["dampers.0.coefficient=[50, 60]", "bodies.coupler.mass=[39, 41]"], None, False),  # both: + map + worst
    (["dampers.0.coefficient=uniform(50, 60)"], 2, True),  # both: + worst
], ids=["grid-of-two-keys", "monte-carlo-with-trajectories"])
def test_the_files_written_are_sweep_files(varies, samples, keep, short_scene, tmp_path, capsys):
    args = sum((["--vary", v] for v in varies), []) + (["--samples", str(samples)] if samples else [])
    args += ["--keep-trajectories"] if keep else []
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", *args, "--engines", "reduced", "--workers", "2")
    assert status == 0, printed
    spec = replace(spec_from_args(varies, samples), engines=Engines.REDUCED)
    expected = sweep_files(spec, keep)
    assert sorted(p.name for p in (tmp_path / "sw").iterdir()) == sorted([*expected, MANIFEST_FILE])
    assert f"wrote {', '.join(expected)} to" in printed  # in the order committed
    assert not {"sweep_gate_map.png", "sweep_worst_differences.png"} & set(expected)
    assert ("sweep_peak_omega_hist.png" if samples else "sweep_peak_omega.png") in expected
    if keep:
        traj = (tmp_path / "sw" / TRAJECTORY_FILE).read_text().splitlines()
        assert {tuple(line.split(",")[:2]) for line in traj[1:]} == {("0", "reduced"), ("1", "reduced")}


@pytest.mark.usefixtures("without_plots")  # the headers and the printed summary are read
def test_the_sweep_tables_engines_and_the_flag_over_it(short_scene, tmp_path, capsys):
    scene = tmp_path / "table.toml"
    scene.write_text(short_scene.read_text() + '\n[sweep]\nengines = "reduced"\n[sweep.vary]\n'
                     '"torque.value" = [240, 250]\n')
    status, printed, _ = _sweep(capsys, scene, tmp_path / "a", "--workers", "1")
    assert status == 0, printed
    assert _header(tmp_path / "a")[-len(REDUCED_ONLY_COLUMNS):] == list(REDUCED_ONLY_COLUMNS)
    assert "reduced engine only" in printed
    status, printed, _ = _sweep(capsys, scene, tmp_path / "b", "--workers", "1", "--engines", "both")
    assert status == 0, printed
    assert "mujoco.peak_omega" in _header(tmp_path / "b") and "worst variant: #" in printed


@pytest.mark.parametrize("args, table, named", [
    (["--vary", "torque.value=[240, 250]", "--engines", "mujoco"], "", "--engines"),
    ([], 'engines = "mujoco"\n', "sweep.engines"),
    ([], "engines = 1\n", "sweep.engines"),
], ids=["flag", "table-value", "table-type"])
def test_a_bad_engines_value_is_refused_up_front(args, table, named, short_scene, tmp_path, capsys):
    scene = tmp_path / "bad.toml"
    scene.write_text(short_scene.read_text() + f'\n[sweep]\n{table}[sweep.vary]\n"torque.value" = [240, 250]\n')
    status, printed, err = _sweep(capsys, scene, tmp_path / "sw", *args)
    assert status == 2 and printed == ""
    assert err.count("\n") == 1 and named in err and "Traceback" not in err, err
    assert not (tmp_path / "sw").exists()


@pytest.mark.parametrize("engines", list(Engines))
@pytest.mark.parametrize("varies", [["dampers.0.coefficient=40:70:5", "bodies.coupler.mass=35:45:12"],
                                    ["bodies.coupler.mass=normal(40, 2)"]], ids=["grid", "monte-carlo"])
def test_no_sweep_plot_has_text_cut_off(tmp_path, monkeypatch, engines, varies):
    """The sweep's plots (not the worst variant's, which is loopcheck run's) with long keys: the
    reduced-only title's second line and the names of a family of twelve lines stay inside
    the figure (measured on synthetic rows: only the layout is tested)."""
    import csv

    from matplotlib.figure import Figure

    from loopcheck.compare.sweep_plots import PLOTS, WORST_PLOT, plot_files
    from loopcheck.compare.sweep_table import columns
    from loopcheck.sweep_spec import variant_values
    from test_startup import text_outside

    spec = replace(spec_from_args(varies, samples=200 if "normal" in varies[0] else None), engines=engines)
    path = tmp_path / CSV_FILE
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns(spec))
        writer.writeheader()
        for index, values in enumerate(variant_values(spec)):
            peak = 30.0 + 0.1 * sum(values.values())
            row = {"index": index, "status": "passed", **values, "reduced.peak_omega": peak}
            if engines is Engines.BOTH:
                row.update({"mujoco.peak_omega": peak * (1 + 1e-5), "gate.worst_ratio": 0.5})
            writer.writerow(row)
    saved = []
    real_savefig = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (saved.append(fig), real_savefig(fig, *a, **k)))
    names = [n for n in plot_files(spec) if n != WORST_PLOT]
    for name in names:
        PLOTS[name](path, spec, str(ROOT / "scenes" / "seed_fourbar.toml"), tmp_path / name, "rad/s")
    assert len(saved) == len(names)
    for fig, name in zip(saved, names):
        assert text_outside(fig) == [], name


@pytest.mark.parametrize("vary,engines", [("reduced.rtol=1e-20,1e-19", "reduced"),
                                          ("mujoco.solimp.0=2,3", "both")], ids=["rtol", "solimp"])
def test_a_sweep_with_no_valid_variant_exits_1(vary, engines, short_scene, tmp_path, capsys):
    """Issue 24: every variant invalid ("2 invalid") exited 0. Both settings are refused by the
    engines' settings (rtol below 100 machine epsilons, solimp dmin above 0.9999), not by the
    scene file, so the variants are built and counted invalid."""
    with open(short_scene, "a") as f:
        f.write("\n[mujoco]\nsolimp = [0.9999, 0.9999, 0.001, 0.5, 2]\n")
    status, printed, err = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", vary, "--engines", engines,
                                  "--workers", "1")
    assert "2 invalid" in printed and "no variant is valid" in printed, printed + err
    assert status == 1
    assert [r["status"] for r in _rows(tmp_path / "sw")] == ["invalid", "invalid"]


# ---------------------------------------------------------------- an interrupted sweep, resumed

RESUMED_VARY = ["--vary", "dampers.0.coefficient=40:60:7", "--engines", "reduced", "--workers", "1"]


def _without_wall_times(rows):
    return [{k: v for k, v in r.items() if "wall_s" not in k} for r in rows]


def test_an_interrupted_sweep_keeps_its_rows_beside_out_and_resume_finishes_it(short_scene, tmp_path, capsys,
                                                                                monkeypatch, interruptible):
    """Issue 24: Ctrl-C discarded every finished row. Decision: --out is left as it was, the
    finished rows are in a journal beside it (never inside), --resume runs only the rest and a
    completed sweep removes the journal. A real SIGINT at variant 4 of 7 (serial, in this
    process); the resumed sweep.csv equals an uninterrupted one's but for the wall times."""
    with plots_left_out():  # the reference's rows are read
        status, _, err = _sweep(capsys, short_scene, tmp_path / "ref", *RESUMED_VARY)
    assert status == 0, err
    out = tmp_path / "sw"
    out.mkdir()
    (out / "sweep.csv").write_text("old\n")
    journal = journal_path(out)
    assert journal.parent == tmp_path and journal.name == "sw.sweep-journal.csv"
    real_run_variant, ran, fired = sweep_module.run_variant, [], []

    def interrupted_at_4(index, *args, **kwargs):
        ran.append(index)
        if index == 4 and not fired:
            fired.append(index)
            os.kill(os.getpid(), signal.SIGINT)
        return real_run_variant(index, *args, **kwargs)
    monkeypatch.setattr(sweep_module, "run_variant", interrupted_at_4)
    status, printed, err = _sweep(capsys, short_scene, out, *RESUMED_VARY)
    assert status == 130 and err == "loopcheck: interrupted\n", err
    assert sorted(p.name for p in out.iterdir()) == ["sweep.csv"] and (out / "sweep.csv").read_text() == "old\n"
    lines = journal.read_text().splitlines()
    assert len(lines) == 2 + 4 and [line.split(",")[0] for line in lines[2:]] == ["0", "1", "2", "3"]
    ran.clear()
    status, printed, err = _sweep(capsys, short_scene, out, *RESUMED_VARY, "--resume")
    assert status == 0, err
    assert ran == [4, 5, 6]  # the journaled rows were not run again
    assert not journal.exists()
    assert _without_wall_times(read_rows(out / CSV_FILE)) == _without_wall_times(read_rows(tmp_path / "ref" / CSV_FILE))
    assert "7 variants" in printed and "7 passed" in printed


def test_resume_needs_the_journal_of_the_same_sweep(short_scene, tmp_path, capsys):
    status, printed, err = _sweep(capsys, short_scene, tmp_path / "sw", *RESUMED_VARY, "--resume")
    assert status == 2 and printed == "" and "nothing to resume" in err and err.count("\n") == 1, err
    journal_path(tmp_path / "sw").write_text("# loopcheck sweep journal 0\nindex,status\n0,passed\n")
    status, printed, err = _sweep(capsys, short_scene, tmp_path / "sw", *RESUMED_VARY, "--resume")
    assert status == 2 and printed == "" and "journal of another sweep" in err and err.count("\n") == 1, err
    assert not (tmp_path / "sw").exists()


@pytest.mark.usefixtures("without_plots")  # what it says is read
def test_a_long_sweep_says_so_before_it_runs_on(short_scene, tmp_path, capsys, monkeypatch):
    """Issue 24: 10^6 variants (hours) were accepted without a word off a terminal. The estimate
    (the second variant's time x the variants left / workers) is one warning line when over
    LONG_SWEEP_S; here the limit is lowered to 1 ms so that a 7-variant sweep crosses it, and the
    real 600 s is not crossed by the same sweep (about 0.1 s a variant)."""
    status, _, err = _sweep(capsys, short_scene, tmp_path / "a", *RESUMED_VARY)
    assert status == 0 and "estimated" not in err, err
    monkeypatch.setattr(sweep_module, "LONG_SWEEP_S", 1e-3)
    status, _, err = _sweep(capsys, short_scene, tmp_path / "b", *RESUMED_VARY)
    lines = [line for line in err.splitlines() if "estimated" in line]
    assert status == 0 and len(lines) == 1, err
    assert lines[0].startswith("loopcheck: warning: this sweep is estimated to take ") and "5 variants at" in lines[0]


def test_a_signal_while_the_sweep_says_what_it_wrote_comes_after_its_files_and_lines(tmp_path):
    """run_sweep's ``committed`` runs with the files in place and the journal gone, while signals
    are held: a SIGTERM sent there comes after the lines (Terminated), so a sweep never exits
    interrupted with new files and no line, nor leaves a journal of a sweep it finished.
    (Planted: removing the journal only after write_folder returns leaves it here.)"""
    from loopcheck.compare.output import Terminated, signals_as_exceptions
    from loopcheck.compare.sweep_scene import load_sweep

    scene = short_seed_file(tmp_path)
    data, _ = load_sweep(str(scene))
    spec = replace(spec_from_args(["dampers.0.coefficient=[50, 60]"]), engines=Engines.REDUCED)
    out = tmp_path / "sw"
    said = []

    def committed(summary, paths):
        os.kill(os.getpid(), signal.SIGTERM)
        said.append((summary.total, [p.name for p in paths]))

    with pytest.raises(Terminated), signals_as_exceptions():
        sweep_module.run_sweep(data, spec, str(scene), out, workers=1, progress=False, committed=committed)
    assert said and said[0][0] == 2 and CSV_FILE in said[0][1]
    assert (out / CSV_FILE).is_file() and not journal_path(out).exists()
