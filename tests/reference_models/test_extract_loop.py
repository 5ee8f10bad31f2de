"""One loop out of a larger model (issue 38): the extracted loop is the loop written alone.

Two hand-written robots (tests/loop_robots.py): (a) a floating-base leg whose foot four-bar lies in
a plane at an angle to every world axis, (b) an arm holding a finger four-bar, a servo on the elbow,
collidable geoms elsewhere. Each loop is also written alone, in its own plane.

Tolerances (the issue's decision): 1e-12 relative on q and q̇ at a fixed RKN4 step (the two
descriptions differ by the round-off of the tilted frames: 3e-15 measured); 1e-10 with the default
DOP853, whose adaptive steps differ between the two, so its samples do not line up: the end state
and the peak are compared (end state 5e-12, peak 3e-11 measured, the worse of the two robots).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from loopcheck.reduced.engine import simulate
from loopcheck.reduced.settings import ReducedSettings
from loopcheck.reference_models.extract import CHECK_SCOPE, extract_loop, import_assembled, import_loop
from loopcheck.reference_models.mjcf_import import Control, MjcfError, import_mjcf

import loop_robots as robots

HORIZON = 0.2
ROBOTS = {  # robot, --loop name, the loop motor's control, the loop alone's arguments
    "leg": (robots.floating_leg, "foot_loop", robots.LEG_KEY_CTRL[-1], dict(normal=robots.LEG_NORMAL)),
    "arm": (robots.finger_arm, "f_crank", robots.ARM_KEY_CTRL[-1], dict(normal=robots.ARM_NORMAL, prefix="f_")),
}


def _write(tmp_path: Path, which: str):
    build, loop, ctrl, alone = ROBOTS[which]
    robot = tmp_path / f"{which}.xml"
    robot.write_text(build())
    by_hand = tmp_path / f"{which}_alone.xml"
    by_hand.write_text(robots.loop_alone(ctrl=ctrl, **alone))
    return robot, loop, by_hand


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("which", ["leg", "arm"])
def test_the_extracted_loop_is_the_loop_written_alone(which, tmp_path):
    robot, loop, by_hand = _write(tmp_path, which)
    imported, _ = import_loop(robot, [loop], horizon=HORIZON)
    alone = import_mjcf(by_hand, horizon=HORIZON)
    fixed = ReducedSettings(method="rkn4", step=1e-4)
    a, b = simulate(imported.scene, fixed).trajectory, simulate(alone.scene, fixed).trajectory
    assert np.array_equal(a.t, b.t)
    assert _rel(a.q, b.q) < 1e-12 and _rel(a.qdot, b.qdot) < 1e-12
    ra, rb = simulate(imported.scene), simulate(alone.scene)
    a, b = ra.trajectory, rb.trajectory
    assert a.t[-1] == b.t[-1] == HORIZON
    assert abs(a.q[-1] - b.q[-1]) < 1e-10 * np.max(np.abs(b.q))
    assert abs(a.qdot[-1] - b.qdot[-1]) < 1e-10 * np.max(np.abs(b.qdot))
    assert abs(ra.peak.omega - rb.peak.omega) < 1e-10 * rb.peak.omega
    assert np.max(np.abs(b.q - b.q[0])) > 1.0  # it moves: the comparison could fail


def test_the_leg_lists_what_was_welded_and_dropped(tmp_path):
    robot, loop, _ = _write(tmp_path, "leg")
    ext = extract_loop(robot, [loop])
    assert ext.loops == ("connect 'foot_loop'",)
    assert ext.moving == ("crank", "coupler", "rocker")
    assert ext.mass == (("pad", "rocker"),)
    assert ext.ground == ("pelvis", "thigh", "shin", "ankle", "base")
    assert [w.split(" at ")[0] for w in ext.welded] == ["joint 'root'", "joint 'hip'", "joint 'knee'", "joint 'pad_j'"]
    assert ext.dropped == ("actuator 'hip_motor' (on welded joint 'hip')",
                           "actuator 'knee_motor' (on welded joint 'knee')")
    n = np.array(robots.LEG_NORMAL) / np.linalg.norm(robots.LEG_NORMAL)
    assert np.allclose(ext.normal, n, atol=1e-12)  # the plane at an angle to every world axis
    assert min(abs(np.array(ext.normal))) > 0.3
    assert ext.key == "stance" and CHECK_SCOPE in ext.lines()[0]


def test_the_arm_keeps_the_finger_motor_and_drops_the_servo(tmp_path):
    robot, loop, _ = _write(tmp_path, "arm")
    imported, ext = import_loop(robot, [loop], horizon=HORIZON)
    assert ext.loops == ("connect #1 (f_coupler–f_rocker)",)
    assert ext.dropped == ("actuator 'elbow_servo' (on welded joint 'elbow')",)
    m = imported.model  # the model loaded back from the written file
    assert [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(m.nu)] == ["finger_motor"]
    assert [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)] == \
        ["f_crank_j", "f_coupler_j", "f_rocker_j"]
    assert "collidable geoms on ground" in " ".join(ext.kept_across)
    # the unnamed connect is named as the messages name it, and a body of the loop names the loop
    assert extract_loop(robot, ["connect #1 (f_coupler–f_rocker)"]).moving == ext.moving
    assert extract_loop(robot, ["f_rocker"]).moving == ext.moving
    assert extract_loop(robot, ["connect #1 (f_coupler-f_rocker)"]).moving == ext.moving  # typed with a hyphen


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    robot = tmp_path / "leg.xml"
    text = robots.floating_leg()
    assert old in text
    robot.write_text(text.replace(old, new, 1))
    return robot


def test_a_name_that_closes_no_loop_is_refused(tmp_path):
    robot, _, _ = _write(tmp_path, "leg")
    with pytest.raises(MjcfError, match=r"--loop thigh: no connect, joint coupling or loop body of that name closes "
                                        r"a loop \(the model's loops: connect 'foot_loop'\)"):
        extract_loop(robot, ["thigh"])


def test_a_spatial_loop_is_refused_and_a_nearly_planar_one_projected(tmp_path):
    robot = _edited(tmp_path, '<joint name="coupler_j" axis="0 0 1"/>', '<joint name="coupler_j" axis="0 0.001 1"/>')
    with pytest.raises(MjcfError, match=r"the loop is spatial: joint 'coupler_j''s axis is at 0.001 rad to "
                                        r"joint 'crank_j''s"):
        extract_loop(robot, ["foot_loop"])
    robot = _edited(tmp_path, '<joint name="coupler_j" axis="0 0 1"/>', '<joint name="coupler_j" axis="0 4e-7 1"/>')
    imported, ext = import_loop(robot, ["foot_loop"], horizon=HORIZON)
    assert ext.largest_angle == pytest.approx(4e-7, rel=1e-3)
    assert any("parallel within 4e-07 rad" in w and "projected" in w for w in imported.warnings)


def test_a_coupling_to_a_joint_outside_the_loop_joins_that_joint_to_the_loop(tmp_path):
    # the knee, coupled to the foot's rocker, moves with the loop (never welded): its axis is then
    # out of the loop's plane
    robot = _edited(tmp_path, "</equality>", '<joint name="tie" joint1="rocker_j" joint2="knee"/></equality>')
    with pytest.raises(MjcfError, match=r"--loop foot_loop: the loop is spatial: joint 'crank_j''s axis is at "
                                        r"1.37 rad to joint 'knee''s"):
        extract_loop(robot, ["foot_loop"])
    inactive = _edited(tmp_path, "</equality>",
                       '<joint name="tie" joint1="rocker_j" joint2="knee" active="false"/></equality>')
    assert "joint equality 'tie' (acts outside the loop)" in extract_loop(inactive, ["foot_loop"]).dropped


def test_a_body_in_two_loops_is_refused_listing_them(tmp_path):
    robot = _edited(tmp_path, "</equality>",
                    '<connect name="ankle_loop" body1="shin" body2="base" anchor="0 0 -0.3"/></equality>')
    with pytest.raises(MjcfError, match=r"body 'base' belongs to 2 loops \(connect 'foot_loop'; connect "
                                        r"'ankle_loop'\)"):
        extract_loop(robot, ["base"])
    assert "connect 'ankle_loop' (acts outside the loop)" in extract_loop(robot, ["foot_loop"]).dropped


def test_a_loop_with_two_dof_is_read_with_two_inputs(tmp_path):
    # the connect closes on the pad, whose own joint then belongs to the loop (closed at qpos0): 2 DOF,
    # read as a scene of two inputs (issue 41: the refusal of a loop of several DOF is gone), said
    robot = _edited(tmp_path, 'body2="rocker" anchor=', 'body2="pad" anchor=')
    assert extract_loop(robot, ["foot_loop"], qpos0=True).moving == ("crank", "coupler", "rocker", "pad")
    imported, _ = import_loop(robot, ["foot_loop"], qpos0=True, horizon=HORIZON)
    assert imported.scene.dof == 2 and set(imported.scene.inputs) <= {j.name for j in imported.scene.mechanism.linkage.joints}
    assert any(line.startswith("2 degrees of freedom (the rank of the loop equations at qpos0)") for line in imported.said)


def test_a_spring_from_a_welded_body_is_kept_with_that_end_as_ground(tmp_path):
    robot = _edited(tmp_path, "<equality>", """<tendon><spatial name="heel_spring" stiffness="20">
      <site site="heel"/><site site="toe"/></spatial><spatial name="calf" stiffness="5"><site site="heel"/>
      <site site="hip_site"/></spatial></tendon><equality>""")
    text = robot.read_text().replace('<body name="ankle" pos="0 0 -0.3">',
                                     '<body name="ankle" pos="0 0 -0.3"><site name="heel" pos="0.05 0 0"/>')
    text = text.replace('<body name="thigh" pos="0 0 -0.1">', '<body name="thigh" pos="0 0 -0.1"><site name="hip_site"/>')
    text = text.replace('<body name="pad" pos="0.01 -0.005 0" >', '<body name="pad" pos="0.01 -0.005 0" ><site name="toe"/>')
    robot.write_text(text)
    imported, ext = import_loop(robot, ["foot_loop"], horizon=HORIZON)
    assert ext.kept_across[0] == "tendon 'heel_spring' (its sites off the loop are ground)"
    assert "tendon 'calf' (between welded bodies)" in ext.dropped
    assert [e.name for e in imported.scene.mechanism.elements if e.kind == "spring"] == ["heel_spring"]


def _open_key(text: str, index: int, value: float) -> str:
    """The text with the only keyframe's qpos[index] set to ``value``."""
    start = text.index('qpos="', text.index("<key ")) + len('qpos="')
    end = text.index('"', start)
    words = text[start:end].split()
    words[index] = repr(value)
    return text[:start] + " ".join(words) + text[end:]


ROCKER = 11  # the leg's qpos: root (7), hip, knee, crank_j, coupler_j, rocker_j, pad_j


def test_assemble_closes_a_loop_left_open_and_reports_the_moves(tmp_path):
    closed, loop, by_hand = _write(tmp_path, "leg")
    robot = tmp_path / "open.xml"
    robot.write_text(_open_key(closed.read_text(), ROCKER, 0.002))  # open by 6e-5 m
    with pytest.raises(MjcfError, match=r"connect 'foot_loop' is open by 6.08e-05 m .*--assemble closes them"):
        import_loop(robot, [loop], horizon=HORIZON)
    imported, ext = import_loop(robot, [loop], horizon=HORIZON, assemble=True)
    a = ext.assembly
    assert a.input == "joint 'crank_j'" and a.input_value == 0.0
    assert [(n, u) for n, _, u in a.moves] == [("joint 'rocker_j'", "rad")]
    assert a.moves[0][1] == pytest.approx(-0.002, abs=1e-12)  # back to the closed pose, in qpos units
    assert a.open_before == pytest.approx(6.08e-5, rel=1e-3) and a.open_after < 1e-15
    assert ext.lines()[-1].startswith("assembled (--assemble): loops open by 6.08e-05")
    # the extracted keyframe is the assembled state: the closed robot's loop, to round-off
    reference, _ = import_loop(closed, [loop], horizon=HORIZON)
    fixed = ReducedSettings(method="rkn4", step=1e-4)
    x, y = simulate(imported.scene, fixed).trajectory, simulate(reference.scene, fixed).trajectory
    assert _rel(x.q, y.q) < 1e-12 and _rel(x.qdot, y.qdot) < 1e-12


def test_assemble_refuses_a_move_above_a_tenth_of_a_radian(tmp_path):
    closed, loop, _ = _write(tmp_path, "leg")
    robot = tmp_path / "far.xml"
    robot.write_text(_open_key(closed.read_text(), ROCKER, 0.3))
    with pytest.raises(MjcfError, match=r"--assemble: closing the loops moves joint 'rocker_j' by -0.3 rad, more than "
                                        r"0.1 rad"):
        import_loop(robot, [loop], assemble=True)


def test_assemble_without_loop_applies_to_the_whole_model(tmp_path):
    _, _, by_hand = _write(tmp_path, "leg")
    robot = tmp_path / "alone_open.xml"
    robot.write_text(_open_key(by_hand.read_text(), 2, 0.002))
    imported = import_assembled(robot, horizon=HORIZON)
    assert imported.scene.source == f"{robot} --assemble"  # the user's model, not the temporary file read
    assert any(line.startswith("assembled (--assemble): loops open by 6.08e-05") and "joint 'rocker_j' by -0.002 rad"
               in line for line in imported.said)
    fixed = ReducedSettings(method="rkn4", step=1e-4)
    x = simulate(imported.scene, fixed).trajectory
    y = simulate(import_mjcf(by_hand, horizon=HORIZON).scene, fixed).trajectory
    assert _rel(x.q, y.q) < 1e-12 and _rel(x.qdot, y.qdot) < 1e-12


def test_a_welded_joints_rate_is_said_to_be_dropped(tmp_path):
    qvel = [0.0] * 6 + [0.5, 0.0] + [0.0] * 4  # root (6), hip, knee, crank_j, coupler_j, rocker_j, pad_j
    robot = _edited(tmp_path, '" ctrl="', f'" qvel="{" ".join(map(str, qvel))}" ctrl="')
    ext = extract_loop(robot, ["foot_loop"])
    assert "joint 'hip' at 0.4 rad (its rate 0.5 dropped: held still)" in ext.welded
    assert "joint 'knee' at -0.7 rad" in ext.welded


@pytest.mark.parametrize("name,loop,kwargs", [
    # read at qpos0: no keyframe written, qpos0 read back
    ("fourbar_xz_degrees.xml", "B", dict(qpos0=True, control=Control.parse("0:250,1:0"))),
    ("gripper_finger.xml", "pad", {}),  # a tendon spring to the palm, a collidable geom on it
    ("coupled_hand.xml", "right_finger", {}),  # two fingers one loop: the coupling joins them
])
def test_a_loop_that_is_the_whole_model_is_the_model(name, loop, kwargs):
    from helpers import DATA

    path = DATA / "mjcf" / name
    imported, ext = import_loop(path, [loop], horizon=HORIZON, **kwargs)
    whole = import_mjcf(path, horizon=HORIZON, **kwargs)
    assert ext.welded == () and ext.dropped == ()
    fixed = ReducedSettings(method="rkn4", step=1e-4)
    a, b = simulate(imported.scene, fixed).trajectory, simulate(whole.scene, fixed).trajectory
    assert _rel(a.q, b.q) < 1e-12 and _rel(a.qdot, b.qdot) < 1e-12
    assert np.max(np.abs(b.qdot)) > 0.1  # it moves
    if name == "coupled_hand.xml":
        assert ext.loops == ("connect #1 (right_finger–right_inner_knuckle)",
                             "connect #2 (left_finger–left_inner_knuckle)", "joint equality #1")


def test_an_include_is_flattened_and_a_welded_body_in_a_frame_refused(tmp_path):
    text = robots.floating_leg()
    start, end = text.index("<actuator>"), text.index("</actuator>") + len("</actuator>")
    (tmp_path / "motors.xml").write_text(f"<mujoco>{text[start:end]}</mujoco>")
    robot = tmp_path / "leg.xml"
    robot.write_text(text[:start] + '<include file="motors.xml"/>' + text[end:])
    imported, ext = import_loop(robot, ["foot_loop"], horizon=HORIZON)
    assert ext.dropped == ("actuator 'hip_motor' (on welded joint 'hip')",
                           "actuator 'knee_motor' (on welded joint 'knee')")
    assert "<include" not in ext.xml and 'name="foot_motor"' in ext.xml  # standalone
    framed = tmp_path / "framed.xml"
    framed.write_text(text.replace('<body name="shin"', '<frame><body name="shin"', 1)
                      .replace('</body>\n      </body>\n    </body>', '</body></frame>\n      </body>\n    </body>', 1))
    with pytest.raises(MjcfError, match=r"cannot be written exactly: shin, welded, sits inside a <frame>"):
        extract_loop(framed, ["foot_loop"])


@pytest.mark.parametrize("name", ["B", "gear", "flywheel"])
def test_a_coupling_that_shares_a_loops_body_keeps_the_geared_four_bar_whole(name, tmp_path):
    """The catalogue's geared four-bar, exported: named by its connect, its coupling or the coupled
    flywheel, the extraction keeps connect and coupling together (the whole model), and its exact
    answer is the scene's (1e-12 relative at a fixed RKN4 step: both describe the same planar
    four-bar in the same frame; 0 measured)."""
    import dataclasses

    from loopcheck.reference_models import MujocoSettings, mjcf_text
    from loopcheck.scenefile import load_scene
    from loopcheck.shipped_scenes import resolve_scene

    scene = dataclasses.replace(load_scene(resolve_scene("seed_fourbar_geared_flywheel")), horizon=HORIZON)
    path = tmp_path / "geared.xml"
    path.write_text(mjcf_text(scene, MujocoSettings()))
    imported, ext = import_loop(path, [name], horizon=HORIZON)
    assert ext.loops == ("connect 'B'", "joint equality 'gear'")
    assert ext.moving == ("crank", "coupler", "flywheel", "rocker") and ext.welded == ()
    fixed = ReducedSettings(method="rkn4", step=1e-4)
    a, b = simulate(imported.scene, fixed).trajectory, simulate(scene, fixed).trajectory
    assert np.array_equal(a.t, b.t)
    assert _rel(a.q, b.q) < 1e-12 and _rel(a.qdot, b.qdot) < 1e-12
    assert np.max(np.abs(b.q - b.q[0])) > 0.1  # it moves: the comparison could fail
