"""xval sweep --engines reduced (compare.sweep, reduced-only mode): rows equal to
reduced.engine.simulate on the same variant scene with the settings the comparison would give
it, MuJoCo neither run nor imported, exit status 1 on a variant failing the reduced engine's own
checks, exactly the files sweep_files lists, the [sweep] table's engines and the flag over it,
and bad values refused up front. Short scenes (the seed with a 0.3 s horizon), 2-3 variants."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import pytest

from compare.cli import main
from compare.sweep import CSV_FILE, JSON_FILE, REDUCED_ONLY_COLUMNS, TRAJECTORY_FILE, read_rows, sweep_files
from compare.sweep_spec import Engines, spec_from_args

from helpers import ROOT, short_seed_file

RKN4 = '\n[reduced]\nmethod = "rkn4"\n'  # its error estimate fails at steps of 2e-2 s on the short seed


@pytest.fixture
def short_scene(tmp_path):
    return short_seed_file(tmp_path)


def _sweep(capsys, scene, out, *args):
    status = main(["sweep", str(scene), "--out", str(out), *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _header(out):
    return (out / CSV_FILE).read_text().splitlines()[0].split(",")


def test_rows_equal_the_reduced_engine_on_the_same_variant_scene(short_scene, tmp_path, capsys, monkeypatch):
    """Each row's reduced figures are those of reduced.engine.simulate with the scene's reduced
    settings as compare.settings resolves them; MuJoCo and the comparison are not run (the
    comparison is planted to fail: a variant that ran it would be a failed row)."""
    import compare.run
    from compare.settings import reduced_settings
    from reduced.engine import simulate
    from reduced.scenefile import load_scene

    def no_comparison(*args, **kwargs):
        raise AssertionError("a reduced-only sweep ran the comparison")

    monkeypatch.setattr(compare.run, "compare_engines", no_comparison)
    short_scene.write_text(short_scene.read_text() + '\n[reduced]\nrtol = 1e-10\n')  # its own settings, used
    status, printed, _ = _sweep(capsys, short_scene, tmp_path / "sw", "--vary", "dampers.0.coefficient=[50, 60.5]",
                                "--engines", "reduced", "--workers", "1")
    assert status == 0, printed
    rows = list(read_rows(tmp_path / "sw" / CSV_FILE))
    assert _header(tmp_path / "sw") == ["index", "status", "reason", "dampers.0.coefficient", *REDUCED_ONLY_COLUMNS]
    assert [(r["index"], r["status"], r["reason"]) for r in rows] == [(0, "passed", ""), (1, "passed", "")]
    for row in rows:
        variant = tmp_path / f"variant{row['index']}.toml"
        variant.write_text(short_scene.read_text().replace("coefficient = 55.0",
                                                           f"coefficient = {row['dampers.0.coefficient']!r}"))
        scene = load_scene(variant)
        result = simulate(scene, reduced_settings(scene))
        assert result.settings["rtol"] == 1e-10
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
    code = ("import sys\nfrom compare.sweep import run_variant\nfrom compare.sweep_spec import Engines, load_sweep\n"
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
    rows = list(read_rows(tmp_path / "sw" / CSV_FILE))
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
    assert sorted(p.name for p in (tmp_path / "sw").iterdir()) == sorted(expected)
    assert f"wrote {', '.join(expected)} to" in printed  # in the order committed
    assert not {"sweep_gate_map.png", "sweep_worst_differences.png"} & set(expected)
    assert ("sweep_peak_omega_hist.png" if samples else "sweep_peak_omega.png") in expected
    if keep:
        traj = (tmp_path / "sw" / TRAJECTORY_FILE).read_text().splitlines()
        assert {tuple(line.split(",")[:2]) for line in traj[1:]} == {("0", "reduced"), ("1", "reduced")}


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
