"""Energy audits of the reduced solver: independent checks of the balance."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from loopcheck.reduced import MechanismModel, ReducedSettings, simulate
from loopcheck.scene import Scene
from loopcheck.scenefile import load_scene, scene_from_dict

from helpers import SEED_SCENE, coefficients_along, conservative, seed_dict, variant


def test_seed_energy_residual_below_1e_8_of_the_work(seed_reference):
    """The issue's requirement. DOP853 at rtol 1e-12 and Gauss-Legendre quadrature on the
    interpolant leave ~1e-11; 1e-8 leaves room for machines and still catches a wrong term
    (a missing damper term would leave ~900 J, 0.3 of the work)."""
    audit = seed_reference.audit
    assert audit.max_abs_residual < 1e-8 * abs(audit.torque_work[-1])
    assert audit.damper_dissipation[-1] > 800.0  # the damper really dissipates (~880 J)


def test_work_of_a_constant_torque_is_torque_times_angle(seed_reference):
    """Independent of the quadrature: during the pulse W = 250 N·m × (q(1 s) − q(0))."""
    tr, audit = seed_reference.trajectory, seed_reference.audit
    k = int(np.flatnonzero(tr.t == 1.0)[0])
    assert audit.torque_work[k] == pytest.approx(250.0 * (tr.q[k] - tr.q[0]), rel=1e-9)
    assert audit.torque_work[-1] == pytest.approx(audit.torque_work[k], rel=1e-12)  # no work after


def test_conservative_scene_keeps_kinetic_energy():
    result = simulate(conservative(qdot0=10.0))
    e = result.audit.kinetic
    assert np.max(np.abs(e - e[0])) / e[0] < 1e-9  # ~1e-11 measured at rtol 1e-12


def test_gravity_and_spring_potential_balance_kinetic_energy():
    bodies = {"crank": {"mass": 2.0, "inertia": 0.05, "com": [0.25, 0.0]},
              "coupler": {"mass": 40.0, "inertia": 5.0, "com": [0.5111, 0.1333]},
              "rocker": {"mass": 3.0, "inertia": 0.1, "com": [0.35, 0.02]}}
    scene = variant(drop=("torque", "dampers"), gravity=[0.0, -9.81], bodies=bodies,
                    springs=[{"stiffness": 500.0, "rest_length": 0.3, "ground_point": [1.3, 0.12],
                              "body": "coupler", "body_point": [0.9, 0.0]}])
    result = simulate(scene)
    audit = result.audit
    assert np.ptp(audit.potential) > 10.0  # the potential really changes
    assert audit.relative_residual < 1e-9


# ---------------------------------------------------------------------------
# Independent checks added: the issue's relative figure, only the declared effects,
# gravity's potential from the positions.
# ---------------------------------------------------------------------------


def test_seed_relative_residual_meets_the_issue_requirement(seed_reference):
    """audit.relative_residual < 1e-8 (the issue's figure; measured 1.2e-11 with DOP853 at
    rtol 1e-12). The scale it divides by is the torque work, checked here independently:
    the work is the largest energy in the run, 250 N·m × Δq over the pulse."""
    audit, tr = seed_reference.audit, seed_reference.trajectory
    assert audit.relative_residual < 1e-8
    k = int(np.flatnonzero(tr.t == 1.0)[0])
    assert audit.scale == pytest.approx(250.0 * (tr.q[k] - tr.q[0]), rel=1e-9)


def test_conservative_scene_from_a_dict_keeps_kinetic_energy():
    """No torque, no damper, no gravity: ½ 𝔍(q) q̇² is a constant of the motion even though
    q̇ varies several-fold with 𝔍. DOP853 at rtol 1e-12 over 2 s leaves ~1e-11 (measured
    1.2e-11 at 5 rad/s; 2.1e-11 at 10 rad/s in the test above); 1e-9 leaves a factor 50 for other machines
    and still fails on any inconsistency between 𝔍 and ζ = ½ d𝔍/dq above 1e-9 of the energy."""
    qdot0 = 5.0
    data = seed_dict()
    for key in ("torque", "dampers", "tolerances"):
        data.pop(key)
    data["initial"] = {"q": 0.2, "qdot": qdot0}
    scene = scene_from_dict(data)
    assert scene.effects == ()
    result = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12))
    e = result.audit.kinetic
    assert np.ptp(result.trajectory.qdot) > 0.5 * qdot0  # the speed really varies
    assert np.max(np.abs(e - e[0])) / e[0] < 1e-9
    assert result.audit.relative_residual < 1e-9


ALL_BODIES = {"crank": {"mass": 2.0, "inertia": 0.05, "com": [0.25, 0.0]},
              "coupler": {"mass": 40.0, "inertia": 5.0, "com": [0.5111, 0.1333]},
              "rocker": {"mass": 3.0, "inertia": 0.1, "com": [0.35, 0.02]}}
SPRING = {"stiffness": 500.0, "rest_length": 0.3, "ground_point": [1.3, 0.12], "body": "coupler",
          "body_point": [0.9, 0.0]}
EFFECTS = ("torque", "damper", "spring", "gravity")


def scene_with(effects) -> Scene:
    data = seed_dict()
    data.pop("tolerances")
    data["bodies"] = ALL_BODIES
    if "torque" not in effects:
        data.pop("torque")
    if "damper" not in effects:
        data.pop("dampers")
    if "spring" in effects:
        data["springs"] = [SPRING]
    if "gravity" in effects:
        data["gravity"] = [0.0, -9.81]
    return scene_from_dict(data)


@pytest.mark.parametrize("effects", [c for n in range(5) for c in itertools.combinations(EFFECTS, n)],
                         ids=lambda c: "+".join(c) or "none")
def test_model_contains_exactly_the_declared_effects(effects):
    """Each of the 16 combinations: the model names exactly the declared effects (in the fixed
    order), and an undeclared effect contributes exactly zero (no tolerance: a term that is
    not built adds nothing) while a declared one contributes somewhere on the revolution."""
    model = MechanismModel(scene_with(effects))
    assert model.effects == effects
    cs = coefficients_along(model, np.linspace(0.0, 2 * np.pi, 13)[:-1])
    damping = [c.damping for c in cs]
    gradient = [c.potential_gradient for c in cs]
    torque = model.load_on_piece(0.0, 1.0)(0.5)
    assert (max(damping) > 0.0) == ("damper" in effects) and min(damping) >= 0.0
    assert (max(map(abs, gradient)) > 0.0) == ("spring" in effects or "gravity" in effects)
    assert (torque == 250.0) if "torque" in effects else (torque == 0.0 and model.load_edges == ())


def gravity_potential(q: float, x) -> float:
    """−Σ m g·r_G from the positions written out here: crank G = R(q) com, coupler
    G = c1 e(q) + R(φ1) com, rocker G = O3 + R(θ3) com (rocker frame along O3→B); x in the
    general coordinates (crank, coupler, rocker) = (q, φ1, θ3 = φ2 + π)."""
    def rotate(angle, p):
        return (p[0] * math.cos(angle) - p[1] * math.sin(angle), p[0] * math.sin(angle) + p[1] * math.cos(angle))
    _, phi1, theta3 = x
    g_crank = rotate(q, ALL_BODIES["crank"]["com"])
    u, v = rotate(phi1, ALL_BODIES["coupler"]["com"])
    g_coupler = (0.5 * math.cos(q) + u, 0.5 * math.sin(q) + v)
    u, v = rotate(theta3, ALL_BODIES["rocker"]["com"])
    g_rocker = (1.0 + u, v)
    return 9.81 * sum(ALL_BODIES[b]["mass"] * g[1]
                      for b, g in (("crank", g_crank), ("coupler", g_coupler), ("rocker", g_rocker)))


def test_gravity_potential_matches_the_positions_and_energy_is_conserved():
    """Gravity only (masses and centres for all three links), no torque, damper or spring.
    V(q) agrees with −Σ m g·r_G written out here to round-off (V ~ 1e2 J: 1e-11 J), and
    dV/dq with its central difference (δ = 1e-5: truncation δ²|V'''|/6 ~ 1e-8, round-off
    ε V/δ ~ 1e-9; bound 1e-6 N·m). The run then trades ~213 J between T and V and keeps
    T + V constant: relative residual < 1e-9 (measured 4e-12 at rtol 1e-12)."""
    scene = scene_with(("gravity",))
    model = MechanismModel(scene)
    d = 1e-5
    qs = np.linspace(0.0, 2 * np.pi, 25)[:-1]
    along = zip(qs, coefficients_along(model, qs), coefficients_along(model, qs + d),
                coefficients_along(model, qs - d))
    for q, c, plus, minus in along:
        assert c.potential == pytest.approx(gravity_potential(q, c.kinematics.x), rel=0, abs=1e-11)
        fd = (plus.potential - minus.potential) / (2 * d)
        assert c.potential_gradient == pytest.approx(fd, rel=0, abs=1e-6)
    audit = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12)).audit
    assert np.ptp(audit.potential) > 100.0  # the potential really changes
    assert np.ptp(audit.kinetic) > 100.0
    assert audit.relative_residual < 1e-9


@pytest.mark.parametrize("method", ["dop853", "scipy-dop853"])
def test_the_restart_after_the_pulse_keeps_the_step_of_before(method):
    """A seed variant (damper 63.25 N·s/m, coupler 36.125 kg) from a sweep: DOP853 restarted at
    the pulse's end with scipy's initial-step selection (8.0 ms where the steps before were
    1.3 ms), accepted that step, and the energy balance missed by 1.10e-8 of the run's scale,
    failing the engine's 1e-8 bound at rtol 1e-12. Both drivers cap the first step after a load
    edge by the steps before it (loopcheck.reduced.kernels.adaptive.RESTART_STEPS): measured 9.9e-12 (compiled)
    and 9.6e-12 (scipy). Bound 5e-11: 5x those, 200x below the failure."""
    data = seed_dict()
    data["dampers"][0]["coefficient"] = 63.25
    data["bodies"]["coupler"]["mass"] = 36.125
    result = simulate(scene_from_dict(data), ReducedSettings(method=method, check_error=False))
    relative = float(np.max(np.abs(result.audit.residual))) / result.details.energy_scale
    assert relative <= 5e-11


@pytest.mark.parametrize("method", ["rkn4", "dop853"])
@pytest.mark.parametrize("path", [SEED_SCENE, SEED_SCENE.parent / "mechanisms" / "slider_crank_driven_slider.toml",
                                  SEED_SCENE.parent / "hard" / "dead_centre.toml"], ids=lambda p: p.stem)
def test_the_fields_a_run_records_at_its_samples_are_a_walk_to_them(method, path):
    """The compiled runs record each sample's coefficient fields where they evaluate it
    (loopcheck.reduced.kernels.physics.Chart.observe), for the outputs and the energy audit, instead of walking
    every chart to its samples again: the same fields as that walk (the chart's own path, from
    its start), to round-off. Measured ≤ 2.6e-13 of each field's largest value (DOP853 on the
    seed; the slider-crank and the 7 charts of dead_centre ≤ 4.5e-14). Bound 1e-12."""
    from loopcheck.reduced.dynamics import MechanismModel
    from loopcheck.reduced.engine import integrate

    model = MechanismModel(load_scene(path))
    solution = integrate(model, ReducedSettings(method=method))
    assert solution.sample_fields is not None and len(solution.sample_fields) == len(solution.segments)
    for (chart, segment), recorded in zip(solution.segments, solution.sample_fields):
        walked, _ = chart.walk(segment.trajectory.q)
        scale = np.maximum(np.max(np.abs(walked), axis=0), np.finfo(float).tiny)
        assert np.max(np.abs(recorded - walked) / scale) <= 1e-12


FLOW_SCENES = [SEED_SCENE] + [SEED_SCENE.parent / "mechanisms" / f"{name}.toml" for name in
                              ("slider_crank_driven_slider", "oscillating_slotted_lever", "slider_crank_gas")]


@pytest.mark.parametrize("path", FLOW_SCENES, ids=lambda p: p.stem)
def test_the_energy_flows_integrated_with_the_state_equal_their_quadrature(path):
    """The compiled DOP853 integrates the work done and the energy dissipated alongside the
    state (its stages' power, loopcheck.reduced.kernels.physics.power); an independent route is
    Gauss-Legendre quadrature of the power over the samples' interpolant (what scipy's runs
    use). Measured difference, relative to the run's energy scale: seed 5e-14, driven slider
    (2 charts) 4e-14, oscillating slotted lever (9 charts) 8e-13, gas slider-crank 3.3e-11 (a point force:
    there the quadrature is the coarser of the two). Bound 1e-10, 3x the largest."""
    import dataclasses

    from loopcheck.reduced.energy import energy_audit, quadrature_energy
    from loopcheck.reduced.engine import integrate

    model = MechanismModel(load_scene(path))
    solution = integrate(model, ReducedSettings(method="dop853"))
    integrated = energy_audit(model, solution)
    quadrature = energy_audit(model, dataclasses.replace(solution, sample_energy=None))
    assert solution.sample_energy is not None
    for (chart, segment), flows in zip(solution.segments, solution.sample_energy):
        assert np.max(np.abs(flows - quadrature_energy(model, chart, segment.trajectory))) <= 1e-10 * integrated.scale
    for name in ("torque_work", "damper_dissipation"):
        assert np.max(np.abs(getattr(integrated, name) - getattr(quadrature, name))) <= 1e-10 * integrated.scale


def test_rkn4s_integrated_energy_flows_converge_at_its_order():
    """RKN4 integrates the energy flows with q̇'s weights (h/6)(P1 + 2P2 + 2P3 + P4): order 4.
    On the seed (steps 2, 1, 0.5 and 0.25 ms against DOP853 at rtol 1e-13) the final work's
    error falls by 2^4.96–2^4.97 per halving and the dissipation's by 2^5.1–2^6.1; the fitted
    order must be at least 3.8 (weights (P1 + P2 + P3 + P4)/4 would give 2)."""
    from loopcheck.reduced.engine import integrate

    model = MechanismModel(load_scene(SEED_SCENE))

    def final(solution):
        return np.sum([flows[-1] for flows in solution.sample_energy], axis=0)

    reference = final(integrate(model, ReducedSettings(method="dop853", rtol=1e-13)))
    steps = np.array([2e-3, 1e-3, 5e-4, 2.5e-4])
    errors = np.array([np.abs(final(integrate(model, ReducedSettings(method="rkn4", step=h))) - reference)
                       for h in steps])
    for flow in range(2):
        order = np.polyfit(np.log(steps), np.log(errors[:, flow]), 1)[0]
        assert order >= 3.8, (flow, order)


def test_an_audit_computes_its_residual_once_and_it_cannot_be_changed():
    """The residual, its scale and largest magnitude are computed on first use and kept (a
    sweep's row reads them three times): the kept residual is the balance's formula exactly
    and read-only, so no caller can change what the next one reads. (Planted: the residual left
    writable: fails here.)"""
    from loopcheck.results import EnergyAudit

    t = np.linspace(0.0, 1.0, 5)
    audit = EnergyAudit(t, kinetic=1.0 + t, potential=2.0 * t, torque_work=3.0 * t, damper_dissipation=0.5 * t)
    total = audit.kinetic + audit.potential
    assert np.array_equal(audit.residual, total - total[0] - audit.torque_work + audit.damper_dissipation)
    assert audit.residual is audit.residual
    with pytest.raises(ValueError):
        audit.residual[0] = 1.0
    assert audit.max_abs_residual == float(np.max(np.abs(audit.residual)))
    assert audit.relative_residual == audit.max_abs_residual / audit.scale
