"""Kinematics: closed-form, generic and finite-difference K, L agree; the seed's 𝔍 and ζ."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reduced import FourBar, LoopLinkage, MechanismModel, SceneError, load_scene
from reduced.scene import FourBarGeometry

from helpers import SEED_SCENE, seed_dict, variant

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


@pytest.mark.parametrize("branch", [1, -1])
def test_closed_form_generic_and_finite_difference_K_L_agree(branch):
    """Over a full revolution, on both assembly branches; the loop residual is asserted first
    so that a wrong configuration cannot pass as a K/L agreement.

    Generic (loop equations) against closed form: both are exact, so they agree to round-off;
    K, L are O(1) here (|K| <= 1.19, |L| <= 2.25), measured gap 2e-15, bound 1e-12.
    Central differences with δ = 1e-5 rad: for K from x(q) the truncation is δ²/6 |d³x/dq³|
    (<= 7.5 over the revolution: 1.3e-10) plus round-off ε |x| / δ ≈ 9e-11, bound 1e-9
    (measured 1.8e-10). For L we difference the closed-form K (differencing x twice would
    cost round-off ε/δ² ≈ 2e-6): truncation δ²/6 |d⁴x/dq⁴| (<= 31.4: 5.2e-10) plus
    round-off ε |K| / δ ≈ 3e-11, bound 2e-9 (measured 5.6e-10)."""
    linkage = FourBar(FourBarGeometry(0.5, 0.9, 0.7, 1.0, branch))
    d = 1e-5
    for q in QS:
        x = linkage.assemble(q)
        assert np.max(np.abs(linkage.loop_residual(x))) < 1e-14
        closed, generic = linkage.kinematics(q), linkage.kinematics_generic(q)
        np.testing.assert_array_equal(closed.x, x)
        np.testing.assert_allclose(generic.K, closed.K, rtol=0, atol=1e-12)
        np.testing.assert_allclose(generic.L, closed.L, rtol=0, atol=1e-12)
        fd_K = signed_gap(linkage.assemble(q + d), linkage.assemble(q - d)) / (2 * d)
        np.testing.assert_allclose(fd_K, closed.K, rtol=0, atol=1e-9)
        fd_L = (linkage.kinematics(q + d).K - linkage.kinematics(q - d).K) / (2 * d)
        np.testing.assert_allclose(fd_L, closed.L, rtol=0, atol=2e-9)


def test_every_chart_closed_form_matches_newton():
    """With φ1 or φ2 as the coordinate the four-bar's dyad closed form and the generic Newton
    path find the same configuration (round-off) and the same K, L."""
    linkage = FourBar(SEED)
    for q in QS[::6]:
        x = linkage.assemble(q)
        for i in range(3):
            sign = linkage.chart_sign(x, i)
            closed = linkage.solve(None, i, x[i], sign)
            newton = LoopLinkage.solve(linkage, x + 0.01, i, x[i], sign)
            assert np.max(angle_gap(closed.x, x)) < 1e-12 and np.max(angle_gap(newton.x, x)) < 1e-12
            np.testing.assert_allclose(closed.K, newton.K, atol=1e-10)
            np.testing.assert_allclose(closed.L, newton.L, atol=1e-9)
        generic = LoopLinkage.conditioning(linkage, x)
        np.testing.assert_allclose(linkage.conditioning(x), generic, atol=1e-14)


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


def test_generalized_inertia_matches_the_seed_formula():
    model = MechanismModel(load_scene(SEED_SCENE))
    for q in QS:
        assert model.generalized_inertia(q) == pytest.approx(seed_generalized_inertia(q), rel=1e-12)


def test_centrifugal_coefficient_is_half_the_derivative_of_inertia():
    """ζ = ½ d𝔍/dq against a central difference (δ = 1e-5: truncation ~1e-10 𝔍''', round-off
    ~1e-11 𝔍/δ): 1e-7 relative to the size of ζ over the revolution."""
    model = MechanismModel(load_scene(SEED_SCENE))
    d = 1e-5
    zetas = np.array([model.coefficients(q).centrifugal for q in QS])
    fd = np.array([(model.generalized_inertia(q + d) - model.generalized_inertia(q - d)) / (4 * d) for q in QS])
    np.testing.assert_allclose(zetas, fd, rtol=0, atol=1e-7 * np.max(np.abs(zetas)))


def test_damper_rate_matches_the_seed():
    """Q_damper = −B K_D² q̇ with the seed's K_D = dD/dq (finite difference of D)."""
    model = MechanismModel(load_scene(SEED_SCENE))
    linkage = model.linkage

    def length(q):
        x = linkage.assemble(q)
        bx = 0.5 * math.cos(q) + 0.9 * math.cos(x[1])
        by = 0.5 * math.sin(q) + 0.9 * math.sin(x[1])
        return math.hypot(1.3 - bx, by - 0.12)

    for q in QS[::4]:
        k_d = (length(q + 1e-6) - length(q - 1e-6)) / 2e-6
        assert model.coefficients(q).damping == pytest.approx(55.0 * k_d**2, rel=1e-6, abs=1e-9)


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
        from reduced import scene_from_dict
        scene_from_dict(data)
