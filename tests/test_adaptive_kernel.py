"""The compiled DOP853 driver (reduced.kernels.adaptive) against scipy on the toy problem.

The same njit ``acceleration`` is called from Python for scipy's side, so any difference is
the integrator's. Fast: about a second after numba has compiled (compiling the kernel cold
costs several seconds once; numba caches it on disk).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

pytest.importorskip("numba")

from reduced.errors import NumericalFailure  # noqa: E402
from reduced.integrators import solve_adaptive  # noqa: E402
from reduced.kernels import adaptive as K  # noqa: E402
from reduced.kernels.problem import acceleration, make_toy, stop_margin  # noqa: E402

EDGES = np.array([0.0, 0.7, 1.9, 3.0])   # three pieces: a restart at every edge
LOADS = np.array([1.5, -2.0, 0.4])
Q0, V0 = 0.3, -0.2
ALL_STEPS = dict(per_step=1, sample_interval=1e9)  # samples = exactly the step times


def scipy_pieces(problem, chart, edges, loads, q0, v0, rtol, *, use_stop=False):
    """solve_ivp(DOP853, dense_output) once per piece, as solve_adaptive calls it."""
    y = np.array([q0, v0])
    sols = []
    for p in range(len(loads)):
        load = float(loads[p])

        def fun(t, s, load=load):
            return np.array([s[1], acceleration(problem, chart, load, t, s[0], s[1])])

        events = None
        if use_stop:
            def event(t, s):
                return stop_margin(problem, chart, t, s[0], s[1])
            event.terminal, event.direction = True, -1
            events = [event]
        sol = solve_ivp(fun, (edges[p], edges[p + 1]), y, method="DOP853", rtol=rtol, atol=rtol,
                        dense_output=True, events=events)
        assert sol.success
        sols.append(sol)
        y = sol.y[:, -1]
        if sol.status == 1:
            break
    return sols


def rhs_factory(problem, chart, edges, loads):
    def rhs_on_piece(start, end):
        p = int(np.searchsorted(edges, start, side="right") - 1)
        load = float(loads[p])
        return lambda t, q, v: acceleration(problem, chart, load, t, q, v)
    return rhs_on_piece


@pytest.mark.parametrize("rtol", [1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("use_stop", [False, True])
def test_steps_states_and_evaluations_equal_scipy(rtol, use_stop):
    problem, chart = make_toy(k=4.0, c=0.3, w=0.5, q_stop=-0.5 if use_stop else math.inf)
    r = K.run(problem, chart, EDGES, LOADS, Q0, V0, rtol=rtol, use_stop=use_stop, **ALL_STEPS)
    sols = scipy_pieces(problem, chart, EDGES, LOADS, Q0, V0, rtol, use_stop=use_stop)
    assert r.status == K.OK
    t_ref = np.concatenate([s.t for s in sols])
    y_ref = np.concatenate([s.y for s in sols], axis=1)
    assert r.t.shape == t_ref.shape
    np.testing.assert_allclose(r.t, t_ref, rtol=1e-13, atol=0)
    np.testing.assert_allclose(r.q, y_ref[0], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(r.v, y_ref[1], rtol=1e-13, atol=1e-13)
    assert r.n_steps == sum(len(s.t) - 1 for s in sols)
    assert r.n_evaluations == sum(s.nfev for s in sols)
    assert r.stopped == use_stop
    if use_stop:
        assert sols[-1].status == 1  # q falls through -0.5 in piece 2 (ignored), rises in 3
        t_event = sols[-1].t_events[0][0]
        assert abs(r.t_reached - t_event) <= 1e-12 * max(1.0, abs(t_event))
        assert abs(r.q[-1] + 0.5) < 1e-12
    else:
        assert r.t_reached == EDGES[-1]


def test_event_direction_rule():
    """Starting above q_stop (g < 0) and falling through it is an upward crossing of g: no stop."""
    problem, chart = make_toy(k=4.0, c=0.0, q_stop=0.2)
    r = K.run(problem, chart, [0.0, 3.0], [0.0], 0.5, 0.0, rtol=1e-9, use_stop=True)
    sol = scipy_pieces(problem, chart, [0.0, 3.0], [0.0], 0.5, 0.0, 1e-9, use_stop=True)[0]
    assert sol.status == 1  # scipy: g goes up through 0 first (ignored), then down again
    assert r.stopped
    assert abs(r.t_reached - sol.t_events[0][0]) <= 1e-12


@pytest.mark.parametrize("rtol", [1e-6, 1e-12])
def test_samples_equal_xval_dense_samples(rtol):
    """Sampling rule and dense output: the kernel's samples are solve_adaptive's (scipy) samples."""
    problem, chart = make_toy(k=4.0, c=0.3, w=0.5)
    r = K.run(problem, chart, EDGES, LOADS, Q0, V0, rtol=rtol, sample_interval=0.05, per_step=4)
    ref = solve_adaptive(rhs_factory(problem, chart, EDGES, LOADS), (EDGES[0], EDGES[-1]), Q0, V0,
                         rtol=rtol, breakpoints=tuple(EDGES[1:-1]), sample_interval=0.05)
    traj = ref.trajectory
    assert r.t.shape == traj.t.shape
    np.testing.assert_allclose(r.t, traj.t, rtol=1e-13, atol=0)
    np.testing.assert_allclose(r.q, traj.q, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(r.v, traj.qdot, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(r.a, traj.qddot, rtol=1e-12, atol=1e-12)
    assert (r.n_steps, r.n_evaluations) == (ref.n_steps, ref.n_evaluations)
    assert r.n_sample_evaluations == r.t.size


def test_dense_output_equals_scipy_sol():
    """Between the steps the samples are scipy's Dop853DenseOutput (sol.sol) at the same times."""
    problem, chart = make_toy(k=9.0, c=0.1, w=0.5)
    r = K.run(problem, chart, [0.0, 2.0], [1.0], 0.4, 0.0, rtol=1e-8, sample_interval=0.01,
              per_step=5)
    sol = scipy_pieces(problem, chart, [0.0, 2.0], [1.0], 0.4, 0.0, 1e-8)[0]
    between = ~np.isin(r.t, sol.t)
    assert between.sum() > 4 * (len(sol.t) - 1)
    y = sol.sol(r.t[between])
    np.testing.assert_allclose(r.q[between], y[0], rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(r.v[between], y[1], rtol=1e-13, atol=1e-14)


def test_chart_mutation_counts_every_evaluation():
    problem, chart = make_toy(k=4.0, c=0.3, w=0.5)
    r = K.run(problem, chart, EDGES, LOADS, Q0, V0, rtol=1e-9)
    assert chart.calls[0] == r.n_evaluations + r.n_sample_evaluations


def test_error_falls_with_rtol():
    """Undamped linear oscillator, closed form: the global error follows the tolerance."""
    w, T = 3.0, 10.0
    problem, chart = make_toy(k=w * w, linear=True)
    rtols = np.array([1e-6, 1e-8, 1e-10])
    errors = []
    for rtol in rtols:
        r = K.run(problem, chart, [0.0, T], [0.0], 1.0, 0.0, rtol=rtol, sample_interval=0.01)
        exact_q = np.cos(w * r.t)
        exact_v = -w * np.sin(w * r.t)
        errors.append(max(np.max(np.abs(r.q - exact_q)), np.max(np.abs(r.v - exact_v)) / w))
    errors = np.array(errors)
    slope = np.polyfit(np.log10(rtols), np.log10(errors), 1)[0]
    assert np.all(np.diff(errors) < 0), errors
    assert 0.7 < slope < 1.3, (slope, errors)
    assert np.all(errors < 1e3 * rtols), errors


def test_nonfinite_acceleration():
    problem, chart = make_toy(k=4.0, c=0.3, w=0.5, t_nan=1.234)
    r = K.run(problem, chart, EDGES, LOADS, Q0, V0, rtol=1e-9)
    assert r.status == K.NONFINITE
    with pytest.raises(NumericalFailure) as exc:
        solve_adaptive(rhs_factory(problem, chart, EDGES, LOADS), (EDGES[0], EDGES[-1]), Q0, V0,
                       rtol=1e-9, breakpoints=tuple(EDGES[1:-1]))
    assert exc.value.reason == "non-finite"
    assert r.fail_time == exc.value.time
    assert r.fail_time >= 1.234
    assert r.t[-1] == EDGES[1]  # the samples of the first piece (finished before the failure)


def test_step_size_when_budget_spent():
    problem, chart = make_toy(k=4.0, c=0.3, w=0.5)
    r = K.run(problem, chart, EDGES, LOADS, Q0, V0, rtol=1e-9, max_evaluations=50)
    assert r.status == K.STEP_SIZE
    assert r.n_evaluations == 50
    with pytest.raises(NumericalFailure) as exc:
        solve_adaptive(rhs_factory(problem, chart, EDGES, LOADS), (EDGES[0], EDGES[-1]), Q0, V0,
                       rtol=1e-9, breakpoints=tuple(EDGES[1:-1]), max_evaluations=50)
    assert exc.value.reason == "step-size"
    assert r.fail_time == exc.value.time


def test_speed_limit():
    problem, chart = make_toy(k=4.0, c=0.3, w=0.5)
    r = K.run(problem, chart, EDGES, LOADS, Q0, V0, rtol=1e-9, speed_limit=0.5)
    assert r.status == K.SPEED
    assert abs(r.fail_value) > 0.5
    with pytest.raises(NumericalFailure) as exc:
        solve_adaptive(rhs_factory(problem, chart, EDGES, LOADS), (EDGES[0], EDGES[-1]), Q0, V0,
                       rtol=1e-9, breakpoints=tuple(EDGES[1:-1]), speed_limit=0.5)
    assert exc.value.reason == "unstable"
    assert r.fail_time == exc.value.time
    initial = K.run(problem, chart, EDGES, LOADS, Q0, 2.0, speed_limit=1.0)
    assert (initial.status, initial.fail_time, initial.t.size) == (K.SPEED, 0.0, 0)
