"""Walks of a chart over hundreds of radians, as a piece's samples are walked to from its end.

Not in test_reduced_kinematics.py, which test_pure_python runs uncompiled: these walks and runs
take minutes there."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopcheck.reduced import MechanismModel
from loopcheck.kinematics import SINGULAR_CONDITIONING
from loopcheck.scenefile import load_scene
from loopcheck.reduced.charts import Chart

from helpers import SEED_SCENE


LONG_CONSERVATIVE = SEED_SCENE.parent / "hard" / "long_conservative.toml"


@pytest.mark.parametrize("far", [200.2, 1350.2, 5000.2, 4e5 + 0.2, 3e7 + 0.2, -3e7])
def test_a_walk_of_hundreds_of_rad_keeps_the_dependent_angles_turns(far):
    """A chart walked far and back in one call each (Chart.kinematics; a far trial stage): the
    crank-rocker's coupler and rocker never turn, so they stay within a turn of their start, and
    the walk back returns to the start configuration. Closed at once, such jumps left them at
    thousands of rad (14 678 and 41 063 rad after 200.2 and back), where the loops could not
    close to Newton's tolerance: the walk back failed. Jumps beyond physics.LONG_JUMP are now
    halved untried; beyond physics.FAR_JUMP (trial stages of blown-up steps, seen at 4e5–3e7 rad)
    closed at once from the base's configuration: from the quadratic predictor, 3e7 rad and back
    ended 1.5e-2 rad off the start, its dependent angles having passed 1e15 rad.
    Measured: back to the start within 3.3e-16 rad (the closed form: round-off of angles of
    1–3 rad); bound 2e-15."""
    from loopcheck.reduced.charts import _start

    model = MechanismModel(load_scene(LONG_CONSERVATIVE))
    x0, i, _, _, _ = _start(model)
    chart = Chart(model, i, x0)
    there = chart.kinematics(far).x
    back = chart.kinematics(float(x0[i])).x
    dependent = [j for j in range(len(x0)) if j != i]
    assert np.all(np.abs(there[dependent]) < 2 * math.pi)
    assert np.max(np.abs(back - x0)) <= 2e-15


# 1e-4 and 2e-3: rejected steps put trial stages at 1e4–3e7 rad; walked out in 2-rad halves they
# took 99 s and over 4 minutes (physics.FAR_JUMP); 0.15 s and 0.16 s before and since.
@pytest.mark.parametrize("method, rtol", [("dop853", 1e-9), ("dop853", 1e-6),
                                          pytest.param("scipy-dop853", 1e-7, marks=pytest.mark.slow),  # ~3 s: scipy's Python steps
                                          ("dop853", 1e-4), ("dop853", 2e-3)])
def test_long_runs_at_loose_tolerances_sample_their_pieces(method, rtol):
    """45 s of a crank coasting at 30 rad/s (about 1 350 rad) in one load piece. These runs
    failed ("Newton's method did not close the loops … crank.angle = 0.2") when the samples were
    walked to from the piece's end, back to its start, in jumps closed at once."""
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.errors import NumericalFailure

    settings = ReducedSettings(method=method, rtol=rtol, check_error=False)
    if rtol < 1e-3:
        result = simulate(load_scene(LONG_CONSERVATIVE), settings)
        assert result.trajectory.t[-1] == pytest.approx(45.0)
        return
    # at 2e-3 of an angle of hundreds of rad DOP853 may accept 0.4 rad of error a step: whether
    # the run then blows up (the energy audit, a collapsed step or the speed limit report it)
    # turns on round-off. Either way it ends, in well under a second
    try:
        result = simulate(load_scene(LONG_CONSERVATIVE), settings)
    except NumericalFailure:
        return
    assert result.trajectory.t[-1] == pytest.approx(45.0)


def drag_link(qdot: float, horizon: float) -> dict:
    """long_conservative made a drag link (ground the shortest link, 0.25 m: crank, coupler and
    rocker all turn), its crank a 200 kg·m² flywheel, coasting at q̇0 from q0 = 0.2 rad."""
    import tomllib

    with open(LONG_CONSERVATIVE, "rb") as f:
        data = tomllib.load(f)
    data["linkage"].update(c4=0.25)
    data["bodies"]["crank"]["pivot_inertia"] = 200.0
    data["initial"]["qdot"], data["simulation"]["horizon"] = qdot, horizon
    data.pop("tolerances", None)
    return data


def test_rotating_dependent_angles_keep_the_start_turns():
    """A drag link at ~110 rad/s for 1 s (17 turns). The chart walked the piece's first sample
    from its end, and its dependent angles (here the crank: the chart is the coupler's) took
    the turn nearest the end's: the run's crank angle started 12 turns (75.4 rad) off q0. The
    samples are now walked forwards from the piece's start (physics.rewind): the outputs start
    on the start's turns (measured 1.1e-13 rad off), and each angle's change
    over the run equals the integral of its rate over the samples: the input's by the
    trapezoid rule with its end correction −h²/12 Δq̈ (O(h⁴): measured 1.6e-8 rad, bound 1e-7),
    every joint's by the plain trapezoid (no accelerations recorded: measured 2.0e-3 rad at
    ~1e4 rad/s² of the coupler, bound 1e-2; a turn is 6.28)."""
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.scenefile import scene_from_dict

    scene = scene_from_dict(drag_link(100.0, 1.0))
    r = simulate(scene, ReducedSettings())
    joints, tr = r.joints, r.trajectory
    x0 = MechanismModel(scene).x0
    assert abs(tr.q[0] - scene.q0) <= 1e-12 and np.max(np.abs(joints.x[0] - x0)) <= 1e-12
    h = np.diff(tr.t)
    q_integral = np.sum(h * (tr.qdot[1:] + tr.qdot[:-1]) / 2 - h * h / 12 * np.diff(tr.qddot))
    assert abs(tr.q[-1] - tr.q[0] - q_integral) <= 1e-7, tr.q[-1] - tr.q[0] - q_integral
    turned = joints.x[-1] - joints.x[0]
    assert np.all(np.abs(turned) > 100.0)  # every angle turns
    integral = np.trapezoid(joints.xdot, joints.t, axis=0)
    assert np.max(np.abs(turned - integral)) <= 1e-2, turned - integral


@pytest.mark.slow  # ~3 s: 110 s of motion, 12 000 rad
def test_loops_close_at_angles_of_ten_thousand_rad():
    """The drag link at ~110 rad/s for 110 s: its angles pass 1.2e4 rad, where their rounding
    (ulp 1.8e-12 rad, times links of ~1 m) is above Newton's 1e-12: the loops could not close,
    and the run failed at t = 74 s (7 400 rad) as "singular". Newton's tolerance now includes
    the rounding of the angles (physics.NEWTON_ROUND_OFF). DOP853 at rtol 1e-8 (its budget of
    evaluations holds 125 s; the energy check is off: over 12 000 rad its residual, 2.9e-5, is
    above 1000 rtol). Conservative: the speed at equal crank angle on the last turn is the
    first turn's (measured 1.6e-4 of the peak; bound 1e-3)."""
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.scenefile import scene_from_dict

    r = simulate(scene_from_dict(drag_link(100.0, 110.0)), ReducedSettings(rtol=1e-8, check_error=False))
    tr = r.trajectory
    assert tr.t[-1] == 110.0 and tr.q[-1] > 1.2e4
    grid = tr.q[0] + np.linspace(0.0, 2 * math.pi, 200)
    turns = math.floor((tr.q[-1] - tr.q[0]) / (2 * math.pi)) - 1
    first, last = np.interp(grid, tr.q, tr.qdot), np.interp(grid + 2 * math.pi * turns, tr.q, tr.qdot)
    assert np.max(np.abs(last - first)) <= 1e-3 * np.max(np.abs(first))


@pytest.mark.slow  # ~1.5 s: the reference is RKN4 at 5e-5 s
def test_a_point_force_on_a_dependent_input_sees_its_true_angle():
    """The catalogue's drag link (its chart the coupler's, the crank's angle solved) with a force
    tabulated on q over 0–120 rad (not periodic). A piece's samples used to be walked to back
    from its end, and its angles that rotate took the end's turns: the chart carried them into
    the next piece, whose force was read whole turns off (max |Δq| 0.22 rad against RKN4). The
    samples are now walked to forwards from the piece's start (physics.mark/rewind, the compiled
    DOP853 and scipy's alike). Reference: RKN4 at 5e-5 s, which samples as it steps (its own
    error ≈ 1/16 of its 3.2e-9 rad difference from the run at 1e-4 s). Measured: DOP853 2.1e-10
    rad, scipy-dop853 2.2e-10; bound 1e-9."""
    import tomllib

    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.scenefile import scene_from_dict

    with open(SEED_SCENE.parent / "mechanisms" / "drag_link.toml", "rb") as f:
        data = tomllib.load(f)
    data.pop("tolerances")
    data["point_forces"] = [{"name": "ramp", "point": "crank.A", "direction": 1.0, "q": [0.0, 40.0, 80.0, 120.0],
                             "values": [0.0, 100.0, -50.0, 0.0]}]
    scene = scene_from_dict(data)
    reference = simulate(scene, ReducedSettings(method="rkn4", step=5e-5)).trajectory
    for method in ("dop853", "scipy-dop853"):
        tr = simulate(scene, ReducedSettings(method=method)).trajectory
        q, _, _ = reference.interpolate(tr.t)
        assert np.max(np.abs(tr.q - q)) <= 1e-9, method
    # At rtol 1e-6 the steps are long and trial stages jump beyond LONG_JUMP. Closed at once with
    # each angle on the turn nearest its base, they left the crank whole turns off in the chart:
    # 8.4e-2 rad of error (1.2e-2 at rtol 1e-4). Halved instead: 1.2e-4 rad (DOP853) and 2.7e-4
    # (scipy-dop853), DOP853's own error at that rtol; bound 1e-3.
    for method in ("dop853", "scipy-dop853"):
        tr = simulate(scene, ReducedSettings(method=method, rtol=1e-6, check_error=False)).trajectory
        q, _, _ = reference.interpolate(tr.t)
        assert np.max(np.abs(tr.q - q)) <= 1e-3, method


@pytest.mark.parametrize("back", [1e-6, 1e-5, 1e-4])
def test_a_chart_started_at_a_fold_follows_it_back(back):
    """The seed's coupler chart started where the coupler angle is extreme in the crank's
    (dφ1/dq ≈ 2e-8: K of the crank ≈ 4.8e7, L ≈ 1.3e23), Newton's method alone closing the loops
    (dyad plans off), walked back by ``back`` in the coupler angle and forth again. The walk
    halves jumps by their predicted motion: counted as max |K Δ| alone, a jump of 2 rad of it
    carried ½ L Δ² ≈ 1e8 rad, and the walk failed from 1e-5 rad on. Now it counts ½ |L| Δ² too.
    Checked: the configuration there has the coupler angle asked for in the crank's chart (an
    independent walk), and back at the start the crank is where it started. Measured: 6.1e-8
    rad at most (x is defined there only to ε / σ_min(Φ_x), conditioning 3e-8); bound 2e-7."""
    from helpers import without_dyad_plans
    from loopcheck.shipped_scenes import default_scene_path
    from loopcheck.reduced.kernels import physics

    model = MechanismModel(load_scene(default_scene_path()))
    crank = model.new_chart()
    assert crank.start(np.ascontiguousarray(model.x0), 0)
    kin = crank.arrays()["kin"]

    def crank_at(q):
        assert crank.evaluate(q)
        return kin[1][1], kin[0].copy()  # dφ1/dq and x

    qs = model.x0[0] + np.linspace(0.0, 2 * math.pi, 721)
    rates = [crank_at(q)[0] for q in qs]
    j = next(j for j in range(len(qs) - 1) if rates[j] > 0 >= rates[j + 1])
    lo, hi = qs[j], qs[j + 1]
    while True:  # bisection to the fold, until dφ1/dq is below 2.5e-8
        mid = 0.5 * (lo + hi)
        rate, x = crank_at(mid)
        if abs(rate) < 2.5e-8:
            break
        lo, hi = (mid, hi) if rate > 0 else (lo, mid)
    arrays = without_dyad_plans(model)
    chart = physics.Chart(arrays, SINGULAR_CONDITIONING)
    assert chart.start(np.ascontiguousarray(x), 1)
    walked = chart.arrays()["kin"]
    assert abs(walked[1][0]) > 1e7  # K of the crank: the fold
    assert chart.evaluate(x[1] - back)
    there = walked[0].copy()
    assert abs(crank_at(there[0])[1][1] - (x[1] - back)) <= 2e-7
    assert chart.evaluate(x[1])
    assert np.max(np.abs(walked[0] - x)) <= 2e-7
