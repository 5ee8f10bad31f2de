"""The catalogue's friction_fourbar (scenes/mechanisms/friction_fourbar.toml): the seed four-bar
with dry friction on O1 (30 N·m) and on the cut joint B (5 N·m) and its damper, spun up by a
150 N·m pulse for 0.5 s, stopped and then held by the friction.

Oracles: the energy balance (at rest, the pulse's work is all dissipated by the damper and the
friction), the friction split in halves (two 15 N·m elements on O1 run the same motion), and
MuJoCo built from the scene (its own soft friction) within the scene's tolerances.
"""

from __future__ import annotations

import numpy as np
import pytest

import loopcheck
from loopcheck.compare.run import compare_engines
from loopcheck.scene_writer import scene_data
from loopcheck.scenefile import load_scene, scene_from_dict

from helpers import ROOT

PATH = ROOT / "scenes" / "mechanisms" / "friction_fourbar.toml"


def test_it_sticks_and_its_energy_balances():
    """A stick phase from t ≈ 2.18 s to the horizon with q̇ = q̈ = 0 exactly; at rest the work of
    the pulse (250 J) equals the dissipation to 2e-10 J (measured; asserted 1e-8 J), and the
    audit's residual is 1.2e-11 of the run's energy (asserted 1e-9)."""
    scene = load_scene(PATH)
    assert scene.effects == ("torque", "damper", "joint-friction")
    result = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-12))
    tr = result.trajectory
    stuck = np.flatnonzero(tr.qdot == 0.0)
    start = tr.t[stuck[stuck > 0][0]]
    assert 2.0 < start < 2.5
    (event,) = result.details.friction_events  # one change of mode: the stick
    assert (event.mode, event.time) == ("stick", start)
    held = tr.t > start  # (the slip segment's last sample, at the same time, has q̇ = 0 and its q̈)
    assert np.all(tr.qdot[held] == 0.0) and np.all(tr.qddot[held] == 0.0) and np.ptp(tr.q[held]) == 0.0
    audit = result.audit
    assert audit.torque_work[-1] == pytest.approx(audit.damper_dissipation[-1], abs=1e-8)
    assert audit.relative_residual < 1e-9


def test_the_friction_split_in_halves_runs_the_same_motion():
    """30 N·m on O1 as one element or as 15 + 15: the same motion, to the bit (the kernel sums the
    frictions of one joint, 15 + 15 = 30 exactly). Planted: the frictions kept apart (the
    capacity then summed from two terms: other steps)."""
    data = scene_data(load_scene(PATH))
    one = scene_from_dict(data)
    frictions = [f for f in data["joint_frictions"] if f["joint"] != "O1"]
    data["joint_frictions"] = frictions + [{"name": f"half{k}", "joint": "O1", "friction": 15.0} for k in (1, 2)]
    two = scene_from_dict(data)
    settings = loopcheck.ReducedSettings(rtol=1e-12)
    a, b = loopcheck.simulate(one, settings).trajectory, loopcheck.simulate(two, settings).trajectory
    assert np.array_equal(a.t, b.t) and np.array_equal(a.q, b.q)


def test_mujoco_meets_the_scenes_tolerances():
    """MuJoCo at its automatic step (the friction a tendon's frictionloss on each joint's
    coordinate): within the scene's tolerances (measured peak 7.5e-5, |dq| 7.8e-4 rad)."""
    assert compare_engines(load_scene(PATH)).gate.passed
