"""The hard-case catalogue: every case runs, each engine does what is expected of it.

Each case is run once per session, on first use (real runs of both engines); the results
keep the engine runs, so no test simulates a case again. Each test reads one claim off
them; none is skipped or marked as expected to fail. The long cases (stiff_damper probes 12
MuJoCo configurations; long_conservative turns 200 times; fast_crank takes 60 000 MuJoCo
steps; off_grid_edge runs both engines twice) are marked slow.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from loopcheck.compare.diff import compare_modes, compare_trajectories
from loopcheck.compare.stress import CATALOGUE, CaseResult, RunStatus, run_case
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import load_scene
from oracles.four_bar import FourBar
from loopcheck.loads import PulseLoad
from loopcheck.trajectory import JointTrajectory
from loopcheck.reference_models import MujocoSettings, build_model, simulate_mujoco

CASES = [c.name for c in CATALOGUE]
BY_NAME = {c.name: c for c in CATALOGUE}
SLOW_CASES = {"stiff_damper", "long_conservative", "fast_crank", "off_grid_edge"}


def case_param(name: str):
    return pytest.param(name, marks=pytest.mark.slow) if name in SLOW_CASES else name


_RESULTS: dict[str, CaseResult] = {}


@pytest.fixture(scope="session")
def results():
    """The case results by name, each run on first use and kept for the session."""
    def get(name: str) -> CaseResult:
        if name not in _RESULTS:
            _RESULTS[name] = run_case(BY_NAME[name])
        return _RESULTS[name]
    return get


def test_catalogue_covers_the_eleven_kinds_of_hard_case():
    assert CASES == ["dead_centre", "start_dead_centre", "near_change_point", "stiff_damper",
                     "long_conservative", "fast_crank", "off_grid_edge", "gravity",
                     "slider_dead_centres", "sixbar_near_toggle", "five_bar_fold"]
    for case in CATALOGUE:
        text = case.path.read_text()
        assert "# HARD CASE" in text and "Expected:" in text  # each scene documents itself


@pytest.mark.parametrize("name", [case_param(n) for n in CASES])
def test_case_passes_over_the_whole_horizon(results, name):
    r = results(name)
    assert r.engines == ("reduced", "mujoco")  # the default pair, the reference first
    assert [o.status for o in r.outcomes] == [RunStatus.OK, RunStatus.OK]
    assert r.passed, r.problems
    d = r.outcome("mujoco").comparison.diff
    assert d.covers_horizon and d.span_end == pytest.approx(load_scene(BY_NAME[name].path).horizon)
    assert r.outcome("mujoco").figures["mode_mismatches"] == 0


@pytest.mark.parametrize("name", [case_param(n) for n in CASES])
def test_tolerances_are_within_10x_of_the_measured_differences(results, name):
    """Each scene sets its tolerances 3-10x above the differences measured (its comment
    says which): a tolerance far above them could never fail, one below would always. With several
    inputs each tolerance is held to the worse input's figure (the one nearest it)."""
    r = results(name)
    comparison = r.outcome("mujoco").comparison
    tol = comparison.gate.tolerances
    keys = ["peak", "q", "omega"] + (["omega_vs_q"] if tol.omega_vs_q_atol is not None else [])
    worst = dict.fromkeys(keys, 0.0)  # each check's largest measured / tolerance over the inputs
    for d in comparison.diffs:
        pairs = {"peak": (d.peak_omega_abs, tol.peak_omega_rtol * abs(d.peak_omega_reference) + tol.peak_omega_atol),
                 "q": (d.q_max_abs, tol.q_atol), "omega": (d.omega_max_abs, tol.omega_atol),
                 "omega_vs_q": (d.omega_vs_q_max_abs, tol.omega_vs_q_atol)}
        for key in keys:
            measured, tolerance = pairs[key]
            worst[key] = max(worst[key], measured / tolerance)
    for key, ratio in worst.items():
        assert 0.1 <= ratio <= 0.4, (key, ratio)


def test_dead_centre_switches_coordinate_and_stays_continuous(results):
    """Across a switch both charts describe the same instant: the angles agree to round-off
    (1e-12 rad) and the rates to 1e-9 rad/s (K of a well-conditioned chart is O(1-10))."""
    result = results("dead_centre").outcome("reduced").result
    switches = result.details.switches
    joints: JointTrajectory = result.joints
    assert len(switches) >= 2
    assert {s.old for s in switches} >= {"crank.angle"}  # q hands over before its dead centre
    assert set(np.unique(joints.mode)) == {-1, 1}  # the mode changes at the limit, tracked
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
    assert result.audit.relative_residual < 1e-9  # conservative: measured 6.9e-11 through the switches


def test_five_bar_fold_leaves_the_inputs_chart_and_is_judged_on_both_inputs(results):
    """The two-DOF case: the reference leaves the inputs' chart (O1, O5) before the arms fold, its
    joints continuous across the switch (the case's own check: 1e-12 rad, 1e-9 rad/s), and MuJoCo is
    judged on both inputs: its figures are the worse input's. Measured: max |Δq| 9.4e-7 rad on O1,
    1.0e-6 rad on O5, so the case's figure is O5's (a first-input-only figure would be O1's)."""
    r = results("five_bar_fold")
    reference = r.outcome("reduced").result
    assert r.figures["switches"] >= 1 and reference.details.switches[0].old == "O1, O5"
    assert any("coordinate switches" in note for note in r.notes)
    mujoco = r.outcome("mujoco")
    diffs = mujoco.comparison.diffs
    assert len(diffs) == 2 and all(d.covers_horizon for d in diffs)
    for key in ("peak_omega_rel", "q_max_abs", "omega_max_abs", "omega_vs_q_max_abs"):
        assert mujoco.figures[key] == max(getattr(d, key) for d in diffs), key
    assert diffs[1].q_max_abs > diffs[0].q_max_abs  # so the figure above is the second input's
    assert reference.audit.relative_residual < 1e-9  # measured 5.1e-12 (no damping, pulses do the work)


def test_an_off_grid_edge_on_a_scene_of_several_dof_fails_saying_so():
    """The off-grid edge is one input's pulse: asked of a two-DOF scene, the case fails naming why,
    never measures the first input's load alone."""
    from loopcheck.compare.stress import Case

    r = run_case(Case("fold_edge", BY_NAME["five_bar_fold"].scene_file, off_grid_edge=True))
    assert not r.passed
    assert r.problems == ("the off-grid edge is one input's pulse: scene 'five_bar_fold' has 2 degrees of freedom "
                          "(its loads are actuators)",)


def test_the_drift_of_a_scene_of_several_dof_counts_the_input_that_turns_most():
    """tests/data/five_bar_pendulum.toml (3 DOF) over its 0.8 s: the cranks turn 1.006 and 0.69
    revolutions, the wrist 4.30 (measured): drift per revolution is |ΔE|/E over the wrist's turns,
    not the first input's."""
    import loopcheck
    from loopcheck.compare.stress import _drift_per_revolution

    from helpers import ROOT

    result = loopcheck.simulate(load_scene(ROOT / "tests" / "data" / "five_bar_pendulum.toml"))
    turns = [abs(tr.q[-1] - tr.q[0]) / (2 * np.pi) for tr, _ in result.inputs]
    assert turns[2] > 4.0 > 1.0 > max(turns[1], turns[0] - 0.01)  # the wrist turns most, by far
    a = result.audit
    energy = a.kinetic + a.potential
    change = abs(energy[-1] - energy[0]) / max(a.scale, abs(energy[0]))
    assert _drift_per_revolution(result) == pytest.approx(change / turns[2], rel=1e-12)


def test_start_at_dead_centre_uses_another_coordinate(results):
    scene = load_scene(BY_NAME["start_dead_centre"].path)
    result = results("start_dead_centre").outcome("reduced").result
    joints = result.joints
    assert FourBar(scene.four_bar).conditioning(joints.x[0])[0] < 1e-9  # exactly at the limit
    assert joints.coordinate[0] != 0
    assert result.audit.relative_residual < 3e-10  # measured 2.9e-11


@pytest.mark.slow
def test_stiff_damper_instability_is_detected_and_stable_paths_agree(results):
    r = results("stiff_damper")
    assert r.outcome("reduced").figures["stability"]["rkn4@0.001"] == "unstable"
    table = r.outcome("mujoco").figures["stability"]
    assert set(table) == {f"{i}@{h:g}" for i in ("euler", "implicit", "implicitfast", "rk4")
                          for h in (1e-3, 1e-4, 1e-5)}
    assert all(table[f"{i}@1e-05"] == "ok" for i in ("euler", "implicit", "implicitfast", "rk4"))
    # Explicit integrators at 1 ms are far outside their stability region (h/τ ≈ 10).
    assert table["euler@0.001"] != "ok" and table["rk4@0.001"] != "ok"


@pytest.mark.slow
def test_long_run_energy_drift_is_bounded(results):
    r = results("long_conservative")
    revolutions_needed = 200
    scene = load_scene(BY_NAME["long_conservative"].path)
    assert scene.qdot0 * scene.horizon / (2 * np.pi) > revolutions_needed * 0.9  # ≥ 200 turns at speed
    # The bound is rtol × steps per revolution (an adaptive step keeps its local error below
    # rtol of the state); it is itself small, so the check means something.
    reduced, mujoco = (r.outcome(name).figures for name in ("reduced", "mujoco"))
    assert reduced["drift_bound"] < 1e-9
    assert reduced["drift_per_revolution"] <= reduced["drift_bound"]
    # MuJoCo's drift is reported, measured 1.1e-6 per turn at 0.5 ms; bound 5.4x. The reduced
    # drift, measured 5.5e-13 per turn, far inside its bound: held to 5.5x the measurement too.
    assert reduced["drift_per_revolution"] < 3e-12
    assert mujoco["drift_per_revolution"] < 6e-6


def test_off_grid_edge_is_warned_and_its_error_quantified(results):
    r = results("off_grid_edge")
    assert any("warned: yes" in n for n in r.notes)
    # The misplaced edge (0.37 ms early) costs far more than MuJoCo's own error on the grid
    # (measured 1.3e-2 against 6.9e-5 rad).
    figures = r.outcome("mujoco").figures
    assert figures["off_grid_q_max"] > 50 * figures["on_grid_q_max"]
    assert "off_grid_q_max" not in r.outcome("reduced").figures  # its steps adapt: no grid


@pytest.mark.slow
def test_off_grid_edge_error_is_first_order_in_the_misplacement():
    """The pulse ends δ early on MuJoCo's 1 ms grid: the crank misses an impulse T·δ, so
    its speed error after the edge, and the angle error it accumulates, are first order
    in δ. The fitted slope of max |Δq| against δ (0.37, 0.25, 0.12 ms) is 1 within 0.05
    (MuJoCo's own on-grid error, 6.9e-5 rad, is under 2 % of the smallest)."""
    scene = load_scene(BY_NAME["off_grid_edge"].path)
    deltas = np.array([0.37e-3, 0.25e-3, 0.12e-3])
    errors = []
    for delta in deltas:
        s = replace(scene, load=replace(scene.load, duration=1.0 + delta))
        assert isinstance(s.load, PulseLoad)
        reference = simulate(s, ReducedSettings(**s.engine_table("reduced")))
        with pytest.warns(UserWarning, match="not a multiple of the timestep"):
            other = simulate_mujoco(s, MujocoSettings(**s.engine_table("mujoco")))
        errors.append(compare_trajectories(reference.trajectory, other.trajectory).q_max_abs)
    slope = np.polyfit(np.log(deltas), np.log(errors), 1)[0]
    assert slope == pytest.approx(1.0, abs=0.05)


def test_gravity_only_where_declared_and_energy_conserved(results):
    r = results("gravity")
    assert r.outcome("reduced").figures["energy_residual"] < 4e-11  # measured 7.8e-12
    for case in CATALOGUE:  # MuJoCo's gravity is the scene's, or zero when it declares none
        scene = load_scene(case.path)
        expected = [*scene.gravity, 0.0] if scene.gravity is not None else [0.0, 0.0, 0.0]
        np.testing.assert_array_equal(build_model(scene).model.opt.gravity, expected)
    assert load_scene(BY_NAME["gravity"].path).gravity == (0.0, -9.81)


# The fast crank's peak from independent high-accuracy reduced runs (DOP853, samples every
# 0.1 ms so the interpolant is not the limit): rtol 1e-12 gives 998.0893449782 rad/s,
# rtol 1e-11 998.0893431560 (1.8e-9 apart), rtol 1e-12 with 20 µs samples 998.0893455623.
FAST_CRANK_PEAK = 998.089345  # rad/s, to ~2e-9 relative


@pytest.mark.slow
def test_fast_crank_peak_is_the_high_accuracy_value(results):
    """The catalogue's reference (rtol 1e-11, 1 ms samples) is 1.2e-8 below the value above
    (its 1 ms interpolant is the limit); bound 3e-8. MuJoCo at 2e-5 s within the scene's
    peak tolerance of it."""
    r = results("fast_crank")
    assert r.outcome("reduced").result.peak.omega == pytest.approx(FAST_CRANK_PEAK, rel=3e-8)
    assert r.outcome("mujoco").comparison.diff.peak_omega_other == pytest.approx(FAST_CRANK_PEAK, rel=3e-5)


def test_mode_jump_is_detected():
    """Put part of a trajectory in the other assembly mode: the check reports it on the loop."""
    from loopcheck.kinematics import assemble, assembly_modes, compile_linkage, positions

    scene = load_scene(BY_NAME["near_change_point"].path)
    system = compile_linkage(scene.mechanism.linkage)
    t = np.linspace(0.0, 1.0, 101)
    q = 0.2 + 3.0 * t

    def track(x):
        out = []
        for qq in q:
            x = assemble(system, float(qq), x)
            out.append(x)
        return np.array(out)

    x_right = track(np.asarray(scene.x0))
    # The other assembly at q0: B reflected in the line A-O3 (frames along the links).
    r = positions(system.points, np.asarray(scene.x0))
    A, B, O3 = (r[system.point_index(body, p)] for body, p in (("coupler", "A"), ("coupler", "B"),
                                                               ("rocker", "O3")))
    u = (O3 - A) / np.hypot(*(O3 - A))
    B2 = A + 2.0 * ((B - A) @ u) * u - (B - A)
    guess = np.array([scene.q0, np.arctan2(*(B2 - A)[::-1]), np.arctan2(*(B2 - O3)[::-1])])
    x_other = track(assemble(system, scene.q0, guess))
    assert np.all(assembly_modes(system, x_other) == -assembly_modes(system, x_right))
    x_wrong = np.vstack([x_right[:60], x_other[60:]])

    def joints(x):
        return JointTrajectory(system.coordinate_names, t, x, np.zeros_like(x), np.zeros(len(t), int),
                               assembly_modes(system, x))

    assert compare_modes(joints(x_right), joints(x_right)).total == 0
    check = compare_modes(joints(x_right), joints(x_wrong))
    assert check.mismatches == (41,) and check.first_times[0] == pytest.approx(0.6)
