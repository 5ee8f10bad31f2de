"""The compiled integrators (loopcheck.reduced.kernels.fixed_step: RKN over a tableau; loopcheck.reduced.kernels.adaptive:
DOP853) on closed forms, through the RightHandSide interface alone.

Every problem here is a :class:`helpers.ClosedForm` (a Python subclass of RightHandSide, called
through the interpreter: ~1 µs an evaluation), with an exact solution to measure against:
q̈ = −q (cos t, sin t), the pendulum q̈ = −sin q (Jacobi's sn, scipy.special.ellipj), damped and
forced oscillators, a load pulse with an edge, and the energy flows' own identities.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

from loopcheck.reduced.kernels import output
from loopcheck.reduced.kernels.adaptive import Steps, dop853_run
from loopcheck.reduced.kernels.fixed_step import RKN4, RKN4_AS_PRINTED, RKNTableau, rkn_chart

from helpers import ROOT, ClosedForm, run_dop853, run_rkn, scipy_in_kernel_order


def observed_order(steps, errors) -> float:
    """Least-squares slope of log(error) against log(step)."""
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def assert_order(steps, errors, order):
    """The fitted slope is the declared order ± 0.2."""
    slope = observed_order(steps, errors)
    assert abs(slope - order) <= 0.2, f"fitted order {slope:.2f}, declared {order}"


def harmonic():
    return ClosedForm(lambda t, q, v, u: -q)


def rkn_errors(rhs, exact, t_end, steps, *, tableau=RKN4, q0=1.0, v0=0.0):
    """Largest |q − q_exact| over the samples of each RKN run."""
    errors = []
    for h in steps:
        outcome, t, q, *_ = run_rkn(rhs, [0.0, t_end], q0, v0, h, tableau=tableau)
        assert outcome.status == output.OK
        errors.append(float(np.max(np.abs(q - exact(t)))))
    return errors


STEPS = [0.1, 0.05, 0.025, 0.0125]

# ---------------------------------------------------------------------------
# RKN: order on closed forms
# ---------------------------------------------------------------------------


def test_rkn4_is_fourth_order_on_harmonic_oscillator():
    """q̈ = −q, q = cos t. Order 4 ± 0.2: the errors (1e-6 … 1e-10) sit far above round-off."""
    assert_order(STEPS, rkn_errors(harmonic(), np.cos, 10.0, STEPS), RKN4.order)


def test_rkn4_is_fourth_order_when_f_depends_on_velocity():
    """Damped oscillator q̈ = −q − 0.5 q̇, q(0) = 1, q̇(0) = 0 (closed form below)."""
    w = np.sqrt(1 - 0.25 ** 2)

    def exact(t):
        return np.exp(-0.25 * t) * (np.cos(w * t) + 0.25 / w * np.sin(w * t))

    errors = rkn_errors(ClosedForm(lambda t, q, v, u: -q - 0.5 * v), exact, 10.0, STEPS)
    assert_order(STEPS, errors, 4)


def test_rkn4_is_fourth_order_when_f_is_nonlinear_in_velocity():
    """q̈ = −q̇², q = ln(1 + t): the centrifugal term ζ q̇² makes the mechanism's f quadratic in q̇."""
    errors = rkn_errors(ClosedForm(lambda t, q, v, u: -v * v), np.log1p, 2.0, STEPS, q0=0.0, v0=1.0)
    assert_order(STEPS, errors, 4)


# The pendulum q̈ = −sin q from rest at θ0: sin(q/2) = k sn(K − t | m), k = sin(θ0/2), m = k²,
# period T = 4 K(m) (complete elliptic integral of the first kind).
THETA0 = 2.0
PEND_K = math.sin(THETA0 / 2)
PEND_QUARTER = float(ellipk(PEND_K ** 2))


def pendulum_exact(t):
    sn, _, _, _ = ellipj(PEND_QUARTER - np.asarray(t), PEND_K ** 2)
    return 2.0 * np.arcsin(PEND_K * sn)


def pendulum():
    return ClosedForm(lambda t, q, v, u: -math.sin(q))


def test_rkn4_is_fourth_order_on_the_nonlinear_pendulum():
    """θ0 = 2 rad (the period 9.3 s, 50 % above the small-angle 2π) over one period. Order 4 ± 0.2
    (measured 3.93 on these steps; 3.84 from 0.1 s, where the pairwise ratios still climb 13 → 15);
    errors 5.9e-8 … 1.7e-11 rad."""
    steps = [0.05, 0.025, 0.0125, 0.00625]
    errors = rkn_errors(pendulum(), pendulum_exact, 4 * PEND_QUARTER, steps, q0=THETA0)
    assert_order(steps, errors, 4)


def test_printed_seed_method_is_only_third_order():
    """seed-notes erratum 2, README: with m2 in the third stage's position argument the method drops
    to order 3 whenever f depends on q; it runs through the same compiled kernel as RKN4."""
    errors = rkn_errors(harmonic(), np.cos, 10.0, STEPS, tableau=RKN4_AS_PRINTED)
    assert_order(STEPS, errors, RKN4_AS_PRINTED.order)


def test_printed_method_is_rkn4_when_f_does_not_depend_on_q():
    """Erratum 2 is in the position argument of the third stage only: on q̈ = −q̇² (f free of
    q) the printed method gives RKN4's numbers to the bit (the same operations on the same
    values: the differing entry multiplies k's that never reach f) and the same order 4 (± 0.2)."""
    rhs = ClosedForm(lambda t, q, v, u: -v * v)
    printed = rkn_errors(rhs, np.log1p, 2.0, STEPS, tableau=RKN4_AS_PRINTED, q0=0.0, v0=1.0)
    corrected = rkn_errors(rhs, np.log1p, 2.0, STEPS, q0=0.0, v0=1.0)
    assert_order(STEPS, printed, 4)
    _, _, _, v_printed, *_ = run_rkn(rhs, [0.0, 2.0], 0.0, 1.0, 0.1, tableau=RKN4_AS_PRINTED)
    _, _, _, v_corrected, *_ = run_rkn(rhs, [0.0, 2.0], 0.0, 1.0, 0.1)
    np.testing.assert_array_equal(v_printed, v_corrected)
    np.testing.assert_allclose(printed, corrected, rtol=1e-12, atol=0)  # q differs by round-off only


def special_rkn_condition(tableau) -> float:
    """Σ_i b_i Σ_j ā_ij c_j − 1/24: the one fourth-order condition of a Nyström method for
    q̈ = f(q) that does not follow from the quadrature conditions and the row sums
    Σ_j ā_ij = c_i²/2 (expand the q̇ update to h⁴: the f_q f_q q̇ term has coefficient 1/24;
    Hairer, Nørsett & Wanner I, §II.14). Written here from the tableau's entries, independently
    of :meth:`RKNTableau.order_condition_residuals`."""
    b = np.asarray(tableau.b) / tableau.denominator
    return float(b @ np.asarray(tableau.abar) @ np.asarray(tableau.c)) - 1 / 24


def classical_rk_conditions(tableau) -> list[float]:
    """The eight order-4 conditions of the Runge-Kutta method (a, b, c) that updates q̇:
    when f depends on q̇ only, RKN reduces to it. Residuals, zero for classical RK4."""
    a = np.asarray(tableau.a)
    b, c = np.asarray(tableau.b) / tableau.denominator, np.asarray(tableau.c)
    return [b.sum() - 1, b @ c - 1 / 2, b @ c**2 - 1 / 3, b @ c**3 - 1 / 4, b @ a @ c - 1 / 6,
            (b * c) @ a @ c - 1 / 8, b @ a @ c**2 - 1 / 12, b @ a @ a @ c - 1 / 24]


def test_tableau_satisfies_the_full_fourth_order_conditions():
    """Exact rationals 1/8, 1/6, 1/3… in float64: each residual is a few ulps of 1/24, so
    1e-15. The printed variant misses Σ b ā c = 1/24 by exactly 1/16 − 1/24 = 1/48, which
    the package's own quadrature-condition list cannot see (it holds for both tables)."""
    assert abs(special_rkn_condition(RKN4)) < 1e-15
    assert max(abs(r) for r in classical_rk_conditions(RKN4)) < 1e-15
    assert special_rkn_condition(RKN4_AS_PRINTED) == pytest.approx(1 / 48, abs=1e-15)
    assert max(abs(r) for r in RKN4_AS_PRINTED.order_condition_residuals().values()) < 1e-15


def test_a_pickled_tableau_runs_the_same():
    """A tableau crosses to a sweep's worker processes by pickle: the copy gives the same run."""
    import pickle

    copy = pickle.loads(pickle.dumps(RKN4_AS_PRINTED))
    assert (copy.name, copy.order, copy.stages) == (RKN4_AS_PRINTED.name, 3, 4)
    for x, y in zip(run_rkn(harmonic(), [0.0, 1.0], 1.0, 0.0, 0.1, tableau=copy)[1:],
                    run_rkn(harmonic(), [0.0, 1.0], 1.0, 0.0, 0.1, tableau=RKN4_AS_PRINTED)[1:]):
        np.testing.assert_array_equal(x, y)


def test_a_tableau_the_kernel_cannot_run_is_refused():
    """The kernel reuses f at a step's end as the next first stage: c[0] must be 0; an implicit
    (non-strictly lower triangular) table is not explicit."""
    with pytest.raises(ValueError, match="c\\[0\\]"):
        RKNTableau("shifted", 4, (0.5, 0.5), ((), (0.5,)), ((), (0.5,)), (1.0, 0.0), (1.0, 1.0), 2.0)
    with pytest.raises(ValueError, match="lower triangular"):
        RKNTableau("implicit", 2, (0.0, 1.0), ((0.0, 0.5), (0.5,)), ((), (1.0,)), (1.0, 0.0), (1.0, 1.0), 2.0)


# ---------------------------------------------------------------------------
# Load edges (two pieces) and the stop event
# ---------------------------------------------------------------------------

# q̈ = −q + P for t < t_e, −q after; q(0) = q̇(0) = 0. Closed form:
# q = P (1 − cos t) before the edge, A cos(t − t_e) + B sin(t − t_e) after it, with
# A = P (1 − cos t_e), B = P sin t_e (q and q̇ continuous at t_e).
EDGE, PULSE = 0.3037, 2.0
EDGE_STEPS = [0.04, 0.02, 0.01, 0.005]  # t_e/h = 7.6, 15.2, 30.4, 60.7: never a whole number


def pulse_exact(t):
    t = np.asarray(t)
    after = PULSE * (1 - np.cos(EDGE)) * np.cos(t - EDGE) + PULSE * np.sin(EDGE) * np.sin(t - EDGE)
    return np.where(t < EDGE, PULSE * (1 - np.cos(t)), after)


def pulse():
    """The pulse as two load pieces (u = PULSE, then 0)."""
    return ClosedForm(lambda t, q, v, u: -q + u, values=(PULSE, 0.0))


def test_rkn_step_boundary_on_a_load_edge_keeps_fourth_order():
    """With the edge as a piece boundary the kernel gives order 4 ± 0.2 against the closed form
    (measured 3.96; errors 6e-9 … 2e-12, above the ~1e-15 round-off), and a sample on each side
    of the jump (q̈ differing by exactly the pulse). The same load evaluated pointwise on one
    piece lets a step straddle the jump, and the order collapses (measured ~1.1, erratic): the
    bound 2.5 separates the two behaviours by a wide margin."""
    with_edge, straddling = [], []
    pointwise = ClosedForm(lambda t, q, v, u: -q + (PULSE if t < EDGE else 0.0))
    for h in EDGE_STEPS:
        _, t, q, _, a, _ = run_rkn(pulse(), [0.0, EDGE, 1.0], 0.0, 0.0, h)
        with_edge.append(float(np.max(np.abs(q - pulse_exact(t)))))
        at_edge = np.flatnonzero(t == EDGE)
        assert len(at_edge) == 2 and a[at_edge[0]] - a[at_edge[1]] == PULSE
        _, t, q, *_ = run_rkn(pointwise, [0.0, 1.0], 0.0, 0.0, h)
        straddling.append(float(np.max(np.abs(q - pulse_exact(t)))))
    assert_order(EDGE_STEPS, with_edge, 4)
    assert observed_order(EDGE_STEPS, straddling) < 2.5
    assert min(straddling) > 100 * max(with_edge)


def test_rkn_starts_inside_a_piece_and_skips_those_before():
    """From t0 = 0.5 (inside the second piece) with the exact state there, the pieces before are
    skipped: the first sample is at t0, every step is ≤ the step asked, the load is the second
    piece's (errors of order 4 at h = 0.01: measured 2.0e-11, bound 1e-10)."""
    h, t0 = 0.01, 0.5
    q0 = float(pulse_exact(t0))
    v0 = -PULSE * (1 - np.cos(EDGE)) * np.sin(t0 - EDGE) + PULSE * np.sin(EDGE) * np.cos(t0 - EDGE)
    outcome, t, q, *_ = run_rkn(pulse(), [0.0, EDGE, 1.0], q0, v0, h, t0=t0)
    assert outcome.status == output.OK and t[0] == t0 and t[-1] == 1.0
    assert np.max(np.diff(t)) <= h * (1 + 1e-12) and outcome.n_steps == 50  # differences of rounded times
    assert np.max(np.abs(q - pulse_exact(t))) < 1e-10


def test_dop853_restarts_at_a_load_edge():
    """DOP853 on the pulse as two pieces at rtol 1e-8 … 1e-12: a sample on each side of the edge
    (q̈ differing by the pulse) and the error within 5 rtol (measured 0.5–1.7 rtol)."""
    for rtol in (1e-8, 1e-10, 1e-12):
        outcome, t, q, _, a, _ = run_dop853(pulse(), [0.0, EDGE, 1.0], 0.0, 0.0, rtol=rtol, sample_interval=0.01)
        assert outcome.status == output.OK and outcome.t_reached == 1.0
        at_edge = np.flatnonzero(t == EDGE)
        assert len(at_edge) == 2 and a[at_edge[0]] - a[at_edge[1]] == PULSE
        assert np.max(np.abs(q - pulse_exact(t))) < 5 * rtol, rtol


def sine_with_stop():
    """q̈ = −q from (0, 1): q = sin t; the stop margin 0.5 − q falls through 0 at t = π/6."""
    return ClosedForm(lambda t, q, v, u: -q, stop=lambda t, q, v: 0.5 - q)


def test_rkn_stop_event_ends_the_run_after_the_first_step_past_it():
    """The margin is checked after every step: the run ends at the first step time past π/6
    (0.53 at h = 0.01), with q̇ still the closed form's there (measured 8.3e-12 off, bound 3e-11)."""
    h = 0.01
    outcome, t, q, v, *_ = run_rkn(sine_with_stop(), [0.0, 3.0], 0.0, 1.0, h, use_stop=True)
    assert outcome.stopped and outcome.status == output.OK
    assert t[-1] == pytest.approx(math.ceil(math.pi / 6 / h) * h, abs=1e-12) == outcome.t_reached
    assert q[-2] < 0.5 <= q[-1]
    assert abs(v[-1] - math.cos(t[-1])) < 3e-11
    outcome, t, *_ = run_rkn(sine_with_stop(), [0.0, 3.0], 0.0, 1.0, h, use_stop=False)
    assert not outcome.stopped and t[-1] == 3.0


def test_dop853_stop_event_finds_the_crossing():
    """Brent's root of the margin on the dense output (xtol 4 ε): t_reached and the last sample
    at π/6 to the accuracy of the state (measured 7e-13 at rtol 1e-12; bound 5e-12), q = 0.5
    there to round-off."""
    outcome, t, q, *_ = run_dop853(sine_with_stop(), [0.0, 3.0], 0.0, 1.0, rtol=1e-12, use_stop=True)
    assert outcome.stopped and outcome.status == output.OK
    assert abs(outcome.t_reached - math.pi / 6) < 5e-12 and t[-1] == outcome.t_reached
    assert abs(q[-1] - 0.5) < 1e-15


# ---------------------------------------------------------------------------
# DOP853: accuracy against rtol, and step for step against scipy
# ---------------------------------------------------------------------------

RTOLS = [1e-6, 1e-8, 1e-10, 1e-12]


def test_dop853_error_is_proportional_to_rtol():
    """q̈ = −q over 10 s and the pendulum (θ0 = 2) over a period. DOP853's error per step stays
    within atol + rtol |y| (≈ 2 rtol here): the global error of these non-growing problems is
    a few rtol. Measured: 3.3–3.5 rtol (harmonic), 3.4–5.3 rtol (pendulum); bound 15 rtol
    (3x). It falls with rtol: the fitted slope of log error against log rtol is 1 ± 0.1
    (tolerance proportionality; measured 1.00 and 0.96)."""
    for rhs, exact, t_end, q0 in ((harmonic(), np.cos, 10.0, 1.0),
                                  (pendulum(), pendulum_exact, 4 * PEND_QUARTER, THETA0)):
        errors = []
        for rtol in RTOLS:
            outcome, t, q, *_ = run_dop853(rhs, [0.0, t_end], q0, 0.0, rtol=rtol, sample_interval=0.01)
            assert outcome.status == output.OK
            errors.append(float(np.max(np.abs(q - exact(t)))))
            assert errors[-1] < 15 * rtol, (rtol, errors[-1])
        assert abs(observed_order(RTOLS, errors) - 1.0) <= 0.1


SCIPY_CASES = {  # f(t, q, q̇, u), q0, q̇0, the rejected steps it has at rtol 1e-6 and 1e-10
    "damped, forced": (lambda t, q, v, u: -q - 0.3 * v + u, 0.5, 1.0, (0, 0)),
    "van der Pol, mu = 5": (lambda t, q, v, u: 5.0 * (1.0 - q * q) * v - q, 2.0, 0.0, (7, 14)),
}


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
@pytest.mark.parametrize("case", list(SCIPY_CASES))
def test_dop853_steps_and_values_equal_scipy(case, rtol):
    """Over 10 s, with each step one sample (per_step 1, no interval) the samples are the accepted
    steps. scipy's solve_ivp(method="DOP853") summed in the kernel's order
    (helpers.scipy_in_kernel_order) takes the same steps to the bit, reaches the same states to
    the bit and counts the same evaluations (2 to start, 12 per attempt, 3 per dense output):
    on a smooth linear problem and on van der Pol's, where steps are rejected (the count
    asserted: the step control's rejection path is compared too)."""
    f, q0, v0, rejected = SCIPY_CASES[case]
    rhs = ClosedForm(f, values=(2.0,))
    outcome, t, q, v, a, _ = run_dop853(rhs, [0.0, 10.0], q0, v0, rtol=rtol, per_step=1, sample_interval=math.inf)
    with scipy_in_kernel_order():
        sol = solve_ivp(lambda tt, y: np.array([y[1], f(tt, y[0], y[1], 2.0)]), (0.0, 10.0), [q0, v0],
                        method="DOP853", rtol=rtol, atol=rtol, dense_output=True)
    np.testing.assert_array_equal(t, sol.t)
    np.testing.assert_array_equal(q, sol.y[0])
    np.testing.assert_array_equal(v, sol.y[1])
    assert outcome.n_steps == len(sol.t) - 1 and outcome.n_evaluations == sol.nfev
    assert outcome.n_sample_evaluations == len(t)
    assert (outcome.n_evaluations - 2 - 15 * outcome.n_steps) / 12 == rejected[0 if rtol == 1e-6 else 1]


def test_dop853_samples_cut_every_step_no_coarser_than_the_interval():
    """At rtol 1e-12 with 4 parts per step and 0.05 s: the samples are sorted, unique, no further
    apart than 0.05 s, and each step (the samples of the per_step 1 run) is cut into at least 4."""
    _, t_steps, *_ = run_dop853(harmonic(), [0.0, 10.0], 1.0, 0.0, per_step=1, sample_interval=math.inf)
    _, t, *_ = run_dop853(harmonic(), [0.0, 10.0], 1.0, 0.0, per_step=4, sample_interval=0.05)
    assert np.all(np.diff(t) > 0) and np.max(np.diff(t)) <= 0.05 * (1 + 1e-12)
    assert set(t_steps) <= set(t)
    assert np.all(np.diff(np.searchsorted(t, t_steps)) >= 4)


# ---------------------------------------------------------------------------
# The energy flows ride along
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kernel", ["rkn4", "dop853"])
def test_energy_flows_match_their_identities(kernel):
    """q̈ = −q − c q̇ + F (c = 0.3, F = 2) from (0.5, 1) over 10 s. The work of a constant force
    is F (q − q0) exactly; both kernels integrate it with the velocity's weights, which give q
    itself (the Nyström condition bbar_j = Σ_i b_i a_ij; in DOP853 the same sum), so they agree
    to round-off (measured 1.5e-14 RKN4, 1.3e-15 DOP853; bound 1e-13). The balance
    ½q̇² + ½q² − E0 = W − D holds to the method's error (measured 8.8e-11 RKN4 at h = 0.01,
    6.0e-10 DOP853 at rtol 1e-10; bounds 3e-10 and 2e-9)."""
    c, F = 0.3, 2.0
    rhs = ClosedForm(lambda t, q, v, u: -q - c * v + u, values=(F,), dissipation=lambda v: c * v * v)
    if kernel == "rkn4":
        outcome, t, q, v, a, energy = run_rkn(rhs, [0.0, 10.0], 0.5, 1.0, 0.01)
        bound = 3e-10
    else:
        outcome, t, q, v, a, energy = run_dop853(rhs, [0.0, 10.0], 0.5, 1.0, rtol=1e-10)
        bound = 2e-9
    assert outcome.status == output.OK and energy[0, 0] == energy[0, 1] == 0.0
    assert np.max(np.abs(energy[:, 0] - F * (q - 0.5))) < 1e-13
    balance = (0.5 * v**2 + 0.5 * q**2) - (0.5 * 1.0**2 + 0.5 * 0.5**2) - (energy[:, 0] - energy[:, 1])
    assert np.max(np.abs(balance)) < bound
    assert energy[-1, 1] > 1.0  # the damper did dissipate


# ---------------------------------------------------------------------------
# Stability and statuses
# ---------------------------------------------------------------------------


def test_stability_check_rejects_a_damped_stiff_step_before_it_is_taken():
    """q̈ = −1e4 q − 50 q̇: λ = −25 ± 96.8i, h·λ = −0.75 ± 2.9i at h = 0.03 s, |R| = 1.24 > 1.
    With the speed limit out of the way the linearized check alone must fire, at t = 0, with
    the mode in outcome.detail (h·λ from the differenced Jacobian, 1e-7 relative)."""
    rhs = ClosedForm(lambda t, q, v, u: -1e4 * q - 50.0 * v)
    outcome, t, *_ = run_rkn(rhs, [0.0, 0.3], 1.0, 0.0, 0.03, speed_limit=1e300)
    assert outcome.status == output.UNSTABLE and outcome.fail_time == 0.0 and len(t) == 1
    re, im, amplification, limit = outcome.detail
    assert re == pytest.approx(-0.75, rel=1e-6) and abs(im) == pytest.approx(0.03 * math.sqrt(1e4 - 625), rel=1e-6)
    assert amplification == pytest.approx(1.2406, abs=1e-4) and limit == 1.0 + 1e-6
    assert outcome.n_evaluations == 1 + 3
    # Inside the stability region (h·λ = −0.025 ± 0.097i at 1 ms) the run completes.
    assert run_rkn(rhs, [0.0, 0.3], 1.0, 0.0, 1e-3, speed_limit=1e300)[0].status == output.OK


def test_undamped_step_outside_the_stability_interval_is_detected():
    """q̈ = −1e4 q (ω = 100 rad/s) at h = 0.03 s: hω = 3 > 2√2, |R(3i)| = 1.5 per step; over
    0.3 s the amplitude grows ~13× (the exact motion stays within √(1 + 1e-4) ≈ 1)."""
    rhs = ClosedForm(lambda t, q, v, u: -1e4 * q)
    outcome, *_ = run_rkn(rhs, [0.0, 0.3], 1.0, 1.0, 0.03, speed_limit=1e300)
    assert outcome.status == output.UNSTABLE and outcome.fail_time == 0.0
    # Inside the interval (hω = 2.7 at h = 0.027 s) the undamped mode is accepted.
    assert run_rkn(rhs, [0.0, 0.3], 1.0, 1.0, 0.027, speed_limit=1e300)[0].status == output.OK


def test_a_physically_growing_mode_is_not_refused():
    """q̈ = 100 q (λ = ±10, an inverted pendulum) at h = 0.01 s: the growing mode has
    R(0.1) = 1.10517 < e^0.1 = 1.10517 (by 8e-8 per step): the method follows the physics and
    no instability is reported; after 100 steps q matches cosh(10) to 3e-6 relative
    (measured; 100 × 8e-8 / 1.1 × ½ of the two modes), bound 1e-5."""
    outcome, t, q, *_ = run_rkn(ClosedForm(lambda t, q, v, u: 100.0 * q), [0.0, 1.0], 1.0, 0.0, 0.01,
                                speed_limit=1e300)
    assert outcome.status == output.OK
    assert q[-1] == pytest.approx(np.cosh(10.0), rel=1e-5)


def test_a_growing_oscillation_resolved_by_the_step_is_not_refused():
    """q̈ = 2a q̇ − (a² + b²) q: modes λ = a ± ib grow. With h = 4 ms, a = 42.25, b = 56 (hλ =
    0.169 + 0.224j, the local mode the seed shows at h = 4 ms), |R(hλ)| exceeds e^{0.169} by
    O(|hλ|⁵) ~ 1e-5, an accuracy defect, not instability: the run is not refused and matches
    q = e^{at} cos(bt) to RK4's accuracy (10 steps: measured error 1.8e-4 of e^{at}; bound 1e-3).
    A method that grows the mode much faster than the problem still is refused (h = 40 ms)."""
    a, b = 42.25, 56.0
    rhs = ClosedForm(lambda t, q, v, u: 2 * a * v - (a * a + b * b) * q)
    outcome, t, q, *_ = run_rkn(rhs, [0.0, 0.04], 1.0, a, 0.004, speed_limit=1e300)
    assert outcome.status == output.OK
    assert np.max(np.abs(q - np.exp(a * t) * np.cos(b * t)) / np.exp(a * t)) < 1e-3
    assert run_rkn(rhs, [0.0, 0.4], 1.0, a, 0.04, speed_limit=1e300)[0].status == output.UNSTABLE


def test_runaway_without_the_stability_check_is_a_speed_failure():
    """q̈ = −1e8 q at h = 0.01 (hω = 100): unchecked, |q̇| passes the limit 1e6 within steps;
    the samples before it stay, the failing state is not among them."""
    outcome, t, q, v, *_ = run_rkn(ClosedForm(lambda t, q, v, u: -1e8 * q), [0.0, 1.0], 1.0, 0.0, 0.01,
                                   stability=False)
    assert outcome.status == output.SPEED and abs(outcome.fail_value) > 1e6
    assert np.all(np.abs(v) <= 1e6) and t[-1] < outcome.fail_time


def test_non_finite_acceleration_fails_where_it_happens():
    """f = −q while q < 0.5, inf beyond (q = sin t crosses 0.5 at π/6): RKN4 fails (FAILED: f not
    evaluable) at the start of the step whose stage went past it; DOP853 (NONFINITE) at the
    stage's time; the samples before stay (RKN4), or none of the failing piece (DOP853)."""
    rhs = ClosedForm(lambda t, q, v, u: -q if q < 0.5 else math.inf)
    outcome, t, *_ = run_rkn(rhs, [0.0, 1.0], 0.0, 1.0, 0.01)
    assert outcome.status == output.FAILED and math.pi / 6 - 0.02 < outcome.fail_time < math.pi / 6
    assert t[-1] == outcome.fail_time
    outcome, t, *_ = run_dop853(rhs, [0.0, 1.0], 0.0, 1.0, rtol=1e-10)
    assert outcome.status == output.NONFINITE and 0.3 < outcome.fail_time < 0.8 and len(t) == 0


def test_dop853_speed_failure_keeps_the_pieces_before():
    """q̈ = 100 q from (1, 0): q̇ = 10 sinh 10t passes 1e3 at t* = asinh(100)/10 = 0.5298 s, in the
    second piece [0.3, 1]. SPEED at the first sample past it (within one sample spacing, 0.01 s),
    fail_value its q̇; the first piece's samples are appended, none of the second's."""
    rhs = ClosedForm(lambda t, q, v, u: 100.0 * q, values=(0.0, 0.0))
    outcome, t, q, v, *_ = run_dop853(rhs, [0.0, 0.3, 1.0], 1.0, 0.0, speed_limit=1e3, sample_interval=0.01)
    t_star = math.asinh(100.0) / 10.0
    assert outcome.status == output.SPEED and t_star <= outcome.fail_time < t_star + 0.01
    assert outcome.fail_value > 1e3 and t[-1] == 0.3 and outcome.t_reached == 0.3


def test_dop853_spent_budget_is_a_step_size_failure():
    """q̈ = −1e30 q: DOP853 needs ~1e15 steps per second. With a budget of 1e4 evaluations it
    stops with STEP_SIZE having spent exactly the budget, instead of running for hours."""
    outcome, t, *_ = run_dop853(ClosedForm(lambda t, q, v, u: -1e30 * q), [0.0, 1.0], 1.0, 0.0,
                                max_evaluations=10_000)
    assert outcome.status == output.STEP_SIZE and outcome.n_evaluations == 10_000 and len(t) == 0
    assert 0.0 < outcome.fail_time < 1e-9


@pytest.mark.parametrize("kernel", ["rkn4", "dop853"])
def test_bad_initial_states_are_refused_at_once(kernel):
    """|q̇0| beyond the speed limit: SPEED at t0 with q̇0; a NaN q0: NONFINITE at t0; no evaluation."""
    run = (lambda q0, v0: run_rkn(harmonic(), [0.0, 1.0], q0, v0, 1e-3)) if kernel == "rkn4" else \
        (lambda q0, v0: run_dop853(harmonic(), [0.0, 1.0], q0, v0))
    outcome, t, *_ = run(0.0, 1e308)
    assert outcome.status == output.SPEED and outcome.fail_time == 0.0 and outcome.fail_value == 1e308
    assert outcome.n_evaluations == 0 and len(t) == 0
    outcome, t, *_ = run(math.nan, 0.0)
    assert outcome.status == output.NONFINITE and outcome.fail_time == 0.0 and len(t) == 0


# ---------------------------------------------------------------------------
# Buffers: appended after the caller's samples; the step workspace reused
# ---------------------------------------------------------------------------


def test_samples_are_appended_after_those_held():
    """A Samples holding 3 samples already: each kernel appends after them (the 3 untouched) the
    samples a fresh Samples gets; a Samples of the wrong width is refused."""
    edges, loads = np.array([0.0, EDGE, 1.0]), np.array([0, 1], dtype=np.intp)
    for kernel in ("rkn4", "dop853"):
        fresh = (run_rkn(pulse(), edges, 0.0, 0.0, 0.01) if kernel == "rkn4"
                 else run_dop853(pulse(), edges, 0.0, 0.0, rtol=1e-10, sample_interval=1e-3))
        out = output.Samples(0, capacity=4)
        out.reserve(3)
        out.n = 3
        held = [np.array(x) for x in out.arrays()]
        if kernel == "rkn4":
            rkn_chart(pulse(), RKN4, edges, loads, 0.0, 0.0, 0.0, 0.01, 1e6, True, False, out)
        else:
            dop853_run(pulse(), edges, loads, 0.0, 0.0, 1e-10, 1e-10, 1e-3, 4, 1e6, 10**6, math.inf, False, out,
                       Steps(2))
        after = out.arrays()
        for before, now, new in zip(held, after, fresh[1:5] + (None, fresh[5])):
            np.testing.assert_array_equal(now[:3], before)
            if new is not None:
                np.testing.assert_array_equal(now[3:], new)
    with pytest.raises(ValueError, match="width"):
        rkn_chart(pulse(), RKN4, edges, loads, 0.0, 0.0, 0.0, 0.01, 1e6, True, False, output.Samples(2))


def test_a_reused_step_workspace_gives_the_same_run():
    """Steps of capacity 2 (grown by doubling during the run) reused for a second, different run,
    then the first again: every run equals its run with a fresh Steps, to the bit."""
    steps = Steps(2)
    first = run_dop853(pulse(), [0.0, EDGE, 1.0], 0.0, 0.0, rtol=1e-12, steps=steps)
    run_dop853(harmonic(), [0.0, 10.0], 1.0, 0.0, rtol=1e-12, steps=steps)
    again = run_dop853(pulse(), [0.0, EDGE, 1.0], 0.0, 0.0, rtol=1e-12, steps=steps)
    fresh = run_dop853(pulse(), [0.0, EDGE, 1.0], 0.0, 0.0, rtol=1e-12)
    assert steps.capacity() >= first[0].n_steps
    for x, y, z in zip(first[1:], again[1:], fresh[1:]):
        np.testing.assert_array_equal(x, z)
        np.testing.assert_array_equal(y, z)


SCRIPT = """
import sys, numpy as np
sys.path.insert(0, {tests!r})
from loopcheck.reduced import kernels
from helpers import ClosedForm, run_dop853, run_rkn
rhs = ClosedForm(lambda t, q, v, u: -q - 0.3 * v + u, values=(2.0, -1.0))
runs = (run_rkn(rhs, [0.0, 0.3, 1.0], 0.5, 1.0, 0.01, use_stop=False),
        run_dop853(rhs, [0.0, 0.3, 1.0], 0.5, 1.0, rtol=1e-10, sample_interval=0.01))
print(kernels.compiled(), [np.concatenate([x.ravel() for x in r[1:]]).tobytes().hex() for r in runs])
"""


@pytest.mark.skipif(not __import__("loopcheck.reduced.kernels").reduced.kernels.compiled(), reason="the kernels are not compiled")
def test_the_uncompiled_source_gives_the_compiled_numbers():
    """LOOPCHECK_PURE_PYTHON=1 (the debugging path) runs the same source as plain Python: both
    kernels give the compiled kernels' samples to the bit (two pieces, energy flows)."""
    script = SCRIPT.format(tests=str(ROOT / "tests"))
    results = {}
    for pure in ("0", "1"):
        env = {**os.environ, "LOOPCHECK_PURE_PYTHON": pure}
        done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300,
                              cwd=ROOT)
        assert done.returncode == 0, done.stderr
        results[pure] = done.stdout.split(" ", 1)
    assert results["0"][0] == "True" and results["1"][0] == "False"
    assert results["0"][1] == results["1"][1]
