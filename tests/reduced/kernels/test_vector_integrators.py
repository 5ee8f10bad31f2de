"""The n-coordinate integrators (loopcheck.reduced.kernels.vector_adaptive: DOP853;
loopcheck.reduced.kernels.vector_fixed_step: RKN4) through the VectorRightHandSide interface alone.

Oracles, each independent of the kernel under test:
- scipy's ``solve_ivp(method="DOP853", dense_output=True, events=[stop])`` on the same vector ODE,
  one call per load piece with the kernel's restart rule (scipy's own ``select_initial_step``,
  capped by the previous piece's last RESTART_STEPS steps), its sums in the kernel's order
  (:func:`scipy_in_vector_kernel_order`: numpy's BLAS sums in an order that depends on the CPU);
- the scalar kernels (loopcheck.reduced.kernels.adaptive, .fixed_step) at n = 1, on a closed
  form and on the seed four-bar's compiled chart (:class:`ScalarAsVector`);
- closed forms: a 2-DOF oscillator (the stop event's root, RKN4's order), and the energy
  balance of a damped, loaded chain of pendulums (E(t) − E(0) = W − D, E written here).

The problems are Python subclasses of VectorRightHandSide (the kernels call them through the
interpreter, a few µs an evaluation): short horizons.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tomllib

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.integrate._ivp import common

from loopcheck.reduced.kernels import adaptive, output, physics
from loopcheck.reduced.kernels import vector_adaptive as VA
from loopcheck.reduced.kernels.fixed_step import RKN4
from loopcheck.reduced.kernels.vector_fixed_step import vector_rkn_chart
from loopcheck.reduced.kernels.vector_output import VectorSamples
from loopcheck.reduced.kernels.vector_problem import ScalarAsVector, VectorRightHandSide

from helpers import ROOT, ClosedForm, run_dop853, run_rkn, scipy_in_vector_kernel_order

EDGES = (0.0, 0.4, 1.1, 2.0)   # three load pieces
LOADS = (0.8, -0.3, 0.0)       # the torque on the first pendulum on each (N·m)
RTOL = 1e-12                   # the engine's DOP853 tolerance (rtol = atol)
ALL_STEPS = dict(per_step=1, sample_interval=1e9)  # samples = exactly the step times


class Pendulums(VectorRightHandSide):
    """n unit pendulums (g/L = w2) in a chain of springs k, viscous damping c, a torque u[load] on
    the first: q̈ᵢ = −w2 sin qᵢ − c q̇ᵢ + k (qᵢ₊₁ − qᵢ) − k (qᵢ − qᵢ₋₁) (+ u on i = 0). Its energy
    E = Σ ½ q̇ᵢ² + w2 (1 − cos qᵢ) + ½ k Σ (qᵢ₊₁ − qᵢ)²; power u q̇₀, dissipation c Σ q̇ᵢ².
    Optional stop margin ``stop(t, q, v)``; observes Σ q̈ᵢ of its latest evaluation."""

    def __init__(self, n, *, w2=9.0, k=4.0, c=0.3, u=LOADS, stop=None, locate=False):
        self.n, self.w2, self.k, self.c, self.u = n, w2, k, c, u
        self._stop, self._locate, self.last = stop, locate, math.nan

    def dimension(self):
        return self.n

    def acceleration(self, load, t, q, v, a):
        n = self.n
        total = 0.0
        for i in range(n):
            x = -self.w2 * math.sin(q[i]) - self.c * v[i]
            if i > 0:
                x -= self.k * (q[i] - q[i - 1])
            if i < n - 1:
                x += self.k * (q[i + 1] - q[i])
            if i == 0:
                x += self.u[load]
            a[i] = x
            total += x
        self.last = total
        return 0

    def power(self, load, v):
        return self.u[load] * v[0]

    def dissipation(self, v):
        return sum(self.c * v[i] * v[i] for i in range(self.n))

    def stop_margin(self, t, q, v):
        return 1.0 if self._stop is None else self._stop(t, q, v)

    def locate(self, t, q, v):
        return self._locate

    def observation_size(self):
        return 1

    def observe(self, out, row):
        out[row, 0] = self.last

    def energy(self, q, v):
        return (0.5 * (v ** 2).sum(axis=1) + self.w2 * (1 - np.cos(q)).sum(axis=1)
                + 0.5 * self.k * ((q[:, 1:] - q[:, :-1]) ** 2).sum(axis=1))


def start(n):
    return np.linspace(0.3, -0.2, n), np.linspace(0.0, -1.0, n)


class Oscillator(VectorRightHandSide):
    """q̈ = −ω² q in two coordinates from q = (1, 0), q̇ = (0, ω): q = (cos ωt, sin ωt). Stop
    margin q₀ − q₁ = cos ωt − sin ωt, or on the rates (``on_rates``) (q̇₀ + q̇₁)/ω, the same
    function: its root is ωt = π/4."""

    def __init__(self, omega, locate=False, on_rates=False):
        self.omega, self._locate, self.on_rates = omega, locate, on_rates

    def dimension(self):
        return 2

    def acceleration(self, load, t, q, v, a):
        a[0] = -self.omega ** 2 * q[0]
        a[1] = -self.omega ** 2 * q[1]
        return 0

    def stop_margin(self, t, q, v):
        return (v[0] + v[1]) / self.omega if self.on_rates else q[0] - q[1]

    def locate(self, t, q, v):
        return self._locate


def scipy_pieces(rhs, edges, q0, v0, rtol, *, use_stop=False):
    """solve_ivp(DOP853, dense_output, events=[stop]) once per load piece (load p on piece p) on
    y = (q, q̇), a piece after an edge started at scipy's select_initial_step capped by the largest
    of the previous piece's last RESTART_STEPS steps. Returns the solutions."""
    n = rhs.dimension()
    y = np.concatenate([q0, v0]).astype(float)
    sols = []
    for p in range(len(edges) - 1):
        def fun(t, s, load=p):
            a = np.empty(n)
            assert rhs.acceleration(load, t, s[:n], s[n:], a) == 0
            return np.concatenate([s[n:], a])

        events = None
        if use_stop:
            def event(t, s):
                return rhs.stop_margin(t, s[:n], s[n:])
            event.terminal, event.direction = True, -1
            events = [event]
        first_step = None
        if sols:
            h = common.select_initial_step(fun, edges[p], y, edges[p + 1], np.inf, fun(edges[p], y), 1, 7, rtol, rtol)
            first_step = min(h, float(np.max(np.diff(sols[-1].t)[-VA.RESTART_STEPS:])))
        sol = solve_ivp(fun, (edges[p], edges[p + 1]), y, method="DOP853", rtol=rtol, atol=rtol, dense_output=True,
                        events=events, first_step=first_step)
        assert sol.status in (0, 1)
        sols.append(sol)
        y = sol.y[:, -1]
        if sol.status == 1:
            break
    return sols


# ---------------------------------------------------------------------------
# DOP853 against scipy
# ---------------------------------------------------------------------------

# Measured (n = 1, 2, 3, 5; three pieces; rtol 1e-12): the same steps, and t, q, q̇ at every step
# equal to the bit (and with the stop event, its root and the state there); between the steps
# (the dense output at per_step = 4, n = 2, 3) equal to the bit too: the same interpolant summed
# in the same order, on the segment scipy's OdeSolution picks. So the tests ask for the bits.


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_dop853_takes_scipys_steps_to_the_bit(n):
    rhs = Pendulums(n)
    q0, v0 = start(n)
    run = VA.run(rhs, EDGES, range(3), q0, v0, rtol=RTOL, **ALL_STEPS)
    with scipy_in_vector_kernel_order():
        sols = scipy_pieces(Pendulums(n), EDGES, q0, v0, RTOL)
    assert run.status == output.OK and not run.stopped
    assert run.n_steps == sum(s.t.size - 1 for s in sols)
    t = np.concatenate([s.t for s in sols])
    y = np.concatenate([s.y for s in sols], axis=1).T
    assert np.array_equal(run.t, t)
    assert np.array_equal(np.hstack([run.q, run.v]), y)
    # the samples' q̈ is the problem's at the sample, and observe() recorded right after it
    totals = []
    for row in run.a:
        total = 0.0
        for x in row:
            total += x
        totals.append(total)
    assert np.array_equal(run.observed[:, 0], totals)


@pytest.mark.parametrize("n", [2, 3])
def test_dop853_dense_samples_are_scipys_dense_output(n):
    rhs = Pendulums(n)
    q0, v0 = start(n)
    run = VA.run(rhs, EDGES, range(3), q0, v0, rtol=RTOL, per_step=4, sample_interval=1e9)
    with scipy_in_vector_kernel_order():
        sols = scipy_pieces(Pendulums(n), EDGES, q0, v0, RTOL)
    assert run.n_steps == sum(s.t.size - 1 for s in sols)
    assert run.t.size == 4 * run.n_steps + 3
    piece = np.cumsum(np.r_[False, np.diff(run.t) == 0])  # a load edge's time repeats: the next piece's first sample
    for i, t in enumerate(run.t):
        assert np.array_equal(np.concatenate([run.q[i], run.v[i]]), sols[piece[i]].sol(t)), t


def stop_when_apart(t, q, v):
    """> 0 until the first pendulum swings below −0.2 − 0.1 q_last (in the second load piece)."""
    return q[0] + 0.2 + 0.1 * q[-1]


@pytest.mark.parametrize("n", [2, 3])
def test_dop853_stop_event_is_scipys(n):
    q0, v0 = start(n)
    run = VA.run(Pendulums(n, stop=stop_when_apart), EDGES, range(3), q0, v0, rtol=RTOL, use_stop=True, **ALL_STEPS)
    with scipy_in_vector_kernel_order():
        sols = scipy_pieces(Pendulums(n, stop=stop_when_apart), EDGES, q0, v0, RTOL, use_stop=True)
    assert sols[-1].status == 1 and len(sols) >= 2  # the event fires after a load edge
    assert run.stopped and run.status == output.OK
    assert run.t_reached == sols[-1].t_events[0][0] == run.t[-1]
    assert np.array_equal(np.concatenate([run.q[-1], run.v[-1]]), sols[-1].y_events[0][0])
    assert np.array_equal(run.t, np.concatenate([s.t for s in sols]))
    assert abs(stop_when_apart(0, run.q[-1], run.v[-1])) < 1e-14


# ---------------------------------------------------------------------------
# n = 1: the scalar kernels' numbers
# ---------------------------------------------------------------------------

def scalar_pendulum(stop=None):
    """Pendulums(1) as a scalar ClosedForm (helpers)."""
    return ClosedForm(lambda t, q, v, u: -9.0 * math.sin(q) - 0.3 * v + u, values=LOADS,
                      dissipation=lambda v: 0.3 * v * v, stop=stop)


def vector_samples(result):
    return result.t, result.q[:, 0], result.v[:, 0], result.a[:, 0], result.energy


@pytest.mark.parametrize("use_stop", [False, True])
def test_dop853_at_n1_gives_the_scalar_kernels_bits(use_stop):
    stop = (lambda t, q, v: q + 0.15) if use_stop else None
    outcome, *scalar = run_dop853(scalar_pendulum(stop), EDGES, 0.3, 0.0, rtol=RTOL, sample_interval=0.01,
                                  use_stop=use_stop)
    run = VA.run(ScalarAsVector(scalar_pendulum(stop)), EDGES, range(3), [0.3], [0.0], rtol=RTOL,
                 sample_interval=0.01, per_step=4, use_stop=use_stop)
    assert outcome.stopped == run.stopped == use_stop
    assert (outcome.n_steps, outcome.n_evaluations, outcome.n_sample_evaluations) == (
        run.n_steps, run.n_evaluations, run.n_sample_evaluations)
    for mine, theirs in zip(vector_samples(run), scalar):
        assert np.array_equal(mine, theirs)


def seed_case():
    from loopcheck.kinematics import SINGULAR_CONDITIONING
    from loopcheck.reduced import MechanismModel
    from loopcheck.reduced.charts import _start, load_pieces
    from loopcheck.scenefile import load_scene
    from loopcheck.shipped_scenes import default_scene_path

    model = MechanismModel(load_scene(default_scene_path()))
    x0, i, v0, _, _ = _start(model)
    edges, loads = load_pieces(model)

    def chart():
        c = physics.Chart(model.arrays, SINGULAR_CONDITIONING)
        assert c.start(np.ascontiguousarray(x0), i)
        return c
    return chart, edges, loads, float(x0[i]), v0


def swing_case():
    """scenes/hard/dead_centre.toml with a torque pulse, started in the crank's chart near its limit
    (tests/reduced/kernels/test_adaptive_kernel.py's SWING): the stop event (the coordinate switch)
    fires in the second piece."""
    from loopcheck.kinematics import SINGULAR_CONDITIONING
    from loopcheck.reduced import MechanismModel
    from loopcheck.reduced.charts import load_pieces
    from loopcheck.scenefile import scene_from_dict
    from loopcheck.shipped_scenes import hard_scene_dir

    with open(hard_scene_dir() / "dead_centre.toml", "rb") as f:
        data = tomllib.load(f)
    for key in ("tolerances", "mujoco"):
        data.pop(key)
    data["initial"] = {"q": 5.8, "qdot": -4.0}
    data["torque"] = {"type": "pulse", "value": 0.5, "start": 0.0, "duration": 0.25}
    model = MechanismModel(scene_from_dict(data))
    x0 = model.assemble(5.8)
    edges, loads = load_pieces(model)

    def chart():
        c = physics.Chart(model.arrays, SINGULAR_CONDITIONING)
        assert c.start(np.ascontiguousarray(x0), 0)
        return c
    return chart, edges, loads, 5.8, -4.0


@pytest.mark.parametrize("case, use_stop", [(seed_case, False), (swing_case, True)], ids=["seed", "swing"])
def test_dop853_at_n1_on_the_linkage_chart_gives_the_scalar_kernels_bits(case, use_stop):
    """The compiled chart of a four-bar (Newton walk, mark and rewind, observations) through
    ScalarAsVector: the scalar kernel's samples, observations, energy flows and counts, bit for bit."""
    chart, edges, loads, q0, v0 = case()
    max_step = 0.005 if use_stop else math.inf  # (test_adaptive_kernel's SWING_MAX_STEP)
    scalar = adaptive.run(chart(), edges, loads, q0, v0, rtol=RTOL, sample_interval=0.01, use_stop=use_stop,
                          max_step=max_step)
    run = VA.run(ScalarAsVector(chart()), edges, loads, [q0], [v0], rtol=RTOL, sample_interval=0.01,
                 use_stop=use_stop, max_step=max_step)
    assert scalar.stopped == run.stopped == use_stop
    assert (scalar.n_steps, scalar.n_evaluations, scalar.n_sample_evaluations) == (
        run.n_steps, run.n_evaluations, run.n_sample_evaluations)
    for name in ("t", "observed", "energy"):
        assert np.array_equal(getattr(run, name), getattr(scalar, name)), name
    for name in ("q", "v", "a"):
        assert np.array_equal(getattr(run, name)[:, 0], getattr(scalar, name)), name


@pytest.mark.parametrize("locate", [False, True])
def test_rkn4_at_n1_gives_the_scalar_kernels_bits(locate):
    scalar_problem = scalar_pendulum(lambda t, q, v: q + 0.15 + 0.01 * v)
    if locate:
        scalar_problem.locate = lambda t, q, v: True
    outcome, *scalar = run_rkn(scalar_problem, EDGES, 0.3, 0.0, 2e-3, use_stop=True)
    out = VectorSamples(1, 0)
    mine = vector_rkn_chart(ScalarAsVector(scalar_problem), RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0,
                            np.array([0.3]), np.array([0.0]), 2e-3, 1e6, True, True, out)
    t, q, v, a, _, energy = out.arrays()
    assert outcome.stopped and mine.stopped
    assert (outcome.n_steps, outcome.n_evaluations, outcome.t_reached) == (mine.n_steps, mine.n_evaluations,
                                                                           mine.t_reached)
    for got, expected in zip((t, q[:, 0], v[:, 0], a[:, 0], energy), scalar):
        assert np.array_equal(got, expected)


# ---------------------------------------------------------------------------
# Closed forms
# ---------------------------------------------------------------------------

OMEGA = 3.0
ROOT_TIME = math.pi / 4 / OMEGA  # q₀ − q₁ = cos ωt − sin ωt = 0


@pytest.mark.parametrize("on_rates", [False, True], ids=["on q", "on q̇"])
def test_dop853_stop_event_root_is_the_closed_forms(on_rates):
    """At rtol 1e-12 the global error of q is ~1e-12 and Brent's tolerance 4 eps: the root within
    1e-12 s (measured 4.9e-14 s), q there within 1e-11 (measured 1.6e-12), q̇ within 1e-11 ω
    (measured 4.8e-12 = 1.6e-12 ω)."""
    run = VA.run(Oscillator(OMEGA, on_rates=on_rates), [0.0, 1.0], [0], [1.0, 0.0], [0.0, OMEGA], rtol=RTOL,
                 use_stop=True)
    assert run.stopped and run.status == output.OK
    assert abs(run.t_reached - ROOT_TIME) < 1e-12
    c, s = math.cos(OMEGA * ROOT_TIME), math.sin(OMEGA * ROOT_TIME)
    assert np.max(np.abs(run.q[-1] - [c, s])) < 1e-11
    assert np.max(np.abs(run.v[-1] - [-OMEGA * s, OMEGA * c])) < 1e-11 * OMEGA


@pytest.mark.parametrize("on_rates", [False, True], ids=["on q", "on q̇"])
def test_rkn4_located_stop_is_the_closed_forms_root(on_rates):
    """RKN4 at h = 1e-3 (error ~ h⁴ = 1e-12 a unit time), the root on the step's Hermite
    interpolants (also fourth order; q̇'s from q̇ and q̈ at the step's ends): within 1e-10 s
    (measured 1.4e-13 s on q, 4.0e-15 s on q̇); unlocated, the run
    ends after the step past the root, within one step (measured 2.0e-4 s after it)."""
    for locate in (False, True):
        out = VectorSamples(2, 0)
        outcome = vector_rkn_chart(Oscillator(OMEGA, locate, on_rates), RKN4, np.array([0.0, 1.0]), np.zeros(1, dtype=np.intp),
                                   0.0, np.array([1.0, 0.0]), np.array([0.0, OMEGA]), 1e-3, 1e6, True, True, out)
        assert outcome.stopped and outcome.status == output.OK
        if locate:
            assert abs(outcome.t_reached - ROOT_TIME) < 1e-10
        else:
            assert 0.0 <= outcome.t_reached - ROOT_TIME <= 1e-3


def coupled_exact(t):
    """q̈ = −K q, K = [[2, −1], [−1, 2]] (modes ω = 1: q₀ = q₁, ω = √3: q₀ = −q₁), from q = (1, 0),
    q̇ = (0, 0.5): q = ½ (cos t + 0.5 sin t) (1, 1) + ½ (cos √3 t − 0.5 sin(√3 t)/√3) (1, −1)."""
    r3 = math.sqrt(3.0)
    m1 = 0.5 * (np.cos(t) + 0.5 * np.sin(t))
    m2 = 0.5 * (np.cos(r3 * t) - 0.5 * np.sin(r3 * t) / r3)
    return np.stack([m1 + m2, m1 - m2], axis=1)


class Coupled(VectorRightHandSide):
    def dimension(self):
        return 2

    def acceleration(self, load, t, q, v, a):
        a[0] = -2.0 * q[0] + q[1]
        a[1] = q[0] - 2.0 * q[1]
        return 0


def test_rkn4_is_fourth_order_on_coupled_oscillators():
    """Largest |q − q_exact| over 4 s at h = 0.1 … 0.0125: fitted slope 4 ± 0.2 (measured 3.97)."""
    steps = [0.1, 0.05, 0.025, 0.0125]
    errors = []
    for h in steps:
        out = VectorSamples(2, 0)
        outcome = vector_rkn_chart(Coupled(), RKN4, np.array([0.0, 4.0]), np.zeros(1, dtype=np.intp), 0.0,
                                   np.array([1.0, 0.0]), np.array([0.0, 0.5]), h, 1e6, True, False, out)
        assert outcome.status == output.OK
        t, q, *_ = out.arrays()
        errors.append(float(np.max(np.abs(q - coupled_exact(t)))))
    slope = float(np.polyfit(np.log(steps), np.log(errors), 1)[0])
    assert abs(slope - 4.0) <= 0.2, (slope, errors)


def test_dop853_error_on_coupled_oscillators_is_at_its_tolerance():
    """At rtol 1e-10 the largest error over 4 s is below 2e-9 (measured 2.3e-10)."""
    run = VA.run(Coupled(), [0.0, 4.0], [0], [1.0, 0.0], [0.0, 0.5], rtol=1e-10, sample_interval=0.01)
    assert run.status == output.OK
    assert np.max(np.abs(run.q - coupled_exact(run.t))) < 2e-9


@pytest.mark.parametrize("kernel", ["dop853", "rkn4"])
def test_energy_flows_balance_the_chains_energy(kernel):
    """E(t) − E(0) = W(t) − D(t) along the run (the work of the torque on pieces, the damping's
    dissipation): within 1e-10 J, W = −0.045 J and D = 0.59 J at the end (measured: DOP853 at
    rtol 1e-12 1.3e-11 J, RKN4 at h = 1e-3 1.5e-12 J)."""
    rhs = Pendulums(3)
    q0, v0 = start(3)
    if kernel == "dop853":
        run = VA.run(rhs, EDGES, range(3), q0, v0, rtol=RTOL, sample_interval=0.01)
        q, v, energy = run.q, run.v, run.energy
    else:
        out = VectorSamples(3, 1)
        outcome = vector_rkn_chart(rhs, RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0, q0, v0, 1e-3, 1e6,
                                   True, False, out)
        assert outcome.status == output.OK
        _, q, v, _, _, energy = out.arrays()
    assert energy[-1, 1] > 0.1 and abs(energy[-1, 0]) > 0.01  # both flows at work
    balance = rhs.energy(q, v) - rhs.energy(q[:1], v[:1]) - (energy[:, 0] - energy[:, 1])
    assert np.max(np.abs(balance)) < 1e-10


# ---------------------------------------------------------------------------
# Statuses and refusals
# ---------------------------------------------------------------------------

class FailsAfter(Pendulums):
    """Pendulums(2) whose acceleration cannot be evaluated from t_fail on: status 3, or (``nan``)
    status 0 with q̈₁ = NaN (the second coordinate's only)."""

    def __init__(self, t_fail, nan=False):
        super().__init__(2)
        self.t_fail, self.nan = t_fail, nan

    def acceleration(self, load, t, q, v, a):
        status = super().acceleration(load, t, q, v, a)
        if t < self.t_fail:
            return status
        if self.nan:
            a[1] = math.nan
            return 0
        return 3


def test_an_unevaluable_acceleration_ends_the_run_where_it_happens():
    """From t = 0.7 on, q̈ cannot be evaluated (status 3) or is NaN in the second coordinate
    alone: either way the run ends at the first evaluation there (the same time and count of
    evaluations), keeping the pieces before."""
    q0, v0 = start(2)
    runs = [VA.run(FailsAfter(0.7, nan), EDGES, range(3), q0, v0, rtol=1e-8) for nan in (False, True)]
    for run in runs:
        assert run.status == output.NONFINITE and 0.7 <= run.fail_time <= 1.1
        assert run.t[-1] == 0.4  # the first piece's samples kept
    assert (runs[0].fail_time, runs[0].n_evaluations) == (runs[1].fail_time, runs[1].n_evaluations)
    outcomes = []
    for nan in (False, True):
        out = VectorSamples(2, 1)
        outcomes.append(vector_rkn_chart(FailsAfter(0.7, nan), RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0,
                                         q0, v0, 0.01, 1e6, False, False, out))
    for outcome in outcomes:
        assert outcome.status == output.FAILED and 0.69 <= outcome.fail_time <= 0.7
    assert outcomes[0].fail_time == outcomes[1].fail_time


def test_speed_limit_names_the_coordinate():
    q0, v0 = start(3)
    out = VectorSamples(3, 1)
    outcome = VA.vector_dop853_run(Pendulums(3), np.array(EDGES), np.arange(3, dtype=np.intp), q0, v0, 1e-8, 1e-8,
                                   1e-3, 4, 0.9, 10 ** 6, math.inf, False, out, VA.VectorSteps(3))
    assert outcome.status == output.SPEED and abs(outcome.fail_value) > 0.9
    i = int(outcome.detail[0])
    assert i == 2  # v0 = (0, −0.5, −1): the third pendulum is the fastest at the start
    out = VectorSamples(3, 1)
    outcome = vector_rkn_chart(Pendulums(3), RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0, q0, v0 * 0.8,
                               0.01, 0.9, False, False, out)
    assert outcome.status == output.SPEED and abs(outcome.fail_value) > 0.9


def test_spent_budget_is_a_step_size_failure():
    q0, v0 = start(2)
    run = VA.run(Pendulums(2), EDGES, range(3), q0, v0, rtol=1e-12, max_evaluations=200)
    assert run.status == output.STEP_SIZE and run.n_evaluations == 200


def test_a_stiff_step_is_refused_by_the_stability_check():
    """Two springs of k = 1e6 (ω ≈ 1.7e3 rad/s: h ω = 17 at h = 0.01): UNSTABLE before the first step."""
    q0, v0 = start(2)
    out = VectorSamples(2, 1)
    outcome = vector_rkn_chart(Pendulums(2, k=1e6), RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0, q0, v0,
                               0.01, 1e6, True, False, out)
    assert outcome.status == output.UNSTABLE and outcome.fail_time == 0.0
    assert outcome.detail[2] > outcome.detail[3]


def test_inputs_the_kernels_cannot_trust_are_refused():
    rhs = Pendulums(2)
    with pytest.raises(ValueError, match="dimension"):
        VA.run(rhs, EDGES, range(3), [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="VectorSteps of 3"):
        VA.run(rhs, EDGES, range(3), [0.0, 0.0], [0.0, 0.0], steps=VA.VectorSteps(3))
    with pytest.raises(ValueError, match="edges"):
        VA.run(rhs, EDGES, range(2), [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="width"):
        vector_rkn_chart(rhs, RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0, np.zeros(2), np.zeros(2), 0.01,
                         1e6, False, False, VectorSamples(2, 0))
    run = VA.run(rhs, EDGES, range(3), [0.0, math.nan], [0.0, 0.0])
    assert run.status == output.NONFINITE and run.t.size == 0


def test_a_reused_workspace_gives_the_same_run():
    q0, v0 = start(3)
    steps = VA.VectorSteps(3, capacity=2)  # grows inside the first run
    first = VA.run(Pendulums(3), EDGES, range(3), q0, v0, rtol=1e-10, steps=steps)
    assert steps.capacity() > 2
    again = VA.run(Pendulums(3), EDGES, range(3), q0, v0, rtol=1e-10, steps=steps)
    for a, b in zip(first, again):
        assert np.array_equal(a, b, equal_nan=True) if isinstance(a, np.ndarray) else a == b or (a != a and b != b)


SCRIPT = """
import sys
sys.path[:0] = [{tests!r}, {here!r}]
import numpy as np
from loopcheck.reduced import kernels
from loopcheck.reduced.kernels import vector_adaptive, vector_fixed_step
from loopcheck.reduced.kernels.fixed_step import RKN4
from loopcheck.reduced.kernels.vector_output import VectorSamples
from test_vector_integrators import Pendulums, start, EDGES
q0, v0 = start(2)
run = vector_adaptive.run(Pendulums(2), EDGES, range(3), q0, v0, rtol=1e-10, sample_interval=0.05)
out = VectorSamples(2, 1)
vector_fixed_step.vector_rkn_chart(Pendulums(2), RKN4, np.array(EDGES), np.arange(3, dtype=np.intp), 0.0, q0, v0,
                                   0.01, 1e6, True, False, out)
arrays = [run.t, run.q, run.v, run.a, run.energy, *out.arrays()]
print(kernels.compiled(), np.concatenate([x.ravel() for x in arrays]).tobytes().hex())
"""


@pytest.mark.skipif(not __import__("loopcheck.reduced.kernels").reduced.kernels.compiled(),
                    reason="the kernels are not compiled")
def test_the_uncompiled_source_gives_the_compiled_numbers():
    """LOOPCHECK_PURE_PYTHON=1 runs the same sources as plain Python: both vector kernels give the
    compiled kernels' samples to the bit (three pieces, energy flows, RKN4's stability checks)."""
    script = SCRIPT.format(tests=str(ROOT / "tests"), here=str(ROOT / "tests" / "reduced" / "kernels"))
    results = {}
    for pure in ("0", "1"):
        env = {**os.environ, "LOOPCHECK_PURE_PYTHON": pure}
        done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300,
                              cwd=ROOT)
        assert done.returncode == 0, done.stderr
        results[pure] = done.stdout.split(" ", 1)
    assert results["0"][0] == "True" and results["1"][0] == "False"
    assert results["0"][1] == results["1"][1]


@pytest.mark.parametrize("stiffness, damping", [(1e6, 50.0), (1e4, 1e3)], ids=["complex modes", "real modes"])
def test_the_stability_check_at_n1_is_the_scalar_kernels(stiffness, damping):
    """Stiff oscillators at h = 0.01: q̈ = −1e6 q − 50 q̇ (a complex pair, hλ ≈ −0.25 ± 10i) and
    the overdamped q̈ = −1e4 q − 1e3 q̇ (hλ ≈ −0.10 and −9.9: the second mode is the unstable one),
    each the same verdict, time and detail (Re hλ, Im hλ, |R|, limit) as fixed_step's, bit for bit."""
    stiff = ClosedForm(lambda t, q, v, u: -stiffness * q - damping * v)
    outcome, *_ = run_rkn(stiff, [0.0, 1.0], 0.1, 0.0, 0.01)
    out = VectorSamples(1, 0)
    mine = vector_rkn_chart(ScalarAsVector(stiff), RKN4, np.array([0.0, 1.0]), np.zeros(1, dtype=np.intp), 0.0,
                            np.array([0.1]), np.array([0.0]), 0.01, 1e6, True, False, out)
    assert outcome.status == mine.status == output.UNSTABLE
    assert (outcome.fail_time, outcome.n_evaluations) == (mine.fail_time, mine.n_evaluations)
    assert np.array_equal(np.asarray(outcome.detail), np.asarray(mine.detail))


class TwoOscillators(VectorRightHandSide):
    """q̈₀ = −q₀, q̈₁ = −ω₁² q₁: uncoupled, the stiff mode (λ = ±i ω₁) in the second coordinate only."""

    def __init__(self, omega1):
        self.omega1 = omega1

    def dimension(self):
        return 2

    def acceleration(self, load, t, q, v, a):
        a[0] = -q[0]
        a[1] = -self.omega1 ** 2 * q[1]
        return 0


def test_the_stability_check_finds_the_stiff_mode_of_any_coordinate():
    """n = 2, ω₁ = 1000 rad/s at h = 0.01: the mode hλ = ±10i (closed form; the differenced
    Jacobian's eigenvalue within 1e-4: measured 1.1e-12) is refused before the first step; at
    h = 1e-3 (|hλ| = 1, inside RK4's interval |hω| < 2√2) the run is stable."""
    for h, status in ((0.01, output.UNSTABLE), (1e-3, output.OK)):
        out = VectorSamples(2, 0)
        outcome = vector_rkn_chart(TwoOscillators(1000.0), RKN4, np.array([0.0, 0.2]), np.zeros(1, dtype=np.intp), 0.0,
                                   np.array([1.0, 1e-3]), np.array([0.0, 0.0]), h, 1e6, True, False, out)
        assert outcome.status == status
    assert outcome.status == output.OK and outcome.n_steps == 200
    out = VectorSamples(2, 0)
    outcome = vector_rkn_chart(TwoOscillators(1000.0), RKN4, np.array([0.0, 0.2]), np.zeros(1, dtype=np.intp), 0.0,
                               np.array([1.0, 1e-3]), np.array([0.0, 0.0]), 0.01, 1e6, True, False, out)
    assert abs(outcome.detail[0]) < 1e-4 and abs(abs(outcome.detail[1]) - 10.0) < 1e-4


def test_the_stability_checks_eigenvalues_are_lapacks():
    """The check's own eigenvalues (EISPACK's balanc, elmhes, hqr: vector_fixed_step.eigenvalues)
    against numpy's (LAPACK's dgeev) on 3 000 random matrices of size 1–10: general ones, and
    Jacobians [[0, I], [F_q, F_q̇]] with F_q up to 1e6 (general and −F Fᵀ: oscillatory). Each
    eigenvalue within 1e-11 of max(1, the largest |λ|) of the other set's nearest (measured
    5.4e-13 over 20 000). Trials 2554 and 2746 (several complex pairs of one modulus) need more
    than Numerical Recipes' 30 iterations."""
    from loopcheck.reduced.kernels.vector_fixed_step import eigenvalues

    rng = np.random.default_rng(1)
    worst = 0.0
    for trial in range(3000):
        size = int(rng.integers(1, 11))
        kind = trial % 3
        if kind == 0:
            matrix = rng.normal(size=(size, size))
        else:
            n = max(1, size // 2)
            f_q = rng.normal(size=(n, n)) * 10 ** rng.uniform(-2, 6)
            f_v = rng.normal(size=(n, n)) * 10 ** rng.uniform(-2, 3)
            if kind == 2:
                f_q = -(f_q @ f_q.T)
            matrix = np.block([[np.zeros((n, n)), np.eye(n)], [f_q, f_v]])
        mine, lapack = eigenvalues(matrix), np.linalg.eigvals(matrix)
        scale = max(1.0, float(np.max(np.abs(lapack))))
        worst = max(worst, max(float(np.min(np.abs(lapack - z))) for z in mine) / scale,
                    max(float(np.min(np.abs(mine - z))) for z in lapack) / scale)
    assert worst < 1e-11, worst
