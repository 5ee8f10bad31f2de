"""Events of the reduced engine: dry joint friction (stick and slip) and joint ranges.

Oracles: a rotor on a pivot (𝔍 = I, K_O = 1) has closed forms. With friction f and a torque T > f
for τ s from rest, q̇ rises at (T − f)/I to ω1 = (T − f) τ / I, falls at f/I, and sticks at
t_s = τ + ω1 I / f, at q_s = ½ (T − f) τ² / I + ½ ω1² I / f, where it stays (no load, 0 < f):
the work of T, T q(τ), is all dissipated by the friction. Under constant T from rest the rotor
reaches u = hi at t = √(2 I hi / T). A four-bar's friction split into two halves on one joint
runs the same motion, and its energy audit (friction counted as dissipation) balances.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import loopcheck
from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.scene import SceneError
from loopcheck.scenefile import scene_from_dict
from tests.helpers import variant

I, T, TAU, F = 2.0, 5.0, 1.0, 1.0
OMEGA1 = (T - F) * TAU / I
T_STICK = TAU + OMEGA1 * I / F                                  # 5 s
Q_STICK = 0.5 * (T - F) * TAU ** 2 / I + 0.5 * OMEGA1 ** 2 * I / F  # 5 rad


def rotor(*, friction=None, span=None, torque=None, horizon=6.0, qdot=0.0) -> dict:
    data = {"name": "rotor", "linkage": {"type": "planar", "input": "O"},
            "bodies": {"ground": {"points": {"O": [0.0, 0.0]}},
                       "rotor": {"points": {"O": [0.0, 0.0], "P": [1.0, 0.0]}, "pivot_inertia": I, "pivot": "O"}},
            "joints": [{"name": "O", "type": "revolute", "a": "ground.O", "b": "rotor.O"}],
            "torque": torque or {"type": "pulse", "value": T, "start": 0.0, "duration": TAU},
            "initial": {"q": 0.0, "qdot": qdot}, "simulation": {"horizon": horizon}}
    if span is not None:
        data["joints"][0]["range"] = list(span)
    if friction is not None:
        data["joint_frictions"] = [{"joint": "O", "friction": friction}]
    return data


def stick_time(result) -> float:
    """The first time after the motion began at which q̇ is exactly 0 (the stick segment's)."""
    tr = result.trajectory
    moved = np.flatnonzero(tr.qdot != 0.0)
    return float(tr.t[moved[-1] + 1])


def test_a_rotor_with_friction_sticks_where_the_closed_form_says():
    """DOP853 (rtol 1e-12) finds the stick at t_s to 3e-15 s and q_s to 5e-15 rad (measured;
    asserted 1e-10: the event is Brent's root on the dense output, xtol 4 ε); after it q̇ = q̈ = 0
    exactly, and the audit balances: the work of T equals the friction's dissipation (2e-14 J
    measured of 5 J, asserted 1e-9 J). Planted: no stick event (slip goes on through q̇ = 0) makes
    the rotor reverse and oscillate; a wrong sign of the friction (+s C) never stops it."""
    result = loopcheck.simulate(scene_from_dict(rotor(friction=F)), loopcheck.ReducedSettings(rtol=1e-12))
    assert stick_time(result) == pytest.approx(T_STICK, abs=1e-10)
    tr = result.trajectory
    after = tr.t >= T_STICK + 1e-6
    assert np.all(tr.qdot[after] == 0.0) and np.all(tr.qddot[after] == 0.0)
    assert tr.q[-1] == pytest.approx(Q_STICK, abs=1e-10)
    audit = result.audit
    assert audit.torque_work[-1] == pytest.approx(T * 0.5 * (T - F) * TAU ** 2 / I, abs=1e-9)
    assert audit.damper_dissipation[-1] == pytest.approx(audit.torque_work[-1], abs=1e-9)
    assert audit.max_abs_residual < 1e-9


def test_a_load_within_the_friction_never_moves_it():
    """T = 0.8 f from rest: sticks from the start (q stays 0, q̇ = 0 exactly); then T = 1.5 f from
    t = 1 s breaks it loose at that load edge, with q̈ = (T − f)/I from there (closed form
    q(2) = ½ (0.5 f / I) 1², measured exact to 1e-15, asserted 1e-10)."""
    torque = {"type": "table", "times": [0.0, 1.0], "values": [0.8 * F, 1.5 * F]}
    result = loopcheck.simulate(scene_from_dict(rotor(friction=F, torque=torque, horizon=2.0)),
                                loopcheck.ReducedSettings(rtol=1e-12))
    tr = result.trajectory
    early = tr.t <= 1.0
    assert np.all(tr.q[early] == 0.0) and np.all(tr.qdot[early] == 0.0)
    assert tr.q[-1] == pytest.approx(0.5 * (0.5 * F / I) * 1.0 ** 2, abs=1e-10)
    assert result.audit.max_abs_residual < 1e-9


def test_rkn4_takes_the_step_again_to_the_stick():
    """RKN4 finds the stick after the step that crossed q̇ = 0, and takes that step again to the
    root of q̇ on the step's Hermite interpolant: at its default 5e-4 s the stick time is within
    7e-13 s and the final angle 3e-13 rad of the closed form (measured; asserted 1e-10), and its
    step-doubling estimate (1.8e-14) passes. Planted: the step not taken again (the stick one step
    late): the estimate refuses the run (1.7e-5 > rtol 1e-5)."""
    result = loopcheck.simulate(scene_from_dict(rotor(friction=F)), loopcheck.ReducedSettings(method="rkn4", step=5e-4))
    assert abs(stick_time(result) - T_STICK) < 1e-10
    assert abs(result.trajectory.q[-1] - Q_STICK) < 1e-10
    assert result.audit.relative_residual < 1e-10


def test_friction_split_in_halves_runs_the_same_motion():
    """The seed four-bar with 3 N·m on B, and with 1.5 + 1.5 N·m as two elements on B: the same
    states (the kernel sums one joint's frictions: equal to the bit; asserted 1e-12 rad); friction
    matters; its audit balances: 1.3e-10 of the run's 3.1e3 J measured, asserted 1e-9. Each kink of
    |K_B| (u̇_B changing sign) is an event that starts a segment, but the step that found it
    straddled it, and its dense output up to the root keeps 4.1e-7 J of error (without the kink
    events 3.4e-6 J, 1.1e-9; the engine's gate is 1e-8). Planted: the two elements kept apart and
    only the fired kink's watch flipped: the two identical kinks fired in turn at each other's
    roots until DOP853's budget was spent."""
    one = variant(joint_frictions=[{"joint": "B", "friction": 3.0}, {"joint": "O1", "friction": 2.0, "name": "f1"}])
    two = variant(joint_frictions=[{"joint": "B", "friction": 1.5, "name": "h1"},
                                   {"joint": "B", "friction": 1.5, "name": "h2"},
                                   {"joint": "O1", "friction": 2.0, "name": "f1"}])
    settings = loopcheck.ReducedSettings(rtol=1e-12)
    a, b = loopcheck.simulate(one, settings), loopcheck.simulate(two, settings)
    assert np.max(np.abs(a.trajectory.q - b.trajectory.q)) < 1e-12
    assert a.audit.relative_residual < 1e-9
    plain = loopcheck.simulate(variant(), settings)
    assert abs(plain.peak.omega - a.peak.omega) > 0.1


def test_a_reached_range_ends_the_run_at_the_closed_form_time():
    """Constant T from rest reaches hi = 1.5 rad at √(2 I hi / T): DOP853's event at 7e-16 s of it
    (measured; asserted 1e-10); RKN4 takes the step that crossed it again to its root, 7e-15 s off
    (measured; asserted 1e-10); the failure names the joint, the bound and the time. Planted: the
    upper margin written as u − hi never fires."""
    scene = scene_from_dict(rotor(span=(-0.5, 1.5), torque={"type": "constant", "value": T}, horizon=2.0))
    expected = math.sqrt(2 * I * 1.5 / T)
    with pytest.raises(NumericalFailure) as caught:
        loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-12))
    assert caught.value.reason == FailureReason.RANGE_REACHED
    assert caught.value.time == pytest.approx(expected, abs=1e-10)
    assert "joint 'O' reached the upper bound 1.5 rad of its range [-0.5, 1.5]" in str(caught.value)
    with pytest.raises(NumericalFailure) as caught:
        loopcheck.simulate(scene, loopcheck.ReducedSettings(method="rkn4", step=5e-4))
    assert caught.value.reason == FailureReason.RANGE_REACHED
    assert caught.value.time == pytest.approx(expected, abs=1e-10)


def test_a_range_not_reached_changes_nothing():
    """Range [-0.5, 100] rad: the run is the unranged one to the bit."""
    torque = {"type": "constant", "value": T}
    ranged = loopcheck.simulate(scene_from_dict(rotor(span=(-0.5, 100.0), torque=torque, horizon=2.0)),
                                loopcheck.ReducedSettings())
    plain = loopcheck.simulate(scene_from_dict(rotor(torque=torque, horizon=2.0)), loopcheck.ReducedSettings())
    assert np.array_equal(ranged.trajectory.q, plain.trajectory.q)


def test_a_scene_starting_outside_its_range_is_refused():
    with pytest.raises(SceneError, match=r"^joint 'O' starts at 0 rad, outside its range \[0.5, 2\] rad$"):
        scene_from_dict(rotor(span=(0.5, 2.0)))
    with pytest.raises(SceneError, match=r"joints\[0\].range' = \[2, 1\]: the lower bound must be below the upper"):
        scene_from_dict(rotor(span=(2.0, 1.0)))
    # outside by no more than the assembly's tolerance is on the bound (Menagerie's Robotiq 2F-85 at
    # qpos0: its driver at its lower bound came out at -3.2e-32 rad); beyond it, outside
    scene_from_dict(rotor(span=(1e-13, 2.0)))
    with pytest.raises(SceneError, match=r"^joint 'O' starts at 0 rad, outside its range \[1e-09, 2\] rad$"):
        scene_from_dict(rotor(span=(1e-9, 2.0)))


def test_the_scipy_methods_refuse_events():
    with pytest.raises(ValueError, match="method radau does not run joint friction or joint ranges \\(joint_friction0\\)"):
        loopcheck.simulate(scene_from_dict(rotor(friction=F)), loopcheck.ReducedSettings(method="radau"))


def test_a_spring_with_friction_reverses_and_sticks_as_the_closed_form_says():
    """A rotor (I = 2) on a joint spring (k = 8) with friction f = 1, released at 1 rad: each half
    period π √(I/k) the amplitude falls by 2 f / k (Coulomb damping of a linear oscillator), so it
    turns at −0.75, 0.5, −0.25 rad (slip → slip reversals: |k q| > f there) and at 0 rad, where the
    spring holds nothing, it sticks from t = 2π for good. DOP853 (rtol 1e-12): turning times within
    1.7e-12 s and angles within 1e-12 rad of the closed form (measured; asserted 1e-10); RKN4 at its
    default 5e-4 s, each step that crossed a turn taken again to it: within 2.6e-14 s (5e-12 at
    2e-3 s: fourth order). Planted: a reversal
    taken as a stick (stick whenever q̇ reaches 0) stops it at −0.75 rad."""
    data = rotor(friction=F, horizon=7.0)
    data.pop("torque")
    data["initial"]["q"] = 1.0
    data["joint_springs"] = [{"joint": "O", "stiffness": 8.0, "rest_angle": 0.0}]
    result = loopcheck.simulate(scene_from_dict(data), loopcheck.ReducedSettings(rtol=1e-12))
    tr = result.trajectory
    turns = tr.qdot == 0.0
    half = math.pi * math.sqrt(I / 8.0)
    for k, amplitude in enumerate((-0.75, 0.5, -0.25, 0.0), start=1):
        at = np.flatnonzero(turns & (np.abs(tr.t - k * half) < 1e-6))
        assert len(at) >= 1 and abs(tr.t[at[0]] - k * half) < 1e-10  # (then the stick's samples at 0)
        assert abs(tr.q[at[0]] - amplitude) < 1e-10
    assert np.all(tr.qdot[tr.t > 4 * half + 1e-9] == 0.0) and abs(tr.q[-1]) < 1e-10
    events = result.details.friction_events  # three reversals, then the stick
    assert [(e.mode, e.direction) for e in events] == [("slip", 1), ("slip", -1), ("slip", 1), ("stick", 0)]
    assert np.allclose([e.time for e in events], [k * half for k in (1, 2, 3, 4)], atol=1e-10)
    rkn4 = loopcheck.simulate(scene_from_dict(data), loopcheck.ReducedSettings(method="rkn4"))
    assert [(e.mode, e.direction) for e in rkn4.details.friction_events] == [(e.mode, e.direction) for e in events]
    assert np.allclose([e.time for e in rkn4.details.friction_events], [k * half for k in (1, 2, 3, 4)], atol=1e-10)
    assert result.audit.relative_residual < 1e-10


def test_friction_keeps_its_sense_across_a_chart_switch():
    """The slider-driven slider-crank (through its dead centre: one chart switch) with 0.05 N·m or N
    of friction on each joint: the friction's dissipation never decreases (a slip's sign is the
    chart coordinate's rate's, which may flip at a switch; measured increments ≥ 0, asserted
    ≥ −1e-12 J), the audit balances (1.2e-11 measured, asserted 1e-9), and MuJoCo built from it
    agrees within (1e-4, 1e-3 m, 0.1 m/s) (measured peak 6.7e-5, |dq| 1.3e-4 m, |dq̇| 3.0e-2 m/s:
    its soft friction creeps; the scene's own tolerances, set without friction, are tighter).
    Planted: the slip's sign kept through the switch (dissipation fell by 8e-3 J in one sample)."""
    from loopcheck.compare.run import compare_engines
    from loopcheck.scene import Tolerances
    from loopcheck.scene_writer import scene_data
    from loopcheck.scenefile import load_scene
    from helpers import ROOT
    data = scene_data(load_scene(ROOT / "scenes" / "mechanisms" / "slider_crank_driven_slider.toml"))
    data["joint_frictions"] = [{"joint": j["name"], "friction": 0.05, "name": f"f{k}"} for k, j in enumerate(data["joints"])]
    scene = scene_from_dict(data)
    result = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-12))
    assert len(result.details.switches) >= 1
    assert np.min(np.diff(result.audit.damper_dissipation)) >= -1e-12
    assert result.audit.relative_residual < 1e-9
    c = compare_engines(scene, tolerances=Tolerances(peak_omega_rtol=1e-4, q_atol=1e-3, omega_atol=0.1))
    assert c.gate.passed
