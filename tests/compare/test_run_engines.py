"""`loopcheck run --engines`: every engine against the reduced reference, the report folder of one
comparison (MuJoCo's, else the list's first other engine) with each engine's verdict in report.json
and engines.png. The seed over 0.2 s keeps each run short (the pulse still on: the peak is the
horizon's end, 6.6 rad/s)."""

from __future__ import annotations

import json

import matplotlib.image
import numpy as np
import pytest

from loopcheck.compare.cli import main
from loopcheck.compare.output import MANIFEST_FILE
from loopcheck.compare.report import ENGINES_PLOT, REPORT_FILES, SCHEMA_VERSION, report_files
from helpers import plots_left_out, short_seed_file

ENTRY_KEYS = {"engine", "passed", "peak_omega", "peak_omega_rel", "q_max_abs", "omega_max_abs", "tolerances",
              "failures", "failure", "failed_at", "known_defects"}


def _scene(tmp_path, extra: str = "") -> str:
    path = short_seed_file(tmp_path, "0.2")
    path.write_text(path.read_text(encoding="utf-8") + extra, encoding="utf-8")
    return str(path)


def _report(out) -> dict:
    return json.loads((out / "report.json").read_text(encoding="utf-8"))


def test_run_with_mujoco_writes_todays_files_and_the_engines_verdicts(tmp_path, capsys):
    """reduced,mujoco: the files of a plain run (its plots left out here: test_run_without_mujoco_...
    draws them) and engines.png (a drawn PNG), report.json's engines list holding MuJoCo's verdict at the
    figures of its diff and gate."""
    out = tmp_path / "out"
    with plots_left_out():
        assert main(["run", _scene(tmp_path), "--engines", "reduced,mujoco", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "MuJoCo (rk4" in printed and "      mujoco   ok" in printed and "wrote 4 files" in printed
    assert sorted(p.name for p in out.iterdir()) == sorted(["reduced.csv", "mujoco.csv", ENGINES_PLOT, "report.json",
                                                            MANIFEST_FILE])
    assert report_files(other="mujoco", engines=True) == (*REPORT_FILES[:-1], ENGINES_PLOT, "report.json")
    image = matplotlib.image.imread(out / ENGINES_PLOT)
    assert image.shape[0] > 400 and np.ptp(image[..., :3]) > 0.5  # drawn, not a blank canvas
    report = _report(out)
    assert report["schema_version"] == SCHEMA_VERSION == 7 and report["other_engine"] == "mujoco"
    assert report["reference_engine"] == "reduced"
    [entry] = report["engines"]
    assert entry.keys() == ENTRY_KEYS and entry["engine"] == "mujoco" and entry["passed"] is True
    assert entry["peak_omega"] == report["mujoco"]["peak_omega"] == report["diff"]["peak_omega_other"]
    assert (entry["q_max_abs"], entry["omega_max_abs"]) == (report["diff"]["q_max_abs"], report["diff"]["omega_max_abs"])
    assert entry["tolerances"] == {"peak_omega_rtol": 1e-4, "peak_omega_atol": 1e-9, "q_atol": 1e-3, "omega_atol": 0.1,
                                   "omega_vs_q_atol": None}
    assert entry["failure"] is None and report["outlier"] is None


def test_run_without_mujoco_describes_the_other_engine(tmp_path, capsys):
    """reduced,pin: the report's files (every plot drawn) are the reference against Pinocchio, named so
    (pin.csv, the "pin" summary, "Pinocchio" in the table), and nothing says MuJoCo."""
    pytest.importorskip("pinocchio")
    out = tmp_path / "out"
    assert main(["run", _scene(tmp_path), "--engines", "reduced,pin", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Pinocchio (DOP853 rtol=1e-10)" in printed and "difference (Pinocchio - reduced)" in printed
    assert "MuJoCo" not in printed
    names = report_files(other="pin", engines=True)
    assert sorted(p.name for p in out.iterdir()) == sorted([*names, MANIFEST_FILE])
    assert "pin.csv" in names and "mujoco.csv" not in names and "differences.png" in names
    report = _report(out)
    assert report["other_engine"] == "pin" and "mujoco" not in report and report["pin"]["details"]["solver"] == "DOP853"
    assert [e["engine"] for e in report["engines"]] == ["pin"] and report["engines"][0]["passed"] is True
    assert {"reduced", "pin"} <= report["joints"][0].keys()
    # Pinocchio's |Δq̇| is 2.6e-9 rad/s over 0.2 s (measured); 1e-7 is the bound of its DOP853 at rtol 1e-10
    assert 0 < report["engines"][0]["omega_max_abs"] < 1e-7


def test_an_engine_beyond_its_own_tolerance_fails_the_run(tmp_path, capsys):
    """[tolerances.pin] omega_atol = 1e-12, below Pinocchio's 2.6e-9 rad/s: exit 1, the files still written,
    pin's verdict failed at its own tolerance, MuJoCo's passed at [tolerances]' 0.1."""
    pytest.importorskip("pinocchio")
    out = tmp_path / "out"
    with plots_left_out():
        assert main(["run", _scene(tmp_path, "\n[tolerances.pin]\nomega_atol = 1e-12\n"),
                     "--engines", "reduced,mujoco,pin", "-o", str(out)]) == 1
    assert "      pin      FAIL" in capsys.readouterr().out
    report = _report(out)
    verdicts = {e["engine"]: e for e in report["engines"]}
    assert verdicts["mujoco"]["passed"] is True and verdicts["mujoco"]["tolerances"]["omega_atol"] == 0.1
    assert verdicts["pin"]["passed"] is False and verdicts["pin"]["tolerances"]["omega_atol"] == 1e-12
    assert len(verdicts["pin"]["failures"]) == 1 and "omega_max_abs" in verdicts["pin"]["failures"][0]
    # the outlier is judged by the peaks: MuJoCo's is 6e-6 off, Pinocchio's 2e-13
    assert report["outlier"] == "mujoco" and report["gate"]["passed"] is True


def test_the_compared_engine_that_does_not_run_writes_nothing(tmp_path, capsys):
    """Pinocchio out of its evaluation budget: its failure printed, exit 1, no report folder."""
    pytest.importorskip("pinocchio")
    out = tmp_path / "out"
    assert main(["run", _scene(tmp_path, "\n[pin]\nmax_evaluations = 10\n"), "--engines", "reduced,pin",
                 "-o", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "      pin      numerical failure" in printed and "Pinocchio did not run: no report written" in printed
    assert not out.exists()


@pytest.mark.parametrize("argv, message", [
    (["tests/data/mjcf/fourbar_xz_degrees.xml", "--engines", "reduced,mujoco"], "--engines runs scenes"),
    (["seed_fourbar", "--engines", "reduced,bullet"], "unknown engine 'bullet'"),
    (["seed_fourbar", "--engines", "mujoco,pin"], "must include 'reduced'"),
])
def test_bad_input_is_one_line_and_exit_2(argv, message, tmp_path, capsys):
    assert main(["run", *argv, "-o", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    assert message in captured.err and captured.err.count("\n") == 1 and not captured.out
    assert not (tmp_path / "out").exists()


def test_a_users_model_is_reported_as_mujoco():
    """A user's MuJoCo model as written (``loopcheck run model.xml``) keeps the report's mujoco names and label."""
    from loopcheck.compare.report import output_name
    from loopcheck.compare.text import engine_label
    from loopcheck.reference_models.user_model import ENGINE

    assert (output_name(ENGINE), engine_label(ENGINE)) == ("mujoco", "MuJoCo")
    assert (output_name("pin"), engine_label("pin")) == ("pin", "Pinocchio")
