"""MuJoCo's joint equality (``<equality><joint joint1 joint2 polycoef>``) read as a coupling, written
back by export-mjcf, and a lock (no joint2) refused by name.

Oracles: MuJoCo running each hand-written file as written (``loopcheck check``'s gate against the
exact reduced solution of the imported scene, the scene's default tolerances: q 1e-3 rad, q̇ 0.1 rad/s,
peak 1e-4 relative); the polynomial by hand (the cam law's keyframe satisfies it, and the imported
coupling must give the follower's coordinate back there); the scene that was exported (export →
import gives its coupling back, to round-off of the re-expansion about qpos0: 1e-15 measured, 1e-13
allowed).

Files: coupled_hand.xml (the xArm7 hand's topology and numbers without meshes: two four-bar fingers,
the drivers coupled by polycoef "0 1 0 0 0", the motor on joint1), cam_rotors.xml (a quadratic cam
law, joint1 about −z, refs on both joints and a keyframe away from qpos0).

Planted: the import's reference taken at the keyframe instead of qpos0 (``float(m.qpos0[adr])`` →
``float(reader.qpos[adr])``) fails test_a_cam_law_is_read_with_qpos0_and_the_hinge_sign (the keyframe no
longer satisfies the coupling as read: Newton moves it by 0.05 rad); the hinge sign left out
(``sy = sx = 1``) fails it and test_the_coupled_hand_is_one_dof_and_checks (the coefficients); the
values check skipping joint equalities again (``!= _CONNECT``) fails the three non-finite cases (a NaN
polycoef then reaches the coupling's own check with the signs applied, an infinite solref MuJoCo
runs); the options' softness taking connects only fails test_the_stiff_loops_trial_and_its_advice_take_the_coupling.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from loopcheck.compare.cli import main
from loopcheck.mechanism import JointCoupling
from loopcheck.reference_models import MujocoSettings, mjcf_text
from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf
from loopcheck.reference_models.user_model import ModelOptions
from loopcheck.scenefile import scene_from_dict
from loopcheck.scene_writer import scene_data

from helpers import DATA

MJCF = DATA / "mjcf"


def test_the_coupled_hand_is_one_dof_and_checks(capsys):
    imported = import_mjcf(MJCF / "coupled_hand.xml")
    linkage = imported.scene.mechanism.linkage
    (coupling,) = linkage.couplings
    assert (coupling.joint, coupling.driver) == ("left_driver_joint", "right_driver_joint")
    # the drivers' axes are opposite (±x) and polycoef "0 1 0 0 0": in the plane the mirrored driver
    # turns the other way; an unnamed equality is named after its index, like the file's other elements
    assert coupling == JointCoupling("coupling2", "left_driver_joint", "right_driver_joint", (0.0, -1.0))
    assert len(linkage.cut_joints) == 2 and linkage.input_joint == "left_driver_joint"
    # 0.3 s: the drivers turn 0.25 rad; MuJoCo as written is 3.8e-5 off the peak (tolerance 1e-4)
    assert main(["check", str(MJCF / "coupled_hand.xml"), "--horizon", "0.3"]) == 0
    assert "1 passed, 0 failed" in capsys.readouterr().out


def test_a_cam_law_is_read_with_qpos0_and_the_hinge_sign(capsys):
    imported = import_mjcf(MJCF / "cam_rotors.xml")
    (c,) = imported.scene.mechanism.linkage.couplings
    assert c.name == "cam_law" and (c.joint, c.driver) == ("follower_shaft", "cam_shaft")
    # joint1 turns about −z: its coordinate is u_y(qpos0) − (qpos_y − 0.1), so p(s) = −P(s)
    assert c.coefficients == pytest.approx((-0.05, 1.0, -0.5, 0.0, 0.0), abs=1e-15)
    # the keyframe (x = 0.3, y = 0.055) satisfies the coupling as read: Newton leaves it where it is
    assert imported.polish <= 1e-15
    assert main(["check", str(MJCF / "cam_rotors.xml"), "--horizon", "0.5"]) == 0
    assert "1 passed, 0 failed" in capsys.readouterr().out


def test_a_lock_is_refused_by_name(tmp_path, capsys):
    text = (MJCF / "coupled_hand.xml").read_text().replace(
        'joint1="left_driver_joint" joint2="right_driver_joint" polycoef="0 1 0 0 0"',
        'name="brake" joint1="right_driver_joint" polycoef="0.1 0 0 0 0"')
    path = tmp_path / "locked.xml"
    path.write_text(text)
    with pytest.raises(MjcfError, match="joint equality 'brake' has no joint2: it locks joint 'right_driver_joint'"):
        import_mjcf(path)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "has no joint2: it locks joint 'right_driver_joint'" in err


def test_export_then_import_gives_the_coupling_back(tmp_path):
    """A quadratic coupling on a joint written from the rotor to the ground (the hinge's sign is
    the opposite of the joint's coordinate) at q0 away from x_ref: MuJoCo's polycoef is re-expanded
    about qpos0 on export and mapped back on import."""
    import sys
    sys.path.insert(0, str(DATA.parent / "core"))
    from test_couplings import rotors

    scene = scene_from_dict(__import__("tomllib").loads(
        rotors([0.05, -1.5, 0.8, 0.1], reference=(0.1, 0.2), q0=0.4, qdot0=1.0, reversed_joint=True)))
    path = tmp_path / "rotors.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=1e-3)))
    back = import_mjcf(path).scene
    (a,), (b,) = scene.mechanism.linkage.couplings, back.mechanism.linkage.couplings
    joint_back = back.mechanism.linkage.joint_map["J2"]
    joint = scene.mechanism.linkage.joint_map["J2"]
    # the import writes each joint from parent to child: J2 comes back as ground → rotor, its
    # coordinate negated, so the coupling is the same law in that coordinate
    flip = -1.0 if (joint_back.body_a, joint_back.body_b) != (joint.body_a, joint.body_b) else 1.0
    assert (b.joint, b.driver) == (a.joint, a.driver)
    x = np.linspace(-0.5, 0.8, 7)
    mine = np.array([a.y_ref + a.polynomial(v)[0] for v in x])
    theirs = np.array([b.y_ref + b.polynomial(v)[0] for v in x])
    np.testing.assert_allclose(theirs, flip * mine, rtol=0, atol=1e-13)
    assert isinstance(b, JointCoupling)
    np.testing.assert_allclose(back.x0, scene.x0, rtol=0, atol=1e-14)
    assert scene_data(back)["couplings"][0]["name"] == "cam"


@pytest.mark.parametrize("change, words", [
    (('polycoef="0.05 -1 0.5 0 0"', 'polycoef="0.05 nan 0.5 0 0"'),
     "equality 'cam_law': polycoef=\"0.05 nan 0.5 0 0\" is not a finite number"),
    (('solref="0.005 1"', 'solref="0.005 inf"'), "equality 'cam_law': solref=\"0.005 inf\" is not a finite number"),
    (('<joint name="cam_law" ', '<joint '), None),  # unnamed: named by its tag, ordinal and joints
])
def test_a_coupling_value_that_is_not_finite_is_refused_by_name(change, words, tmp_path):
    text = (MJCF / "cam_rotors.xml").read_text().replace(*change)
    if words is None:
        text = text.replace('polycoef="0.05 -1 0.5 0 0"', 'polycoef="0.05 -1 0.5 inf 0"')
        words = "joint equality #1 (follower_shaft–cam_shaft): polycoef=\"0.05 -1 0.5 inf 0\" is not a finite number"
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(MjcfError, match=re.escape(words)) as caught:
        import_mjcf(path)
    assert "\n" not in str(caught.value)


def test_the_stiff_loops_trial_and_its_advice_take_the_coupling():
    """`check`'s "stiff loops" trial sets the coupling's softness with the connects', and the MJCF it
    advises names the coupling by its own tag (it sets its own solref, so a default does not reach it)."""
    imported = import_mjcf(MJCF / "cam_rotors.xml")
    written = ModelOptions.as_written(imported.model)
    assert written.solref == ((0.005, 1.0),)
    advice = written.stiff_loops().mjcf(imported.connects)
    assert '<joint name="cam_law" solref="0.001 1"' in advice, advice


@pytest.mark.parametrize("qpos, words", [
    ("0.3 0.155", "joint equality 'cam_law' is open by 0.1 rad at the configuration read"),
    ("0.3 0.0550000001", None),  # 1e-10 rad: within the 1e-6 closure bound, Newton polishes it
])
def test_a_keyframe_off_its_coupling_is_refused_like_an_open_connect(qpos, words, tmp_path, capsys):
    """The keyframe's follower 0.1 rad off cam_law(cam_shaft): the scene's Newton would move it
    there silently, as it would an open connect; refused by name, with --assemble's hint."""
    path = tmp_path / "open.xml"
    path.write_text((MJCF / "cam_rotors.xml").read_text().replace('qpos="0.3 0.055"', f'qpos="{qpos}"'))
    if words is None:
        assert import_mjcf(path).polish <= 1e-9
        return
    with pytest.raises(MjcfError, match=re.escape(words)) as caught:
        import_mjcf(path)
    assert "--assemble" in str(caught.value) and "\n" not in str(caught.value)
    assert main(["import-mjcf", str(path), "-o", str(tmp_path / "out.toml")]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not (tmp_path / "out.toml").exists()


def _locked_input(tmp_path):
    """The geared flywheel's export with the coupling moved to the rocker: O3 = −2·O1 locks the
    four-bar (one loop, one coupling: zero DOF there), and the flywheel F turns freely at 3 rad/s."""
    import loopcheck
    from loopcheck.reference_models import MujocoSettings, mjcf_text
    scene = loopcheck.load_scene(DATA.parent.parent / "scenes" / "mechanisms" / "seed_fourbar_geared_flywheel.toml")
    text = mjcf_text(scene, MujocoSettings(timestep=5e-4))
    for old, new in (('joint1="F" joint2="O1"', 'joint1="O3" joint2="O1"'),
                     ('<key name="home" ctrl="250" />', '<key name="home" ctrl="0" qvel="0 0 3 0" />')):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "locked_input.xml"
    path.write_text(text)
    return path


def test_an_input_a_coupling_locks_is_refused_naming_a_joint_that_can_drive(tmp_path, capsys):
    """The motor's joint O1 cannot drive the linkage (driving conditioning 0): the scene would hold
    q̇ = 0 and drop F's 3 rad/s. Refused by name, with the joint that can (planted: the check
    removed, it imports with input 'O1' and qdot 0)."""
    path = _locked_input(tmp_path)
    with pytest.raises(MjcfError, match=re.escape("joint 'O1' (the input) cannot drive the linkage at keyframe "
                                                  "'home'")) as caught:
        import_mjcf(path)
    assert "--input 'F'" in str(caught.value) and "\n" not in str(caught.value)
    assert main(["import-mjcf", str(path), "-o", str(tmp_path / "out.toml")]) == 2
    assert capsys.readouterr().err.count("error") == 1
    driven = import_mjcf(path, input_joint="F").scene
    assert driven.qdot0 == 3.0


@pytest.mark.parametrize("qvel, off", [("1 -0.9", None), ("0 -0.9", "0.9"), ("1 -0.5", "0.4")])
def test_rates_the_input_does_not_reproduce_are_said(qvel, off, tmp_path):
    """The follower's keyframe rate beside the cam shaft's (the input's): −0.9 is cam_law's slope at
    the keyframe (−1 + 2·0.5·0.1), so it is kept; at rest input with −0.9 on the follower, or −0.5,
    the scene starts from the input's rate alone and says so (planted: the warning only when the
    input's own rate is not zero; the first case then says nothing)."""
    path = tmp_path / "rates.xml"
    path.write_text((MJCF / "cam_rotors.xml").read_text().replace('qvel="1 -0.9"', f'qvel="{qvel}"'))
    said = [w for w in import_mjcf(path).warnings if "qvel" in w]
    if off is None:
        assert said == []
    else:
        assert len(said) == 1 and f"rate residual {off}" in said[0] and "the input joint's does not reproduce" in said[0]
