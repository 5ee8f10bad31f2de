"""Actuators in MuJoCo, built from a scene and as written, and through export → import.

Oracles: the reduced engine (itself checked against closed forms: tests/reduced/test_actuators.py),
an element split in two halves (two motors of half the torque each on one joint are the seed's one
motor), the closed-form damped oscillator of a rotor held by a servo on a fixed tendon, and the
energy audits' balance.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from loopcheck.api import load_scene, mujoco_settings, reduced_settings, simulate
from loopcheck.reference_models import MujocoSettings, mjcf_text
from loopcheck.reference_models.mjcf_import import Control, MjcfError, import_mjcf
from loopcheck.reference_models.user_model import run_model

ROOT = Path(__file__).parent.parent.parent
DATA = ROOT / "tests" / "data" / "mjcf"
SERVO_FOURBAR = ROOT / "scenes" / "mechanisms" / "servo_fourbar.toml"


def residual(audit):
    r = audit.kinetic + audit.potential - audit.torque_work + audit.damper_dissipation
    return float(np.max(np.abs(r - r[0])))


def test_catalogue_servo_fourbar_mujoco_against_reduced():
    """MuJoCo built from the scene (general actuators: a servo on a joint, an affine one on a fixed
    tendon over a cut joint) against the reduced engine: measured q 2.4e-9 rad, peak ω 2.4e-7 relative at
    the scene's automatic step; the scene's tolerances are 1e-3 rad, 1e-4. Audits: reduced 9.7e-11 J,
    MuJoCo 6.3e-5 J (the trapezoid of f·L̇ over 5e-4 s steps) of 0.18 J of work. Planted: the length
    offset b1·gear·l0 left out of MuJoCo's b0 → ω off by 0.9 rad/s, the gate fails."""
    scene = load_scene(SERVO_FOURBAR)
    reduced = simulate(scene, reduced_settings(scene))
    mujoco = simulate(scene, mujoco_settings(scene))
    q = np.interp(reduced.trajectory.t, mujoco.trajectory.t, mujoco.trajectory.q)
    assert np.max(np.abs(q - reduced.trajectory.q)) < 1e-6
    assert residual(reduced.audit) < 1e-9
    assert residual(mujoco.audit) < 1e-3 * abs(mujoco.audit.torque_work).max() + 1e-4
    assert abs(reduced.audit.torque_work[-1] - mujoco.audit.torque_work[-1]) < 1e-3


def test_catalogue_servo_fourbar_export_import_round_trip(tmp_path):
    """export-mjcf → import-mjcf: the same actuators as generalized forces (a tendon over the cut joint B
    comes back over MuJoCo's tree joints: the same length as a function of the coordinates), the same
    controls (loopcheck.ctrl.NAME), and the same reduced trajectory: b0 comes back through b1·gear·l0
    and its inverse, an ulp apart, and the tendon's other terms round differently, so DOP853 takes other
    steps (sample times 1e-9 s apart): compared at the end of the run, where both stop, to 1e-9 rad."""
    scene = load_scene(SERVO_FOURBAR)
    path = tmp_path / "model.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=1e-3)))
    back = import_mjcf(path).scene
    assert back.load is None and [a.name for a in back.mechanism.actuators] == ["servo", "tendon_drive"]
    for a, b in zip(scene.mechanism.actuators, back.mechanism.actuators):
        assert (a.gain, a.bias[1:], a.gear, a.ctrlrange, a.forcerange, a.control) == (
            b.gain, b.bias[1:], b.gear, b.ctrlrange, b.forcerange, b.control)
        assert b.bias[0] == pytest.approx(a.bias[0], abs=1e-12)
    r0 = simulate(scene, reduced_settings(scene))
    r1 = simulate(back, reduced_settings(back))
    assert r0.trajectory.t[-1] == r1.trajectory.t[-1]
    assert abs(r0.trajectory.q[-1] - r1.trajectory.q[-1]) < 1e-9


def test_two_motors_are_the_one_motor_split_in_halves():
    """Genesis' two-motor style: 125 N·m from one motor and 62.5 × gear 2 from the other on O1 are the
    seed's 250 N·m: the reduced engine gives the same trajectory to 1e-12 rad (measured equal), and the
    model as written moves as the one-motor model does (run_model, same options: equal to 1e-12)."""
    two, one = import_mjcf(DATA / "two_motor_fourbar.xml"), import_mjcf(DATA / "fourbar_sites_keyframe.xml")
    assert len(two.scene.mechanism.actuators) == 2 and two.scene.load is None
    a = simulate(two.scene, reduced_settings(two.scene))
    b = simulate(one.scene, reduced_settings(one.scene))
    assert np.max(np.abs(a.trajectory.q - b.trajectory.q)) < 1e-12
    assert abs(a.audit.torque_work[-1] - b.audit.torque_work[-1]) < 1e-9 * abs(b.audit.torque_work[-1])
    ma, mb = run_model(two), run_model(one)
    assert np.max(np.abs(ma.trajectory.q - mb.trajectory.q)) < 1e-12
    assert abs(ma.audit.torque_work[-1] - mb.audit.torque_work[-1]) < 1e-9 * abs(mb.audit.torque_work[-1])


def test_servo_on_a_fixed_tendon_as_written_is_the_oscillator():
    """Menagerie's gripper style (general, biastype affine, gainprm/biasprm from a default class, ctrlrange,
    a fixed tendon of coef 0.5): I θ̈ = 0.5 kp (c − 0.5 θ) − 0.25 kv θ̇ about 2c with c clamped to 1.
    The reduced engine to 1e-9 rad (measured 7e-12) and the model as written (RK4 at 5e-4 s) to 1e-6
    (measured 1e-12); both audits balance (reduced 2.4e-11 J, MuJoCo as written 9e-7 J)."""
    imported = import_mjcf(DATA / "servo_tendon_rotor.xml")
    (servo,) = imported.scene.mechanism.actuators
    assert servo.tendon == (("pivot", 0.5),) and servo.ctrlrange == (0.0, 1.0) and servo.bias == (0.0, -8.0, -0.6)
    reduced = simulate(imported.scene, reduced_settings(imported.scene))
    written = run_model(imported)
    inertia, kp, kv, target = 0.5, 2.0, 0.15, 2.0
    for result, tol in ((reduced, 1e-9), (written, 1e-6)):
        t = result.trajectory.t
        alpha = kv / (2 * inertia)
        wd = math.sqrt(kp / inertia - alpha * alpha)
        e0 = 0.2 - target
        exact = target + np.exp(-alpha * t) * (e0 * np.cos(wd * t) + (1.0 + alpha * e0) / wd * np.sin(wd * t))
        assert np.max(np.abs(result.trajectory.q - exact)) < tol, result.engine
    assert residual(reduced.audit) < 1e-9 and residual(written.audit) < 1e-5


def test_controls_by_name_replace_the_keyframe():
    """--ctrl NAME=... (import_mjcf's controls): each actuator its own; an unknown name is refused."""
    two = import_mjcf(DATA / "two_motor_fourbar.xml", controls={"left": Control.parse("0:250,0.5:0"),
                                                                  "right": Control.constant(0.0)})
    left, right = two.scene.mechanism.actuators
    assert left.control.edges == (0.0, 0.5) and right.control is None
    with pytest.raises(MjcfError, match="no actuator 'middle'"):
        import_mjcf(DATA / "two_motor_fourbar.xml", controls={"middle": Control.constant(1.0)})
    with pytest.raises(MjcfError, match="2 actuators: name the one"):
        import_mjcf(DATA / "two_motor_fourbar.xml", control=Control.constant(1.0))


ROTOR = """<mujoco>
  <option gravity="0 0 0"/>
  <worldbody><body name="rotor"><joint name="pivot" type="hinge" axis="0 0 1"/>
    <inertial pos="0 0 0" mass="1" diaginertia="0.5 0.5 0.5"/>
    <site name="tip" pos="0.3 0 0"/></body><site name="ground" pos="1 0 0"/></worldbody>
  <tendon><spatial name="line"><site site="ground"/><site site="tip"/></spatial></tendon>
  <actuator>{actuator}</actuator>
</mujoco>"""


@pytest.mark.parametrize("actuator, message", [
    ('<general joint="pivot" dyntype="filter" dynprm="0.1"/>', "actuator 'a0' has activation dynamics"),
    ('<general joint="pivot" gaintype="affine" gainprm="1 1"/>', "actuator 'a0' has gaintype"),
    ('<general tendon="line"/>', "actuator 'a0' acts on spatial tendon 'line'"),
    ('<general site="tip" gear="1 0 0 0 0 0"/>', "actuator 'a0' has a mjTRN_SITE transmission"),
    # the file's element named once (planted: the scene's value's message kept its own "actuator 'a0': ")
    ('<general joint="pivot" gear="0" biastype="affine" biasprm="0 -1 0"/>', r"xml: actuator 'a0': gear must be nonzero$"),
])
def test_refused_actuators_are_named(tmp_path, actuator, message):
    path = tmp_path / "m.xml"
    path.write_text(ROTOR.format(actuator=actuator.replace("<general ", '<general name="a0" ')))
    with pytest.raises(MjcfError, match=message):
        import_mjcf(path)


def test_the_model_as_written_counts_each_steps_control_at_both_its_ends(tmp_path):
    """run_model's audit of servo_fourbar exported (a servo on a joint and an affine actuator on a fixed
    tendon, controls that jump at 0.25, 0.4 and 0.6 s): the actuators' power at a step's end is taken
    with that step's control. Measured relative residual 8.4e-6 at 5e-4 s (8.1e-8 at a tenth of it:
    second order); planted, the next step's control there (the trapezoid of qfrc_actuator·qvel alone):
    2.9e-3 (2.9e-4 at a tenth: first order). Bound 5e-5."""
    scene = load_scene(SERVO_FOURBAR)
    path = tmp_path / "model.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=5e-4)))
    written = run_model(import_mjcf(path))
    assert written.audit.relative_residual < 5e-5


def _one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]


@pytest.mark.parametrize("flags, said", [
    (["--ctrl", "middle=1"], "no actuator 'middle'"),
    (["--ctrl", "left=1", "--ctrl", "left=2"], "--ctrl left=...: given twice"),
    (["--ctrl", "1"], "--ctrl VALUE: the model has 2 actuators"),
    (["--ctrl", "left=0:1,x"], "--ctrl"),
])
def test_cli_ctrl_by_name_refusals_are_one_line(tmp_path, capsys, flags, said):
    from loopcheck.compare.cli import main

    out = tmp_path / "s.toml"
    code = main(["import-mjcf", str(DATA / "two_motor_fourbar.xml"), *flags, "-o", str(out)])
    assert code == 2 and not out.exists()
    line = _one_error_line(capsys)
    assert said in line, line


def test_cli_ctrl_by_name_sets_each_actuators_control(tmp_path, capsys):
    from loopcheck.compare.cli import main
    from loopcheck.scenefile import load_scene as read

    out = tmp_path / "s.toml"
    assert main(["import-mjcf", str(DATA / "two_motor_fourbar.xml"), "--ctrl", "left=0:250,0.5:0",
                 "--ctrl", "right=3", "-o", str(out)]) == 0
    left, right = read(out).mechanism.actuators
    assert (left.control.times, left.control.values) == ((0.0, 0.5), (250.0, 0.0))
    assert right.control.amplitude == 3.0


def test_a_servo_with_a_clamped_force_runs_as_written_and_in_the_reduced_engine(tmp_path):
    """Menagerie's gripper actuator as written (a forcerange on a servo's force, which depends on the
    state): MuJoCo as written runs it and its audit balances with the clamp active (measured 8.6e-8 J of
    0.13 J of work); the reduced engine runs it with the clamp's switching as events (its audit measured
    3.2e-12 relative, bound 1e-9), the two agree within 1e-5 rad (measured 2.1e-8). (It was refused until
    the events were built: tests/reduced/test_clamp_events.py checks them on closed forms.)"""
    text = (DATA / "servo_tendon_rotor.xml").read_text().replace('ctrlrange="0 1"', 'ctrlrange="0 1" forcerange="-0.3 0.3"')
    path = tmp_path / "clamped.xml"
    path.write_text(text)
    imported = import_mjcf(path)
    assert imported.scene.mechanism.actuators[0].forcerange == (-0.3, 0.3)
    written = run_model(imported)
    force = written.trajectory.qddot  # I θ̈ = 0.5 f with I = 0.5: θ̈ is the force, held at the clamp
    assert np.max(np.abs(force)) == pytest.approx(0.3, abs=1e-9)
    assert residual(written.audit) < 1e-5
    reduced = simulate(imported.scene, reduced_settings(imported.scene))
    assert [e.mode for e in reduced.details.clamp_events][:2] == ["free", "lower"]  # from upper at the start
    assert reduced.audit.relative_residual < 1e-9
    q = np.interp(reduced.trajectory.t, written.trajectory.t, written.trajectory.q)
    assert np.max(np.abs(q - reduced.trajectory.q)) < 1e-5


def test_two_motors_on_the_two_ground_pivots_mujoco_against_reduced(tmp_path):
    """Genesis' two-motor four-bar: one motor on each ground pivot (O1: 125 N·m; O3: 62.5 × gear 2). MuJoCo
    built from the imported scene against the reduced engine at MuJoCo's automatic step (5e-4 s): measured
    max |Δq| 3.0e-7 rad, audits 6.4e-12 (reduced) and 1.2e-5 (MuJoCo) relative; bounds 1e-5 rad, 1e-9 and
    1e-4."""
    path = tmp_path / "pivots.xml"
    path.write_text((DATA / "two_motor_fourbar.xml").read_text().replace('joint="O1" gear="2"', 'joint="O3" gear="2"'))
    scene = import_mjcf(path).scene
    assert [a.joint for a in scene.mechanism.actuators] == ["O1", "O3"]
    reduced = simulate(scene, reduced_settings(scene))
    mujoco = simulate(scene, mujoco_settings(scene))
    q, _, _ = reduced.trajectory.interpolate(mujoco.trajectory.t)
    assert np.max(np.abs(q - mujoco.trajectory.q)) < 1e-5
    assert reduced.audit.relative_residual < 1e-9 and mujoco.audit.relative_residual < 1e-4


def test_an_input_motors_control_beyond_its_forcerange_is_clamped_as_mujoco_clamps_it(tmp_path):
    """The input motor's force gain × control is constant on each piece of its control, so its forcerange
    clamp is exact on the scene's load: the import warns and loads the clamped force (it refused before).
    Oracle: the same model with its control at the bound (ctrl 1 instead of 2 clamped to 1): the same
    scene load, the same reduced run, and MuJoCo as written (which clamps) the same run to the bit; the
    gap between the two engines is then the model's own (soft loops at Euler's step: 0.62 rad, which
    `check` reports with its cause), the same with and without the clamp. Planted: the unclamped force
    kept as the load: the loads differ (2 against 1 N·m): fails."""
    base = (DATA / "crank_rocker_keyframe.xml").read_text()
    clamped = tmp_path / "clamped.xml"
    clamped.write_text(base.replace('<motor gear="1" ctrlrange="-5 5"/>', '<motor gear="1" ctrlrange="-5 5" forcerange="-1 1"/>'))
    at_bound = tmp_path / "at_bound.xml"
    at_bound.write_text(base.replace('ctrl="2"', 'ctrl="1"'))
    imported, same = import_mjcf(clamped), import_mjcf(at_bound)
    assert any("clamped to its forcerange [-1, 1], as MuJoCo clamps it" in w for w in imported.warnings)
    assert imported.control.values == (2.0,)  # MuJoCo as written is fed the control as given, and clamps it
    assert imported.scene.load == same.scene.load and float(same.scene.load.sample(np.array([0.0]))[0]) == 1.0
    written, written_same = run_model(imported), run_model(same)
    assert np.array_equal(written.trajectory.q, written_same.trajectory.q)
    reduced, reduced_same = (simulate(i.scene, reduced_settings(i.scene)) for i in (imported, same))
    assert np.array_equal(reduced.trajectory.q, reduced_same.trajectory.q)


def test_ctrl_named_for_the_input_motor_is_its_control(tmp_path, capsys):
    """--ctrl drive=5 names the input motor: the same scene as a bare --ctrl 5, with --loop too (the
    foot four-bar's kept motor is its input motor); given twice, or an unknown name, refused."""
    import loop_robots as robots

    from loopcheck.compare.cli import main

    rotor, named, bare = DATA / "rotor_frictionloss.xml", tmp_path / "named.toml", tmp_path / "bare.toml"
    assert main(["import-mjcf", str(rotor), "--ctrl", "drive=5", "-o", str(named)]) == 0
    assert main(["import-mjcf", str(rotor), "--ctrl", "5", "-o", str(bare)]) == 0
    assert named.read_text() == bare.read_text() and "value = 5" in named.read_text()
    leg = tmp_path / "leg.xml"
    leg.write_text(robots.floating_leg())
    assert main(["import-mjcf", str(leg), "--loop", "foot_loop", "--ctrl", "foot_motor=0.002", "-o", str(named)]) == 0
    assert main(["import-mjcf", str(leg), "--loop", "foot_loop", "--ctrl", "0.002", "-o", str(bare)]) == 0
    assert named.read_text() == bare.read_text() and "value = 0.002" in named.read_text()
    capsys.readouterr()
    out = tmp_path / "x.toml"
    assert main(["import-mjcf", str(rotor), "--ctrl", "5", "--ctrl", "drive=5", "-o", str(out)]) == 2
    assert "--ctrl drive=...: given twice" in _one_error_line(capsys) and not out.exists()
    assert main(["import-mjcf", str(rotor), "--ctrl", "drive=5", "--ctrl", "drive=6", "-o", str(out)]) == 2
    assert "--ctrl drive=...: given twice" in _one_error_line(capsys)
    assert main(["import-mjcf", str(rotor), "--ctrl", "nope=5", "-o", str(out)]) == 2
    assert "no actuator 'nope'" in _one_error_line(capsys) and not out.exists()


def test_the_file_numeric_named_for_the_input_motor_is_its_control(tmp_path):
    """loopcheck.ctrl.drive names the input motor: its control, as loopcheck.ctrl; both refused."""
    text = (DATA / "rotor_frictionloss.xml").read_text()
    named = tmp_path / "named.xml"
    named.write_text(text.replace("</mujoco>", '<custom><numeric name="loopcheck.ctrl.drive" size="2" data="0 5"/>'
                                               "</custom></mujoco>"))
    imported = import_mjcf(named)
    assert imported.control == Control.constant(5.0)
    bare = import_mjcf(DATA / "rotor_frictionloss.xml", control=Control.constant(5.0))
    assert imported.scene.load == bare.scene.load and imported.scene.load is not None
    both = tmp_path / "both.xml"
    both.write_text(named.read_text().replace("<custom>", '<custom><numeric name="loopcheck.ctrl" size="2" data="0 4"/>'))
    with pytest.raises(MjcfError, match=r"'loopcheck.ctrl' and 'loopcheck.ctrl.drive' both give the input motor's "
                                        r"control"):
        import_mjcf(both)


def test_with_actuation_disabled_there_is_no_load_and_no_actuator(tmp_path, capsys):
    """MuJoCo applies no actuator force under actuation="disable": the scene has neither the input
    motor's load nor the other actuator, a warning says so, and a control given is refused
    (planted: the flag ignored, the 2 N·m load and the servo come back)."""
    from loopcheck.compare.cli import main
    path = tmp_path / "off.xml"
    path.write_text(ROTOR.format(actuator='<motor name="input_motor" joint="pivot"/>'
                                 '<position name="servo" joint="pivot" kp="3"/>')
                    .replace('<option gravity="0 0 0"/>', '<option gravity="0 0 0"><flag actuation="disable"/></option>')
                    .replace("</mujoco>", '<keyframe><key name="k" ctrl="2 0.5"/></keyframe></mujoco>'))
    imported = import_mjcf(path)
    assert imported.scene.load is None and imported.scene.mechanism.actuators == ()
    assert any('option flag actuation="disable"' in w for w in imported.warnings)
    with pytest.raises(MjcfError, match='--ctrl: option flag actuation="disable"'):
        import_mjcf(path, control=Control.constant(1.0))
    assert main(["import-mjcf", str(path), "--ctrl", "1", "-o", str(tmp_path / "out.toml")]) == 2
    err = capsys.readouterr().err
    assert err.count("error") == 1 and not (tmp_path / "out.toml").exists()


@pytest.mark.parametrize("joint, words", [
    ('<joint name="O1" actuatorfrcrange="-50 50"/>', "joint 'O1': actuatorfrcrange=\"-50 50\" cannot be represented"),
    ('<joint name="O1" actuatorfrcrange="-50 50" actuatorfrclimited="false"/>', None),
])
def test_a_joints_actuatorfrcrange_is_refused_by_name(tmp_path, joint, words):
    """MuJoCo clamps the total actuator force on a joint to its actuatorfrcrange (limited; autolimits
    makes a range limited); loopcheck has no such clamp: refused, never dropped (planted: accepted)."""
    path = tmp_path / "clamped.xml"
    text = (DATA / "two_motor_fourbar.xml").read_text()
    assert '<joint name="O1"/>' in text
    path.write_text(text.replace('<joint name="O1"/>', joint))
    if words is None:
        assert len(import_mjcf(path).scene.mechanism.actuators) == 2  # not limited: never clamps, imported
        return
    with pytest.raises(MjcfError, match=re.escape(words)) as caught:
        import_mjcf(path)
    assert "\n" not in str(caught.value)


def test_with_clampctrl_disabled_the_control_is_not_clamped(tmp_path):
    """MuJoCo leaves ctrl outside ctrlrange as given under clampctrl="disable" (measured: a motor's
    force 5 for ctrl 5 in [-1, 1]): the input motor's load and a servo's control are not clamped
    either (planted: the flag ignored, the load 1 and the servo's ctrlrange come back)."""
    path = tmp_path / "noclamp.xml"
    path.write_text(ROTOR.format(actuator='<motor name="input_motor" joint="pivot" ctrlrange="-1 1"/>'
                                 '<position name="servo" joint="pivot" kp="3" ctrlrange="-1 1"/>')
                    .replace('<option gravity="0 0 0"/>', '<option gravity="0 0 0"><flag clampctrl="disable"/></option>')
                    .replace("</mujoco>", '<keyframe><key name="k" ctrl="5 0.5"/></keyframe></mujoco>'))
    imported = import_mjcf(path)
    assert imported.scene.load(0.0) == 5.0
    assert imported.control.values == (5.0,)
    (servo,) = imported.scene.mechanism.actuators
    assert servo.ctrlrange is None
