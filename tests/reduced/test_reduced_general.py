"""The reduced engine on the general description: kinematics, dynamics, partitioning, energy.

The engine runs one compiled implementation for every linkage (loopcheck.reduced.kernels.physics). The
four-bar closed form (tests/oracles/four_bar.py) is its independent oracle: the seed's Eksergian
coefficients and right-hand side are written out here from the closed form's x, K, L and the
bodies' geometry, and compared with the engine's.
"""

from __future__ import annotations

import copy
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from oracles.four_bar import FourBar
from loopcheck.reduced import MechanismModel, ReducedSettings, simulate
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.reduced.integrators import solve_adaptive
from loopcheck.kinematics import assemble
from loopcheck.reduced.charts import Chart, conditioning

from helpers import DATA, ROOT, SEED_SCENE

PLANAR_SEED = ROOT / "scenes" / "mechanisms" / "seed_fourbar.toml"
BEFORE = DATA / "seed_reduced_before_general.json"


def _planar_seed(**changes) -> dict:
    with open(PLANAR_SEED, "rb") as f:
        data = tomllib.load(f)
    data.update(changes)
    return data


# -- the four-bar fast path: the same numbers as before the port ----------------------

# Peaks of scenes/seed_fourbar.toml measured with the engine at 7054af1 (check_error=False).
PEAK_BEFORE = {"dop853": (34.26441305844235, 1.154455342337707),
               "rkn4": (34.26441303828835, 1.1544553420518502)}


# The compiled engine closes the loop by Newton's method where 7054af1 used the four-bar's
# closed form: the same equation in other arithmetic, so the runs agree to round-off grown along
# 2 s of motion. Measured (after the port): peak ω 3.3e-12 (dop853) and 2.8e-13 rad/s (rkn4),
# peak time 1.2e-12 s, q 8.5e-13 rad, q̇ 2.3e-11 rad/s (6.6e-13 of the peak) at the old samples;
# DOP853's steps moved by up to 7.5e-7 s (one step-size decision flipped by round-off), so the
# comparison is at the old sample times through the trajectory's interpolant. Bounds ~3-4x those.
BEFORE_BOUNDS = {"peak": 1e-11, "peak_time": 5e-12, "q": 3e-12, "qdot": 1e-10}
# Since then DOP853 restarts after a load edge with its initial step capped by the steps before
# (loopcheck.reduced.kernels.adaptive.RESTART_STEPS): after the pulse's end at 1 s it takes other steps, an
# equally valid run at rtol 1e-12 (4 more samples). Before 1 s the bounds above still hold
# (measured: q 3.6e-14 rad, q̇ 1.4e-12 rad/s); after it the runs differ by the integrator's
# error: peak ω 1.7e-10 rad/s (5e-12 relative), its time 2.9e-10 s, q 3.8e-12 rad (rtol 1e-12 of
# q's 13–35 rad there), q̇ 3.9e-9 rad/s (1.1e-10 of the peak; DOP853 at rtol 1e-12 and 1e-11
# differ by 4e-11 in peak ω). (Closing four-bar loops in closed form, loopcheck.reduced.kernels.physics
# _dyads, moved q from 4.6e-13 to 3.8e-12 rad and the peak from 9.2e-11 rad/s.) Bounds ~2-5x those.
PULSE_END = 1.0  # s, scenes/seed_fourbar.toml
AFTER_RESTART_BOUNDS = {"peak": 5e-10, "peak_time": 1e-9, "q": 1.5e-11, "qdot": 2e-8}
# Since DOP853's samples cut each step into equal parts (integrators.sample_parts) instead of
# adding a 1 ms grid, the old sample times are no longer samples: before 1 s the comparison is
# through the quintic Hermite interpolant, whose own error in q̇ (against samples 20 µs apart of
# the same dense output) is up to 1.1e-8 rad/s on the seed (1.4e-8 with the old samples).
# Measured before 1 s: q 4.3e-13 rad (within BEFORE_BOUNDS), q̇ 1.3e-9 rad/s. Bound ~4x.
INTERPOLATED_QDOT = 5e-9


@pytest.mark.parametrize("method", ["dop853", "rkn4"])
def test_seed_gives_the_numbers_of_the_engine_before_the_port(method):
    before = json.loads(BEFORE.read_text())[method]
    result = simulate(load_scene(SEED_SCENE), ReducedSettings(method=method, check_error=False))
    tr, joints = result.trajectory, result.joints
    t_before = np.array(before["t"])
    q, qdot, _ = tr.interpolate(t_before)
    dq, dqdot = np.abs(q - before["q"]), np.abs(qdot - before["qdot"])
    if method == "dop853":  # the same steps up to the pulse's end only
        after = AFTER_RESTART_BOUNDS
        assert abs(result.peak.omega - PEAK_BEFORE[method][0]) <= after["peak"]
        assert abs(result.peak.time - PEAK_BEFORE[method][1]) <= after["peak_time"]
        assert np.max(dq) <= after["q"] and np.max(dqdot) <= after["qdot"]
        dq, dqdot = dq[t_before < PULSE_END], dqdot[t_before < PULSE_END]
    else:
        assert len(tr.t) == before["n"]
        assert abs(result.peak.omega - PEAK_BEFORE[method][0]) <= BEFORE_BOUNDS["peak"]
        assert abs(result.peak.time - PEAK_BEFORE[method][1]) <= BEFORE_BOUNDS["peak_time"]
    assert np.max(dq) <= BEFORE_BOUNDS["q"]
    assert np.max(dqdot) <= (INTERPOLATED_QDOT if method == "dop853" else BEFORE_BOUNDS["qdot"])
    if method == "rkn4":  # the same fixed grid: the joint coordinates sample for sample
        idx = before["index"]
        assert np.array_equal(tr.t[idx], before["t"])
        # the joint coordinates are the general ones: (crank, coupler, rocker) = (q, φ1, φ2 + π)
        assert np.max(np.abs(joints.x[idx] - np.array(before["x"]) - [0.0, 0.0, math.pi])) <= BEFORE_BOUNDS["q"]
    assert joints.names == ("crank.angle", "coupler.angle", "rocker.angle")
    assert joints.mode.shape == (len(tr.t), 1) and set(np.unique(joints.mode)) == {1}


def closed_form_coefficients(scene, q: float) -> dict:
    """𝔍, ζ, dV/dq, Σ b K_D² and V of a ``four_bar`` scene at input q, written out from the
    closed form's x, K, L (:meth:`FourBar.kinematics`) and the bodies' geometry: body frames
    crank at O1 turning with q, coupler at A = c1 e(q) turning with φ1, rocker at O3 = (c4, 0)
    turning with φ2 + π; a point p of a body is r = o + R(θ) p, K_r = K_o + θ' (R p)⊥,
    L_r = L_o + θ'' (R p)⊥ − θ'² R p. No loopcheck.kinematics, no kernel."""
    g = scene.four_bar
    kin = FourBar(g).kinematics(q)
    x, K, L = kin.x, kin.K, kin.L

    def e(th):
        return np.array([math.cos(th), math.sin(th)])

    def perp(v):
        return np.array([-v[1], v[0]])
    zero = np.zeros(2)
    a = g.c1 * e(x[0])
    frames = {"ground": (zero, zero, zero, 0.0, 0.0, 0.0),
              "crank": (zero, zero, zero, x[0], K[0], L[0]),
              "coupler": (a, K[0] * perp(a), L[0] * perp(a) - K[0] ** 2 * a, x[1], K[1], L[1]),
              "rocker": (np.array([g.c4, 0.0]), zero, zero, x[2] + math.pi, K[2], L[2])}

    def point(body, p):
        o, ko, lo, th, kt, lt = frames[body]
        rp = np.array([math.cos(th) * p[0] - math.sin(th) * p[1], math.sin(th) * p[0] + math.cos(th) * p[1]])
        return o + rp, ko + kt * perp(rp), lo + lt * perp(rp) - kt * kt * rp

    mech = scene.mechanism
    bodies = mech.linkage.body_map
    gravity = np.zeros(2) if scene.gravity is None else np.array(scene.gravity, dtype=float)
    J = zeta = dV = V = 0.0
    for name in ("crank", "coupler", "rocker"):
        b = bodies[name]
        r, k, l = point(name, b.com)
        kt, lt = frames[name][4], frames[name][5]
        J += b.mass * (k @ k) + b.inertia * kt * kt
        zeta += b.mass * (k @ l) + b.inertia * kt * lt
        V -= b.mass * (gravity @ r)
        dV -= b.mass * (gravity @ k)
    damping = 0.0
    for element in (*mech.dampers, *mech.springs):
        ra, ka, _ = point(element.body_a, bodies[element.body_a].points[element.point_a])
        rb, kb, _ = point(element.body_b, bodies[element.body_b].points[element.point_b])
        d = rb - ra
        length = math.hypot(*d)
        k_d = d @ (kb - ka) / length
        if element.kind == "damper":
            damping += element.coefficient * k_d * k_d
        else:
            V += 0.5 * element.coefficient * (length - element.rest_length) ** 2
            dV += element.coefficient * (length - element.rest_length) * k_d
    return {"generalized_inertia": J, "centrifugal": zeta, "potential_gradient": dV, "damping": damping,
            "potential": V}


def closed_form_rhs(scene):
    """q̈ = f(t, q, q̇) of a ``four_bar`` scene from :func:`closed_form_coefficients`, per smooth
    piece of its load (the integrators' interface)."""
    def on_piece(start, end):
        load = scene.load.on_piece(start, end) if scene.load is not None else (lambda t: 0.0)

        def f(t, q, qdot):
            c = closed_form_coefficients(scene, q)
            Q = load(t) - c["damping"] * qdot
            return (Q - c["centrifugal"] * qdot * qdot - c["potential_gradient"]) / c["generalized_inertia"]
        return f
    return on_piece


def test_engine_agrees_with_the_closed_form_on_the_seed():
    """The engine on the seed, given both as the ``four_bar`` shorthand and as a planar
    description, against the closed form's own right-hand side (:func:`closed_form_rhs`)
    integrated by the same DOP853 driver (solve_adaptive, rtol 1e-12, the load's edges as
    breakpoints) over 0.4 s. When the right-hand sides agree to round-off DOP853 takes the same
    steps: the general Python path measured max |Δq| 2.2e-15 rad, |Δq̇| 1.3e-14 rad/s at the
    closed form's sample times; bounds 2e-14 rad and 1e-13 rad/s. A real difference would show
    at the integrator tolerance (rtol 1e-12 of states ~10-30, ~1e-11) or above."""
    shorthand = scene_from_dict({**_seed_dict(), "simulation": {"horizon": 0.4}})
    closed = solve_adaptive(closed_form_rhs(shorthand), (0.0, 0.4), shorthand.q0, shorthand.qdot0, rtol=1e-12,
                            breakpoints=shorthand.load.edges).trajectory
    t = closed.t
    for scene in (shorthand, scene_from_dict(_planar_seed(simulation={"horizon": 0.4}))):
        result = simulate(scene)
        assert result.joints.names == ("crank.angle", "coupler.angle", "rocker.angle")
        assert not result.details.switches
        q, v, _ = result.trajectory.interpolate(t)
        assert np.max(np.abs(q - closed.q)) <= 2e-14
        assert np.max(np.abs(v - closed.qdot)) <= 1e-13


def rich_scene(branch=1):
    """The seed with masses on every link, gravity, a damper on the crank and a spring on the
    rocker besides the seed's damper on the coupler (moved here from test_expand.py)."""
    data = _seed_dict()
    data["linkage"]["branch"] = branch
    data["gravity"] = [0.0, -9.81]
    data["bodies"] = {"crank": {"mass": 2.0, "inertia": 0.05, "com": [0.25, 0.01]},
                      "coupler": {"mass": 40.0, "inertia": 5.0, "com": [0.5111, 0.1333]},
                      "rocker": {"mass": 3.0, "inertia": 0.12, "com": [0.35, 0.02]}}
    data["dampers"].append({"coefficient": 7.0, "ground_point": [-0.3, 0.4], "body": "crank",
                            "body_point": [0.3, -0.05]})
    data["springs"] = [{"stiffness": 300.0, "rest_length": 0.5, "ground_point": [1.2, 0.8],
                        "body": "rocker", "body_point": [0.6, 0.1]}]
    return scene_from_dict(data)


@pytest.mark.parametrize("which", ["seed", "rich+", "rich-"])
def test_closed_form_and_general_coefficients_agree_at_the_same_configuration(which):
    """𝔍, ζ, dV/dq, damping and V over a revolution: written out from the closed form
    (:func:`closed_form_coefficients`) against the compiled general arrays at the same
    configuration. Round-off of two exact computations of O(1-100) quantities: measured
    ≤ 1.4e-14 relative (6e-14 between the old fast path and the general Python path); bound 1e-12."""
    scene = load_scene(SEED_SCENE) if which == "seed" else rich_scene(1 if which == "rich+" else -1)
    model = MechanismModel(scene)
    linkage = FourBar(scene.four_bar)
    assert scene.mode == ((-1,) if which == "rich-" else (1,))
    for q in np.linspace(0.0, 2 * math.pi, 25)[:-1]:
        c = closed_form_coefficients(scene, float(q))
        g = model.coefficients_at(linkage.to_general(linkage.assemble(float(q))))
        for name in ("generalized_inertia", "centrifugal", "damping", "potential_gradient", "potential"):
            a, b = c[name], getattr(g, name)
            assert abs(a - b) <= 1e-12 * max(1.0, abs(a)), (q, name, a, b)


def _seed_dict() -> dict:
    with open(SEED_SCENE, "rb") as f:
        return tomllib.load(f)


# -- kinematics against finite differences --------------------------------------------

# Central differences with Richardson extrapolation: D(h) of step h has error c h² + O(h⁴),
# so (4 D(h/2) − D(h))/3 has error O(h⁴) (plus round-off ~ε/h for K, ε/h² for L). With
# h = 5e-4 (rad or m) at states where the coordinate's conditioning is ≥ 0.3: measured
# worst errors 3.0e-8 (K) and 9.1e-8 (L) relative to max(1, |K|), max(1, |L|) (the slider-
# crank; the seed 4.9e-10, 1.7e-8); bounds 1.5e-7 and 5e-7 (5x).
FD_STEP = 5e-4


def _fd_check(model, x0, index):
    """K and L of the compiled chart of coordinate ``index`` at x0 against Richardson-extrapolated
    central differences of positions assembled by loopcheck.kinematics' Newton (numpy) with that
    coordinate driving."""
    driven = model.system.driven_by(index)
    value = x0[index]
    kin = Chart(model, index, x0).start

    def diffs(h):
        xp = assemble(driven, value + h, x0 + kin.K * h + 0.5 * kin.L * h * h)
        xm = assemble(driven, value - h, x0 - kin.K * h + 0.5 * kin.L * h * h)
        return (xp - xm) / (2 * h), (xp - 2 * x0 + xm) / h ** 2
    k1, l1 = diffs(FD_STEP)
    k2, l2 = diffs(FD_STEP / 2)
    K_fd, L_fd = (4 * k2 - k1) / 3, (4 * l2 - l1) / 3
    k_err = np.max(np.abs(kin.K - K_fd)) / max(1.0, np.max(np.abs(kin.K)))
    l_err = np.max(np.abs(kin.L - L_fd)) / max(1.0, np.max(np.abs(kin.L)))
    return k_err, l_err


def _states(system, guess, values):
    out = []
    x = np.array(guess, dtype=float)
    for q in values:
        x = assemble(system, q, x)
        out.append(x.copy())
    return out


def _slider_crank_scene(input_joint: str):
    data = copy.deepcopy(SLIDER_CRANK)
    data["linkage"]["input"] = input_joint
    if input_joint == "crank":
        del data["force"]
        data["initial"] = {"q": 1.3, "qdot": 0.0, "guess": {"rod": -0.25, "slide": 0.35}}
    return scene_from_dict(data)


@pytest.mark.parametrize("case", ["seed", "slider_crank_crank", "slider_crank_slide"])
def test_K_and_L_match_finite_differences_for_every_independent_coordinate(case):
    if case == "seed":
        model = MechanismModel(load_scene(SEED_SCENE))
        states = _states(model.system, model.x0, np.linspace(0.2, 0.2 + 2 * math.pi, 9)[:-1])
    else:
        model = MechanismModel(_slider_crank_scene("crank" if case.endswith("crank") else "slide"))
        crank = MechanismModel(_slider_crank_scene("crank")).system
        states = _states(crank, [1.3, -0.25, 0.0, 0.35], np.linspace(0.3, 0.3 + 2 * math.pi, 9)[:-1])
    checked = 0
    for x in states:
        c = conditioning(model, x)
        for i in range(model.system.n):
            if c[i] < 0.3:  # near a dead centre of that coordinate (or a slider's fixed angle)
                continue
            k_err, l_err = _fd_check(model, x, i)
            assert k_err <= 1.5e-7, (model.coordinate_names[i], x, k_err)
            assert l_err <= 5e-7, (model.coordinate_names[i], x, l_err)
            checked += 1
    assert checked >= len(states) * 2  # several coordinates per state, including the slide's s


# -- a slider-driven slider-crank through its dead centres -----------------------------

SLIDER_CRANK = {
    "name": "slider_driven_slider_crank",
    "description": "offset slider-crank driven by a force on the slider; a flywheel crank carries it "
                   "through the dead centres",
    "linkage": {"type": "planar", "input": "slide"},
    "bodies": {
        "ground": {"points": {"O": [0.0, 0.0], "line": [0.0, 0.03], "anchor": [0.2, 0.2]}},
        "crank": {"points": {"O": [0.0, 0.0], "A": [0.1, 0.0]}, "pivot_inertia": 0.02, "pivot": "O"},
        "rod": {"points": {"A": [0.0, 0.0], "B": [0.35, 0.0]}, "mass": 0.6, "com": [0.12, 0.01],
                "inertia": 0.008},
        "slider": {"points": {"pin": [0.0, 0.0]}, "mass": 0.4, "com": [0.0, 0.0], "inertia": 1e-4},
    },
    "joints": [
        {"name": "crank", "type": "revolute", "a": "ground.O", "b": "crank.O"},
        {"name": "crank_pin", "type": "revolute", "a": "crank.A", "b": "rod.A"},
        {"name": "wrist_pin", "type": "revolute", "a": "rod.B", "b": "slider.pin"},
        {"name": "slide", "type": "prismatic", "a": "ground.line", "b": "slider.pin", "direction": 0.0},
    ],
    "dampers": [{"a": "ground.anchor", "b": "rod.B", "coefficient": 0.3}],
    "springs": [{"a": "ground.anchor", "b": "crank.A", "stiffness": 20.0, "rest_length": 0.15}],
    "force": {"type": "pulse", "value": 8.0, "start": 0.0, "duration": 0.2},
    "gravity": [0.0, -9.81],
    "initial": {"q": 0.35, "qdot": -3.0, "guess": {"crank": 1.3, "rod": -0.25, "slide": 0.35}},
    "simulation": {"horizon": 0.25},
}


def test_slider_driven_slider_crank_passes_its_dead_centres_and_balances_energy():
    """DOP853 at rtol 1e-12 (the default) over 0.25 s: the slide's displacement cannot drive
    the linkage at the crank's dead centres, so the run leaves it for a better-conditioned
    coordinate (the crank angle) and carries on through both dead centres. Energy residual
    measured 2.1e-10 of the run's scale (0.6 s); bound 1e-9 (the issue's)."""
    scene = scene_from_dict(copy.deepcopy(SLIDER_CRANK))
    assert scene.input_unit == "m" and scene.four_bar is None
    result = simulate(scene)
    switches = result.details.switches
    assert switches and switches[0].old == "slide.s", switches
    joints = result.joints
    assert joints.coordinate[0] == joints.names.index("slide.s")
    assert result.audit.max_abs_residual / result.audit.scale <= 1e-9
    # both dead centres reached: s = √((l ± r)² − e²), within the samples' spacing
    s = joints.x[:, joints.names.index("slide.s")]
    assert abs(s.max() - math.sqrt(0.45 ** 2 - 0.03 ** 2)) < 1e-3
    assert abs(s.min() - math.sqrt(0.25 ** 2 - 0.03 ** 2)) < 1e-3
    assert np.ptp(joints.x[:, joints.names.index("crank.angle")]) > 2 * math.pi
    # q is the slide's displacement and q̇ its rate
    assert np.max(np.abs(result.trajectory.q - s)) == 0.0


def test_point_force_work_closes_the_energy_balance():
    """A gas-force table on the slider of a crank-driven slider-crank: its work is in the audit
    (residual measured 5.5e-11 of the scale over 0.4 s; bound 1e-9)."""
    data = copy.deepcopy(SLIDER_CRANK)
    data["linkage"]["input"] = "crank"
    del data["force"]
    data["torque"] = {"type": "constant", "value": 0.5}
    data["initial"] = {"q": 1.3, "qdot": 20.0, "guess": {"rod": -0.25, "slide": 0.35}}
    data["point_forces"] = [{"point": "slider.pin", "direction": math.pi, "q": [0.0, 1.5, 3.0, 4.5],
                             "values": [0.0, 30.0, 5.0, 0.0], "period": 2 * math.pi}]
    data["simulation"] = {"horizon": 0.4}
    scene = scene_from_dict(data)
    assert "point-force" in scene.effects
    result = simulate(scene)
    audit = result.audit
    assert audit.max_abs_residual / audit.scale <= 1e-9
    # the point force did work: dropping it from the model changes the energy by far more
    model = MechanismModel(scene)
    c = model.coefficients_at(np.array(scene.x0))
    assert c.point_force != 0.0


# -- RKN4 through the general path ---------------------------------------------------

def test_rkn4_is_fourth_order_through_the_general_path():
    """RKN4 on the general seed over 0.25 s at 4, 2, 1 ms against DOP853 (rtol 1e-12): the
    error ratio per halving is 2^p with p measured 4.09 and 4.08; bound 4.0 ± 0.2."""
    scene = scene_from_dict(_planar_seed(simulation={"horizon": 0.25}))
    ref = simulate(scene).trajectory
    errors = []
    for h in (4e-3, 2e-3, 1e-3):
        tr = simulate(scene, ReducedSettings(method="rkn4", step=h, check_error=False)).trajectory
        _, v, _ = ref.interpolate(np.array([0.25]))
        errors.append(abs(tr.qdot[-1] - v[0]))
    orders = [math.log2(errors[k] / errors[k + 1]) for k in range(2)]
    assert all(abs(p - 4.0) <= 0.2 for p in orders), orders


def test_model_coefficients_follow_the_input_around_a_whole_turn():
    """MechanismModel.coefficients(q) walks the input's chart from q0: on the seed's crank-rocker
    it gives the closed form's 𝔍, ζ and damping at every q of a turn (Newton from x0 alone
    failed half a turn away). 1e-12 relative: both are round-off from the same configuration."""
    scene = load_scene(SEED_SCENE)
    model = MechanismModel(scene)
    for q in scene.q0 + np.linspace(0.0, 2 * math.pi, 13):
        got, want = model.coefficients(float(q)), closed_form_coefficients(scene, float(q))
        for name in ("generalized_inertia", "centrifugal", "damping"):
            assert abs(getattr(got, name) - want[name]) <= 1e-12 * abs(want["generalized_inertia"]), (q, name)
