"""The comparison, its report and plots, and the CLI gate (real runs, nothing mocked)."""

from __future__ import annotations

import json

import matplotlib.image
import numpy as np
import pytest

import loopcheck.compare.report
from loopcheck.compare.cli import main
from loopcheck.compare.diff import compare_trajectories, gate
from loopcheck.compare.output import MANIFEST_FILE
from loopcheck.compare.report import REPORT_FILES, write_outputs
from loopcheck.trajectory import Trajectory
from loopcheck.scene import Tolerances

from helpers import SEED_SCENE

REPORT_ENGINE_KEYS = {"peak_omega", "t_peak", "peak_still_rising", "wall_s", "settings", "energy_residual"}
REPORT_DIFF_KEYS = {"peak_omega_abs", "peak_omega_rel", "t_peak_abs", "q_max_abs", "q_rms",
                    "omega_max_abs", "omega_rms", "omega_vs_q_max_abs", "mode_mismatches",
                    "mode_mismatch_first_times", "mode_mismatches_total", "peak_omega_reference", "peak_omega_other",
                    "t_peak_reference", "t_peak_other", "span_start", "span_end", "horizon"}


def smooth_trajectory(shift: float = 0.0, n: int = 2001) -> Trajectory:
    """A crank turning unevenly: q = 20 t + 0.3 sin(8 t), sampled on [0, 2] s, delayed by ``shift``."""
    t = np.linspace(0.0, 2.0, n)
    s = t - shift
    return Trajectory(t, 20 * s + 0.3 * np.sin(8 * s), 20 + 2.4 * np.cos(8 * s), -19.2 * np.sin(8 * s))


def test_identical_trajectories_differ_by_nothing():
    a = smooth_trajectory()
    d = compare_trajectories(a, a)
    # Interpolating a trajectory at its own samples returns them (to round-off in q̇ = c1/h).
    assert d.q_max_abs == 0.0
    assert d.omega_max_abs < 1e-12 and d.omega_vs_q_max_abs < 1e-12
    assert d.peak_omega_abs == 0.0 and d.t_peak_abs == 0.0


def test_time_shift_is_reported_as_phase_not_speed_error():
    """A 1 ms delay of a fast crank: |Δω(t)| is large (ω̇ · 1 ms ≈ 0.02 rad/s), but at equal
    angle the speeds agree to the interpolation error of the reference (≈ 1e-9 here)."""
    ref, late = smooth_trajectory(), smooth_trajectory(shift=1e-3)
    d = compare_trajectories(ref, late)
    assert d.omega_max_abs > 0.015
    assert d.q_max_abs > 0.015  # ≈ 20 rad/s × 1 ms
    assert d.omega_vs_q_max_abs < 1e-6
    assert d.t_peak_abs == pytest.approx(1e-3, abs=1e-6)


def test_gate_uses_tolerances(seed_comparison):
    d = seed_comparison.diff
    assert seed_comparison.gate.passed, seed_comparison.gate.failures
    tight = gate(d, Tolerances(peak_omega_rtol=d.peak_omega_rel / 2, q_atol=1.0, omega_atol=10.0))
    assert not tight.passed and len(tight.failures) == 1 and "peak_omega_rel" in tight.failures[0]


def test_outputs_are_written_and_follow_the_schema(seed_comparison, tmp_path):
    paths = write_outputs(seed_comparison, tmp_path / "out")
    names = {p.name for p in paths}
    assert {"report.json", "reduced.csv", "mujoco.csv", "trajectories.png", "differences.png",
            "omega_vs_q.png", "constraint_violation.png", "energy.png"} <= names
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]  # no staging left
    for p in paths:
        assert p.stat().st_size > 0
        if p.suffix == ".png":
            assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
            image = matplotlib.image.imread(p)
            assert image.shape[0] > 200 and image.shape[1] > 400
            assert np.ptp(image[..., :3]) > 0.5  # not a blank canvas
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert {"scene", "reduced", "mujoco", "diff", "gate"} <= report.keys()
    for engine in ("reduced", "mujoco"):
        assert REPORT_ENGINE_KEYS <= report[engine].keys()
        assert isinstance(report[engine]["peak_omega"], float)
    assert isinstance(report["mujoco"]["max_constraint_violation"], float)
    assert report["diff"].keys() == REPORT_DIFF_KEYS
    assert report["gate"]["passed"] is True and report["gate"]["failures"] == []
    assert report["gate"]["tolerances"] == {"peak_omega_rtol": 1e-4, "q_atol": 1e-3, "omega_atol": 0.1,
                                            "omega_vs_q_atol": None}
    assert report["diff"]["mode_mismatches"] == [0] and report["diff"]["mode_mismatches_total"] == 0
    assert report["schema_version"] == 7
    # a plain run (no --engines): MuJoCo, the one engine judged, is the engines list
    assert report["other_engine"] == "mujoco" and report["outlier"] is None
    assert [(e["engine"], e["passed"], e["q_max_abs"]) for e in report["engines"]] == [
        ("mujoco", True, report["diff"]["q_max_abs"])]
    assert report["scene"]["input_unit"] == "rad" and report["scene"]["mode"] == [1]
    assert (tmp_path / "out" / "mujoco.csv").read_text().startswith("t_s,q_rad,qdot_rad_per_s,")
    csv = np.loadtxt(tmp_path / "out" / "mujoco.csv", delimiter=",", skiprows=1)
    # t, q, q̇, q̈, then u and u̇ of each of the four-bar's 4 joints
    assert csv.shape[1] == 4 + 2 * 4 and np.all(np.diff(csv[:, 0]) >= 0)
    assert [j["name"] for j in report["joints"]] == ["O1", "A", "B", "O3"]


def test_check_passes_on_seed_and_fails_below_measured_difference(seed_comparison, capsys):
    assert main(["check", str(SEED_SCENE)]) == 0
    assert "1 passed, 0 failed" in capsys.readouterr().out
    # at MuJoCo's step of that run (an automatic step would be chosen for the tighter gate)
    tight = seed_comparison.diff.peak_omega_rel / 10
    step = seed_comparison.other.settings.timestep
    assert main(["check", str(SEED_SCENE), "--peak-rtol", f"{tight:.3e}", "--timestep", f"{step!r}"]) == 1
    out = capsys.readouterr().out
    assert "peak_omega_rel" in out and "> tolerance" in out and "fixed timestep" in out and "--timestep" in out


def test_run_writes_report(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(SEED_SCENE), "--out", str(out)]) == 0
    assert "gate: PASSED" in capsys.readouterr().out
    report = json.loads((out / "report.json").read_text(),
                        parse_constant=lambda token: pytest.fail(f"bare {token} in report.json"))
    assert report["scene"]["name"] == "seed_fourbar"
    assert sorted(p.name for p in out.iterdir()) == sorted([*REPORT_FILES, MANIFEST_FILE])  # no staging left
    assert (out / MANIFEST_FILE).read_text().splitlines() == list(REPORT_FILES)


@pytest.mark.parametrize("command", ["run", "check", "mujoco", "reduced"])
def test_bad_scene_exits_2_with_one_line_and_no_outputs(command, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(SEED_SCENE.read_text().replace("c2 = 0.9", "c2 = -0.9"))
    out = tmp_path / "out"
    args = [command, str(bad)] + (["--out", str(out)] if command == "run" else [])
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and "linkage.c2" in err
    assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.slow  # end to end (~1.5 s each); tests/compare/test_outputs.py catches the same at the writer, fast
@pytest.mark.parametrize("error", [RuntimeError("plot failed"), KeyboardInterrupt()], ids=["exception", "ctrl-c"])
def test_failed_run_leaves_the_output_folder_as_it_was(seed_comparison, tmp_path, monkeypatch, error):
    """Issue 9, planted bug 3: a plot that fails after the CSVs are written leaves the earlier
    run's complete report (and nothing hidden) in place."""
    out = tmp_path / "out"
    write_outputs(seed_comparison, out)
    (out / "report.json").write_text('{"old": true}\n')
    before = {p.name: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}

    def failing_plot(c, path):
        path.write_bytes(b"\x89PNG half")
        raise error
    monkeypatch.setitem(loopcheck.compare.report.PLOTS, "energy.png", failing_plot)
    with pytest.raises(type(error)):
        write_outputs(seed_comparison, out)
    assert {p.name: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.rglob("*")) == sorted(["out", *before])
