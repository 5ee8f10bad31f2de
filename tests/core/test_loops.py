"""Loop kinematics of the general description against closed forms and finite differences.

Oracles: the four-bar closed form of tests/oracles/four_bar.py (FourBar.kinematics, an independent
implementation), the offset slider-crank's closed form x = r cos q + √(l² − (r sin q − e)²)
and its derivatives, and central finite differences of Newton-assembled positions.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopcheck.errors import FailureReason, NumericalFailure
from oracles.four_bar import FourBar
from loopcheck.kinematics import (AssemblyError, assemble, coefficients, compile_linkage,
                           conditioning, constraint_residual, jacobian_rank, point_kinematics)
from loopcheck.scene import FourBarGeometry

from test_mechanism import (SEED, andrews, four_bar, inverted_slider_crank,
                            slider_crank, watt_ii)

QS = np.linspace(0.0, 2 * np.pi, 73)[:-1]  # a full crank revolution, every 5°
# Round-off: the closed forms and Newton's polished solution each carry a few ulps of the
# O(1) angles and lengths; measured worst over a revolution, both branches: 1.3e-15 (x),
# 1.0e-15 (K), 3.1e-15 (L and the points' L_r). 1e-14 is 3–10× above that.
ROUND_OFF = 1e-14


def wrap(a):
    return np.angle(np.exp(1j * np.asarray(a)))


def track(system, qs, x0):
    """Assemble along qs by continuation from x0 (each solution guesses the next)."""
    out, x = [], np.asarray(x0, float)
    for q in qs:
        x = assemble(system, q, x)
        out.append(x)
    return out


# -- the seed four-bar against its closed form ----------------------------------------

def pivoted_point(pivot, length, index, ref, offset=0.0) -> np.ndarray:
    """(r, K_r, L_r) flattened (6,) of the point at ``length`` along a link turning about a
    ground pivot at angle θ = x[index] + offset, from closed-form x, K, L (``ref``):
    r = pivot + c e(θ), K_r = c K e⊥(θ), L_r = c (L e⊥(θ) − K² e(θ))."""
    th = ref.x[index] + offset
    e, ep = np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])
    k, l = ref.K[index], ref.L[index]
    return np.r_[np.asarray(pivot) + length * e, length * k * ep, length * (l * ep - k * k * e)]


@pytest.mark.parametrize("branch", [1, -1])
def test_four_bar_matches_closed_form_over_a_revolution(branch):
    system = compile_linkage(four_bar())
    fb = FourBar(FourBarGeometry(*SEED, branch))
    ref0 = fb.kinematics(QS[0])
    # Body angles: crank = q, coupler = φ1, rocker = φ2 + π (φ2 is the angle of B→O3).
    # The guess is 0.2 rad off, so Newton (not the oracle) picks the branch.
    guess = np.array([QS[0], ref0.x[1] + 0.2, ref0.x[2] + math.pi - 0.2])
    worst = np.zeros(5)
    for q, x in zip(QS, track(system, QS, guess)):
        ref = fb.kinematics(q)
        K, L = coefficients(system, x)
        r, kr, lr = point_kinematics(system, x, K, L)
        worst[0] = max(worst[0], np.max(np.abs(wrap(x - ref.x - [0.0, 0.0, math.pi]))))
        worst[1] = max(worst[1], np.max(np.abs(K - ref.K)))
        worst[2] = max(worst[2], np.max(np.abs(L - ref.L)))
        # Points A and B written out from the closed form (B on the rocker, at O3 + c3 e(φ2 + π)).
        for body, name, e in (("crank", "A", pivoted_point((0.0, 0.0), SEED[0], 0, ref)),
                              ("rocker", "B", pivoted_point((SEED[3], 0.0), SEED[2], 2, ref, math.pi))):
            i = system.point_index(body, name)
            worst[3] = max(worst[3], np.max(np.abs(r[i] - e[0:2])))
            worst[4] = max(worst[4], np.max(np.abs(np.r_[kr[i], lr[i]] - e[2:6])))
        assert np.max(np.abs(constraint_residual(system, x))) < ROUND_OFF
    assert np.all(worst < ROUND_OFF), worst


def test_relative_angle_input_follows_the_chain_rule():
    """Input at the crank–coupler pin: q = φ1 − θ_crank, K and L by the chain rule from the
    closed form with the crank independent: dq/dθ = K_φ1 − 1."""
    system = compile_linkage(four_bar(input_joint="A"))
    fb = FourBar(FourBarGeometry(*SEED, 1))
    for theta in QS[::6]:
        ref = fb.kinematics(theta)
        g = ref.K[1] - 1.0
        h = ref.L[1]
        q = ref.x[1] - theta
        x = assemble(system, q, ref.x + [0.05, -0.05, math.pi + 0.05])
        K, L = coefficients(system, x)
        assert abs(wrap(x[0] - theta)) < ROUND_OFF
        # d x/dq = K_ref / g;  d²x/dq² = (L_ref g − K_ref h) / g³
        # Measured worst: 1.8e-15 (K), 1.5e-14 (L, divided by g³ with |g| down to ~0.6).
        np.testing.assert_allclose(K, ref.K / g, rtol=0, atol=ROUND_OFF)
        np.testing.assert_allclose(L, (ref.L * g - ref.K * h) / g**3, rtol=0, atol=5 * ROUND_OFF)


# -- the offset slider-crank against its closed form -----------------------------------

R, LEN, E = 0.1, 0.35, 0.03
# The slider-crank's lengths are ~0.1–0.45 m: measured worst 3.9e-16 (positions), 4e-17 (K, L).
SLIDER_ROUND_OFF = 2e-15


def slider_closed_form(q):
    """x, dx/dq, d²x/dq² of the slider pin, and the rod's angle (m, m/rad, m/rad², rad)."""
    h, hp, hpp = R * math.sin(q) - E, R * math.cos(q), -R * math.sin(q)
    w = math.sqrt(LEN**2 - h * h)
    x = R * math.cos(q) + w
    xp = -R * math.sin(q) - h * hp / w
    xpp = -R * math.cos(q) - (hp * hp + h * hpp) / w - (h * hp) ** 2 / w**3
    return x, xp, xpp, math.atan2(-h, w)


def test_slider_crank_with_crank_input():
    system = compile_linkage(slider_crank(R, LEN, E))
    assert system.coordinate_names == ("crank.angle", "rod.angle", "slider.angle", "slide.s")
    i_pin = system.point_index("slider", "pin")
    worst = np.zeros(4)
    for q, x in zip(QS, track(system, QS, [0.0, 0.1, 0.1, 0.4])):
        xs, xp, xpp, rod = slider_closed_form(q)
        K, L = coefficients(system, x)
        r, kr, lr = point_kinematics(system, x, K, L)
        worst[0] = max(worst[0], abs(x[3] - xs), abs(wrap(x[1] - rod)), abs(x[2]),
                       np.max(np.abs(r[i_pin] - [xs, E])))
        worst[1] = max(worst[1], abs(K[3] - xp), np.max(np.abs(kr[i_pin] - [xp, 0.0])))
        worst[2] = max(worst[2], abs(L[3] - xpp), np.max(np.abs(lr[i_pin] - [xpp, 0.0])))
        worst[3] = max(worst[3], abs(K[2]), abs(L[2]))  # the slider does not turn
    assert np.all(worst < SLIDER_ROUND_OFF), worst


def test_slider_crank_with_slider_input():
    """q = s: the crank angle θ is dependent, dθ/ds = 1/x'(θ), d²θ/ds² = −x''/x'³."""
    system = compile_linkage(slider_crank(R, LEN, E, input_joint="slide"))
    # Away from the dead centres (x' = 0 near θ ≈ 0.09 and π + …), both strokes.
    for theta in np.r_[np.linspace(0.4, 2.7, 8), np.linspace(3.6, 5.9, 8)]:
        xs, xp, xpp, rod = slider_closed_form(theta)
        x = assemble(system, xs, [theta + 0.05, rod - 0.05, 0.0, xs])
        K, L = coefficients(system, x)
        # Measured worst: 1.8e-15 (θ, amplified by |1/x'| ≤ 12 rad/m), 5.8e-15 relative (K),
        # 6.4e-13 relative (L: −x''/x'³ passes near zero on each stroke).
        assert abs(wrap(x[0] - theta)) < ROUND_OFF
        assert abs(K[0] - 1.0 / xp) < 3e-14 * abs(1.0 / xp)
        assert abs(L[0] + xpp / xp**3) < 3e-12 * abs(xpp / xp**3)
        assert K[3] == 1.0 and L[3] == 0.0


# -- a slider on a turning link: the Coriolis term 2 ṡ θ̇ e⊥ --------------------------

def inverted_closed_form(q, r=0.3, d=0.5):
    """s = |v|, ψ = angle of v, v = A − O2 = r e(q) − (d, 0), and their first two
    q-derivatives (v' = r e⊥(q), v'' = −r e(q))."""
    v = np.array([r * math.cos(q) - d, r * math.sin(q)])
    v1 = r * np.array([-math.sin(q), math.cos(q)])
    v2 = -r * np.array([math.cos(q), math.sin(q)])
    s = math.hypot(*v)
    dot, cross = v @ v1, v[0] * v1[1] - v[1] * v1[0]
    s1 = dot / s
    s2 = (v1 @ v1 + v @ v2) / s - dot**2 / s**3
    psi1 = cross / s**2
    psi2 = (v[0] * v2[1] - v[1] * v2[0]) / s**2 - 2 * cross * dot / s**4
    return (s, s1, s2), (math.atan2(v[1], v[0]), psi1, psi2)


@pytest.mark.parametrize("line_on_rocker", [True, False])
def test_inverted_slider_crank_matches_closed_form(line_on_rocker):
    """The rocker and block turn by ψ, the slide's s is ±|A − O2| (its sign follows which
    body carries the line)."""
    system = compile_linkage(inverted_slider_crank(line_on_rocker=line_on_rocker))
    sign = 1.0 if line_on_rocker else -1.0
    worst = np.zeros(3)
    for q, x in zip(QS, track(system, QS, [0.0, 3.0, 3.0, sign * 0.2])):
        (s, s1, s2), (psi, psi1, psi2) = inverted_closed_form(q)
        K, L = coefficients(system, x)
        worst[0] = max(worst[0], abs(x[3] - sign * s), np.max(np.abs(wrap(x[1:3] - psi))))
        worst[1] = max(worst[1], abs(K[3] - sign * s1), np.max(np.abs(K[1:3] - psi1)))
        worst[2] = max(worst[2], abs(L[3] - sign * s2), np.max(np.abs(L[1:3] - psi2)))
    # Measured worst 2.4e-16 (x), 3.3e-16 (K), 8.9e-16 (L; |ψ''| reaches 2.5 rad/rad²).
    assert np.all(worst < 3e-15), worst


# -- finite differences ------------------------------------------------------------------

# Central differences, errors relative to max |K| or max |L|. The step is scaled to the input's
# range (1 rad; 0.1 m for the slider, whose K is ~10 rad/m). K from positions with h = 1e-5:
# truncation h²/6·x‴ and round-off ε/h both ~1e-11. L from differences of the analytic K
# with h = 1e-5 (it converges as h², 100× per decade of h, measured from h = 1e-3 down) and,
# independently of K, from second differences of positions with h = 1e-4 (round-off ε/h²
# dominates). Measured worst over the four cases: 1.4e-10 (K), 2.3e-10 (L from K), 2.5e-7 (L
# from positions), 8e-11 and 1.1e-10 (the points' K_r and L_r).
FD_K, FD_L_FROM_K, FD_L = 1e-9, 1e-9, 1e-6

CASES = {  # builder, guess, q0, step scale
    "four-bar": (lambda: four_bar(), [0.3, 0.5, 1.2], 0.3, 1.0),
    "slider-crank, crank input": (lambda: slider_crank(R, LEN, E), [1.0, 0.3, 0.0, 0.3], 1.0, 1.0),
    "slider-crank, slider input": (lambda: slider_crank(R, LEN, E, "slide"), [1.0, 0.0, 0.0, 0.3],
                                   0.3, 0.1),
    "Watt II": (watt_ii, [0.3, 0.5, 1.2, 0.8, 1.5], 0.3, 1.0),
    "inverted slider-crank": (lambda: inverted_slider_crank(), [1.0, 2.0, 2.0, 0.4], 1.0, 1.0),
}


@pytest.mark.parametrize("case", list(CASES))
def test_coefficients_against_finite_differences(case):
    build, guess, q0, scale = CASES[case]
    system = compile_linkage(build())
    x0 = assemble(system, q0, guess)
    assert jacobian_rank(system, x0) == system.n - 1  # exactly one DOF at q0
    hk, hl = 1e-5 * scale, 1e-4 * scale
    for q in (q0, q0 + 0.05 * scale):
        x = assemble(system, q, x0)
        K, L = coefficients(system, x)
        kmax, lmax = np.max(np.abs(K)), np.max(np.abs(L))
        xp, xm = assemble(system, q + hk, x), assemble(system, q - hk, x)
        assert np.max(np.abs(K - (xp - xm) / (2 * hk))) < FD_K * kmax
        dl = (coefficients(system, xp)[0] - coefficients(system, xm)[0]) / (2 * hk)
        assert np.max(np.abs(L - dl)) < FD_L_FROM_K * lmax
        dl = (assemble(system, q + hl, x) - 2 * x + assemble(system, q - hl, x)) / hl**2
        assert np.max(np.abs(L - dl)) < FD_L * lmax
        # Points: K_r from positions, L_r from the K_r of neighbouring states.
        _, kr, lr = point_kinematics(system, x, K, L)
        rp, krp, _ = point_kinematics(system, xp, *coefficients(system, xp))
        rm, krm, _ = point_kinematics(system, xm, *coefficients(system, xm))
        assert np.max(np.abs(kr - (rp - rm) / (2 * hk))) < FD_K * max(1.0, kmax)
        assert np.max(np.abs(lr - (krp - krm) / (2 * hk))) < FD_L_FROM_K * max(1.0, lmax)


# -- rank, conditioning and failures ----------------------------------------------------

def test_conditioning_matches_the_four_bar_closed_form():
    system = compile_linkage(four_bar())
    fb = FourBar(FourBarGeometry(*SEED, 1))
    for q in QS[::8]:
        ref = fb.kinematics(q)
        x = assemble(system, q, ref.x + [0.0, 0.0, math.pi])
        # Measured worst 7.8e-16.
        np.testing.assert_allclose(conditioning(system, x), fb.conditioning(ref.x), rtol=0,
                                   atol=3e-15)


def test_rank_drops_at_a_change_point():
    """A parallelogram (c1 = c3, c2 = c4) folded flat at q = 0: all Jacobian columns are
    parallel, rank n − 2 = 1 (two branches meet)."""
    system = compile_linkage(four_bar((0.5, 1.0, 0.5, 1.0)))
    x = np.array([0.0, 0.0, 0.0])
    assert np.max(np.abs(constraint_residual(system, x))) == 0.0
    assert jacobian_rank(system, x) == 1
    assert jacobian_rank(system, np.array([0.5, 0.0, 0.5])) == 2  # an ordinary position


def test_driven_by_another_coordinate_is_the_other_input_joint():
    """The crank-driven slider-crank re-driven by its slide coordinate gives the same x, K, L
    as the linkage declared with the slide as input joint. The two spanning trees differ (the
    input joint is taken into the tree first), so the loop vector is summed in another order:
    equal to round-off, a few ulps."""
    crank = compile_linkage(slider_crank(R, LEN, E))
    by_slide = crank.driven_by(crank.coordinate("slide.s"))
    declared = compile_linkage(slider_crank(R, LEN, E, input_joint="slide"))
    assert by_slide.input_unit == "m"
    x = assemble(by_slide, 0.3, [1.0, 0.0, 0.0, 0.3])
    np.testing.assert_allclose(x, assemble(declared, 0.3, [1.0, 0.0, 0.0, 0.3]), rtol=0, atol=1e-14)
    for a, b in zip(coefficients(by_slide, x), coefficients(declared, x)):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


def test_slider_input_at_dead_centre():
    """Centred slider-crank at θ = 0: s is at its extreme, so s cannot be the independent
    coordinate (conditioning 0, coefficients refused) while the crank can."""
    crank = compile_linkage(slider_crank(R, LEN, 0.0))
    x = assemble(crank, 0.0, [0.1, 0.1, 0.0, 0.4])
    np.testing.assert_allclose(x, [0.0, 0.0, 0.0, R + LEN], atol=ROUND_OFF)
    cond = conditioning(crank, x)
    assert cond[3] < ROUND_OFF and cond[0] > 0.5
    assert cond[2] < ROUND_OFF  # the slider's angle never can
    slider = compile_linkage(slider_crank(R, LEN, 0.0, "slide"))
    with pytest.raises(NumericalFailure) as info:
        coefficients(slider, x)
    assert info.value.reason is FailureReason.SINGULAR
    assert "dead-centre" in str(info.value)


def test_assembly_takes_one_step_past_the_tolerance():
    """Converged at residual ≤ tol, one more Newton step squares it: with tol = 1e-4 the
    residual left is ~tol² (measured worst 9.1e-10 over three guesses; bound 5e-9)."""
    system = compile_linkage(four_bar())
    for guess in ([0.3, 0.5, 1.2], [0.3, 0.6, 1.0], [0.3, 0.4, 1.3]):
        x = assemble(system, 0.3, guess, tol=1e-4)
        assert np.max(np.abs(constraint_residual(system, x))) < 5e-9


def test_loop_that_cannot_close():
    # c2 + c3 = 0.4 < c4 − c1 = 0.5: B cannot reach from A to the rocker at any q.
    system = compile_linkage(four_bar((0.5, 0.2, 0.2, 1.0)))
    with pytest.raises(AssemblyError, match=r"the loops do not close at q = 0\.3 rad: largest residual"):
        assemble(system, 0.3, [0.3, 0.5, 2.0])


def test_singular_jacobian_during_assembly():
    # Centred slider-crank driven by s with crank and rod guessed collinear: the x row of the
    # loop and the driving row are parallel.
    system = compile_linkage(slider_crank(R, LEN, 0.0, "slide"))
    with pytest.raises(AssemblyError, match="the loop Jacobian is singular at q = 0.3 m"):
        assemble(system, 0.3, [0.0, 0.0, 0.0, 0.4])


@pytest.mark.parametrize("q, guess, message", [
    (0.3, [0.3, 0.5], r"the guess has shape \(2,\), expected \(3,\)"),
    (math.nan, [0.3, 0.5, 1.2], "must be finite"),
])
def test_bad_assembly_input(q, guess, message):
    with pytest.raises(AssemblyError, match=message):
        assemble(compile_linkage(four_bar()), q, guess)


def test_watt_ii_closes_both_loops():
    lk = watt_ii()
    system = compile_linkage(lk)
    x = assemble(system, 0.3, CASES["Watt II"][1])
    assert system.loops.rows == 2
    r = point_kinematics(system, x, np.zeros(system.n), np.zeros(system.n))[0]
    for a, pa, b, pb in (("coupler", "B", "rocker", "B"), ("link6", "O5", "ground", "O5"),
                         ("link5", "D", "rocker", "D")):
        assert np.max(np.abs(r[system.point_index(a, pa)] - r[system.point_index(b, pb)])) < ROUND_OFF
    # Link lengths are kept: |E − D| = 0.8 m on link5.
    d = r[system.point_index("link5", "E")] - r[system.point_index("rocker", "D")]
    assert abs(math.hypot(*d) - 0.8) < ROUND_OFF


# -- Andrews' squeezing mechanism: the published states -----------------------------------
# Source: /work/shared/benchmarks/andrews-testset.md, transcribed from the Test Set for IVP
# Solvers (problem "andrews"; Hairer & Wanner, Solving ODEs II, VII.7). Published
# coordinates (β, Θ, γ, Φ, δ, Ω, ε); Θ, Φ, Ω are relative angles.
ANDREWS_Q0 = [-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
              0.222668390165885884674473185609, 0.487364979543842550225598953530,
              -0.222668390165885884674473185609, 1.23054744454982119249735015568]
ANDREWS_Q_END = [15.81077119629904, -15.75637105984298, 0.04082224013073101,
                 -0.5347301163226948, 0.5244099658805303, 0.5347301163226948, 1.048080741042263]
ANDREWS_QDOT_END = [1139.920302151208, -1424.379294994111, 11.03291221937134,
                    19.29337464421385, 0.5735699284790808, -19.29337464421385,
                    0.3231791658026955]


def andrews_to_x(p):
    """Published coordinates → absolute body angles (b1 … b7); linear, so rates map alike."""
    beta, theta, gamma, phi, delta, omega, eps = p
    return np.array([beta, beta + theta, gamma, phi + delta, delta, omega + eps, eps])


def andrews_from_x(x):
    return np.array([x[0], x[1] - x[0], x[2], x[3] - x[4], x[4], x[5] - x[6], x[6]])


@pytest.mark.parametrize("published", [ANDREWS_Q0, ANDREWS_Q_END], ids=["t=0", "t=0.03"])
def test_andrews_assembles_to_the_published_state(published):
    """Assembled at the published β from a guess 0.02 rad off every angle, the other six
    coordinates are the published ones. Measured worst 1.0e-15 (t = 0) and 1.8e-15 (t = 0.03,
    |Θ| ≈ 15.8 rad): the published positions satisfy the loop equations to round-off,
    well inside the ~10 digits they are said to carry. Tolerance 1e-14 rad."""
    system = compile_linkage(andrews())
    x = assemble(system, published[0], andrews_to_x(published) + 0.02)
    assert jacobian_rank(system, x) == system.n - 1
    np.testing.assert_allclose(andrews_from_x(x), published, rtol=0, atol=1e-14)


def test_andrews_rates_are_k_times_the_crank_rate():
    """q̇ = K β̇ at t = 0.03 against the published rates (7–8 correct digits): measured
    worst relative gap 2.1e-8 (ε̇); tolerance 1e-7 relative."""
    system = compile_linkage(andrews())
    x = assemble(system, ANDREWS_Q_END[0], andrews_to_x(ANDREWS_Q_END) + 0.02)
    K, _ = coefficients(system, x)
    rates = andrews_from_x(K * ANDREWS_QDOT_END[0])
    np.testing.assert_allclose(rates, ANDREWS_QDOT_END, rtol=1e-7)


def test_andrews_spring_length_at_t0():
    """The spring D–C is 0.0526725 m long at t = 0 (published to 6 digits; ours 0.05267252)."""
    system = compile_linkage(andrews())
    x = assemble(system, ANDREWS_Q0[0], andrews_to_x(ANDREWS_Q0))
    r = point_kinematics(system, x, np.zeros(system.n), np.zeros(system.n))[0]
    gap = r[system.point_index("b3", "D")] - r[system.point_index("ground", "C")]
    assert abs(math.hypot(*gap) - 0.0526725) < 5e-8  # half a unit of the 7th digit


@pytest.mark.parametrize("case", list(CASES))
def test_independent_rows_of_a_linkage_without_redundancy_are_all_its_rows(case):
    """A linkage that Grübler's count accepts has n − 1 independent rows: choosing them at q0
    (LoopSystem.with_independent_rows) keeps every row, and the kernel's x, K and L are the same
    bits as without a selection (the rows are copied in another order, never recombined)."""
    build, guess, q0, _ = CASES[case]
    system = compile_linkage(build())
    x0 = assemble(system, q0, guess)
    chosen = system.with_independent_rows(x0)
    assert sorted(chosen.rows) == list(range(system.n - 1))
    np.testing.assert_array_equal(assemble(chosen, q0, guess), x0)
    for a, b in zip(coefficients(chosen, x0), coefficients(system, x0)):
        np.testing.assert_array_equal(a, b)


def test_unwrap_angles_is_numpys_unwrap_bit_for_bit():
    """loopcheck.kinematics.unwrap_angles saves np.unwrap's corrections where no sample jumps by π:
    its result must be np.unwrap's exactly (bits, −0.0 included) with jumps and without."""
    from loopcheck.kinematics import unwrap_angles

    rng = np.random.default_rng(3)
    smooth = np.cumsum(rng.uniform(-1.0, 1.0, (200, 3)), axis=0)
    smooth[5, 1] = smooth[0, 2] = -0.0
    jumps = smooth.copy()
    jumps[100:, 0] += 2 * np.pi  # a 2π jump to remove
    jumps[50, 2] = jumps[49, 2] + np.pi  # a jump of exactly π (np.unwrap keeps it)
    for angles in (smooth, jumps, smooth[:1], np.array([[np.nan, 0.0], [1.0, -0.0]])):
        got, want = unwrap_angles(angles), np.unwrap(angles, axis=0)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got.view(np.int64), want.view(np.int64))  # bits: −0.0 is not 0.0
