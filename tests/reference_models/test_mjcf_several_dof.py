"""MJCF models of several degrees of freedom (issue 41): `import-mjcf`, `--loop`, `--ctrl` per
actuator and MuJoCo's run of the model as written.

The model: tests/data/mjcf/two_finger_gripper.xml, written by hand in the style of a Menagerie
gripper (not copied from one): two five-bar fingers, the knuckles coupled by a joint equality, a
position servo on a fixed tendon over both knuckles, the fingertips' joints held by springs. Its
DOF (3) are counted by hand in the file: 2 per five-bar finger, less the coupling.
Oracles: that count, the model's mirror symmetry (the left finger's coordinates are the right's,
negated: its joints turn about −x), the loop equations (the rates the import reads keep them closed)
and the reduced engine's energy balance.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pytest

import loopcheck
from loopcheck import kinematics as loops
from loopcheck.reference_models.extract import import_loop
from loopcheck.reference_models.mjcf_import import Control, MjcfError, import_mjcf
from loopcheck.reference_models.user_model import run_model

GRIPPER = Path(__file__).parent.parent / "data" / "mjcf" / "two_finger_gripper.xml"
INPUTS = ("right_knuckle_joint", "right_tip_joint", "left_tip_joint")


@pytest.fixture(scope="module")
def gripper():
    return import_mjcf(GRIPPER)


def test_the_gripper_has_three_dof_and_says_how_its_inputs_were_chosen(gripper):
    """3 DOF by the rank of the loop equations (two five-bars, one coupling); the inputs: the
    servo's first knuckle (its tendon's first joint), the other knuckle left out (the coupling ties
    it), then the two fingertips by coordinate partitioning; the choice is said, one line each."""
    scene = gripper.scene
    assert scene.dof == 3 and scene.inputs == INPUTS
    system = loops.compile_linkage(scene.mechanism.linkage)
    assert loops.rank_dof(loops.all_constraints(system, np.asarray(scene.x0))[1]) == 3
    said = "\n".join(gripper.said)
    assert "3 degrees of freedom (the rank of the loop equations at keyframe 'grasp')" in said
    assert "driven by an actuator: 'right_knuckle_joint' (actuator 'servo' through tendon 'split')" in said
    assert "a coupling or a loop ties it): 'left_knuckle_joint'" in said
    assert "coordinate partitioning (pivoted QR on the loop Jacobian among the joints' own coordinates): " \
           "'right_tip_joint', 'left_tip_joint'" in said
    # what the gripper holds: the coupling, the springs on the fingertips, the servo on the tendon
    mech = scene.mechanism
    assert [(c.joint, c.driver) for c in mech.linkage.couplings] == [("left_knuckle_joint", "right_knuckle_joint")]
    springs = {e.joint: e.coefficient for e in mech.joint_elements if e.kind == "spring"}
    assert springs == {"right_tip_joint": 0.015, "left_tip_joint": 0.015}
    (servo,) = mech.actuators
    # l = ½ qpos_right + ½ qpos_left; the left knuckle's scene coordinate is −qpos (its joint turns about −x)
    assert servo.name == "servo" and dict(servo.tendon) == {"right_knuckle_joint": 0.5, "left_knuckle_joint": -0.5}
    assert scene.load is None and scene.initial_qdot() == (0.0, 0.0, 0.0)


def _with_key(tmp_path, qvel) -> Path:
    path = tmp_path / "gripper.xml"
    path.write_text(GRIPPER.read_text().replace('qpos="0 0 0 0 0 0 0 0"',
                                                 f'qpos="0 0 0 0 0 0 0 0" qvel="{" ".join(repr(float(v)) for v in qvel)}"'))
    return path


def test_every_input_rate_comes_from_the_keyframe_qvel(gripper, tmp_path):
    """A keyframe whose qvel moves the gripper with input rates (2, −0.7, 0.4) rad/s (the joints'
    qvel from ẋ = K q̇, K by the loop equations): the import reads those rates back, every one, to
    round-off (1e-13 rad/s: the qvel is written to 17 digits), with no warning; a qvel that opens the
    loops is said."""
    scene = gripper.scene
    system = loops.compile_linkage(scene.mechanism.linkage)
    rates = (2.0, -0.7, 0.4)
    xdot = loops.input_rates(system, np.asarray(scene.x0), rates)
    qvel = np.linalg.solve(gripper.qpos_map, xdot)  # x = x_read + T (qpos − qpos_read): T square here (8 hinges)
    imported = import_mjcf(_with_key(tmp_path, qvel))
    assert imported.scene.initial_qdot() == pytest.approx(rates, abs=1e-13)
    assert not any("qvel" in w for w in imported.warnings)
    opened = qvel.copy()
    opened[0] += 1.0  # the right knuckle alone
    imported = import_mjcf(_with_key(tmp_path, opened))
    assert any("qvel does not keep the loops closed" in w and "the inputs' do not reproduce" in w
               for w in imported.warnings)


def test_input_names_the_inputs_in_order_and_refuses_a_dependent_one(tmp_path):
    imported = import_mjcf(GRIPPER, input_joint="left_rocker_joint,right_knuckle_joint")
    assert imported.scene.inputs[:2] == ("left_rocker_joint", "right_knuckle_joint")
    assert imported.scene.dof == 3 and "named by --input: 'left_rocker_joint', 'right_knuckle_joint'" in \
        "\n".join(imported.said)
    with pytest.raises(MjcfError, match="--input 'left_knuckle_joint' moves with the inputs named before it"):
        import_mjcf(GRIPPER, input_joint="right_knuckle_joint,left_knuckle_joint")


def test_ctrl_sets_the_servo_by_name(tmp_path):
    imported = import_mjcf(GRIPPER, controls={"servo": Control((0.0, 0.1), (0.7, 0.2))})
    (servo,) = imported.scene.mechanism.actuators
    np.testing.assert_array_equal(servo.control.sample(np.array([0.0, 0.05, 0.1, 0.5])), [0.7, 0.7, 0.2, 0.2])
    with pytest.raises(MjcfError, match="--ctrl motor=...: the model has no actuator 'motor'"):
        import_mjcf(GRIPPER, controls={"motor": Control.constant(1.0)})


def test_the_model_as_written_runs_in_mujoco_with_every_input(gripper):
    """MuJoCo runs the file as written (0.1 s, 200 steps): every input is recorded, and the mirror
    symmetry holds: the left fingertip's q is the right's negated (its joint turns about −x), to
    1e-9 rad (measured 0 to 1e-12: MuJoCo's solver sees the same numbers on both sides)."""
    imported = dataclasses.replace(gripper, scene=dataclasses.replace(gripper.scene, horizon=0.1))
    result = run_model(imported)
    assert len(result.inputs) == 3
    right_tip, left_tip = result.other_inputs[0][0], result.other_inputs[1][0]
    assert np.max(np.abs(right_tip.q)) > 0.05  # the servo closes the fingers: the tips turn
    np.testing.assert_allclose(right_tip.q, -left_tip.q, rtol=0, atol=1e-9)
    assert result.other_inputs[0][1].omega == pytest.approx(-result.other_inputs[1][1].omega, abs=1e-8)
    # the first input is the right knuckle, which the servo drives towards its target 0.4 rad
    assert 0.2 < float(result.trajectory.q[-1]) < 0.8


def test_the_gripper_balances_its_energy_in_the_reduced_engine(gripper):
    """The imported gripper under the reduced engine (DOP853, rtol 1e-12) over 0.3 s: its energy
    balance holds to 1e-9 relative (the issue's target; measured 6.3e-13 over 1 s, no coordinate
    switch), and its fingertips' peaks are mirror images."""
    run = loopcheck.simulate(dataclasses.replace(gripper.scene, horizon=0.3), loopcheck.ReducedSettings())
    assert run.audit.relative_residual <= 1e-9
    (_, right), (_, left) = run.other_inputs
    assert right.omega == pytest.approx(-left.omega, rel=1e-9)


def _one_finger(tmp_path) -> Path:
    """The gripper without the knuckles' coupling and with the servo on the right knuckle alone:
    each finger is a five-bar of its own, so --loop can cut one out."""
    text = GRIPPER.read_text()
    start = text.index('<joint name="knuckles"')
    text = text[:start] + text[text.index("/>", start) + 2:]
    text = text.replace('<general class="gripper" name="servo" tendon="split"/>',
                        '<general class="gripper" name="servo" joint="right_knuckle_joint"/>')
    start = text.index("<tendon>")
    text = text[:start] + text[text.index("</tendon>") + len("</tendon>"):]
    path = tmp_path / "fingers.xml"
    path.write_text(text)
    return path


def test_loop_cuts_one_finger_of_two_dof_out(tmp_path):
    """--loop right_pin on the uncoupled gripper: the right finger alone, a five-bar of 2 DOF (the
    refusal of a loop of several DOF is gone); its inputs the servo's knuckle, then the fingertip by
    partitioning; the left finger is welded and its pin dropped, said in the extraction."""
    imported, extraction = import_loop(_one_finger(tmp_path), ["right_pin"])
    scene = imported.scene
    assert scene.dof == 2 and scene.inputs[0] == "right_knuckle_joint"
    assert set(scene.mechanism.linkage.moving) == {"right_knuckle", "right_link", "right_rocker", "right_tip"}
    assert scene.inputs[1] in {"right_link_joint", "right_rocker_joint", "right_tip_joint"}
    assert "left_pin" in " ".join(extraction.dropped)


def test_without_actuators_every_input_comes_by_partitioning_and_unnamed_joints_are_labelled(tmp_path):
    """The five-bar robot's MJCF without its motors and with its cranks' and elbow's joints unnamed:
    2 DOF, both inputs chosen by partitioning (the largest remainders: the left elbow and the right
    elbow, measured), an unnamed one said by its label, and its initial rate read from the keyframe."""
    import re

    from loopcheck.reference_models import MujocoSettings, mjcf_text
    from loopcheck.scenefile import load_scene

    scene = load_scene(Path(__file__).parent.parent.parent / "scenes" / "mechanisms" / "five_bar_robot.toml")
    text = mjcf_text(scene, MujocoSettings(timestep=5e-4))
    text = re.sub(r"<actuator>.*?</actuator>|<sensor>.*?</sensor>", "", text, flags=re.S)
    text = re.sub(r'<numeric name="loopcheck.ctrl[^/]*/>', "", text).replace(' ctrl="8 0"', "")
    text = re.sub(r'<text name="loopcheck.inputs"[^/]*/>', "", text)  # export's inputs, which name O1
    for joint in ("O1", "A"):
        text = text.replace(f'<joint name="{joint}" />', "<joint />")
    path = tmp_path / "five_bar.xml"
    path.write_text(text)
    imported = import_mjcf(path)
    back = imported.scene
    assert back.dof == 2 and imported.model.nu == 0
    said = "\n".join(imported.said)
    assert "inputs, in order: joint #2 (left_crank–left_arm), 'B'" in said and "partitioning" in said
    # the rates read are the original motion's, in the new inputs: every body's angular rate is the same
    system, original = loops.compile_linkage(back.mechanism.linkage), loops.compile_linkage(scene.mechanism.linkage)
    rates = dict(zip(original.coordinate_names, loops.input_rates(original, np.asarray(scene.x0), scene.initial_qdot())))
    xdot = np.array([rates[name] for name in system.coordinate_names])
    assert back.initial_qdot() == pytest.approx(tuple(system.input_rows @ xdot), abs=1e-14)


def test_cli_import_says_the_inputs_and_writes_a_scene_of_three(tmp_path, capsys):
    from loopcheck.compare.cli import main
    from loopcheck.scenefile import load_scene

    out = tmp_path / "gripper.toml"
    assert main(["import-mjcf", str(GRIPPER), "--ctrl", "servo=0:0.6,0.2:0.1", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "3 degrees of freedom (the rank of the loop equations at keyframe 'grasp'); inputs, in order: " \
           "'right_knuckle_joint', 'right_tip_joint', 'left_tip_joint'" in printed
    assert "inputs 'right_knuckle_joint', 'right_tip_joint', 'left_tip_joint'; the first, 'right_knuckle_joint'" in printed
    scene = load_scene(out)
    assert scene.inputs == INPUTS and scene.mechanism.actuators[0].control.sample(np.array([0.1, 0.3])).tolist() == [0.6, 0.1]


def test_ctrl_gives_each_motor_of_the_five_bar_its_own_control(tmp_path):
    """--ctrl NAME=... once per actuator on a model of two motors (the five-bar's MJCF): each scene
    actuator takes its own; a bare value is refused (two actuators, neither the input motor)."""
    from loopcheck.reference_models import MujocoSettings, mjcf_text
    from loopcheck.scenefile import load_scene

    path = tmp_path / "five_bar.xml"
    path.write_text(mjcf_text(load_scene(Path(__file__).parent.parent.parent / "scenes" / "mechanisms" /
                                         "five_bar_robot.toml"), MujocoSettings(timestep=5e-4)))
    imported = import_mjcf(path, controls={"left_motor": Control.constant(2.0),
                                           "right_motor": Control((0.0, 0.2), (1.0, 0.0))})
    left, right = imported.scene.mechanism.actuators
    times = np.array([0.0, 0.1, 0.3])
    assert left.control.sample(times).tolist() == [2.0, 2.0, 2.0] and right.control.sample(times).tolist() == [1.0, 1.0, 0.0]
    with pytest.raises(MjcfError, match="--ctrl VALUE: the model has 2 actuators: name the one each control is for"):
        import_mjcf(path, control=Control.constant(1.0))


def test_input_naming_more_joints_than_a_one_dof_linkage_has_is_refused():
    path = Path(__file__).parent.parent / "data" / "mjcf" / "fourbar_sites_keyframe.xml"
    with pytest.raises(MjcfError, match="--input names 2 joints, and the linkage has 1 degree of freedom"):
        import_mjcf(path, keyframe="assembled", input_joint="O1,O3")
