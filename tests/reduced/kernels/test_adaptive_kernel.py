"""The compiled DOP853 driver (loopcheck.reduced.kernels.adaptive) against scipy on real scenes.

The kernel calls the compiled physics (a ``loopcheck.reduced.kernels.physics.Chart``, the
``RightHandSide`` of Eksergian's equation in one chart of a linkage); scipy's side calls the same
chart's ``acceleration`` and ``stop_margin`` from Python, so any difference is the integrator's. A chart is mutable (its Newton walk starts from
the last configuration), so every run, the kernel's and scipy's, gets a FRESH chart started
identically (:func:`Case.chart`).

Scenes:
- SEED: the seed four-bar (reduced.default_scene_path()): crank chart, two load pieces (250 N·m
  for 1 s, then none), damper; the crank stays well conditioned (the stop event never fires).
- SWING: scenes/hard/dead_centre.toml (a triple rocker) with a 0.5 N·m torque pulse on
  [0, 0.25] s (two pieces), started in the CRANK chart at q = 5.8 rad, q̇ = −4 rad/s: 0.19 rad
  from the crank's limit position at 5.987 rad, where another coordinate is better conditioned
  (stop margin < 0 at the start). The crank swings away from that limit (the margin rises
  through 0 in piece 1: an upward crossing, ignored) to the other limit (0.296 rad), where the
  margin falls through 0 in piece 2: the coordinate switch, the stop event. Without the stop
  event the chart is walked past the limit and the acceleration is NaN.

Fast: a few seconds.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, replace
from functools import cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from loopcheck.reduced import MechanismModel  # noqa: E402
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.shipped_scenes import default_scene_path
from loopcheck.errors import NumericalFailure  # noqa: E402
from loopcheck.kinematics import SINGULAR_CONDITIONING  # noqa: E402
from loopcheck.reduced.integrators import restart, solve_adaptive  # noqa: E402
from loopcheck.reduced.kernels import adaptive as K  # noqa: E402
from loopcheck.reduced.kernels import output  # noqa: E402
from loopcheck.reduced.kernels import physics  # noqa: E402
from loopcheck.reduced.charts import _start, load_pieces  # noqa: E402
from loopcheck.shipped_scenes import hard_scene_dir  # noqa: E402

from helpers import scipy_in_kernel_order, without_dyad_plans  # noqa: E402


@pytest.fixture(autouse=True)
def _scipy_sums_in_kernel_order():
    """scipy sums its stages in the kernel's order here (helpers.scipy_in_kernel_order): the
    comparisons below are step for step, and the BLAS's order varies with the CPU."""
    with scipy_in_kernel_order():
        yield

ALL_STEPS = dict(per_step=1, sample_interval=1e9)  # samples = exactly the step times

# Kernel vs scipy: the same arithmetic in the same order on the same evaluation points of the
# same compiled physics, each on a fresh chart walked through the same points. Measured:
# - steps (t, q, q̇ at every step): bit-equal on the seed at rtol 1e-6, 1e-9, 1e-12; on the
#   swing bit-equal but for the stop event's root, 1 ulp apart at rtol 1e-6 (1.1e-16 s; q
#   3.5e-15, q̇ 2.7e-14 relative there): Brent's iteration runs on the step's dense output,
#   whose coefficients differ in their last bits (next item);
# - samples between the steps (dense output): up to 3.9e-15 relative in q, q̇ (scipy sums the
#   dense-output coefficients h·D·K with numpy's BLAS dot, in another order).
RTOL_EQUAL = 1e-13
ATOL_EQUAL = 1e-13
# - q̈ at those samples: a q that differs in its last bits is closed by Newton's method (to
#   physics.NEWTON_TOL = 1e-12) from another start: measured up to 3.2e-11 absolute (5.7e-14
#   relative, |q̈| ≈ 570 rad/s² on the seed) and 3.6e-12 absolute where |q̈| ≈ 0.9; ≥ 2.8x margin.
RTOL_ACCEL = 2e-13
ATOL_ACCEL = 1e-11


@dataclass(frozen=True)
class Case:
    model: MechanismModel
    x0: np.ndarray       # assembled configuration at the start
    independent: int     # the chart's coordinate
    v0: float            # its rate at the start
    edges: np.ndarray    # load pieces
    loads: np.ndarray
    max_step: float = math.inf  # s, for the kernel and scipy alike
    newton: bool = False  # the charts' dyad plans switched off: Newton's method closes the loops

    @property
    def arrays(self):
        return without_dyad_plans(self.model) if self.newton else self.model.arrays

    @property
    def q0(self) -> float:
        return float(self.x0[self.independent])

    def chart(self):
        """A fresh chart of the coordinate, started at x0 (the kernel and scipy each get one)."""
        chart = physics.Chart(self.arrays, SINGULAR_CONDITIONING)
        assert chart.start(np.ascontiguousarray(self.x0), self.independent)
        return chart

    def margin(self, q: float) -> float:
        return self.chart().stop_margin(0.0, q, 0.0)

    def run(self, *, chart=None, **kw) -> K.RunResult:
        return K.run(self.chart() if chart is None else chart, self.edges, self.loads,
                     self.q0, self.v0, **{"max_step": self.max_step, **kw})


@cache
def seed() -> Case:
    model = MechanismModel(load_scene(default_scene_path()))
    x0, i, v0, _, _ = _start(model)
    assert i == 0 and v0 == 0.0  # the crank's chart, at rest
    return Case(model, x0, i, v0, *load_pieces(model))


@cache
def seed_newton() -> Case:
    """The seed closed by Newton's method: q̈ then depends on the chart's walk in its last bits,
    so scipy's restart after the pulse must start from the f0 computed before its probe
    (loopcheck.reduced.integrators.restart), as the kernel does; the closed form is history-free."""
    return replace(seed(), newton=True)


SWING_Q0, SWING_V0 = 5.8, -4.0
SWING_PULSE_END = 0.25
# The stop event fires at t = 0.5828 s; from 0.5868 s on the crank cannot close the loop (NaN).
# A step that jumps those 4 ms puts a stage there before the event is seen (measured at rtol 1e-6
# with steps of 0.06 s, and with 0.02 s): the engine then runs the chart again with a capped
# step (loopcheck.reduced.engine.CHART_RETRY_MAX_STEP); the kernel alone does not. So the case caps the
# step at 5 ms, for the kernel and scipy alike.
SWING_MAX_STEP = 0.005


@cache
def swing() -> Case:
    with open(hard_scene_dir() / "dead_centre.toml", "rb") as f:
        data = tomllib.load(f)
    for key in ("tolerances", "mujoco"):
        data.pop(key)
    data["initial"] = {"q": SWING_Q0, "qdot": SWING_V0}
    data["torque"] = {"type": "pulse", "value": 0.5, "start": 0.0, "duration": SWING_PULSE_END}
    model = MechanismModel(scene_from_dict(data))
    x0 = model.assemble(SWING_Q0)
    edges, loads = load_pieces(model)
    assert edges.tolist() == [0.0, SWING_PULSE_END, 3.0]
    return Case(model, x0, 0, SWING_V0, edges, loads, SWING_MAX_STEP)   # the crank's chart (not the best one)


def rhs_factory(case: Case, chart):
    """solve_adaptive's rhs_on_piece with the compiled acceleration on ``chart``."""
    def rhs_on_piece(start, end):
        p = int(np.searchsorted(case.edges, start, side="right") - 1)
        load = int(case.loads[p])
        return lambda t, q, v: chart.acceleration(load, t, q, v)
    return rhs_on_piece


def adaptive(case: Case, rtol: float, *, use_stop=False, **kw):
    """loopcheck.reduced.integrators.solve_adaptive (loopcheck's scipy path) on a fresh chart."""
    chart = case.chart()
    stop = chart.stop_margin if use_stop else None
    return solve_adaptive(rhs_factory(case, chart), (case.edges[0], case.edges[-1]), case.q0, case.v0,
                          rtol=rtol, breakpoints=tuple(case.edges[1:-1]), stop=stop,
                          **{"max_step": case.max_step, **kw})


def scipy_pieces(case: Case, rtol, *, use_stop=False):
    """solve_ivp(DOP853, dense_output) once per piece on one fresh chart, as solve_adaptive calls it.

    After each piece the chart is walked through q̈ at the step states, in order, as the kernel
    evaluates its samples with ALL_STEPS (and solve_adaptive its own): the chart's Newton walk
    starts from its last configuration, and the configuration it closes to differs with that
    start by up to the Newton tolerance (q̈ measured 3.6e-11 relative apart on the seed from two
    walk histories); DOP853's error estimate amplifies such a difference into step sizes
    5e-6 relative apart one piece later. With the same history, the same bits."""
    chart = case.chart()
    y = np.array([case.q0, case.v0])
    sols = []
    for p in range(len(case.loads)):
        load = int(case.loads[p])

        def fun(t, s, load=load):
            return np.array([s[1], chart.acceleration(load, t, s[0], s[1])])

        events = None
        if use_stop:
            def event(t, s):
                return chart.stop_margin(t, s[0], s[1])
            event.terminal, event.direction = True, -1
            events = [event]
        first_step = None
        if sols:  # a restart at a load edge (loopcheck.reduced.kernels.adaptive.RESTART_STEPS), as solve_adaptive
            first_step, fun = restart(fun, case.edges[p], y, case.edges[p + 1], case.max_step, 7, rtol, rtol,
                                      sols[-1].t)
        sol = solve_ivp(fun, (case.edges[p], case.edges[p + 1]), y, method="DOP853", rtol=rtol, atol=rtol,
                        dense_output=True, events=events, first_step=first_step, max_step=case.max_step)
        assert sol.success
        sols.append(sol)
        for j in range(sol.t.size):  # the samples' q̈ (ALL_STEPS: the step times)
            chart.acceleration(load, sol.t[j], sol.y[0, j], sol.y[1, j])
        y = sol.y[:, -1]
        if sol.status == 1:
            break
    return sols


CASES = {"seed": (seed, False), "seed-stop": (seed, True), "swing-stop": (swing, True),
         "seed-newton": (seed_newton, False)}


@pytest.mark.parametrize("rtol", [1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("name", list(CASES))
def test_steps_states_and_evaluations_equal_scipy(rtol, name):
    make, use_stop = CASES[name]
    case = make()
    r = case.run(rtol=rtol, use_stop=use_stop, **ALL_STEPS)
    sols = scipy_pieces(case, rtol, use_stop=use_stop)
    assert r.status == output.OK
    t_ref = np.concatenate([s.t for s in sols])
    y_ref = np.concatenate([s.y for s in sols], axis=1)
    assert r.t.shape == t_ref.shape
    # every step bit-equal (the states at the steps are the solver's own, not its dense output);
    # the stop event's root within RTOL_EQUAL
    steps = slice(None, -1) if use_stop and r.stopped else slice(None)
    np.testing.assert_array_equal(r.t[steps], t_ref[steps])
    np.testing.assert_array_equal(r.q[steps], y_ref[0][steps])
    np.testing.assert_array_equal(r.v[steps], y_ref[1][steps])
    np.testing.assert_allclose(r.t, t_ref, rtol=RTOL_EQUAL, atol=0)
    np.testing.assert_allclose(r.q, y_ref[0], rtol=RTOL_EQUAL, atol=ATOL_EQUAL)
    np.testing.assert_allclose(r.v, y_ref[1], rtol=RTOL_EQUAL, atol=ATOL_EQUAL)
    assert r.n_steps == sum(len(s.t) - 1 for s in sols)
    # each restart's select_initial_step probe is one evaluation beyond solve_ivp's nfev there
    assert r.n_evaluations == sum(s.nfev for s in sols) + len(sols) - 1
    stops = make is swing
    assert r.stopped == stops
    if stops:
        # piece 1: the margin rises through 0 (ignored); piece 2: it falls through 0 (the stop)
        assert len(sols) == 2 and sols[0].status == 0 and sols[1].status == 1
        t_event = sols[-1].t_events[0][0]
        assert abs(r.t_reached - t_event) <= 1e-12 * max(1.0, abs(t_event))
        assert abs(case.margin(r.q[-1])) < 1e-9
    else:
        assert r.t_reached == case.edges[-1]


def test_event_direction_rule():
    """The swing starts with a stop margin < 0 (the crank near its limit); the margin crosses 0
    upwards (ignored: direction −1), then downwards at the other limit (the stop)."""
    case = swing()
    assert case.margin(case.q0) < 0
    r = case.run(rtol=1e-9, use_stop=True, **ALL_STEPS)
    assert r.stopped
    assert r.t_reached > 0.5                                      # the other limit, far away
    margins = np.array([case.margin(q) for q in r.q])
    up = np.flatnonzero((margins[:-1] < 0) & (margins[1:] > 0))
    assert up.size == 1 and r.t[up[0] + 1] < SWING_PULSE_END   # the ignored crossing, piece 1
    assert np.all(margins[up[0] + 1:-1] > 0)                     # positive until the stop
    sol = scipy_pieces(case, 1e-9, use_stop=True)
    assert sol[-1].status == 1
    assert abs(r.t_reached - sol[-1].t_events[0][0]) <= 1e-12


@pytest.mark.parametrize("interval", [0.05, 1e-3])  # 1e-3: steps cut finer than 4 parts
@pytest.mark.parametrize("rtol", [1e-6, 1e-12])
@pytest.mark.parametrize("name", ["seed", "swing-stop"])
def test_samples_equal_loopcheck_dense_samples(rtol, name, interval):
    """Sampling rule and dense output: the kernel's samples are solve_adaptive's (scipy) samples."""
    make, use_stop = CASES[name]
    case = make()
    r = case.run(rtol=rtol, sample_interval=interval, per_step=4, use_stop=use_stop)
    ref = adaptive(case, rtol, use_stop=use_stop, sample_interval=interval)
    traj = ref.trajectory
    assert r.status == output.OK and r.stopped == ref.stopped == use_stop
    assert r.t.shape == traj.t.shape
    np.testing.assert_allclose(r.t, traj.t, rtol=RTOL_EQUAL, atol=0)
    np.testing.assert_allclose(r.q, traj.q, rtol=RTOL_EQUAL, atol=ATOL_EQUAL)
    np.testing.assert_allclose(r.v, traj.qdot, rtol=RTOL_EQUAL, atol=ATOL_EQUAL)
    np.testing.assert_allclose(r.a, traj.qddot, rtol=RTOL_ACCEL, atol=ATOL_ACCEL)
    assert (r.n_steps, r.n_evaluations) == (ref.n_steps, ref.n_evaluations)
    assert r.n_sample_evaluations == r.t.size


@pytest.mark.parametrize("interval", [0.05, 0.002, 1e-4])
def test_every_step_is_cut_into_equal_parts_no_longer_than_the_interval(interval):
    """The sampling rule (integrators.sample_parts): each accepted step of h cut into
    max(4, ⌈h / interval⌉) equal parts, so that the samples are no further apart than the
    interval nor than h / 4, with no more samples than that (the seed's first piece; the
    steps are those of a run sampled at its steps alone). Round-off: the cuts are
    t_j + h (k / p), within a few ulp of the exact fractions."""
    case = seed()
    one = Case(case.model, case.x0, case.independent, case.v0, case.edges[:2], case.loads[:1])
    steps = one.run(rtol=1e-8, **ALL_STEPS).t
    r = one.run(rtol=1e-8, sample_interval=interval, per_step=4)
    h = np.diff(steps)
    parts = np.maximum(4, np.ceil(h / interval)).astype(int)
    assert np.all(np.isin(steps, r.t))
    np.testing.assert_array_equal(np.diff(np.searchsorted(r.t, steps)), parts)
    gaps = np.diff(r.t)
    np.testing.assert_allclose(gaps, np.repeat(h / parts, parts), rtol=1e-9, atol=1e-15)
    assert np.all(gaps <= np.minimum(interval, np.repeat(h, parts) / 4) * (1 + 1e-9))


def test_dense_output_equals_scipy_sol():
    """Between the steps the samples are scipy's Dop853DenseOutput (sol.sol) at the same times
    (the seed's first piece)."""
    case = seed()
    one = Case(case.model, case.x0, case.independent, case.v0, case.edges[:2], case.loads[:1])
    r = one.run(rtol=1e-8, sample_interval=0.002, per_step=5)
    sol = scipy_pieces(one, 1e-8)[0]
    between = ~np.isin(r.t, sol.t)
    assert between.sum() > 4 * (len(sol.t) - 1)
    y = sol.sol(r.t[between])
    np.testing.assert_allclose(r.q[between], y[0], rtol=RTOL_EQUAL, atol=1e-14)
    np.testing.assert_allclose(r.v[between], y[1], rtol=RTOL_EQUAL, atol=1e-14)


SLOPE_BAND = (0.7, 1.3)


def test_error_falls_with_rtol():
    """No closed form among the scenes: the seed's error (q, and q̇ / 10 s⁻¹; peak |q̇| ≈ 34
    rad/s) against scipy's DOP853 at rtol 1e-13, whose own error (against rtol 2.2e-14) is
    1.1e-11 rad and 3.0e-11 (q̇ / 10), 1000x below the smallest error here. Measured errors
    7.8e-5, 3.8e-6, 3.8e-8 at rtol 1e-6, 1e-8, 1e-10: slope 0.83 (DOP853's global error
    follows the tolerance roughly, not exactly), each below 1e3 rtol (2.6x margin at 1e-10)."""
    case = seed()
    ref = scipy_pieces(case, 1e-13)
    rtols = np.array([1e-6, 1e-8, 1e-10])
    errors = []
    for rtol in rtols:
        r = case.run(rtol=rtol, sample_interval=0.01)
        piece = np.clip(np.searchsorted(case.edges, r.t, side="right") - 1, 0, len(ref) - 1)
        exact = np.empty((2, r.t.size))
        for p, sol in enumerate(ref):
            exact[:, piece == p] = sol.sol(r.t[piece == p])
        errors.append(max(np.max(np.abs(r.q - exact[0])), np.max(np.abs(r.v - exact[1])) / 10.0))
    errors = np.array(errors)
    slope = np.polyfit(np.log10(rtols), np.log10(errors), 1)[0]
    assert np.all(np.diff(errors) < 0), errors
    assert SLOPE_BAND[0] < slope < SLOPE_BAND[1], (slope, errors)
    assert np.all(errors < 1e3 * rtols), errors


def test_nonfinite_acceleration():
    """The swing without the stop event: the crank's chart is walked past its limit, where the
    configuration cannot be found and acceleration is NaN (piece 2)."""
    case = swing()
    chart = case.chart()
    r = case.run(chart=chart, rtol=1e-9)
    assert r.status == output.NONFINITE
    assert chart.S[physics.STATUS] == physics.SINGULAR
    with pytest.raises(NumericalFailure) as exc:
        adaptive(case, 1e-9)
    assert exc.value.reason == "non-finite"
    assert r.fail_time == exc.value.time
    assert r.fail_time > SWING_PULSE_END
    assert r.t[-1] == case.edges[1]  # the samples of the first piece (finished before the failure)


def test_step_size_when_budget_spent():
    case = seed()
    r = case.run(rtol=1e-9, max_evaluations=50)
    assert r.status == output.STEP_SIZE
    assert r.n_evaluations == 50
    with pytest.raises(NumericalFailure) as exc:
        adaptive(case, 1e-9, max_evaluations=50)
    assert exc.value.reason == "step-size"
    assert r.fail_time == exc.value.time


def test_speed_limit():
    case = seed()
    r = case.run(rtol=1e-9, speed_limit=0.5)
    assert r.status == output.SPEED
    assert abs(r.fail_value) > 0.5
    with pytest.raises(NumericalFailure) as exc:
        adaptive(case, 1e-9, speed_limit=0.5)
    assert exc.value.reason == "unstable"
    assert r.fail_time == exc.value.time
    moving = Case(case.model, case.x0, case.independent, 2.0, case.edges, case.loads)
    initial = moving.run(speed_limit=1.0)
    # checked before any evaluation, as solve_adaptive does (a check of the first sample would
    # give the same status and time)
    assert (initial.status, initial.fail_time, initial.t.size) == (output.SPEED, 0.0, 0)
    assert (initial.n_evaluations, initial.n_sample_evaluations) == (0, 0)
    with pytest.raises(NumericalFailure) as exc:
        adaptive(moving, 1e-9, speed_limit=1.0)
    assert (exc.value.reason, exc.value.time) == ("unstable", 0.0)
