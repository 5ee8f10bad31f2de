"""A joint inertia (MuJoCo's armature): ½ I u̇² on a joint's own coordinate, in both engines.

Oracles: on the crank's pin to ground it is the crank's pivot inertia plus I (closed form of the
same kinetic energy); both engines agree through a loop; the exported MJCF reads back the same
inertias; an MJCF joint armature reads as one.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import loopcheck
from tests.helpers import patched, variant
from loopcheck.compare.run import compare_engines
from loopcheck.reference_models import MujocoSettings, mjcf_text
from loopcheck.reference_models.mjcf_import import import_mjcf
from loopcheck.reference_models.user_model import ModelOptions, run_model
from loopcheck.scenefile import scene_from_dict


def test_an_inertia_on_the_cranks_pin_is_pivot_inertia():
    """I on O1 (u = the crank's angle) adds ½ I q̇² like I more pivot inertia: the reduced peaks
    agree to 2.2e-15 measured (asserted 1e-13), through a separate term of the kernel."""
    on_pin = loopcheck.simulate(variant(joint_inertias=[{"joint": "O1", "inertia": 0.7}]), loopcheck.ReducedSettings())
    heavier = loopcheck.simulate(scene_from_dict(patched({"bodies.crank.pivot_inertia": 2.2})), loopcheck.ReducedSettings())
    assert on_pin.peak.omega == pytest.approx(heavier.peak.omega, rel=1e-13)
    plain = loopcheck.simulate(variant(), loopcheck.ReducedSettings())
    assert abs(on_pin.peak.omega - plain.peak.omega) > 1.0  # it matters


def test_both_engines_agree_with_inertias_on_the_loop():
    """Inertias on the crank's pin and on B (which the tree then takes, the four-bar cut at
    another joint): MuJoCo at its automatic step meets the seed's gate (measured 6.2e-6 on the
    peak), both energy audits close, and both start from the same kinetic energy."""
    scene = variant(joint_inertias=[{"joint": "O1", "inertia": 0.7}, {"joint": "B", "inertia": 0.3, "name": "rotor"}])
    assert "B" not in scene.mechanism.linkage.cut_joints and "joint-inertia" in scene.effects
    c = compare_engines(scene)
    assert c.gate.passed
    assert c.other.audit.kinetic[0] == pytest.approx(c.reference.audit.kinetic[0], rel=1e-12)


def test_mujoco_refuses_an_inertia_it_cannot_hold():
    """On every joint of one loop, one inertia must sit on the cut joint: MuJoCo's tendon
    armature keeps only one branch's mass-matrix terms (it would not be ½ I u̇²), so the MuJoCo
    engine refuses, naming the inertia; the reduced engine runs it."""
    scene = variant(joint_inertias=[{"joint": j, "inertia": 0.1, "name": f"rotor_{j}"} for j in ("O1", "A", "B", "O3")])
    with pytest.raises(ValueError, match="joint inertia 'rotor_.*closes a loop"):
        mjcf_text(scene, MujocoSettings(timestep=1e-3))
    assert loopcheck.simulate(scene, loopcheck.ReducedSettings()).audit.relative_residual < 1e-9


def test_inertias_survive_export_and_import(tmp_path):
    scene = variant(joint_inertias=[{"joint": "O1", "inertia": 0.7}, {"joint": "B", "inertia": 0.3, "name": "rotor"}])
    path = tmp_path / "model.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=1e-3)))
    back = import_mjcf(path, keyframe="home", horizon=scene.horizon).scene
    assert back.mechanism.joint_inertias == scene.mechanism.joint_inertias


def test_a_joint_armature_is_a_joint_inertia(tmp_path):
    """MJCF armature on a hinge reads as a joint inertia on it; MuJoCo's own run of the model
    (stiff loops at 0.25 ms) meets the seed's tolerances against the reduced solution."""


    source = (Path(__file__).parent.parent / "data" / "mjcf" / "fourbar_sites_keyframe.xml").read_text()
    path = tmp_path / "armature.xml"
    path.write_text(source.replace('<joint name="A"/>', '<joint name="A" armature="0.3"/>'))
    imported = import_mjcf(path, keyframe="assembled", horizon=1.0)
    (inertia,) = imported.scene.mechanism.joint_inertias
    assert (inertia.name, inertia.joint, inertia.coefficient) == ("A_armature", "A", 0.3)
    reference = loopcheck.simulate(imported.scene, loopcheck.ReducedSettings())
    stiff = run_model(imported, ModelOptions.as_written(imported.model).stiff_loops())
    assert stiff.peak.omega == pytest.approx(reference.peak.omega, rel=1e-4)
