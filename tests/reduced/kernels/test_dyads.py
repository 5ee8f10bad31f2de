"""Closed-form dyads (loopcheck.reduced.kernels.physics._dyads): a chart whose loops are RRR dyads (two
unknown angles per loop, fixed lengths) closes them by intersecting two circles instead of
Newton's method. Checked against Newton's method on the same linkages: configurations assembled
by loopcheck.kinematics (the Python path, another implementation), and whole walks of the compiled
chart with the plans switched off."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopcheck.reduced import MechanismModel
from loopcheck.scenefile import load_scene
from loopcheck.reduced.kernels import physics
from loopcheck.kinematics import SINGULAR_CONDITIONING, assemble
from loopcheck.reduced.charts import HYSTERESIS, conditioning

from helpers import ROOT, without_dyad_plans

MECHANISMS = ROOT / "scenes" / "mechanisms"
WITH_PLANS = ["seed_fourbar", "andrews_squeezer", "stephenson3_sixbar", "watt2_sixbar"]
# Round-off. The closed form against loopcheck.kinematics' Newton: measured ≤ 1.9e-14 rad on one dyad
# (the four-bar, the squeezer, Stephenson III), 1.25e-13 on the Watt six-bar (two dyads, the
# second built on the first). On the squeezer at its start, in the chart of a coordinate whose
# conditioning is 1e-16 of the best (one the solver leaves), both satisfy the loops to 1.4e-17 m
# and differ by 4.7e-8 rad: x is defined there only to ε / σ_min(Φ_x); such charts are skipped.
# Whole walks with and without the plans (closed form vs Newton inside the compiled chart):
# x 1.6e-15 rad, K and L 5.1e-15 relative, 𝔍, ζ and dq/dx_i 4.2e-15 of their largest. Bounds ~4-6x.
ANGLE_BOUND = 5e-13
# The cos and sin the closed form leaves for Newton's first iteration are computed from the
# dyad's vectors (the chart's coordinate's by libm): round-off from those of the x it returns,
# measured ≤ 1.3e-15 along walks of 3 rad of every shipped chart with a plan; bound 3x.
TRIG_BOUND = 4e-15
WALK_ANGLE_BOUND = 1e-14
RATE_BOUND = 3e-14


def model(name: str) -> MechanismModel:
    return MechanismModel(load_scene(MECHANISMS / f"{name}.toml"))


def plans(m: MechanismModel) -> list[int]:
    I = m.arrays.I
    return [int(I[I[physics.DYAD_PLAN] + i]) for i in range(m.system.n)]


def test_which_charts_close_in_closed_form():
    # the four-bar: any one of its three angles leaves one loop with two unknown angles
    assert all(p >= 0 for p in plans(model("seed_fourbar")))
    # a slider's length is a coordinate of its loop: Newton alone
    assert all(p < 0 for p in plans(model("slider_crank_gas")))


@pytest.mark.parametrize("name", WITH_PLANS)
def test_the_closed_form_is_newtons_configuration(name):
    """From a predictor 0.05 rad off in every dependent angle, the closed form lands on the
    configuration loopcheck.kinematics assembles by Newton's method (Python), for every chart with a
    plan that the solver would use there (conditioning within the partition's hysteresis of the
    best), at inputs over 0.6 rad."""
    m = model(name)
    F, I = m.arrays
    x = m.x0.copy()
    checked = 0
    for q in m.scene.q0 + np.linspace(0.0, 0.6, 7):
        x = assemble(m.system, float(q), x)
        for i, plan in enumerate(plans(m)):
            if plan < 0:
                continue
            c = conditioning(m, x)
            if c[i] < HYSTERESIS * np.max(c):  # a chart the solver leaves (nearly flat dyad):
                continue                       # x is defined there only to ε / σ_min(Φ_x)
            guess = x + 0.05 * (np.arange(len(x)) != i)
            trig = np.full((2, len(x)), np.nan)
            assert physics._dyads(F, I, plan, guess, x.copy(), trig, i)
            assert np.max(np.abs(guess - x)) <= ANGLE_BOUND, (q, i)
            # the trig it leaves is that of the x it returns, every angle (a NaN left fails)
            exact = [[math.cos(v) for v in guess], [math.sin(v) for v in guess]]
            assert np.all(np.abs(trig - exact) <= TRIG_BOUND), (q, i)
            checked += 1
    assert checked >= 7


@pytest.mark.parametrize("name", WITH_PLANS)
def test_a_walk_in_closed_form_equals_newtons(name):
    """The compiled chart walked along its input with and without the plans: the same
    configurations, K and L, and coefficients."""
    m = model(name)
    i = int(np.flatnonzero(np.array(plans(m)) >= 0)[0])
    x0 = m.x0.copy()
    values = x0[i] + np.linspace(0.0, 0.5, 200)
    runs = []
    for arrays in (m.arrays, without_dyad_plans(m)):
        chart = physics.Chart(arrays, SINGULAR_CONDITIONING)
        assert chart.start(x0, i)
        fields = np.empty((len(values), physics.N_FIELDS))
        kin = np.empty((len(values), 3, m.system.n))
        assert chart.walk(values, fields, kin) == len(values)
        runs.append((fields, kin))
    (f_closed, k_closed), (f_newton, k_newton) = runs
    assert np.max(np.abs(k_closed[:, 0] - k_newton[:, 0])) <= WALK_ANGLE_BOUND
    scale = np.maximum(np.abs(k_newton[:, 1:]), 1.0)
    assert np.max(np.abs(k_closed[:, 1:] - k_newton[:, 1:]) / scale) <= RATE_BOUND
    for field in (physics.INERTIA, physics.CENTRIFUGAL, physics.INPUT_RATE):
        scale = np.max(np.abs(f_newton[:, field]))
        assert np.max(np.abs(f_closed[:, field] - f_newton[:, field])) <= RATE_BOUND * scale


def _mirrored(m: MechanismModel, x: np.ndarray, i: int) -> tuple[np.ndarray, float, float]:
    """The four-bar's other assembly at x's x_i (its one dyad mirrored: the closed form from a base
    whose θ_b + φ_b − θ_a − φ_a is negated), and the dyad's sin(θ_b + φ_b − θ_a − φ_a) at x and
    there (of the sign of R(θ_a) W_a × R(θ_b) W_b: :meth:`physics.Chart._dyads`)."""
    F, I = m.arrays
    plan = plans(m)[i]
    a, b = (int(v) for v in I[I[physics.DYAD_STEPS] + 3 * plan + 1:I[physics.DYAD_STEPS] + 3 * plan + 3])
    phi_a, phi_b = F[I[physics.DYAD_W] + 6 * plan + 4:I[physics.DYAD_W] + 6 * plan + 6]
    base = x.copy()
    base[b] = 2.0 * (x[a] + phi_a) - x[b] - 2.0 * phi_b
    other = x.copy()
    assert physics._dyads(F, I, plan, other, base, np.zeros((2, len(x))), i)
    return other, math.sin(x[b] + phi_b - x[a] - phi_a), math.sin(other[b] + phi_b - other[a] - phi_a)


@pytest.mark.parametrize("i", [0, 1, 2])
def test_a_chart_keeps_the_assembly_it_starts_on(i):
    """The assembly a chart's closed form takes is stored when it starts (Chart.start), not read
    from the walk's base at every closure: one chart started on each assembly of the seed four-bar
    in turn (in the chart of each of its angles, at its start) walks where Newton's method alone
    walks from the same start (the plans switched off), on the assembly it started on, to
    WALK_ANGLE_BOUND and RATE_BOUND (the bounds of the walks above: closed form against Newton).
    Newton's walk keeps its assembly by the sign of det A, which a mirrored dyad flips."""
    m = model("seed_fourbar")
    x0 = m.x0.copy()
    other, side, other_side = _mirrored(m, x0, i)
    assert side * other_side < 0.0 and np.max(np.abs(other - x0)) > 0.5  # the two assemblies, 0.6 rad apart or more
    values = x0[i] + np.linspace(0.0, 0.05, 6)
    closed = physics.Chart(m.arrays, SINGULAR_CONDITIONING)  # one chart, restarted: no sides left over
    newton = physics.Chart(without_dyad_plans(m), SINGULAR_CONDITIONING)
    for start, sign in ((x0, side), (other, other_side), (x0, side)):
        walks = []
        for chart in (closed, newton):
            assert chart.start(start, i)
            kin = np.empty((len(values), 3, m.system.n))
            assert chart.walk(values, np.empty((len(values), physics.N_FIELDS)), kin) == len(values)
            walks.append(kin)
        closed_kin, newton_kin = walks
        _, walked, _ = _mirrored(m, newton_kin[-1, 0], i)
        assert walked * sign > 0.0  # Newton's walk stayed on the assembly it started on
        assert np.max(np.abs(closed_kin[:, 0] - newton_kin[:, 0])) <= WALK_ANGLE_BOUND
        scale = np.maximum(np.abs(newton_kin[:, 1:]), 1.0)
        assert np.max(np.abs(closed_kin[:, 1:] - newton_kin[:, 1:]) / scale) <= RATE_BOUND
