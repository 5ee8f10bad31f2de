"""Gravity compensation (MuJoCo's body ``gravcomp``): a body's weight scaled by (1 − gravcomp) in
every engine that runs it (issue 36: a Playground-style finger with ``gravcomp="1"`` on every body
got the same exact answer as without it, and the check then failed by 10 %).

Oracles, independent of the code under test: a fully compensated finger moves as the same finger
with gravity off, and gravcomp 0.5 on every body as the finger under half the gravity; MuJoCo's own
run of the model as written (its passive gravcomp force) converges on the exact answer; MuJoCo's
energy balance closes with gravcomp's work counted (``mj_energyPos`` leaves it out). Refusals: a
NaN or negative gravcomp, welded bodies with different gravcomp, ``actuatorgravcomp`` clamped by
``actuatorfrcrange``. The pin engine's gravcomp is tested in tests/pin/test_pin_engine.py."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from loopcheck.reference_models import MujocoSettings, mjcf_text
from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf
from loopcheck.reference_models.run import simulate_mujoco
from loopcheck.reference_models.user_model import ModelOptions, run_model
from loopcheck.reduced.engine import simulate
from loopcheck.scene import SceneError
from loopcheck.scene_writer import scene_toml
from loopcheck.scenefile import load_scene

FINGER = Path(__file__).parent.parent / "data" / "mjcf" / "gravcomp_finger.xml"  # gravcomp="1" on every body


def _variant(tmp_path: Path, *changes: tuple[str, str], name: str = "finger.xml") -> Path:
    text = FINGER.read_text()
    for old, new in changes:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def _refusal(path: Path) -> str:
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path, keyframe="home")
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


def _scaled(scene, gravcomp: float, gravity_scale: float = 1.0):
    """The scene with every massive body's gravcomp set, and its gravity scaled."""
    linkage = scene.mechanism.linkage
    bodies = tuple(dataclasses.replace(b, gravcomp=gravcomp) if b.mass else b for b in linkage.bodies)
    mechanism = dataclasses.replace(scene.mechanism, linkage=dataclasses.replace(linkage, bodies=bodies))
    return dataclasses.replace(scene, mechanism=mechanism, gravity=tuple(gravity_scale * g for g in scene.gravity))


def test_the_finger_imports_with_its_gravcomp():
    """Every moving body of the finger carries gravcomp 1 (planted: the importer leaves it at 0)."""
    scene = import_mjcf(FINGER, keyframe="home").scene
    moving = [b for b in scene.mechanism.linkage.bodies if b.name != "ground"]
    assert moving and all(b.gravcomp == 1.0 for b in moving)


def test_the_exact_answer_is_gravitys_with_each_bodys_weight_scaled():
    """gravcomp 1 on every body gives the trajectory of gravity off, gravcomp 0.5 that of gravity at
    half strength (the same arithmetic, g·(1 − gravcomp) = g·0.5: compared to 1e-12 rad/s, round-off
    of the adaptive integrator's steps), and both differ from the full weight's by far more (planted:
    gravcomp ignored by the reduced engine, the peaks differ by 3.6 rad/s: −2.24 with the full
    weight, 1.37 compensated)."""
    scene = import_mjcf(FINGER, keyframe="home").scene
    compensated, off = simulate(scene), simulate(_scaled(scene, 0.0, 0.0))
    half, half_gravity = simulate(_scaled(scene, 0.5)), simulate(_scaled(scene, 0.0, 0.5))
    full = simulate(_scaled(scene, 0.0))
    for a, b in ((compensated, off), (half, half_gravity)):
        assert abs(a.peak.omega - b.peak.omega) <= 1e-12
        assert a.trajectory.t.shape == b.trajectory.t.shape
        assert np.max(np.abs(a.trajectory.qdot - b.trajectory.qdot)) <= 1e-12
    assert abs(compensated.peak.omega - full.peak.omega) > 1.0  # the weight matters: the test can see it


@pytest.mark.parametrize("gravcomp", [1.0, 0.5])
def test_mujoco_as_written_agrees_and_its_energy_balance_closes(tmp_path, gravcomp):
    """The model as written (its own passive gravcomp), at 1e-4 s and loops as stiff as MuJoCo
    allows: peak within 1e-3 of the exact one (MuJoCo's error at this step is ~1e-4 of it), and
    the energy balance closes to 1e-3 of the peak kinetic energy (measured 3e-4 and 5e-4; planted:
    gravcomp's work left out, the imbalance is the compensated weight's potential, 1.6 (gravcomp 1)
    and 0.49 (0.5) times the peak kinetic energy)."""
    path = _variant(tmp_path, ('gravcomp="1"', f'gravcomp="{gravcomp:g}"'))
    imported = import_mjcf(path, keyframe="home")
    exact = simulate(imported.scene)
    options = dataclasses.replace(ModelOptions.as_written(imported.model), timestep=1e-4).stiff_loops()
    model = run_model(imported, options)
    assert abs(model.peak.omega - exact.peak.omega) <= 1e-3 * abs(exact.peak.omega)
    audit = model.audit
    balance = audit.kinetic + audit.potential - audit.potential[0] - audit.torque_work + audit.damper_dissipation
    assert np.max(np.abs(balance)) <= 1e-3 * np.max(audit.kinetic)


def test_loopchecks_mujoco_model_applies_gravcomp_and_its_audit_closes():
    """The scene's own MuJoCo model (build.py sets each body's gravcomp) at 1e-4 s agrees with the
    exact peak to 1e-3 and its energy audit closes to 1e-3 of the peak kinetic energy (planted: the
    builder leaves gravcomp out, the peak is the full weight's, −2.24 rad/s against 1.37; the audit
    counts the weight in full, off by the compensated weight's potential)."""
    scene = import_mjcf(FINGER, keyframe="home").scene
    exact = simulate(scene)
    run = simulate_mujoco(scene, MujocoSettings(timestep=1e-4))
    assert abs(run.peak.omega - exact.peak.omega) <= 1e-3 * abs(exact.peak.omega)
    audit = run.audit
    balance = audit.kinetic + audit.potential - audit.potential[0] - audit.torque_work + audit.damper_dissipation
    assert np.max(np.abs(balance)) <= 1e-3 * np.max(audit.kinetic)


def test_the_scene_file_and_the_exported_mjcf_carry_gravcomp(tmp_path):
    """Scene writer → scene file, and export-mjcf → import-mjcf, give gravcomp 0.5 back (planted:
    the writer or the builder leaves it out: 0 comes back)."""
    scene = _scaled(import_mjcf(FINGER, keyframe="home").scene, 0.5)
    path = tmp_path / "finger.toml"
    path.write_text(scene_toml(scene))
    assert "gravcomp = 0.5" in path.read_text()
    assert load_scene(path).mechanism == scene.mechanism
    exported = tmp_path / "exported.xml"
    exported.write_text(mjcf_text(scene, MujocoSettings(timestep=1e-4)))
    back = import_mjcf(exported, input_joint=scene.mechanism.linkage.input_joint).scene
    assert {b.name: b.gravcomp for b in back.mechanism.linkage.bodies} == {
        b.name: b.gravcomp for b in scene.mechanism.linkage.bodies}


@pytest.mark.parametrize("value, words", [(-1.0, "'bodies.proximal.gravcomp' must not be negative, got -1.0"),
                                          (101.0, "'bodies.proximal.gravcomp' = 101 is out of range: gravity "
                                                  "compensation must be in ±100 (× the body's weight)")])
def test_a_gravcomp_outside_the_range_is_refused_in_the_scene_file(tmp_path, value, words):
    """The scene key bodies.<name>.gravcomp: ≥ 0 and at most 100 (MuJoCo takes any finite value;
    above 1 the body floats up)."""
    scene = _scaled(import_mjcf(FINGER, keyframe="home").scene, 0.5)
    path = tmp_path / "finger.toml"
    path.write_text(scene_toml(scene).replace("gravcomp = 0.5", f"gravcomp = {value}", 1))
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    assert str(caught.value) == f"{path}: {words}"


@pytest.mark.parametrize("value, words", [("nan", 'gravcomp="nan" is not a finite number'),
                                          ("-1", 'gravcomp="-1" cannot be represented: a body\'s gravity '
                                                 "compensation must be ≥ 0"),
                                          ("1000", "gravcomp = 1000 cannot be represented")])
def test_a_bad_gravcomp_is_refused_naming_the_body(tmp_path, value, words):
    """NaN, negative and out-of-range gravcomp refused in one line naming the body (planted: the
    check removed, NaN reaches the scene as 'body ...: gravcomp must be a finite number')."""
    path = _variant(tmp_path, ('<body name="follower" gravcomp="1"', f'<body name="follower" gravcomp="{value}"'))
    message = _refusal(path)
    assert "'follower'" in message and words in message


def test_welded_bodies_with_different_gravcomp_are_refused(tmp_path):
    """A body welded to the distal link with another gravcomp: its weight acts at another centre
    than its mass's, which one body cannot carry (planted: the check removed, the first value wins
    silently)."""
    path = _variant(tmp_path, ('<geom type="box" size="0.006 0.01 0.002" pos="0.025741623423167694 0 0"/>',
                               '<body name="pad" gravcomp="0.5" pos="0.025741623423167694 0 0"><geom type="box" '
                               'size="0.006 0.01 0.002"/></body>'))
    message = _refusal(path)
    assert "body 'distal' (gravcomp=\"1\") and body 'pad' (gravcomp=\"0.5\") are welded together" in message


def test_actuatorgravcomp_is_the_same_force_unless_clamped(tmp_path):
    """actuatorgravcomp without actuatorfrcrange: the same scene as the passive gravcomp, and MuJoCo's
    energy balance still closes (the motor's work leaves the gravcomp force out); with an
    actuatorfrcrange it is refused, naming the joint (planted: that refusal removed, it imports)."""
    plain = import_mjcf(FINGER, keyframe="home")
    routed_path = _variant(tmp_path, ('damping="0.00002"', 'damping="0.00002" actuatorgravcomp="true"'))
    routed = import_mjcf(routed_path, keyframe="home")
    assert routed.scene.mechanism == plain.scene.mechanism
    options = dataclasses.replace(ModelOptions.as_written(routed.model), timestep=1e-4).stiff_loops()
    audit = run_model(routed, options).audit
    balance = audit.kinetic + audit.potential - audit.potential[0] - audit.torque_work + audit.damper_dissipation
    assert np.max(np.abs(balance)) <= 1e-3 * np.max(audit.kinetic)
    clamped = _variant(tmp_path, ('damping="0.00002"', 'damping="0.00002" actuatorgravcomp="true" '
                                  'actuatorfrcrange="-1 1"'), name="clamped.xml")
    assert "joint 'finger_joint': actuatorgravcomp=\"true\" with actuatorfrcrange cannot be represented" in _refusal(
        clamped)


def test_zero_and_a_welded_body_stay_absent(tmp_path):
    """gravcomp="0" on every body, or gravcomp="1" on the base welded to the world only: the same
    mechanism as without gravcomp."""
    plain = import_mjcf(_variant(tmp_path, (' gravcomp="1"', "")), keyframe="home").scene
    zero = import_mjcf(_variant(tmp_path, ('gravcomp="1"', 'gravcomp="0"'), name="zero.xml"), keyframe="home").scene
    text = FINGER.read_text().replace(' gravcomp="1"', "").replace('<body name="base"', '<body name="base" gravcomp="1"')
    welded_path = tmp_path / "welded.xml"
    welded_path.write_text(text)
    welded = import_mjcf(welded_path, keyframe="home").scene
    assert all(b.gravcomp == 0.0 for b in plain.mechanism.linkage.bodies)
    assert zero.mechanism == plain.mechanism and welded.mechanism == plain.mechanism


def test_actuatorgravcomp_with_actuation_disabled_is_refused(tmp_path):
    """Under actuation="disable" MuJoCo drops the gravity compensation routed through the joint's
    actuator (qfrc_actuator is zero) but keeps it on the others: one body's gravcomp cannot carry
    that (planted: the refusal removed, it imports with the full compensation)."""
    path = _variant(tmp_path, ('damping="0.00002"', 'damping="0.00002" actuatorgravcomp="true"'),
                    ('gravity="0 0 -9.81"/>', 'gravity="0 0 -9.81"><flag actuation="disable"/></option>'))
    assert "actuatorgravcomp=\"true\" with option flag actuation=\"disable\" cannot be represented" in _refusal(path)
