"""Kinematics: closed-form, compiled general and finite-difference K, L agree; the seed's 𝔍 and ζ.

The four-bar's closed form (:class:`oracles.four_bar.FourBar`) and the dyad closed form written
below are the oracles of the compiled general path (:mod:`loopcheck.reduced.kernels.physics`, through
:class:`loopcheck.reduced.dynamics.MechanismModel` and :class:`loopcheck.reduced.charts.Chart`); the pure-numpy
loop equations of :mod:`loopcheck.kinematics` are a third, independent evaluation of K and L."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oracles.four_bar import FourBar
from loopcheck.reduced import MechanismModel
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck import kinematics as loops
from loopcheck.reduced.charts import Chart
from loopcheck.scene import FourBarGeometry

from helpers import SEED_SCENE, coefficients_along, seed_dict, variant

SEED = FourBarGeometry(0.5, 0.9, 0.7, 1.0, 1)
QS = np.linspace(0.0, 2 * np.pi, 73)[:-1]  # a full crank revolution, every 5°


def signed_gap(a, b):
    """a − b for angles, wrapped into (−π, π]."""
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


def angle_gap(a, b):
    return np.abs(signed_gap(a, b))


@pytest.mark.parametrize("branch", [1, -1])
def test_loop_closes_at_every_angle(branch):
    linkage = FourBar(FourBarGeometry(0.5, 0.9, 0.7, 1.0, branch))
    for q in QS:
        assert np.max(np.abs(linkage.loop_residual(linkage.assemble(q)))) < 1e-14


def test_seed_configuration_and_branches():
    linkage = FourBar(SEED)
    x = linkage.assemble(0.2)
    assert x[1] == pytest.approx(0.696, abs=5e-4) and x[2] == pytest.approx(-1.832, abs=5e-4)
    other = FourBar(FourBarGeometry(0.5, 0.9, 0.7, 1.0, -1)).assemble(0.2)
    assert np.max(np.abs(linkage.loop_residual(other))) < 1e-14
    assert angle_gap(other[1], x[1]) > 1.0  # the crossed assembly is a different configuration
    assert linkage.branch_of(x) == 1 and linkage.branch_of(other) == -1


def seed_model(branch: int = 1) -> MechanismModel:
    """The seed scene on assembly branch ``branch`` (compiled general path)."""
    data = seed_dict()
    data["linkage"]["branch"] = branch
    return MechanismModel(scene_from_dict(data))


@pytest.mark.parametrize("branch", [1, -1])
def test_closed_form_general_and_finite_difference_K_L_agree(branch):
    """Over a full revolution, on both assembly branches; the loop residual is asserted first
    so that a wrong configuration cannot pass as a K/L agreement.

    Compiled general path (loop equations, :meth:`MechanismModel.coefficients_at` at the
    closed form's configuration, in the general coordinates (q, φ1, φ2 + π): K and L are the
    same) against the closed form: both are exact, so they agree to round-off; K, L are O(1)
    here (|K| <= 1.19, |L| <= 2.25), bound 1e-12.
    Central differences with δ = 1e-5 rad: for K from x(q) the truncation is δ²/6 |d³x/dq³|
    (<= 7.5 over the revolution: 1.3e-10) plus round-off ε |x| / δ ≈ 9e-11, bound 1e-9
    (measured 1.8e-10). For L we difference the closed-form K (differencing x twice would
    cost round-off ε/δ² ≈ 2e-6): truncation δ²/6 |d⁴x/dq⁴| (<= 31.4: 5.2e-10) plus
    round-off ε |K| / δ ≈ 3e-11, bound 2e-9 (measured 5.6e-10)."""
    linkage = FourBar(FourBarGeometry(0.5, 0.9, 0.7, 1.0, branch))
    model = seed_model(branch)
    d = 1e-5
    for q in QS:
        x = linkage.assemble(q)
        assert np.max(np.abs(linkage.loop_residual(x))) < 1e-14
        xg = linkage.to_general(x)
        assert np.max(np.abs(loops.constraint_residual(model.system, xg))) < 1e-14
        closed, general = linkage.kinematics(q), model.coefficients_at(xg).kinematics
        np.testing.assert_array_equal(closed.x, x)
        np.testing.assert_array_equal(general.x, xg)
        np.testing.assert_allclose(general.K, closed.K, rtol=0, atol=1e-12)
        np.testing.assert_allclose(general.L, closed.L, rtol=0, atol=1e-12)
        fd_K = signed_gap(linkage.assemble(q + d), linkage.assemble(q - d)) / (2 * d)
        np.testing.assert_allclose(fd_K, closed.K, rtol=0, atol=1e-9)
        fd_L = (linkage.kinematics(q + d).K - linkage.kinematics(q - d).K) / (2 * d)
        np.testing.assert_allclose(fd_L, closed.L, rtol=0, atol=2e-9)


def dyad_closed_form(g: FourBarGeometry, independent: int, value: float, sign: int) -> np.ndarray:
    """The four-bar closed with x_i = value held, in its closed-form coordinates (q, φ1, φ2):
    the other two links form a dyad. c_a e(a) + c_b e(b) = P = (c4, 0) − c_i e(x_i), so
    a = ψ ± α with ψ = atan2(P), cos α = (c_a² + |P|² − c_b²) / (2 c_a |P|), and b from the
    remainder; of the two roots the one with sign(sin(b − a)) = ``sign`` (the sign of
    det J_dep = c_a c_b sin(b − a), a before b in x: constant on a chart's branch)."""
    lengths = (g.c1, g.c2, g.c3)
    ia, ib = [j for j in range(3) if j != independent]
    ca, cb = lengths[ia], lengths[ib]
    px = g.c4 - lengths[independent] * math.cos(value)
    py = -lengths[independent] * math.sin(value)
    dist = math.hypot(px, py)
    alpha = math.acos(max(-1.0, min(1.0, (ca * ca + dist * dist - cb * cb) / (2.0 * ca * dist))))
    psi = math.atan2(py, px)
    for a in (psi + alpha, psi - alpha):
        b = math.atan2(py - ca * math.sin(a), px - ca * math.cos(a))
        if (1 if math.sin(b - a) >= 0.0 else -1) == sign:
            break
    x = np.empty(3)
    x[independent], x[ia], x[ib] = value, a, b
    return x


def test_every_chart_matches_the_dyad_closed_form_and_newton():
    """With q, φ1 or φ2 as the chart's coordinate, the compiled chart (started at the closed
    form's configuration, then walked 0.02 rad along its coordinate) lands where the dyad's
    closed form puts the linkage (round-off), with the K, L of the pure-numpy loop equations
    (:func:`loopcheck.kinematics.coefficients` with that coordinate driving, at the same x) and, for
    q, of the four-bar closed form (bounds 1e-10, 1e-9: the walked x is Newton's, ~1e-12 from
    the closed form's, and |L| reaches 90 here; measured ≤ 1.4e-12 for L). Conditioning: the closed form (|sin|), loopcheck.kinematics and
    the compiled chart agree."""
    g = SEED
    linkage = FourBar(g)
    model = seed_model(1)
    shift = np.array([0.0, 0.0, math.pi])  # closed-form (q, φ1, φ2) → general (crank, coupler, rocker)
    step = 0.02
    checked = 0
    for q in QS[::6]:
        x = linkage.assemble(q)
        xg = linkage.to_general(x)
        c_closed = linkage.conditioning(x)
        np.testing.assert_allclose(loops.conditioning(model.system, xg), c_closed, rtol=0, atol=1e-14)
        for i in range(3):
            if c_closed[i] < 0.05:  # the chart's own dead centre: not a chart there
                continue
            ia, ib = [j for j in range(3) if j != i]
            sign = 1 if math.sin(x[ib] - x[ia]) >= 0.0 else -1
            chart = Chart(model, i, xg)
            c_i, c_best, best = chart.conditioning(float(xg[i]))
            assert c_i == pytest.approx(c_closed[i], abs=1e-12)
            assert c_best == pytest.approx(np.max(c_closed), abs=1e-12) and best == int(np.argmax(c_closed))
            start = chart.start  # K, L at the closed form's configuration
            K, L = loops.coefficients(model.system.driven_by(i), xg)
            np.testing.assert_allclose(start.K, K, rtol=0, atol=1e-10)
            np.testing.assert_allclose(start.L, L, rtol=0, atol=1e-9)
            value = float(xg[i]) + step
            kin = chart.kinematics(value)
            closed = dyad_closed_form(g, i, value - shift[i], sign) + shift
            assert np.max(angle_gap(kin.x, closed)) < 1e-12, (q, i, kin.x, closed)
            # continuous with the chart's start: |K| ≤ 6.3 at these conditionings moves x by ≤ 0.13 rad,
            # a 2π jump would move it by more than 6
            assert np.max(np.abs(kin.x - xg)) < 1.0, (q, i, kin.x, xg)
            # after a walk the kernel's K, L come from the factors of A before Newton's last
            # (polishing) step, ~1e-12 rad from the x it returns: measured up to 5.1e-11 in K and
            # 1.9e-9 in L (|L| = 38.6, 4.9e-11 relative) at q = 5.76 in the φ1 chart; bound
            # 2e-10 relative to max(1, |K|), max(1, |L|)
            K, L = loops.coefficients(model.system.driven_by(i), kin.x)
            assert np.max(np.abs(kin.K - K)) <= 2e-10 * max(1.0, np.max(np.abs(K))), (q, i)
            assert np.max(np.abs(kin.L - L)) <= 2e-10 * max(1.0, np.max(np.abs(L))), (q, i)
            if i == 0:
                seed = linkage.kinematics(value)
                assert np.max(np.abs(kin.K - seed.K)) <= 2e-10 * max(1.0, np.max(np.abs(seed.K))), q
                assert np.max(np.abs(kin.L - seed.L)) <= 2e-10 * max(1.0, np.max(np.abs(seed.L))), q
            checked += 1
    assert checked >= 2 * len(QS[::6])


def seed_generalized_inertia(q: float) -> float:
    """𝔍 written out from the seed: I_O1 + I_O3 K_φ2² + M2 (K_G2x² + K_G2y²) + I_G2 K_φ1²."""
    c1, c2, c3, c4 = 0.5, 0.9, 0.7, 1.0
    U, V = 0.5111, 0.1333
    A = 2 * c1 * c2 * math.sin(q)
    B = 2 * c2 * (c1 * math.cos(q) - c4)
    C = c1**2 + c2**2 - c3**2 + c4**2 - 2 * c1 * c4 * math.cos(q)
    phi1 = 2 * math.atan((-A + math.sqrt(A * A + B * B - C * C)) / (C - B))
    phi2 = math.atan2(-(c1 * math.sin(q) + c2 * math.sin(phi1)), c4 - c1 * math.cos(q) - c2 * math.cos(phi1))
    k1 = c1 * math.sin(q - phi2) / (c2 * math.sin(phi2 - phi1))
    k2 = c1 * math.sin(phi1 - q) / (c3 * math.sin(phi2 - phi1))
    kgx = -c1 * math.sin(q) - U * k1 * math.sin(phi1) - V * k1 * math.cos(phi1)
    kgy = c1 * math.cos(q) + U * k1 * math.cos(phi1) - V * k1 * math.sin(phi1)
    return 1.5 + 3.5 * k2**2 + 40.0 * (kgx**2 + kgy**2) + 5.0 * k1**2


def seed_coefficients(qs):
    """The compiled coefficients of the seed at each q of ``qs`` (:func:`helpers.coefficients_along`)."""
    return coefficients_along(MechanismModel(load_scene(SEED_SCENE)), qs)


def test_generalized_inertia_matches_the_seed_formula():
    for q, c in zip(QS, seed_coefficients(QS)):
        assert c.generalized_inertia == pytest.approx(seed_generalized_inertia(q), rel=1e-12)


def test_centrifugal_coefficient_is_half_the_derivative_of_inertia():
    """ζ = ½ d𝔍/dq against a central difference (δ = 1e-5: truncation ~1e-10 𝔍''', round-off
    ~1e-11 𝔍/δ): 1e-7 relative to the size of ζ over the revolution."""
    d = 1e-5
    zetas = np.array([c.centrifugal for c in seed_coefficients(QS)])
    plus = np.array([c.generalized_inertia for c in seed_coefficients(QS + d)])
    minus = np.array([c.generalized_inertia for c in seed_coefficients(QS - d)])
    fd = (plus - minus) / (4 * d)
    np.testing.assert_allclose(zetas, fd, rtol=0, atol=1e-7 * np.max(np.abs(zetas)))


def test_damper_rate_matches_the_seed():
    """Q_damper = −B K_D² q̇ with the seed's K_D = dD/dq (finite difference of D)."""
    scene = load_scene(SEED_SCENE)
    model = MechanismModel(scene)
    linkage = FourBar(scene.four_bar)  # the closed form: independent of the compiled path

    def length(q):
        x = linkage.assemble(q)
        bx = 0.5 * math.cos(q) + 0.9 * math.cos(x[1])
        by = 0.5 * math.sin(q) + 0.9 * math.sin(x[1])
        return math.hypot(1.3 - bx, by - 0.12)

    for q, c in zip(QS[::4], coefficients_along(model, QS[::4])):
        k_d = (length(q + 1e-6) - length(q - 1e-6)) / 2e-6
        assert c.damping == pytest.approx(55.0 * k_d**2, rel=1e-6, abs=1e-9)


def test_model_contains_only_declared_effects():
    assert MechanismModel(load_scene(SEED_SCENE)).effects == ("torque", "damper")
    bare = variant(drop=("torque", "dampers"))
    assert MechanismModel(bare).effects == ()
    c = MechanismModel(bare).coefficients(0.7)
    assert c.damping == 0.0 and c.potential_gradient == 0.0 and c.potential == 0.0


def test_scene_that_cannot_assemble_names_the_discriminant():
    data = seed_dict()
    data["linkage"]["c3"] = 0.05
    with pytest.raises(SceneError, match="discriminant"):
        from loopcheck.scenefile import scene_from_dict
        scene_from_dict(data)
