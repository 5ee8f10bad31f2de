"""``loopcheck check model.xml --loop NAME`` (issue 38): the check of a loop cut out of a robot is the
check of the same loop written alone (tests/loop_robots.py).

Tolerance: the same verdict, every figure within 1e-6 relative (the issue's decision: MuJoCo in a
tilted plane differs from MuJoCo in z = 0 by round-off; the figures printed agree to every digit).
A figure is a difference (MuJoCo's peak less the exact one): it is judged against the size of what
it measures (the peak, the horizon, max |q|), since the stiff loops' differences are small (5.8e-4
rad/s of a 48.8 rad/s peak: its round-off, 1e-9, is 2e-6 of the difference but 2e-11 of the peak);
the model as written's, large, are also within 1e-6 of themselves (but the peak times' difference).
"""

from __future__ import annotations

import json

import pytest

from loopcheck.compare.cli import main
from loopcheck.compare.model_check import check_model
from loopcheck.reference_models.extract import CHECK_SCOPE, import_loop
from loopcheck.reference_models.mjcf_import import import_mjcf

import loop_robots as robots

HORIZON = 0.2


def _robot(tmp_path, which: str):
    if which == "leg":
        robot, alone = robots.floating_leg(), robots.loop_alone(robots.LEG_NORMAL, robots.LEG_KEY_CTRL[-1])
    else:
        robot, alone = robots.finger_arm(), robots.loop_alone(robots.ARM_NORMAL, robots.ARM_KEY_CTRL[-1], prefix="f_")
    (tmp_path / f"{which}.xml").write_text(robot)
    (tmp_path / "alone.xml").write_text(alone)
    return tmp_path / f"{which}.xml", tmp_path / "alone.xml"


@pytest.mark.parametrize("which,loop", [("leg", "foot_loop"), ("arm", "f_crank")])
def test_the_check_of_the_extracted_loop_is_the_check_of_the_loop_alone(which, loop, tmp_path):
    robot, alone = _robot(tmp_path, which)
    a = check_model(import_loop(robot, [loop], horizon=HORIZON)[0])
    b = check_model(import_mjcf(alone, horizon=HORIZON))
    assert a.passed == b.passed
    for trial_a, trial_b in ((a.as_written, b.as_written), (a.stiff_loops, b.stiff_loops)):
        ca, cb = trial_a.comparison, trial_b.comparison
        fa, fb = ca.diff.figures(), cb.diff.figures()
        assert fa.keys() == fb.keys()
        peak, horizon = cb.diff.peak_omega_reference, HORIZON
        q_size = float(abs(cb.reference.trajectory.q).max())
        for key in fa:  # each figure against the size of what it measures (a difference of peaks: the peak)
            scale = (horizon if key.startswith(("t_", "span", "horizon")) else 1.0 if key == "peak_omega_rel"
                     else q_size if key.startswith("q_") else peak)
            assert abs(fa[key] - fb[key]) <= 1e-6 * scale, key
            if trial_a is a.as_written and key != "t_peak_abs":  # large differences: relative to themselves too
                assert fa[key] == pytest.approx(fb[key], rel=1e-6), key
        assert ca.other.peak.omega == pytest.approx(cb.other.peak.omega, rel=1e-6)
    assert (a.cheapest is None) == (b.cheapest is None)


def test_check_loop_prints_what_was_welded_dropped_and_the_plane(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "arm")
    out = tmp_path / "finger.xml"
    status = main(["check", str(robot), "--loop", "connect #1 (f_coupler–f_rocker)", "--horizon", str(HORIZON),
                   "--write-submodel", str(out)])
    printed = capsys.readouterr().out
    assert status == 1  # MuJoCo's default softness misses the tolerances, as for the loop alone
    assert CHECK_SCOPE in printed
    assert "dropped: actuator 'elbow_servo' (on welded joint 'elbow')" in printed
    assert "welded at the configuration read: joint 'shoulder' at 0.5 rad; joint 'elbow' at -0.3 rad" in printed
    assert "plane: normal (-0.409852, 0.717242, 0.563547)" in printed
    # the written model loads on its own and is the one the check ran
    assert 'name="finger_motor"' in out.read_text() and "elbow_servo" not in out.read_text()
    assert main(["check", str(out), "--horizon", str(HORIZON)]) == 1
    assert "peak 34.82845712 rad/s" in capsys.readouterr().out


def test_write_submodel_never_overwrites_the_input(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "leg")
    before = robot.read_text()
    assert main(["check", str(robot), "--loop", "foot_loop", "--write-submodel", str(robot)]) == 2
    assert robot.read_text() == before
    assert "--write-submodel" in capsys.readouterr().err


def test_two_outputs_naming_one_file_are_refused_before_any_work(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "leg")
    same = tmp_path / "same.toml"
    assert main(["import-mjcf", str(robot), "--loop", "foot_loop", "--write-submodel", str(same),
                 "-o", str(same)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "name the same file" in err and "--write-submodel" in err
    assert not same.exists()
    link = tmp_path / "link.toml"
    link.symlink_to(same)  # a link to a file not there yet: the same file once written
    assert main(["import-mjcf", str(robot), "--loop", "foot_loop", "--write-submodel", str(link),
                 "-o", str(tmp_path / "." / "same.toml")]) == 2
    assert "name the same file" in capsys.readouterr().err
    assert not same.exists()


def test_refusals_are_one_line(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "leg")
    assert main(["check", str(robot), "--loop", "nowhere"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "--loop nowhere: no connect, joint coupling or loop body of that name closes a loop" in err
    assert main(["check", str(robot), "--write-submodel", str(tmp_path / "x.xml")]) == 2
    assert "give --loop" in capsys.readouterr().err
    assert not (tmp_path / "x.xml").exists()


def test_run_loop_writes_the_extraction_in_report_json(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "leg")
    out = tmp_path / "report"
    main(["run", str(robot), "--loop", "foot_loop", "--horizon", "0.05", "-o", str(out)])
    printed = capsys.readouterr().out
    assert f"scene: leg ({robot} --loop foot_loop); input crank_j" in printed  # the user's model, not a temporary file
    assert "loopcheck-loop" not in printed and "leg.loop.xml" not in printed
    report = json.loads((out / "report.json").read_text())
    assert report["scene"]["source"].endswith("leg.xml --loop foot_loop")
    assert report["scene"]["description"] == "imported from leg.xml (--loop foot_loop)"
    assert "loopcheck-loop" not in (out / "report.json").read_text()
    ext = report["extraction"]
    assert ext["check"] == CHECK_SCOPE
    assert ext["dropped"] == ["actuator 'hip_motor' (on welded joint 'hip')",
                              "actuator 'knee_motor' (on welded joint 'knee')"]
    assert ext["mass"] == [{"body": "pad", "welded_to": "rocker"}]
    assert [w.split(" at ")[0] for w in ext["welded"]] == ["joint 'root'", "joint 'hip'", "joint 'knee'",
                                                           "joint 'pad_j'"]


def test_a_control_for_a_dropped_actuator_says_it_was_dropped(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "leg")
    assert main(["check", str(robot), "--loop", "foot_loop", "--ctrl", "hip_motor=1"]) == 2
    assert "--loop dropped actuator 'hip_motor': it acts outside the loop" in capsys.readouterr().err
    out = tmp_path / "leg.toml"
    assert main(["import-mjcf", str(robot), "--loop", "foot_loop", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "read at keyframe 'stance', the model's only keyframe" in printed  # said, as for any model
    assert "dropped: actuator 'hip_motor'" in printed and out.is_file()


def test_an_input_the_extraction_welded_says_so(tmp_path, capsys):
    """--input names a joint --loop welded (the leg's hip): the refusal says the extraction welded it
    (planted: the import's "not a joint of the model" alone, of a joint the user's file has)."""
    robot, _ = _robot(tmp_path, "leg")
    assert main(["check", str(robot), "--loop", "foot_loop", "--input", "hip"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(--loop welded joint 'hip': the input is one of the loop's joints)" in err


def test_check_assemble_prints_the_moves(tmp_path, capsys):
    robot, _ = _robot(tmp_path, "leg")
    text = robot.read_text()
    start = text.index('qpos="', text.index("<key ")) + len('qpos="')
    end = text.index('"', start)
    words = text[start:end].split()
    words[11] = "0.002"  # rocker_j: the foot loop open by 6e-5 m
    robot.write_text(text[:start] + " ".join(words) + text[end:])
    assert main(["check", str(robot), "--loop", "foot_loop", "--horizon", "0.05"]) == 2
    assert "--assemble closes them by Newton" in capsys.readouterr().err
    out = tmp_path / "foot.xml"
    assert main(["check", str(robot), "--loop", "foot_loop", "--horizon", "0.05", "--assemble",
                 "--write-submodel", str(out)]) in (0, 1)
    printed = capsys.readouterr().out
    assert "assembled (--assemble): loops open by 6.08e-05" in printed
    assert "with joint 'crank_j' held at 0; it moved joint 'rocker_j' by -0.002 rad" in printed
    # the written model's keyframe is the assembled state: it is read closed, without --assemble
    assert main(["check", str(out), "--horizon", "0.05"]) in (0, 1)
    assert "loops closed to" in capsys.readouterr().out
