"""The hard-case catalogue: every case runs, each engine does what is expected of it.

The catalogue is run once for the module (real runs of both engines, ~1 min). Each test
reads one claim off the results; none is skipped or marked as expected to fail.
"""

from __future__ import annotations

import numpy as np
import pytest

from compare.diff import compare_branches
from compare.stress import CATALOGUE, run_catalogue
from reduced import ReducedSettings, load_scene, simulate
from reduced.linkage import FourBar
from reduced.partition import JointTrajectory
from reference_models import build_model

CASES = [c.name for c in CATALOGUE]


@pytest.fixture(scope="module")
def results():
    return {r.name: r for r in run_catalogue()}


def test_catalogue_covers_the_eight_kinds_of_hard_case():
    assert CASES == ["dead_centre", "start_dead_centre", "near_change_point", "stiff_damper",
                     "long_conservative", "fast_crank", "off_grid_edge", "gravity"]
    for case in CATALOGUE:
        text = case.path.read_text()
        assert "# HARD CASE" in text and "Expected:" in text  # each scene documents itself


@pytest.mark.parametrize("name", CASES)
def test_case_passes_with_both_engines_finishing(results, name):
    r = results[name]
    assert r.reduced_status == "ok" and r.mujoco_status == "ok"
    assert r.passed, r.problems
    # Agreement within the per-case tolerances in each scene file (see their comments).
    assert np.isfinite(r.figures["peak_omega_rel"]) and np.isfinite(r.figures["q_max_abs"])
    assert r.figures["branch_mismatches"] == 0


def test_dead_centre_switches_coordinate_and_stays_continuous():
    """Across a switch both charts describe the same instant: the angles agree to round-off
    (1e-12 rad) and the rates to 1e-9 rad/s (K of a well-conditioned chart is O(1-10))."""
    result = simulate(load_scene(CATALOGUE[0].path))
    switches = result.diagnostics["switches"]
    joints: JointTrajectory = result.diagnostics["joints"]
    assert len(switches) >= 2
    assert {s["old"] for s in switches} >= {"q"}  # q hands over before its dead centre
    assert set(np.unique(joints.branch)) == {-1, 1}  # the branch changes at the limit, tracked
    same = np.diff(joints.t) == 0.0
    assert same.sum() == len(switches)
    assert np.max(np.abs(np.diff(joints.x, axis=0))[same]) < 1e-12
    assert np.max(np.abs(np.diff(joints.xdot, axis=0))[same]) < 1e-9
    # Between samples the angles move smoothly: no jump bigger than max rate × spacing.
    dt = np.diff(joints.t)
    moving = dt > 0
    speed = np.max(np.abs(joints.xdot))
    assert np.all(np.abs(np.diff(joints.x, axis=0))[moving] <= 1.01 * speed * dt[moving, None])
    # The input link reaches its limit q = 0.29655 rad (and 2π − it) but never goes past it.
    q_limit = np.arccos((0.7**2 + 0.45**2 - 0.3**2) / (2 * 0.7 * 0.45))
    assert joints.x[:, 0].min() >= q_limit - 1e-9
    assert joints.x[:, 0].min() < q_limit + 1e-3
    assert result.audit.relative_residual < 1e-8  # conservative: energy kept through the switches


def test_start_at_dead_centre_uses_another_coordinate(results):
    scene = load_scene(CATALOGUE[1].path)
    result = simulate(scene)
    joints = result.diagnostics["joints"]
    assert FourBar(scene.linkage).conditioning(joints.x[0])[0] < 1e-9  # exactly at the limit
    assert joints.coordinate[0] != 0
    assert result.audit.relative_residual < 1e-8


def test_stiff_damper_instability_is_detected_and_stable_paths_agree(results):
    r = results["stiff_damper"]
    assert r.figures["rkn4_status"] == "unstable"
    table = r.figures["mujoco_stability"]
    assert set(table) == {f"{i}@{h:g}" for i in ("euler", "implicit", "implicitfast", "rk4")
                          for h in (1e-3, 1e-4, 1e-5)}
    assert all(table[f"{i}@1e-05"] == "ok" for i in ("euler", "implicit", "implicitfast", "rk4"))
    # Radau (the scene's reference) and MuJoCo RK4 at 0.1 ms agree to 1e-4 in peak ω.
    assert r.figures["peak_omega_rel"] < 1e-4


def test_long_run_energy_drift_is_bounded(results):
    r = results["long_conservative"]
    revolutions_needed = 200
    scene = load_scene(CATALOGUE[4].path)
    assert scene.qdot0 * scene.horizon / (2 * np.pi) > revolutions_needed * 0.9  # ≥ 200 turns at speed
    # The bound is rtol × steps per revolution (an adaptive step keeps its local error below
    # rtol of the state); it is itself small, so the check means something.
    assert r.figures["reduced_drift_bound"] < 1e-9
    assert r.figures["reduced_drift_per_revolution"] <= r.figures["reduced_drift_bound"]
    assert r.figures["mujoco_drift_per_revolution"] < 1e-5  # reported; MuJoCo's is O(h²) per turn


def test_off_grid_edge_is_warned_and_its_error_quantified(results):
    r = results["off_grid_edge"]
    assert any("warned: yes" in n for n in r.notes)
    # The misplaced edge (0.37 ms early) costs far more than MuJoCo's own error on the grid.
    assert r.figures["off_grid_q_max"] > 10 * r.figures["on_grid_q_max"]


def test_gravity_only_where_declared_and_energy_conserved(results):
    r = results["gravity"]
    assert r.figures["reduced_energy_residual"] < 1e-9
    for case in CATALOGUE:  # MuJoCo's gravity is the scene's, or zero when it declares none
        scene = load_scene(case.path)
        expected = [*scene.gravity, 0.0] if scene.gravity is not None else [0.0, 0.0, 0.0]
        np.testing.assert_array_equal(build_model(scene).model.opt.gravity, expected)
    assert load_scene(CATALOGUE[7].path).gravity == (0.0, -9.81)


def test_fast_crank_reaches_about_1000_rad_per_s(results):
    result = simulate(load_scene(CATALOGUE[5].path), ReducedSettings(rtol=1e-9))
    assert 800.0 < result.peak.omega < 1200.0


def test_branch_jump_is_detected():
    """Put part of a trajectory on the other assembly branch: the check reports it."""
    scene = load_scene(CATALOGUE[2].path)
    linkage = FourBar(scene.linkage)
    t = np.linspace(0.0, 1.0, 101)
    q = 0.2 + 3.0 * t
    x_right = np.array([linkage.assemble(qq, 1) for qq in q])
    x_wrong = x_right.copy()
    x_wrong[60:] = [linkage.assemble(qq, -1) for qq in q[60:]]

    def joints(x):
        return JointTrajectory(linkage.coordinate_names, t, x, np.zeros_like(x), np.zeros(len(t), int),
                               linkage.branches(x))

    assert compare_branches(joints(x_right), joints(x_right)).mismatches == 0
    check = compare_branches(joints(x_right), joints(x_wrong))
    assert check.mismatches == 41 and check.first_time == pytest.approx(0.6)
