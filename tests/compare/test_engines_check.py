"""`loopcheck check --engines`: each engine against the reduced reference; the outlier named."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from loopcheck.compare.engines import check_engines, engines_lines, parse_engines
from loopcheck.compare.settings import engine_settings
from loopcheck.reference_models import MujocoSettings
from loopcheck.scenefile import load_scene

from helpers import ROOT

HAS_PIN = importlib.util.find_spec("pinocchio") is not None
# MuJoCo's own default softness on the loop at RK4 1 ms: it runs (its gap and energy bounds opened)
# with the seed's peak 3.2e-2 low (tests/compare/test_model_check.py measures the same model)
SOFT = dict(timestep=0.001, solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001, 0.5, 2.0), max_constraint_violation=0.01,
            max_energy_residual=1.0)


@pytest.mark.parametrize("text, message", [("reduced,nope", "unknown engine 'nope'"), ("mujoco,pin", "must include 'reduced'"),
                                           ("reduced,mujoco,reduced", "named twice"), ("reduced", "at least one other")])
def test_the_engine_list_is_checked(text, message):
    with pytest.raises(ValueError, match=message):
        parse_engines(text)


def _settings(scene, engines, **mujoco):
    return {name: MujocoSettings(**mujoco) if name == "mujoco" else engine_settings(name, scene) for name in engines}


def test_the_outlier_is_farthest_from_the_median_of_the_others():
    """Five peaks (rad/s) as the seed's table has them: three engines agree, MJWarp is 2e-4 off and
    MJX 1.4e-2 off; the median of the others is the agreeing value for both ports, so MJX, the
    farther, is named. Six, two of them agreeing far from the other four: the lone one is named.
    (Planted: min for max names 'mujoco' and 'c'.)"""
    from loopcheck.compare.engines import farthest_from_the_others

    peaks = {"reduced": 34.264413, "mujoco": 34.264320, "pin": 34.264413, "mjx": 33.78, "mjwarp": 34.258}
    assert farthest_from_the_others(peaks) == "mjx"
    assert farthest_from_the_others({"a": 0.0, "b": 0.0, "c": 1.0, "d": 1.0, "e": 1.0, "f": 5.0}) == "f"


def test_the_engine_s_own_peak_is_not_in_the_median_it_is_measured_from():
    """Peaks 0, 0, 5, 6, 9: from the others' medians (2.5 for 'e', 5.5 for 'a') 'e' is 6.5 away
    and 'a' 5.5: 'e' is named. The median of all five peaks (5), the engine's own included, would
    put 'a' 5 away and 'e' 4 and name 'a' (planted so, this fails; with three or four engines
    the two rules agree, so five)."""
    from loopcheck.compare.engines import farthest_from_the_others

    assert farthest_from_the_others({"a": 0.0, "b": 0.0, "c": 5.0, "d": 6.0, "e": 9.0}) == "e"


def test_two_engines_name_no_outlier():
    """With only MuJoCo beside the reference, a failing MuJoCo (MuJoCo's default softness: the
    seed's peak 3.2e-2 off) fails the check, and nobody is called an outlier."""
    scene = load_scene("scenes/seed_fourbar.toml")
    check = check_engines(scene, ("reduced", "mujoco"), _settings(scene, ("reduced", "mujoco"), **SOFT))
    assert not check.passed and check.outlier is None


@pytest.mark.skipif(not HAS_PIN, reason="Pinocchio (the extra loopcheck[pin]) is not installed")
def test_the_engine_farthest_from_the_others_is_named():
    """MuJoCo with its default softness against the reduced solution and Pinocchio, which agree to 4e-11 on the
    seed's peak: MuJoCo is named."""
    scene = load_scene("scenes/seed_fourbar.toml")
    engines = ("reduced", "mujoco", "pin")
    check = check_engines(scene, engines, _settings(scene, engines, **SOFT))
    assert not check.passed and check.outlier == "mujoco"
    assert check.spread[("reduced", "pin")] < 1e-9 < min(check.spread[("reduced", "mujoco")], check.spread[("mujoco", "pin")])


@pytest.mark.skipif(not HAS_PIN, reason="Pinocchio (the extra loopcheck[pin]) is not installed")
def test_cli_check_with_three_engines(capsys):
    from loopcheck.compare.cli import main

    assert main(["check", "seed_fourbar", "--engines", "reduced,mujoco,pin"]) == 0
    out = capsys.readouterr().out
    assert "      mujoco   ok" in out and "      pin      ok" in out and "farthest" not in out


def test_cli_engines_run_a_model_as_written_in_its_reader_and_its_scene_in_the_others(capsys):
    """A model listed with --engines: MuJoCo (the engine that read it) runs the file as written, the
    others its imported scene (issue 39: "an MJX user thus learns what MJX does to their model"). The
    oracle: MuJoCo's peak in the engines' lines is the as-written run's that plain ``check model.xml``
    prints, to its 10 digits (MuJoCo's own model of the imported scene differs from the file: its
    default softness and step; plant: the scene run in MuJoCo instead, and the peaks differ)."""
    import re

    from loopcheck.compare.cli import main

    model = ROOT / "tests" / "data" / "mjcf" / "fourbar_xz_degrees.xml"
    assert main(["check", str(model), "--horizon", "0.2", "--ctrl", "50"]) in (0, 1)
    plain = capsys.readouterr().out
    written = re.search(r"as written: +peak (\S+) ", plain).group(1)
    assert main(["check", str(model), "--engines", "reduced,mujoco", "--horizon", "0.2", "--ctrl", "50"]) in (0, 1)
    out = capsys.readouterr().out
    assert f"  {model}: reduced peak" in out and out.rstrip().endswith("failed")
    mujoco = re.search(r"      mujoco   (?:ok  |FAIL)  peak (\S+) ", out).group(1)
    assert mujoco == written, (mujoco, written)
    assert f"               ran {model} as written (the others: its scene as imported)" in out


def test_cli_engines_refuse_a_model_whose_check_could_not_fail(capsys):
    """A model read at rest without control does not move: with --engines, as without, the check is
    refused in one line (exit 2) before MuJoCo runs, not passed by every engine at zero difference
    (plant: no refusal, and the command printed "1 passed")."""
    from loopcheck.compare.cli import main

    model = ROOT / "tests" / "data" / "mjcf" / "fourbar_xz_degrees.xml"
    assert main(["check", str(model), "--engines", "reduced,mujoco", "--horizon", "0.2"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    error = [line for line in captured.err.splitlines() if line.startswith("loopcheck: error: ")]
    assert len(error) == 1 and "the check could not fail" in error[0]


def _short_seed(extra: str = "") -> str:
    """The seed over 0.2 s (the pulse still on, the peak the horizon's end: 6.6 rad/s), with ``extra`` TOML."""
    from helpers import SEED_SCENE

    text = SEED_SCENE.read_text(encoding="utf-8")
    assert "\nhorizon = 2.0" in text
    return text.replace("\nhorizon = 2.0", "\nhorizon = 0.2", 1) + extra


def test_each_engine_is_judged_by_its_own_table():
    """MuJoCo at its default softness is 3e-2 off on the seed (test_two_engines_name_no_outlier): loosened
    in [tolerances.mujoco] alone it passes, while the same tables with the looseness in [tolerances.pin]
    fail it. What a check judged by [tolerances] (ignoring the engine's table) gives neither way."""
    from loopcheck.scenefile import scene_from_dict
    from loopcheck.toml_reader import parse_toml
    from pathlib import Path

    loose = "peak_omega_rtol = 0.5\nq_atol = 1.0\nomega_atol = 20.0\n"
    for table, passes in (("mujoco", True), ("pin", False)):
        scene = scene_from_dict(parse_toml(_short_seed(f"\n[tolerances.{table}]\n{loose}"), Path("s.toml")))
        check = check_engines(scene, ("reduced", "mujoco"), _settings(scene, ("reduced", "mujoco"), **SOFT))
        assert check.passed is passes, check.verdicts[0].comparison.gate.failures
        assert check.verdicts[0].tolerances == scene.tolerances_for("mujoco")
        assert check.verdicts[0].comparison.gate.tolerances.omega_atol == (20.0 if passes else 0.1)


@pytest.mark.skipif(not HAS_PIN, reason="Pinocchio (the extra loopcheck[pin]) is not installed")
def test_cli_check_fails_the_engine_whose_table_is_impossibly_tight_and_flags_override_it(tmp_path, capsys):
    """Pinocchio's |Δq̇| is 2.6e-9 rad/s over 0.2 s (measured); [tolerances.pin] omega_atol = 1e-12 fails pin
    alone (exit 1), MuJoCo keeps [tolerances]' 0.1; --omega-atol 0.1 overrides every engine's: exit 0."""
    from loopcheck.compare.cli import main

    path = tmp_path / "tight.toml"
    path.write_text(_short_seed("\n[tolerances.pin]\nomega_atol = 1e-12\n"), encoding="utf-8")
    assert main(["check", str(path), "--engines", "reduced,mujoco,pin"]) == 1
    out = capsys.readouterr().out
    assert "      mujoco   ok" in out and "(tol 0.1)" in out
    assert "      pin      FAIL" in out and "(tol 1e-12)" in out
    assert main(["check", str(path), "--engines", "reduced,mujoco,pin", "--omega-atol", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "      pin      ok" in out and "1e-12" not in out


def test_mujocos_own_table_is_its_gate_in_a_plain_check(tmp_path, capsys):
    """[tolerances.mujoco] is MuJoCo's gate without --engines too (MuJoCo's |Δq̇| is ~5e-5 rad/s over 0.2 s,
    measured): omega_atol = 1e-12 there fails `loopcheck check`, the same key in [tolerances.pin] does not. At a
    fixed step: the automatic one would be searched for 1e-12 and fail as a numerical failure."""
    from loopcheck.compare.cli import main

    for table, status in (("mujoco", 1), ("pin", 0)):
        path = tmp_path / f"{table}.toml"
        path.write_text(_short_seed(f"\n[tolerances.{table}]\nomega_atol = 1e-12\n"), encoding="utf-8")
        assert main(["check", str(path), "--timestep", "5e-4"]) == status  # fixed: no step search for 1e-12
        assert ("(tol 1e-12)" in capsys.readouterr().out) is (status == 1)


@pytest.fixture(scope="module")
def failed_part_way():
    """The seed over 0.5 s with MuJoCo at a fixed 1 ms step held to loops closed within 1e-7 m:
    its loops open by 3.2e-7 m at t = 0.496 s (measured), so its own gate fails it part-way: a
    real run, not a made-up failure."""
    import dataclasses

    scene = dataclasses.replace(load_scene("scenes/seed_fourbar.toml"), horizon=0.5)
    settings = {"reduced": engine_settings("reduced", scene),
                "mujoco": MujocoSettings(timestep=0.001, max_constraint_violation=1e-7)}
    return check_engines(scene, ("reduced", "mujoco"), settings)


def test_a_failed_engine_s_run_travels_with_its_failure(failed_part_way, tmp_path, saved_figures):
    """Issue: MJX, failed on loop drift at t = 1.012 s, printed no known defect under its line,
    report.json had known_defects [] and engines.png said "did not run" though it ran to 1.012 s.
    Engine-generic, shown with MuJoCo failed by its own gate: the verdict keeps the run and the
    failure's time; its known defects (here one given to the run, MuJoCo C has none) are printed
    under the failure and written to report.json; engines.png draws its |Δq̇| up to the failure.
    (Planted: check_engines dropping the run fails each part.)"""
    import dataclasses

    from loopcheck.compare.plots import plot_engines
    from loopcheck.compare.report import engines_report

    (v,) = failed_part_way.verdicts
    assert v.comparison is None and "constraint-drift" in v.failure
    assert v.partial is not None and v.partial.engine == "mujoco"
    assert v.failed_at == pytest.approx(0.496, abs=1e-9) and v.partial.trajectory.t[-1] >= v.failed_at
    defect = "a known defect of this engine (test)"
    check = dataclasses.replace(failed_part_way, verdicts=(dataclasses.replace(
        v, partial=dataclasses.replace(v.partial, caveats=(defect,))),))
    lines = engines_lines(check)
    at = next(k for k, line in enumerate(lines) if "constraint-drift" in line)
    assert lines[at + 1].strip() == f"known defect: {defect}"
    (entry,) = engines_report(None, check)
    assert entry["known_defects"] == [defect] and entry["failed_at"] == v.failed_at and not entry["passed"]
    plot_engines(check, tmp_path / "engines.png")
    (fig,) = saved_figures
    (line,) = [l for l in fig.axes[0].get_lines() if len(l.get_xdata()) > 2]
    t = np.asarray(line.get_xdata())
    assert t[-1] <= v.failed_at and t[-1] > v.failed_at - 0.01  # up to the failure, its samples 1 ms apart
    assert np.nanmax(line.get_ydata()) < 1e-3  # |Δq̇| before the loops opened: a real curve (measured 2.4e-4 rad/s)
    legend = [text.get_text() for text in fig.axes[0].get_legend().get_texts()]
    assert legend[0].startswith("MuJoCo: FAILED at t = 0.496 s") and "did not run" not in legend[0]


def test_an_engine_that_did_not_run_has_a_verdict_and_no_comparison():
    """check.comparison(name) of an engine that did not run says why in one line (planted: returning
    the verdict's None comparison fails); an engine not judged is a KeyError naming those judged."""
    import dataclasses

    from loopcheck.compare.engines import EnginesCheck, EngineVerdict
    from loopcheck.reduced import ReducedSettings, simulate

    scene = dataclasses.replace(load_scene("scenes/seed_fourbar.toml"), horizon=0.05)
    reference = simulate(scene, ReducedSettings())
    refused = EngineVerdict("mjx", scene.tolerances, None, "refused: MJX does not run point forces")
    check = EnginesCheck(scene, reference, (refused,), None, {})
    assert check.engines == ("reduced", "mjx") and not check.passed and check.verdict("mjx") is refused
    with pytest.raises(ValueError, match=r"^mjx has no comparison: refused: MJX does not run point forces$"):
        check.comparison("mjx")
    with pytest.raises(KeyError, match="'pin' was not judged in this check .judged: mjx."):
        check.verdict("pin")


def test_check_engines_says_when_each_engine_starts_and_ends(tmp_path):
    """Long engine runs talk (issue 39): `check --engines` prints on stderr a line when each engine
    starts and one when it ends, with its time and verdict; -q silences them (planted: no lines). Run
    as the command (a process of its own: the loggers as a user's shell has them)."""
    import subprocess
    import sys

    from helpers import SEED_SCENE

    # from a folder of its own: the installed loopcheck, not a checkout's folder on the path
    argv = [sys.executable, "-m", "loopcheck.compare.cli", "check", str(SEED_SCENE), "--engines", "reduced,mujoco",
            "--horizon", "0.2"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    err = done.stderr.splitlines()
    assert len(err) == 4 and err[0] == "loopcheck: seed_fourbar: reduced started (the reference)", err
    assert err[1].startswith("loopcheck: seed_fourbar: reduced ended in ") and err[1].endswith(" s")
    assert err[2] == "loopcheck: seed_fourbar: mujoco started"
    assert err[3].startswith("loopcheck: seed_fourbar: mujoco ended in ") and err[3].endswith(" s (passed)")
    quiet = subprocess.run([argv[0], *argv[1:3], "-q", *argv[3:]], capture_output=True, text=True, timeout=120,
                           cwd=tmp_path)
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_with_several_inputs_the_outlier_is_farthest_on_any_input():
    """Two inputs, each engine's peak relative to the reference's of that input: 'b' agrees on the
    first and is 1e-2 off on the second, 'c' is 1e-4 off on the first and agrees on the second; 'b' is
    named. (Planted: the first input alone names 'c'.)"""
    from loopcheck.compare.engines import farthest_from_the_others

    first = {"reduced": 1.0, "a": 1.0, "b": 1.0, "c": 1.0001}
    second = {"reduced": 1.0, "a": 1.0, "b": 1.01, "c": 1.0}
    assert farthest_from_the_others([first, second]) == "b"
    assert farthest_from_the_others([first]) == "c"
