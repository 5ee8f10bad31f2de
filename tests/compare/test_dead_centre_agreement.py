"""Both engines from a start where the input angle q is not the reduced engine's coordinate.

Near an input-link dead centre the reduced engine starts in (or switches to) a chart whose
independent coordinate is φ1 or φ2; the closed-form dyad solution of that chart used to return
the dependent angles in another turn than the assembled configuration (q = q0 − 2π), so the
reduced trajectory was the scene's motion shifted by 2π in q: MuJoCo and the reduced engine
disagreed by 6.283 rad at every MuJoCo step while ω agreed to 1e-6 (found on random four-bars,
with an independent Lagrange-multiplier DAE integration agreeing with MuJoCo and with the
shifted reduced run to 3e-11 rad once the shift was removed).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from loopcheck.compare.run import compare_engines
from oracles.four_bar import FourBar
from loopcheck.reduced import MechanismModel, simulate
from loopcheck.scenefile import scene_from_dict
from loopcheck.reduced.charts import Chart

# q0 = 2.379 rad is within the hysteresis of a dead centre: the run starts in a φ chart and never
# leaves it. Measured |Δq| 3.2e-10 rad between the engines (MuJoCo's automatic step, 0.5 ms).
START_IN_PHI_CHART = {
    "name": "start_in_phi_chart",
    "linkage": {"type": "four_bar", "c1": 0.372, "c2": 1.549, "c3": 1.912, "c4": 0.301, "branch": -1},
    "bodies": {"crank": {"pivot_inertia": 1.5},
               "coupler": {"mass": 17.4, "inertia": 5.0, "com": [0.643, -0.091]},
               "rocker": {"pivot_inertia": 3.5}},
    "initial": {"q": 2.379, "qdot": 0.977},
    "simulation": {"horizon": 1.0},
}
# q0 = 3.13 rad, just below π, under gravity: starts in the φ2 chart, passes a dead centre and
# switches twice (φ2 → q → φ1). Measured |Δq| 1.2e-6 rad (MuJoCo's automatic step, 0.125 ms).
THROUGH_DEAD_CENTRE = {
    "name": "through_dead_centre",
    "gravity": [0.0, -9.81],
    "linkage": {"type": "four_bar", "c1": 0.384, "c2": 1.674, "c3": 1.822, "c4": 0.451, "branch": -1},
    "bodies": {"crank": {"mass": 1.18, "inertia": 0.465, "com": [0.192, 0.0]},
               "coupler": {"mass": 12.4, "inertia": 5.0, "com": [1.217, -0.185]},
               "rocker": {"mass": 1.42, "inertia": 0.223, "com": [0.911, 0.0]}},
    "initial": {"q": 3.13, "qdot": 7.2},
    "simulation": {"horizon": 0.5},
}
# Bound on max |Δq| between the engines: 5-6x the measured difference (a 2π shift is 6.28 rad).
CASES = [(START_IN_PHI_CHART, 0, 2e-9), (THROUGH_DEAD_CENTRE, 2, 6e-6)]


@pytest.mark.parametrize("data, switches, q_bound", CASES, ids=[c[0]["name"] for c in CASES])
def test_reduced_run_starts_at_the_assembled_state(data, switches, q_bound):
    """The reduced trajectory's first sample is the scene's configuration, in the same turn."""
    scene = scene_from_dict(data)
    result = simulate(scene)
    joints = result.joints
    assert joints.coordinate[0] != 0, "precondition: the run starts in a φ chart"
    assert len(result.details.switches) == switches
    # Round-off of the closed-form dyad solution (1e-15 rad); a wrong turn is off by 6.28.
    closed_form = FourBar(scene.four_bar).assemble(scene.q0) + np.array([0.0, 0.0, np.pi])  # rocker frame O3 → B
    np.testing.assert_allclose(joints.x[0], closed_form, rtol=0, atol=1e-12)
    assert result.trajectory.q[0] == pytest.approx(scene.q0, abs=1e-12)


@pytest.mark.parametrize("data, switches, q_bound", CASES, ids=[c[0]["name"] for c in CASES])
def test_engines_agree_from_a_phi_chart_start(data, switches, q_bound):
    """MuJoCo (maximal coordinates, no charts) and the reduced engine agree in q, not modulo 2π."""
    scene = scene_from_dict(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        comparison = compare_engines(scene)
    assert comparison.gate.passed, comparison.gate.failures
    assert comparison.diff.q_max_abs <= q_bound
    assert comparison.modes.total == 0


def test_chart_continues_the_turn_of_its_start():
    """A chart of φ1 or φ2 (:class:`loopcheck.reduced.charts.Chart`, compiled Newton from the chart's
    last configuration) started at the closed form's configuration shifted by whole turns in
    the dependent angles keeps those turns as it walks (0.01 rad along its coordinate), and
    lands on the closed form modulo 2π (the chart's continuity relies on it; the closed-form
    dyad solution once returned another turn: the engines then disagreed by 2π in q)."""
    scene = scene_from_dict(START_IN_PHI_CHART)
    linkage = FourBar(scene.four_bar)
    model = MechanismModel(scene)
    checked = 0
    for q in np.linspace(-3.0, 3.0, 13):
        try:
            x = linkage.to_general(linkage.assemble(float(q)))  # general (crank, coupler, rocker)
        except ValueError:
            continue
        for i in (1, 2):
            if linkage.conditioning(linkage.assemble(float(q)))[i] < 0.1:  # near the chart's own dead centre
                continue
            for turns in (-1, 0, 1):
                start = x + 2.0 * math.pi * turns * (np.arange(3) != i)
                kin = Chart(model, i, start).kinematics(float(x[i]) + 0.01)
                # moved by |K| · 0.01 ≤ 0.1 rad here; another turn is 6.28 rad away
                assert np.max(np.abs(kin.x - start)) < 0.5, (q, i, turns, kin.x, start)
                wrapped = np.angle(np.exp(1j * (kin.x - start)))
                np.testing.assert_allclose(kin.x - start, wrapped, rtol=0, atol=1e-12)
                closed = linkage.to_general(linkage.assemble(float(kin.x[0])))  # same branch, mod 2π
                assert np.max(np.abs(np.angle(np.exp(1j * (kin.x - closed))))) < 1e-9, (q, i, kin.x, closed)
                checked += 1
    assert checked >= 12


# A triple rocker at 9.9 rad/s: DOP853 (the default reference) tries a stage past the reach of
# the φ2 chart (|cos α| > 1 in the dyad solution) before the switch event fires and stops with
# a singular position at t = 0.24 s; RKN4 and Radau pass (3 switches). Found on 3 of ~600
# random valid four-bars. The fix belongs in loopcheck/reduced/charts.py or loopcheck/reduced/integrators.py.
DOP853_PAST_CHART_REACH = {
    "name": "dop853_past_chart_reach",
    "linkage": {"type": "four_bar", "c1": 1.622, "c2": 0.8123, "c3": 1.2582, "c4": 0.4901, "branch": 1},
    "bodies": {"crank": {"pivot_inertia": 1.5},
               "coupler": {"mass": 40.0, "inertia": 5.0, "com": [0.5111, 0.1333]},
               "rocker": {"pivot_inertia": 3.5}},
    "torque": {"type": "pulse", "value": 35.2, "start": 0.086, "duration": 0.215},
    "initial": {"q": -0.01136, "qdot": 9.859},
    "simulation": {"horizon": 0.5},
}


def test_default_reference_passes_a_fast_dead_centre():
    result = simulate(scene_from_dict(DOP853_PAST_CHART_REACH))
    assert len(result.details.switches) == 3
    # Radau at rtol 1e-12 measures 1.1e-12 on this scene; DOP853 elsewhere ~1e-11.
    assert result.audit.relative_residual < 1e-9


# A short-coupler triple rocker under gravity, spring and damper, started inside a φ chart (14
# switches in 0.4 s). |ω| has near-equal extrema: the global one at t = 0.014245 s lies between
# the reference's 1 ms samples, and its largest sample there (13.8409) is below the largest
# sample of another extremum (13.8445 at t = 0.353 s). Trajectory.peak_rate refines
# only around the largest sample, so the reduced peak is −13.844503 against MuJoCo's −13.847762
# (automatic 0.5 ms step): 2.35e-4 relative at every MuJoCo step, gate failed. An independent
# DAE integration (three joint angles, Lagrange multipliers, DOP853 rtol 1e-12, 1 µs grid) puts
# the peak at −13.8487445140 rad/s, t = 0.014245 s.
PEAK_BETWEEN_SAMPLES = {
    "name": "peak_between_samples",
    "gravity": [0.0, -9.81],
    "linkage": {"type": "four_bar", "c1": 1.8486439005233317, "c2": 0.13755483351109005,
                "c3": 0.7478344723940439, "c4": 1.3029167474133803, "branch": 1},
    "bodies": {"crank": {"mass": 0.7897567585776608, "inertia": 0.3758097320966053,
                         "com": [0.9243219502616659, 0.0]},
               "coupler": {"mass": 6.856734856542474, "inertia": 5.0,
                           "com": [0.09873586912303196, 0.1986080136257899]},
               "rocker": {"mass": 2.7802599731147057, "inertia": 0.8127318764404874,
                          "com": [0.37391723619702194, 0.0]}},
    "dampers": [{"coefficient": 9.394842881576299, "ground_point": [1.3, 0.12], "body": "coupler",
                 "body_point": [0.13755483351109005, 0.0]}],
    "springs": [{"stiffness": 317.52400653416777, "rest_length": 0.3636278860520819,
                 "ground_point": [0.3252688601563072, 0.4846443387365831], "body": "rocker",
                 "body_point": [0.2, 0.0]}],
    "initial": {"q": 0.4433350462220931, "qdot": -4.068258108286629},
    "simulation": {"horizon": 0.4},
}
PEAK_BETWEEN_SAMPLES_ORACLE = -13.8487445140  # rad/s, the independent DAE integration above


def test_peak_between_samples_is_found():
    """|ω| has near-equal extremes; the true top (oracle −13.8487445140 rad/s) falls between the
    reduced run's samples while another extremum has the larger sample (13.8445): refining only
    around the largest sample reported −13.844503, 2.35e-4 relative off, at every MuJoCo step."""
    scene = scene_from_dict(PEAK_BETWEEN_SAMPLES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        comparison = compare_engines(scene)
    # With the refinement around every local maximum: reduced −13.848744524 (1.0e-8 from the
    # oracle: the bound is 5x that), engines 1.76e-6 apart (bound 1e-5, ~6x).
    assert comparison.reference.peak.omega == pytest.approx(PEAK_BETWEEN_SAMPLES_ORACLE, abs=5e-8)
    assert comparison.diff.peak_omega_rel <= 1e-5
    assert comparison.gate.passed, comparison.gate.failures


# Random valid four-bars started near an input dead centre (helper's generator, seed 8): the
# first balanced its energy to 1.23e-9 at rtol 1e-12 and failed the bound 1000 × rtol before
# the bound got its floor (the audit's own accuracy, ENERGY_FLOOR); the second stopped at a
# singular position, loudly, before the compiled core.
NEAR_DEAD_CENTRE_ENERGY = {
    "linkage": {"type": "four_bar", "c1": 0.1749518900706536, "c2": 1.7097807659213184,
                "c3": 1.8820335140425044, "c4": 0.7074123058607469, "branch": 1},
    "bodies": {"crank": {"pivot_inertia": 1.5},
               "coupler": {"mass": 21.003317653825594, "inertia": 5.0,
                           "com": [0.7629353368506654, 0.07407101008429323]},
               "rocker": {"pivot_inertia": 3.5}},
    "initial": {"q": -2.646142391242351, "qdot": -6.6412245707209365},
    "simulation": {"horizon": 1.0},
}
NEAR_DEAD_CENTRE_SINGULAR = {
    "gravity": [0.0, -9.81],
    "linkage": {"type": "four_bar", "c1": 0.6308765585455877, "c2": 1.1030368635416494,
                "c3": 1.9781234635416494, "c4": 0.35993116332811304, "branch": -1},
    "bodies": {"crank": {"mass": 4.3154100979318795, "inertia": 0.6540828655641658,
                         "com": [0.31543827927279383, 0.0]},
               "coupler": {"mass": 4.43993152001835, "inertia": 5.0,
                           "com": [0.6384591513064339, 0.1879387281844354]},
               "rocker": {"mass": 1.9844103707016942, "inertia": 0.7419386083123936,
                          "com": [0.9890617317708247, 0.0]}},
    "torque": {"type": "pulse", "value": 241.89973953335254, "start": 0.15, "duration": 0.404},
    "dampers": [{"coefficient": 14.386963066676724, "ground_point": [1.3, 0.12], "body": "coupler",
                 "body_point": [1.1030368635416494, 0.0]}],
    "initial": {"q": 2.197185021567287, "qdot": 0.6264126336072895},
    "simulation": {"horizon": 2.0},
}


def test_a_good_run_near_dead_centres_passes_the_energy_gate():
    """Residual measured 1.23e-9 of 59.4 J at rtol 1e-12 (3.9e-9 at 1e-11: it no longer falls
    with rtol, the audit's floor); the bound max(1000 rtol, 1e-8) passes it, 8x above."""
    result = simulate(scene_from_dict(NEAR_DEAD_CENTRE_ENERGY))
    assert result.details.switches
    assert result.audit.relative_residual < 5e-9


def test_default_reference_passes_every_near_dead_centre_start():
    """Was a strict xfail (DOP853 stopped at a singular position past a chart's reach, even with
    the step capped to 1e-4 of the chart's span). The compiled chart walk halves jumps too long
    for its predictor, so the run now reaches its horizon: 17 switches, energy residual measured
    4.4e-10 of 559 J at rtol 1e-12; bound 5e-9, as the other near-dead-centre scene."""
    result = simulate(scene_from_dict(NEAR_DEAD_CENTRE_SINGULAR))
    assert result.trajectory.t[-1] == 2.0
    assert result.details.switches
    assert result.audit.relative_residual < 5e-9
