"""`loopcheck check model.xml`: a user's MuJoCo model as written against the exact solution, the cause
of the difference, and options that fix it (checked by pasting them into the file)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from loopcheck.compare.model_check import check_model
from loopcheck.reference_models.mjcf_import import Control, import_mjcf
from loopcheck.reference_models.user_model import ModelOptions, run_model

DATA = Path(__file__).parent.parent / "data" / "mjcf"
SEED_PULSE = Control((0.0, 1.0), (250.0, 0.0))


def _pasted(path: Path, snippet: str, out: Path) -> Path:
    """The model with the check's MJCF snippet pasted in, as a user would: the snippet's
    <option> attributes over the model's, its <default> entries into the model's top default."""
    root = ET.parse(path).getroot()
    pasted = ET.fromstring(f"<snippet>{snippet}</snippet>")
    option = root.find("option")
    if option is None:
        option = ET.SubElement(root, "option")
    option.attrib.update(pasted.find("option").attrib)
    default = root.find("default")
    if default is None:
        default = ET.Element("default")
        root.insert(0, default)
    for element in pasted.find("default"):
        default.append(element)
    out.write_text(ET.tostring(root, encoding="unicode"))
    return out


def test_mujoco_defaults_open_the_loop_and_the_suggested_options_close_it(tmp_path):
    """The seed's four-bar with MuJoCo's default softness (solref 0.02 1, solimp 0.9 0.95 ...) at
    RK4 1 ms: the peak is 3.2 % off and the loop opens by 3 mm (measured 3.18e-2, 2.96e-3 m);
    stiff loops alone bring it within the gate, a tenth of the step alone does not, so the
    softness is named. The options suggested, pasted into the file, pass the gate."""
    imported = import_mjcf(DATA / "fourbar_xz_degrees.xml", control=SEED_PULSE, horizon=2.0)
    check = check_model(imported)
    assert not check.passed
    assert check.as_written.comparison.diff.peak_omega_rel > 0.01
    assert check.as_written.comparison.other.constraint_violation.max > 1e-3
    assert check.stiff_loops.passed and not check.smaller_step.passed
    assert check.cause.startswith("the loops' softness")
    assert check.cheapest is not None and check.cheapest.passed

    fixed = _pasted(DATA / "fourbar_xz_degrees.xml", check.cheapest.options.mjcf(), tmp_path / "fixed.xml")
    again = import_mjcf(fixed, control=SEED_PULSE, horizon=2.0)
    assert ModelOptions.as_written(again.model) == check.cheapest.options
    recheck = check_model(again)
    assert recheck.passed and recheck.cheapest is recheck.as_written


def test_a_coarse_euler_step_is_named(tmp_path):
    """Stiff loops but Euler at 4 ms: the peak is 5 % off (measured 5.03e-2); stiffening the loops
    changes nothing, a tenth of the step removes most of it (4.4e-3 off; not all: the loops' time
    constant, 8 ms, is then 20 steps), so the timestep is named first."""
    text = (DATA / "fourbar_sites_keyframe.xml").read_text()
    text = text.replace('<option timestep="0.001" integrator="RK4" gravity="0 0 0"/>',
                        '<option timestep="0.004" integrator="Euler" gravity="0 0 0"/>')
    text = text.replace("<default>", '<default><equality solref="0.008 1" solimp="0.9999 0.9999 0.001 0.5 2"/>', 1)
    path = tmp_path / "coarse.xml"
    path.write_text(text)
    check = check_model(import_mjcf(path, keyframe="assembled", control=SEED_PULSE, horizon=2.0))
    assert not check.passed and check.cause.startswith("both the timestep")
    assert "a smaller step removes more" in check.cause
    assert check.smaller_step.excess < check.as_written.excess / 5
    assert check.cheapest.passed and check.cheapest.options.timestep < 0.004


def test_the_run_as_written_changes_nothing_but_the_energy_flag():
    """The model's own options, read back from the run's settings; its energy audit closes for
    stiff loops (measured 1.05e-3 of the energy scale at 1 ms, asserted 5e-3)."""
    imported = import_mjcf(DATA / "fourbar_xz_degrees.xml", control=SEED_PULSE, horizon=2.0)
    written = ModelOptions.as_written(imported.model)
    assert (written.integrator, written.timestep, written.solref, written.solimp) == (
        "rk4", 0.001, ((0.02, 1.0),), ((0.9, 0.95, 0.001, 0.5, 2.0),))
    result = run_model(imported, written.stiff_loops())
    assert result.audit.relative_residual < 5e-3
    assert result.settings == written.stiff_loops()


def test_cli_check_of_a_model(tmp_path, capsys):
    from loopcheck.compare.cli import main

    code = main(["check", str(DATA / "fourbar_xz_degrees.xml"), "--ctrl", "0:250,1:0", "--horizon", "2"])
    out = capsys.readouterr().out
    assert code == 1
    assert "the difference comes from: the loops' softness" in out
    # stiff loops pass at the model's 1 ms and at 2 ms (half the work), not at 4 ms
    assert '<option integrator="RK4" timestep="0.002"/>' in out
    assert '<default><equality solref="0.004 1" solimp="0.9999 0.9999 0.001 0.5 2"/></default>' in out
    assert out.strip().endswith("0 passed, 1 failed")


@pytest.mark.parametrize("flag", [["--keyframe", "nope"], ["--input", "nope"]])
def test_cli_check_of_a_model_refuses_bad_flags(flag, capsys):
    from loopcheck.compare.cli import main

    assert main(["check", str(DATA / "fourbar_xz_degrees.xml"), *flag]) == 2
    assert "'nope'" in capsys.readouterr().err


def test_cli_run_of_a_model_writes_the_report(tmp_path, capsys):
    """`loopcheck run model.xml`: the table of the reduced solution and the model as written, the
    diagnosis under it, and the report folder (report.json names the model's options)."""
    import json

    from loopcheck.compare.cli import main

    out = tmp_path / "report"
    code = main(["run", str(DATA / "fourbar_xz_degrees.xml"), "--ctrl", "0:250,1:0", "--horizon", "2", "-o", str(out)])
    text = capsys.readouterr().out
    assert code == 1 and "the difference comes from: the loops' softness" in text
    report = json.loads((out / "report.json").read_text())
    assert report["mujoco"]["settings"]["solref"] == [[0.02, 1.0]] and not report["gate"]["passed"]


def test_mujocos_own_defaults_need_both_changes(tmp_path):
    """No <option> at all (Euler at 2 ms) and MuJoCo's default softness: the errors partly cancel
    in the peak (measured 2.84e-3 off, the loop 13.8 mm open), and neither change alone meets the
    gate (stiff loops 9.0e-4 off, a tenth of the step 3.4e-2): both are named, stiffer loops first."""
    text = (DATA / "fourbar_xz_degrees.xml").read_text().replace(
        '<option timestep="0.001" integrator="RK4" gravity="0 0 0"/>', '<option gravity="0 0 0"/>')
    path = tmp_path / "defaults.xml"
    path.write_text(text)
    check = check_model(import_mjcf(path, control=SEED_PULSE, horizon=2.0))
    assert check.as_written.options.integrator == "euler" and check.as_written.options.timestep == 0.002
    assert not (check.passed or check.stiff_loops.passed or check.smaller_step.passed)
    assert check.cause.startswith("both the loops' softness") and "stiffer loops remove more" in check.cause
    assert check.cheapest.passed


def test_cli_check_goes_on_after_a_reference_that_fails(tmp_path, capsys):
    """A model whose reduced reference fails (RKN4 at 0.1 s misses its own error bound) is one
    FAIL line, and the next model is still checked."""
    from loopcheck.compare.cli import main

    other = tmp_path / "other.xml"
    other.write_text((DATA / "fourbar_xz_degrees.xml").read_text())
    code = main(["check", str(DATA / "fourbar_xz_degrees.xml"), str(other),
                 "--ctrl", "0:250,1:0", "--horizon", "2", "--reference-method", "rkn4", "--reference-step", "0.1"])
    out = capsys.readouterr().out
    assert code == 1 and out.count("FAIL  ") == 2 and "numerical failure of the reduced reference" in out


def test_a_legal_model_gets_its_verdict_when_the_smaller_step_trial_is_past_its_budget(monkeypatch):
    """A run may take 5000 steps here (MAX_STEPS lowered for the test): the model as written (500
    steps at 1 ms over 0.5 s) is legal, its timestep / 10 trial (5000 steps... 5001 with the
    limit at 4000) is not: the check gives the verdict and notes the trial as skipped (planted
    without the trials' budget: run_model's ValueError names the trial's step, not the model's)."""
    import loopcheck.reference_models.model_check as model_check
    import loopcheck.reference_models.user_model as user_model

    monkeypatch.setattr(user_model, "MAX_STEPS", 4000)
    monkeypatch.setattr(model_check, "MAX_STEPS", 4000)
    imported = import_mjcf(DATA / "fourbar_sites_keyframe.xml", keyframe="assembled", control=SEED_PULSE, horizon=0.5)
    check = check_model(imported)
    assert check.as_written.comparison is not None
    assert check.smaller_step.comparison is None and check.smaller_step.failure is None
    assert check.smaller_step.skipped.startswith("skipped: 5e+03 steps at 0.0001 s, more than this trial's budget of "
                                                 "4e+03 steps")
    lines = model_check.diagnosis_lines(check)
    assert any("timestep / 10:" in line and "skipped" in line for line in lines)
    assert "skipped" in check.cause or check.cause.startswith("the loops' softness")


def test_the_cheapest_search_costs_rk4_four_evaluations_a_step(tmp_path):
    """Every trial's cost is its steps × 4 for RK4, × 1 for Euler and the implicit integrators, and
    the cheapest options found are the fewest evaluations among the passing trials (planted with
    RK4 costed as one evaluation a step: the RK4 trials' costs are a quarter). The seed's four-bar
    by Euler at 1 ms with MuJoCo's default loop softness: both integrators are searched."""
    path = tmp_path / "euler.xml"
    path.write_text((DATA / "fourbar_sites_keyframe.xml").read_text().replace('integrator="RK4"', 'integrator="Euler"'))
    imported = import_mjcf(path, keyframe="assembled", control=SEED_PULSE, horizon=0.5)
    check = check_model(imported)
    ran = [t for t in check.tried if t.comparison is not None]
    assert any(t.options.integrator == "rk4" for t in ran) and any(t.options.integrator != "rk4" for t in ran)
    for t in ran:
        assert t.evaluations == t.comparison.other.n_steps * (4 if t.options.integrator == "rk4" else 1)
    assert check.cheapest is not None
    assert check.cheapest.evaluations == min(t.evaluations for t in ran if t.passed)


CRANK_ROCKER = DATA / "crank_rocker_keyframe.xml"  # its only load: the keyframe 'home''s ctrl, 2 N·m


def test_a_keyframe_only_load_is_checked_loaded(capsys):
    """Without --keyframe, the model's only keyframe is read and its ctrl drives the check (the
    exact peak is 120.756 rad/s at 0.2 s); before, the check ran unloaded: "ok ... peak 0 rad/s"."""
    from loopcheck.compare.cli import main

    code = main(["check", str(CRANK_ROCKER), "--horizon", "0.2"])
    out = capsys.readouterr().out
    assert "read at keyframe 'home', the model's only keyframe" in out
    assert code == 1 and "peak 120.756" in out  # Euler at 2 ms with soft loops misses it by 36 %


@pytest.mark.parametrize("flags", [["--qpos0"], ["--ctrl", "1e-9"]])
def test_a_check_that_does_not_move_is_refused(flags, capsys):
    """At rest with no load (--qpos0), or a load too small to move the crank by q_atol or to
    omega_atol in 0.2 s: the gate could not see any difference, so the check is refused (exit 2),
    naming --ctrl and --keyframe, before MuJoCo runs: one line on stderr, nothing on stdout (planted:
    the keyframe's note printed before the check, as it was)."""
    from loopcheck.compare.cli import main

    assert main(["check", str(CRANK_ROCKER), "--horizon", "0.2", *flags]) == 2
    captured = capsys.readouterr()
    error = captured.err.splitlines()
    assert len(error) == 1 and "does not move" in error[0] and "--ctrl" in error[0] and "--keyframe" in error[0]
    assert captured.out == ""


def test_the_refusal_needs_both_q_and_its_rate_within_the_tolerances():
    """The refusal needs both: a model whose rate passes omega_atol is checked even when q barely
    moves (a small load, omega_atol lowered under its peak)."""
    from loopcheck.reference_models.model_check import VacuousCheck, refuse_vacuous
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.scene import Tolerances

    imported = import_mjcf(CRANK_ROCKER, control=Control.constant(1e-6), horizon=0.2)
    reference = simulate(imported.scene, ReducedSettings())
    fastest = float(np.max(np.abs(reference.trajectory.qdot)))
    with pytest.raises(VacuousCheck):
        refuse_vacuous(reference, Tolerances(), "m", "rad")
    refuse_vacuous(reference, Tolerances(omega_atol=0.5 * fastest), "m", "rad")  # sees the rate: not refused
