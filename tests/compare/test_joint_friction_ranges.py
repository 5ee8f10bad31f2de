"""Dry joint friction (frictionloss) and joint ranges in MuJoCo, built from a scene and as written.

Oracles: the closed forms of a rotor on a pivot (I = 2 kg·m², friction f = 1 N·m; a 3 N·m pulse
for 1 s spins it to 1 rad/s, the friction stops it at t = 3 s, q = 1.5 rad, and holds it; the work of
the pulse, 3 × 0.5 J, is all dissipated), the reduced engine's exact solution, the energy balance
of MuJoCo's own run (the friction rows' dissipation counted), and the round trip export → import.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import loopcheck
from loopcheck.compare.cli import main
from loopcheck.compare.model_check import check_model
from loopcheck.reference_models.model_check import FRICTION_CAUSE, friction_snippet
from loopcheck.compare.run import compare_engines, judge
from loopcheck.mechanism import JointElement
from loopcheck.mujoco_model.port import PortRefusal, prepare
from loopcheck.mjx.settings import MjxSettings
from loopcheck.reference_models import MujocoSettings, mjcf_text
from loopcheck.reference_models.mjcf_import import Control, import_mjcf
from loopcheck.reference_models.user_model import run_model
from loopcheck.scenefile import scene_from_dict
from tests.reduced.test_joint_events import rotor

ROTOR = Path(__file__).parent.parent / "data" / "mjcf" / "rotor_frictionloss.xml"
PULSE = Control((0.0, 1.0), (3.0, 0.0))


def _written(tmp_path, name: str, *replacements: tuple[str, str]) -> Path:
    text = ROTOR.read_text()
    for old, new in replacements:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_joint_frictionloss_is_a_joint_friction_and_mujoco_meets_the_exact_stick():
    """The Menagerie-style rotor (frictionloss from its default class) reads as a 1 N·m joint
    friction; the reduced reference sticks at t = 3 s and q = 1.5 rad (closed form, measured to
    1e-15, asserted 1e-10); MuJoCo as written meets the gate (its creep measured 7e-6 rad on q,
    peak 1e-5 off), and its audit counts the friction: it dissipated the pulse's 1.5 J (measured
    1.4999; asserted 1e-3 relative, the trapezoid rule over MuJoCo's 1 ms states). Planted: the
    friction rows' power left out of run_model's audit (dissipation 0)."""
    imported = import_mjcf(ROTOR, control=PULSE, horizon=3.5)
    assert imported.scene.mechanism.joint_frictions == (JointElement("friction", "spin_frictionloss", "spin", 1.0),)
    reference = loopcheck.simulate(imported.scene, loopcheck.ReducedSettings(rtol=1e-12))
    tr = reference.trajectory
    assert tr.q[-1] == pytest.approx(1.5, abs=1e-10)
    assert tr.t[np.flatnonzero(tr.qdot != 0.0)[-1] + 1] == pytest.approx(3.0, abs=1e-10)
    written = run_model(imported)
    assert judge(imported.scene, reference, written, imported.scene.tolerances).gate.passed
    assert written.audit.damper_dissipation[-1] == pytest.approx(1.5, rel=1e-3)
    assert reference.audit.damper_dissipation[-1] == pytest.approx(1.5, abs=1e-9)


@pytest.mark.slow  # four MuJoCo runs as written over 2 s, one at a tenth of the step: 3 to 5 s
def test_soft_friction_is_named_and_its_snippet_fixes_it(tmp_path):
    """A light rotor (0.2 kg·m²) spun up by 3 N·m for 0.2 s, then held by f = 1 N·m against
    0.5 N·m from t = 1 s: MuJoCo's soft friction creeps 2.8e-3 rad by 2 s (measured) where the
    exact solution holds; neither stiff loops nor a tenth of the step helps, stiff friction rows
    do (1.5e-6 rad measured), so the check names the friction's softness, and its snippet pasted
    into the file passes. Planted: no stiff-friction trial (the cause then names the loops and the
    step)."""
    light = _written(tmp_path, "light.xml", ('diaginertia="2 2 2"', 'diaginertia="0.2 0.2 0.2"'))
    control = Control((0.0, 0.2), (3.0, 0.5))
    check = check_model(import_mjcf(light, control=control, horizon=2.0))
    assert not check.passed and check.cause == FRICTION_CAUSE
    fixed = _written(tmp_path, "fixed.xml", ('diaginertia="2 2 2"', 'diaginertia="0.2 0.2 0.2"'),
                     ("<default>\n", "<default>\n" + friction_snippet(0.001)[len("<default>"):-len("</default>")]))
    assert check_model(import_mjcf(fixed, control=control, horizon=2.0)).passed


def test_a_range_reached_fails_the_check_naming_the_joint(tmp_path, capsys):
    """range="-0.5 1.5" (autolimits: limited): 5 N·m reaches 1.5 rad at √(2·2·1.5/5) = 1.0954 s, and
    the check fails there (exit 1) naming the joint, the bound and the time; 0.5 N·m stays inside
    (exit 0). limited="false" reads no range."""
    ranged = _written(tmp_path, "ranged.xml", ('frictionloss="1"', 'range="-0.5 1.5"'))
    assert main(["check", str(ranged), "--ctrl", "5", "--horizon", "2"]) == 1
    out = capsys.readouterr().out
    assert "joint 'spin' reached the upper bound 1.5 rad of its range [-0.5, 1.5] rad at t = 1.09544512 s" in out
    assert main(["check", str(ranged), "--ctrl", "0.5", "--horizon", "2"]) == 0
    unlimited = _written(tmp_path, "unlimited.xml", ('frictionloss="1"', 'range="-0.5 1.5" limited="false"'))
    assert import_mjcf(unlimited, horizon=1.0).scene.mechanism.linkage.joints[0].range is None
    assert import_mjcf(ranged, horizon=1.0).scene.mechanism.linkage.joints[0].range == (-0.5, 1.5)


def test_a_range_reached_in_a_turned_body_quotes_the_file_s_range(tmp_path, capsys):
    """The rotor's body turned 0.3 rad in its plane: the scene's coordinate of 'spin' is qpos + 0.3,
    so range="-0.5 1.5" is [-0.2, 1.8] in the scene, reached at the same 1.0954 s (qpos 0 → 1.5);
    the failure quotes the file's range and the map (planted: the line left out)."""
    turned = _written(tmp_path, "turned.xml", ('frictionloss="1"', 'range="-0.5 1.5"'),
                      ('<body name="rotor">', '<body name="rotor" euler="0 0 0.3">'))
    assert main(["check", str(turned), "--ctrl", "5", "--horizon", "2"]) == 1
    out = capsys.readouterr().out
    assert "joint 'spin' reached the upper bound 1.8 rad of its range [-0.2, 1.8] rad at t = 1.09544512 s" in out
    assert ("      in the file: joint 'spin' has range=\"-0.5 1.5\" in its qpos; the scene's coordinate of joint "
            "'spin' is qpos + 0.3 rad\n") in out


def test_friction_and_ranges_survive_export_and_import(tmp_path):
    scene = scene_from_dict(rotor(friction=1.0, span=(-0.5, 8.0)))
    path = tmp_path / "rotor.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=1e-3)))
    back = import_mjcf(path, keyframe="home", horizon=scene.horizon)
    assert back.scene.mechanism.joint_frictions == scene.mechanism.joint_frictions
    assert [j.range for j in back.scene.mechanism.linkage.joints] == [(-0.5, 8.0)]
    assert back.warnings == ()


def test_mujoco_built_from_the_scene_meets_the_exact_friction():
    """The rotor scene with friction (2 kg·m², 5 N·m for 1 s, f = 1 N·m: sticks at 5 s, 5 rad):
    MuJoCo at 1 ms meets the gate (creep measured 2.8e-5 rad), and its audit, the friction
    tendon's dissipation counted, closes (measured 1.6e-8 J of 5 J; asserted 1e-5 relative)."""
    scene = scene_from_dict(rotor(friction=1.0))
    c = compare_engines(scene, mujoco=MujocoSettings(timestep=1e-3))
    assert c.gate.passed
    assert abs(c.other.trajectory.q[-1] - 5.0) < 1e-3
    assert c.other.audit.relative_residual < 1e-5


def test_mujocos_limit_is_a_note_and_the_ports_refuse(tmp_path):
    """MuJoCo alone runs the ranged rotor past its range and notes when its limit acted (the
    exact solution ends there); MJX refuses friction and ranges by name. The limit rows' work is
    booked with the dissipation, but the impact, inside a step, is resolved to first order by the
    trapezoid rule over the steps' starts: residual 6.2e-2 of the run's energy at 1 ms, 6.3e-3 at
    0.1 ms (measured), so the gate is loosened to 0.1 here."""
    scene = scene_from_dict(rotor(span=(-0.5, 1.5), torque={"type": "constant", "value": 5.0}, horizon=2.0))
    result = loopcheck.simulate(scene, MujocoSettings(timestep=1e-3, max_energy_residual=0.1))
    (note,) = result.caveats
    assert note.startswith("tendon 'O_range': MuJoCo's limit acted from t = 1.09")
    with pytest.raises(PortRefusal, match=r"^MJX does not run joint ranges \(O\)"):
        prepare(scene, MjxSettings(), "MJX", "mjx")
    with pytest.raises(PortRefusal, match=r"^MJX does not run joint friction \(joint_friction0\)"):
        prepare(scene_from_dict(rotor(friction=1.0)), MjxSettings(), "MJX", "mjx")


@pytest.mark.parametrize("flag, said", [
    ('frictionloss="disable"', 'option flag frictionloss="disable"'),
    ('limit="disable"', 'option flag limit="disable"'),
    ('constraint="disable"', 'option flag constraint="disable"'),
])
def test_a_disabled_flag_leaves_out_what_mujoco_does_not_apply(tmp_path, flag, said):
    """MuJoCo makes no friction-loss rows under frictionloss="disable", no limit rows under
    limit="disable", neither under constraint="disable": the scene has none either, and a warning
    says so (planted: the flags ignored, the friction and the range come back)."""
    path = _written(tmp_path, "flagged.xml", ('gravity="0 0 0"/>', f'gravity="0 0 0"><flag {flag}/></option>'),
                    ('<joint name="spin" class="rotor"/>', '<joint name="spin" class="rotor" range="-0.1 0.1"/>'))
    imported = import_mjcf(path)
    mechanism = imported.scene.mechanism
    friction_off = "limit" not in flag
    limit_off = "frictionloss" not in flag
    assert (mechanism.joint_frictions == ()) == friction_off
    assert (mechanism.linkage.joint_map["spin"].range is None) == limit_off
    assert sum(said in w for w in imported.warnings) == friction_off + limit_off


def test_with_frictionloss_disabled_mujoco_as_written_meets_the_free_rotor(tmp_path):
    """MuJoCo as written spins freely under frictionloss="disable" (the 3 N·m pulse for 1 s on
    2 kg·m²: 1.5 rad/s, kept); the imported scene's reference meets it (planted: the friction kept,
    the reference sticks at t = 3 s and the gate fails)."""
    path = _written(tmp_path, "free.xml", ('gravity="0 0 0"/>', 'gravity="0 0 0"><flag frictionloss="disable"/></option>'))
    imported = import_mjcf(path, control=PULSE, horizon=1.5)
    reference = loopcheck.simulate(imported.scene, loopcheck.ReducedSettings(rtol=1e-12))
    assert reference.trajectory.qdot[-1] == pytest.approx(1.5, abs=1e-9)  # closed form, round-off
    assert judge(imported.scene, reference, run_model(imported), imported.scene.tolerances).gate.passed
