"""`loopcheck check model.xml` on a model of several DOF (issue 41): the check's figures and advice
over every input, naming the coordinate whose difference fails.

The model: tests/data/mjcf/two_finger_gripper.xml (3 DOF: two five-bar fingers, coupled knuckles,
a servo on a fixed tendon, sprung fingertips), as written (implicitfast at 0.5 ms, soft loops),
against the reduced reference of several DOF (DOP853 at its default rtol 1e-12).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import loopcheck
from loopcheck.compare.run import judge
from loopcheck.reference_models.mjcf_import import import_mjcf
from loopcheck.reference_models.model_check import MARGIN, check_lines, check_model
from loopcheck.scene import Tolerances

GRIPPER = Path(__file__).parent.parent / "data" / "mjcf" / "two_finger_gripper.xml"
HORIZON = 0.1  # the differences arise in the first 40 ms (the fingertips' peak at 18 ms)


@pytest.fixture(scope="module")
def imported():
    return import_mjcf(GRIPPER, horizon=HORIZON)


@pytest.fixture(scope="module")
def fine(imported):
    """The reduced reference of the imported scene (what ``check`` compares with)."""
    return loopcheck.simulate(imported.scene, loopcheck.ReducedSettings())


def test_the_advice_names_only_the_coordinates_that_fail(imported, fine):
    """With tolerances the knuckle meets (peak_omega_rtol 1e-3, q_atol 2.5e-3 rad; measured: the
    knuckle's peak 4.7e-4 off and its q 2.0e-3 rad; the fingertips' peaks 5.1e-3 off and q̇ 0.12
    rad/s), the failures and the advice name the two fingertips, and not the knuckle; the figures
    are the worst input's, named."""
    tolerances = Tolerances(peak_omega_rtol=1e-3, q_atol=2.5e-3)
    check = check_model(imported, fine, judge, tolerances=tolerances)
    assert not check.passed
    lines = check_lines(check, "gripper.xml")
    text = "\n".join(lines)
    assert "inputs 'right_knuckle_joint', 'right_tip_joint', 'left_tip_joint'" in lines[0]
    failures = check.as_written.comparison.gate.failures
    assert failures and all(f.startswith(("right_tip_joint: ", "left_tip_joint: ")) for f in failures)
    (advice,) = [line for line in lines if "the coordinate whose difference fails" in line]
    assert "'right_tip_joint', 'left_tip_joint'" in advice and "right_knuckle_joint" not in advice.split("(")[0]
    # the fingertips are mirror images: either may be the worst by round-off
    assert re.search(r"as written:        worst input '(right|left)_tip_joint': peak", text)
    # every input's excess, the knuckle's below 1, the fingertips' (mirror images) above
    knuckle, right, left = check.as_written.excesses
    assert knuckle < 1.0 < right and right == pytest.approx(left, rel=1e-6)
    # the suggestion has its margin on every input (each difference at most half its tolerance), at its step and half
    assert check.cheapest is not None
    assert max(check.cheapest.excesses) <= MARGIN and max(check.cheapest_half.excesses) <= MARGIN


def test_a_reference_that_does_not_move_is_refused_over_every_input(imported, fine):
    """The vacuous-check refusal looks at every input: the gripper's knuckle alone moves less than
    the fingertips, and a check whose q_atol and omega_atol exceed the knuckle's motion but not the
    fingertips' still runs (their motion counts)."""
    knuckle = fine.trajectory
    moved = float(abs(knuckle.q - knuckle.q[0]).max())
    fastest = float(abs(knuckle.qdot).max())
    tips = max(float(abs(t.qdot).max()) for t, _ in fine.other_inputs)
    assert tips > fastest  # the premise: the fingertips are faster than the knuckle
    tolerances = Tolerances(q_atol=2 * moved, omega_atol=0.5 * (fastest + tips))
    check = check_model(imported, fine, judge, tolerances=tolerances)  # no VacuousCheck raised
    assert check.as_written.comparison is not None


def test_check_against_the_reduced_reference(imported):
    """The check as the command runs it (the comparison's own reduced reference): the model as
    written fails on every input, the advice names them, and the cheapest options found pass with
    margin (measured over 1 s: as written 51× the tolerance on the fingertips' peak; RK4 at 2 ms with
    stiff loops within 0.14 of every tolerance)."""
    from loopcheck.compare.model_check import check_model as check_with_reference

    check = check_with_reference(imported)
    lines = check_lines(check, "gripper.xml")
    assert not check.passed and any("the coordinate whose difference fails: 'right_knuckle_joint', 'right_tip_joint', "
                                    "'left_tip_joint'" in line for line in lines)
    assert check.cheapest is not None and check.cheapest.with_margin


def test_cli_check_of_the_gripper_fails_naming_the_coordinates(tmp_path, capsys, monkeypatch):
    """`loopcheck check two_finger_gripper.xml --horizon 0.05`: exit 1, every input's failures and
    the line naming the coordinates whose difference fails."""
    from loopcheck.compare.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["check", str(GRIPPER), "--horizon", "0.05"]) == 1
    printed = capsys.readouterr().out
    assert "FAIL" in printed and "right_tip_joint: peak_omega_abs" in printed
    assert "the coordinate whose difference fails: 'right_knuckle_joint', 'right_tip_joint', 'left_tip_joint'" in printed
