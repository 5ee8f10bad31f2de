"""A forcerange clamp on a force that depends on the state: its switching is an event of the reduced engine.

Oracle: a rotor on a pivot (I = 0.5 kg·m²) held by a position servo (kp 8, kv 0.6) whose force is
clamped to [−1, 1] N·m, at rest until its set-point steps from 0 to 1 rad at t = 0.1 s. The motion is
piecewise closed form: while the force is held at a bound, θ̈ = ±F / I (a parabola, left where the
unclamped force kp (c − θ) − kv θ̇ comes back to the bound: a quadratic's root); between the bounds the
damped oscillator I θ̈ = kp (c − θ) − kv θ̇ (left where the unclamped force reaches a bound: brentq on
the closed form, to 1e-15 s). The run passes through upper, free, lower, free, upper.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from loopcheck.api import ReducedSettings, check, scene_from_string, simulate
from loopcheck.reduced.kernels import physics

INERTIA, KP, KV, F, TARGET, STEP_AT = 0.5, 8.0, 0.6, 1.0, 1.0, 0.1
HORIZON = 3.0

ROTOR = """
name = "clamped_servo_rotor"
[linkage]
type = "planar"
input = "O"
[bodies.ground]
points = {{ O = [0.0, 0.0] }}
[bodies.rotor]
points = {{ O = [0.0, 0.0] }}
pivot_inertia = {inertia}
pivot = "O"
[[joints]]
name = "O"
type = "revolute"
a = "ground.O"
b = "rotor.O"
[[actuators]]
name = "servo"
joint = "O"
gain = {kp}
bias = [0.0, -{kp}, -{kv}]
forcerange = [-{f}, {f}]
[actuators.control]
type = "table"
times = {times}
values = {values}
[initial]
q = 0.0
qdot = 0.0
[simulation]
horizon = {horizon}
"""


def clamped_rotor(times=(0.0, STEP_AT), values=(0.0, TARGET), horizon=HORIZON):
    """The rotor at rest, its servo's set-point a table (piecewise constant)."""
    return scene_from_string(ROTOR.format(inertia=INERTIA, kp=KP, kv=KV, f=F, times=list(times), values=list(values),
                                          horizon=horizon))


def _free(s, q, v, target=TARGET):
    """θ, θ̇ of the oscillator s seconds after (q, v) (s a number or an array)."""
    alpha = KV / (2 * INERTIA)
    wd = math.sqrt(KP / INERTIA - alpha * alpha)
    e0, b = q - target, (v + alpha * (q - target)) / wd
    ex, c, sn = np.exp(-alpha * s), np.cos(wd * s), np.sin(wd * s)
    return target + ex * (e0 * c + b * sn), ex * (-alpha * (e0 * c + b * sn) + wd * (b * c - e0 * sn))


def phases(t0=STEP_AT, q0=0.0, v0=0.0):
    """[(start, θ, θ̇, mode)]: mode +1 held at F, −1 at −F, 0 free, until HORIZON."""
    unclamped = lambda q, v: KP * (TARGET - q) - KV * v  # noqa: E731
    f = unclamped(q0, v0)
    mode = 1 if f > F else (-1 if f < -F else 0)
    out, t, q, v = [], t0, q0, v0
    while t < HORIZON:
        out.append((t, q, v, mode))
        if mode:
            a = mode * F / INERTIA  # unclamped(q + v s + a s²/2, v + a s) = mode F
            roots = np.roots([-KP * a / 2, -KP * v - KV * a, unclamped(q, v) - mode * F])
            s = min((r.real for r in roots if r.imag == 0 and r.real > 1e-12), default=math.inf)
            q, v, mode = q + v * s + a * s * s / 2, v + a * s, 0
        else:
            g = lambda s, side: side * (side * F - unclamped(*_free(s, q, v)))  # noqa: E731  > 0 inside
            s, ds, found = 0.0, 1e-3, None
            while found is None and t + s < HORIZON:
                hits = [(brentq(g, s, s + ds, args=(side,), xtol=1e-16, rtol=1e-15), side)
                        for side in (1, -1) if g(s, side) >= 0 > g(s + ds, side)]
                found = min(hits) if hits else None
                s += ds
            if found is None:
                break
            s, mode = found
            q, v = _free(s, q, v)
        t += s
    return out


def exact(t, table):
    starts = np.array([p[0] for p in table])
    q = np.zeros_like(t)
    for k, tk in enumerate(t):
        j = np.searchsorted(starts, tk, side="right") - 1
        if j < 0:
            continue  # at rest before the step
        t0, q0, v0, mode = table[j]
        s = tk - t0
        q[k] = q0 + v0 * s + mode * F / INERTIA * s * s / 2 if mode else _free(s, q0, v0)[0]
    return q


TABLE = phases()


def run(method, **changes):
    return simulate(clamped_rotor(), ReducedSettings(method=method, **changes))


def test_the_oracle_passes_through_every_mode():
    assert [p[3] for p in TABLE] == [1, 0, -1, 0, 1]


@pytest.mark.parametrize("method", ["dop853", "rkn4"])
def test_a_saturating_servo_is_the_closed_form(method):
    """Both integrators at their defaults (DOP853 rtol 1e-12, RKN4 step 5e-4 s) against the piecewise
    closed form, bound 1e-9 rad: measured 3.9e-12 (DOP853), 1.2e-13 (RKN4). The events are where the
    oracle's phases change, to 1e-9 s (measured 1.0e-10 s: the clamp's hysteresis, 1e-9 N·m, over
    ḟ_u ≈ 10 N·m/s). The audit balances (servo's work against
    kinetic energy; measured 3.8e-12 (DOP853), 1.4e-13 (RKN4) relative). Planted: no clamp event
    (N_CLAMPED = 0 in dynamics.build_arrays: the kink crossed inside a step): RKN4's error 1.2e-7 rad,
    this test fails; DOP853 at rtol 1e-12 stays at 2.1e-11 but takes 74 steps instead of 30 (below)."""
    result = run(method)
    t, q = result.trajectory.t, result.trajectory.q
    assert np.max(np.abs(q - exact(t, TABLE))) < 1e-9
    events = result.details.clamp_events
    assert [e.mode for e in events] == ["upper", "free", "lower", "free", "upper"]
    assert all(e.actuator == "servo" for e in events)
    assert np.max(np.abs(np.array([e.time for e in events]) - [p[0] for p in TABLE])) < 1e-9
    assert result.audit.relative_residual < 1e-9 and abs(result.audit.torque_work[-1]) > 0.1


def test_the_event_keeps_dop853_within_its_rtol():
    """At rtol 1e-8 the run stays within 10 rtol of the closed form (measured 2.1e-8 rad in 20 steps).
    Planted: no clamp event: 3.2e-6 rad in 51 steps, 150 times the rtol, unannounced: fails."""
    result = run("dop853", rtol=1e-8)
    t, q = result.trajectory.t, result.trajectory.q
    assert np.max(np.abs(q - exact(t, TABLE))) < 1e-7


def test_the_event_spares_dop853_its_rejected_steps():
    """At its default rtol DOP853 without the event still meets 1e-9 (2.1e-11) by cutting its steps at
    each kink: 74 steps, 1 726 evaluations; with it 30 and 464. Bound 40 steps. Planted (no event): fails."""
    assert run("dop853").n_steps <= 40


def test_mujoco_built_from_the_scene_agrees():
    """MuJoCo clamps the same way (actuator_forcerange): the check passes at the scene's tolerances
    (q 1e-3 rad); measured 1.2e-7 rad in q, 4.3e-7 rad/s in q̇ (MuJoCo's RK4 at its step)."""
    comparison = check(clamped_rotor()).comparison("mujoco")
    assert comparison.gate.passed, comparison.gate.failures
    assert comparison.diff.q_max_abs < 1e-5


def test_the_clamp_modes_follow_a_control_step_back_inside():
    """The set-point stepped back at 0.3 s, mid-saturation, to where the servo's force is within its
    range: the load edge itself is the event (stop_at_start), and the run is the oscillator from the
    state at the edge (closed form, 1e-9 rad; measured 2.1e-12). Planted: stop_at_start blind to the
    clamps (physics.Chart.stop_at_start): DOP853 runs on with the unclamped force, 0.24 rad off: fails
    (and the first test's DOP853 run, 1.9 rad off, and MuJoCo's check)."""
    result = simulate(clamped_rotor((0.0, STEP_AT, 0.3), (0.0, TARGET, 0.05), horizon=0.6), ReducedSettings())
    t, q, v = result.trajectory.t, result.trajectory.q, result.trajectory.qdot
    held = (t >= STEP_AT) & (t <= 0.3)
    assert np.max(np.abs(q[held] - F / INERTIA * (t[held] - STEP_AT) ** 2 / 2)) < 1e-9  # held at F until the edge
    k = np.flatnonzero(t >= 0.3)[0]
    after = t >= 0.3
    free, rate = _free(t[after] - 0.3, q[k], v[k], target=0.05)
    assert np.max(np.abs(KP * (0.05 - free) - KV * rate)) < F  # the oscillator stays inside the range
    assert np.max(np.abs(q[after] - free)) < 1e-9
    assert [(e.mode, e.time) for e in result.details.clamp_events] == [("upper", STEP_AT), ("free", 0.3)]


def test_the_servo_split_in_halves_switches_both_clamps_at_once():
    """The servo as two halves: one on the joint (kp/2, kv/2, ±F/2), one on a tendon l = 2θ (gain kp/4,
    bias [0, −kp/8, −kv/8], ±F/4: generalized force 2 f). Their clamps cross their bounds at the same
    instants: the run is the one servo's closed form (1e-9 rad; measured 3.9e-12 DOP853, 1.2e-13 RKN4) and
    each event sets both modes (one stop, two changes). Planted: set_clamps stopping after its first
    change: the second half is never given a mode (clamped by value, its kinks inside steps, still
    within 1e-9 rad here) and has no events: fails."""
    text = ROTOR.replace("""[[actuators]]
name = "servo"
joint = "O"
gain = {kp}
bias = [0.0, -{kp}, -{kv}]
forcerange = [-{f}, {f}]
""", """[[actuators]]
name = "servo_b"
tendon = {{ O = 2.0 }}
gain = {kp4}
bias = [0.0, -{kp8}, -{kv8}]
forcerange = [-{f4}, {f4}]
[actuators.control]
type = "table"
times = {times}
values = {values}
[[actuators]]
name = "servo_a"
joint = "O"
gain = {kp2}
bias = [0.0, -{kp2}, -{kv2}]
forcerange = [-{f2}, {f2}]
""")
    scene = scene_from_string(text.format(inertia=INERTIA, kp2=KP / 2, kv2=KV / 2, f2=F / 2, kp4=KP / 4, kp8=KP / 8,
                                          kv8=KV / 8, f4=F / 4, times=[0.0, STEP_AT], values=[0.0, TARGET],
                                          horizon=HORIZON))
    for method in ("dop853", "rkn4"):
        result = simulate(scene, ReducedSettings(method=method))
        assert np.max(np.abs(result.trajectory.q - exact(result.trajectory.t, TABLE))) < 1e-9
        events = result.details.clamp_events
        assert [e.actuator for e in events] == ["servo_b", "servo_a"] * 5
        assert [e.time for e in events[::2]] == [e.time for e in events[1::2]]


def test_scipys_methods_refuse_the_clamp_by_name():
    with pytest.raises(ValueError, match=r"method radau does not run a forcerange clamp on a force that depends "
                                         r"on the state \(actuator 'servo'\)"):
        simulate(clamped_rotor(), ReducedSettings(method="radau"))


def test_the_kernel_numbers_a_clamp_event_after_the_ranges():
    from loopcheck.reduced.dynamics import MechanismModel

    model = MechanismModel(clamped_rotor())
    assert int(model.arrays.I[physics.N_CLAMPED]) == 1
    chart = physics.Chart(model.arrays, 1e-9)
    assert chart.clamp_event(physics.RANGE_EVENT) == 0 and chart.clamp_event(physics.RANGE_EVENT + 1) == -1
    assert chart.clamp_event(physics.FRICTION_EVENT) == -1
