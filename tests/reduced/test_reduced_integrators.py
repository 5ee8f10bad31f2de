"""Integrators on real scenes: measured convergence order, load edges, peak location, RKN4's error
estimate, settings, the scipy path's failures. (The compiled kernels on closed forms: order, the
tableau and its printed erratum, load edges, stability: tests/reduced/kernels/test_kernel_integrators.py.)"""

from __future__ import annotations

import dataclasses

import importlib
import tomllib

import numpy as np
import pytest

from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.reduced.integrators import solve_adaptive
from loopcheck.reduced.kernels.fixed_step import RKN4
from loopcheck.errors import IgnoredSettingWarning, NumericalFailure
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.reduced.integrators import MAX_EVALUATIONS
from loopcheck.shipped_scenes import hard_scene_dir

from helpers import SEED_SCENE, seed_dict, variant

simulate_module = importlib.import_module("loopcheck.reduced.engine")  # the package's `simulate` is the function


def observed_order(steps, errors) -> float:
    """Least-squares slope of log(error) against log(step)."""
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def constant_piece(f):
    return lambda start, end: f


def assert_order(steps, errors, tableau=RKN4):
    """The fitted slope is the method's declared order ± 0.2."""
    slope = observed_order(steps, errors)
    assert abs(slope - tableau.order) <= 0.2, f"fitted order {slope:.2f}, declared {tableau.order}"


# The reference for convergence studies is sampled every 0.25 ms: its quintic Hermite
# interpolant then adds < 1e-11 rad in q, below every RKN4 error measured here.
REFERENCE = ReducedSettings(method="dop853", rtol=1e-12, sample_interval=2.5e-4)
ORDER_STEPS = [8e-3, 4e-3, 2e-3, 1e-3, 5e-4]


@pytest.fixture(scope="module")
def seed_reference():
    return simulate(load_scene(SEED_SCENE), REFERENCE)


def rkn4_unchecked(h: float) -> ReducedSettings:
    """RKN4 at step h with its error gate off: convergence studies measure coarse steps."""
    return ReducedSettings(method="rkn4", step=h, check_error=False)


def max_q_error(result, reference) -> float:
    q_ref, _, _ = reference.trajectory.interpolate(result.trajectory.t)
    return float(np.max(np.abs(result.trajectory.q - q_ref)))


def test_rkn4_is_fourth_order_on_the_seed_four_bar():
    """The seed scene over its first 0.7 s (pulse on, first speed spike at 0.7 s). Errors
    5e-5 … 8e-10 rad, far above the reference's ~1e-11. Over the full 2 s the largest error
    is a sum of contributions of both signs from the speed spikes that cancel at some steps,
    so pairwise ratios there are erratic (measured: 43, 142, 5); the fit is done where the
    error is one clean term."""
    scene = variant(simulation={"horizon": 0.7})
    reference = simulate(scene, REFERENCE)
    errors = [max_q_error(simulate(scene, rkn4_unchecked(h)), reference) for h in ORDER_STEPS]
    assert errors[-1] > 1e-11 * 30
    assert_order(ORDER_STEPS, errors)


def test_pulse_edge_inside_a_step_keeps_fourth_order():
    """A pulse of 0.3037 s is not a multiple of any step below: the driver shortens the steps
    of each piece so that the edge is a step boundary, and the order stays 4."""
    scene = variant(simulation={"horizon": 0.5},
                    torque={"type": "pulse", "value": 250.0, "start": 0.0, "duration": 0.3037})
    reference = simulate(scene, REFERENCE)
    errors = [max_q_error(simulate(scene, rkn4_unchecked(h)), reference) for h in ORDER_STEPS]
    assert_order(ORDER_STEPS, errors)
    edge = scene.load.start + scene.load.duration
    result = simulate(scene, rkn4_unchecked(1e-3))
    assert np.sum(result.trajectory.t == edge) == 2  # a sample on each side of the jump


def test_fixed_step_and_adaptive_agree_on_the_seed(seed_reference):
    """RKN4 at 0.5 ms against DOP853 at 1e-12 over the whole seed run. Tolerances: the
    errors measured at 1 ms (1.0e-5 rad in q, 3.0e-4 rad/s in q̇, 1.6e-7 in peak ω) divided
    by 2⁴ for the halved step of a fourth-order method, rounded up: 7e-7 rad, 2e-5 rad/s,
    1e-8."""
    result = simulate(load_scene(SEED_SCENE), ReducedSettings(method="rkn4", step=5e-4))
    _, v_ref, _ = seed_reference.trajectory.interpolate(result.trajectory.t)
    assert max_q_error(result, seed_reference) < 7e-7
    assert np.max(np.abs(result.trajectory.qdot - v_ref)) < 2e-5
    assert abs(result.peak.omega / seed_reference.peak.omega - 1) < 1e-8
    assert abs(result.peak.time - seed_reference.peak.time) < 1e-6


def test_peak_is_located_between_samples(seed_reference):
    """The peak of the seed (at t ≈ 1.1545 s, not on a sample) from a 10 ms-sampled run is
    closer to the reference than the largest sample of that run."""
    coarse = simulate(load_scene(SEED_SCENE), ReducedSettings(method="dop853", rtol=1e-12,
                                                              sample_interval=1e-2))
    largest_sample = float(np.max(coarse.trajectory.qdot))
    truth = seed_reference.peak.omega
    assert abs(coarse.peak.omega - truth) < 1e-3 * abs(largest_sample - truth)
    assert abs(coarse.peak.omega - truth) < 1e-7 * truth
    assert seed_reference.peak.time not in set(seed_reference.trajectory.t)


# ---------------------------------------------------------------------------
# RKN4 estimates its own error; settings are validated; unbounded work is refused
# ---------------------------------------------------------------------------


def test_fixed_step_too_large_for_the_fast_crank_is_a_failure_not_a_result():
    """fast_crank at h = 0.01 s gave a peak of 284.6 rad/s (truth 998.1) and exit 0. The run
    at 2h is unstable, so the estimate comes from h/2: 1.6 of the run's scale, far above
    rtol = 1e-5; the message names the estimate, the tolerance and `--step`."""
    scene = load_scene(hard_scene_dir() / "fast_crank.toml")
    with pytest.raises(NumericalFailure) as info:
        simulate(scene, ReducedSettings(method="rkn4", step=0.01))
    message = str(info.value)
    assert info.value.reason == "inaccurate"
    assert "rtol = 1e-05" in message and "--step" in message and "estimates its own error" in message


ESTIMATE_STEPS = [4e-3, 2e-3, 1e-3, 5e-4]


def test_error_estimate_tracks_the_true_error_on_the_seed():
    """Step doubling against the true error (DOP853 at 1e-12, sampled every 0.25 ms) on the
    seed's first 0.7 s (one clean error term, see the order test above). Measured ratios
    estimate/true: q 0.97–1.04, q̇ 1.06–1.19 for h = 4, 2, 1, 0.5 ms; bound [1/3, 3].
    (At 0.25 ms the reference's own q̇ error, ~1e-8 rad/s, is the limit; over the full 2 s the
    largest error is a sum of cancelling terms and the estimate is 2–9× pessimistic.)"""
    scene = variant(simulation={"horizon": 0.7})
    reference = simulate(scene, REFERENCE)
    for h in ESTIMATE_STEPS:
        result = simulate(scene, rkn4_unchecked(h))
        q_ref, v_ref, _ = reference.trajectory.interpolate(result.trajectory.t)
        true_q = np.max(np.abs(result.trajectory.q - q_ref))
        true_v = np.max(np.abs(result.trajectory.qdot - v_ref))
        estimate = result.details.error_estimate
        assert 1 / 3 < estimate.q_abs / true_q < 3, h
        assert 1 / 3 < estimate.qdot_abs / true_v < 3, h


def test_rtol_is_the_accuracy_request_of_rkn4():
    """The seed at 1 ms: estimate 2.4e-5 of the peak speed. It fails the default rtol 1e-5
    and passes rtol 1e-4; the estimate is recorded with its units and tolerance."""
    scene = load_scene(SEED_SCENE)
    with pytest.raises(NumericalFailure) as info:
        simulate(scene, ReducedSettings(method="rkn4", step=1e-3))
    assert info.value.reason == "inaccurate"
    result = simulate(scene, ReducedSettings(method="rkn4", step=1e-3, rtol=1e-4))
    estimate = result.details.error_estimate
    assert estimate.tolerance == 1e-4 and 1e-5 < estimate.relative < 1e-4
    assert estimate.qdot_scale == pytest.approx(np.max(np.abs(result.trajectory.qdot)))


def test_default_settings_resolve_per_method():
    assert ReducedSettings().rtol == 1e-12 and ReducedSettings().step is None
    rkn4 = ReducedSettings(method="rkn4")
    assert (rkn4.rtol, rkn4.step, rkn4.sample_interval) == (1e-5, 5e-4, None) and rkn4.given == frozenset()
    assert ReducedSettings(method="radau", rtol=1e-8).given == {"rtol"}


@pytest.mark.parametrize("kwargs, field", [
    ({"method": "euler"}, "method"), ({"rtol": float("nan")}, "rtol"), ({"rtol": 1e-16}, "rtol"),
    ({"rtol": 0.5}, "rtol"), ({"rtol": -1e-6}, "rtol"), ({"method": "rkn4", "step": 0.0}, "step"),
    ({"method": "rkn4", "step": float("inf")}, "step"), ({"method": "rkn4", "step": "1e-3"}, "step"),
    ({"sample_interval": -1e-3}, "sample_interval"), ({"check_error": "no"}, "check_error")])
def test_invalid_settings_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=rf"ReducedSettings\.{field}\b"):
        ReducedSettings(**kwargs)


@pytest.mark.parametrize("kwargs, ignored", [({"method": "dop853", "step": 1e-3}, "step"),
                                             ({"method": "radau", "step": 1e-3}, "step"),
                                             ({"method": "rkn4", "sample_interval": 1e-3}, "sample_interval")])
def test_settings_the_method_ignores_are_reported(kwargs, ignored):
    with pytest.warns(IgnoredSettingWarning, match=ignored):
        ReducedSettings(**kwargs)


@pytest.mark.filterwarnings("error::loopcheck.errors.IgnoredSettingWarning")
def test_settings_the_method_uses_raise_no_warning():
    ReducedSettings(method="rkn4", step=1e-3, rtol=1e-3)
    ReducedSettings(method="dop853", rtol=1e-9, sample_interval=1e-4)


@pytest.mark.parametrize("settings, changes, key", [
    (dict(method="rkn4", step=1e-12), {}, "--step"),
    (dict(), {"horizon": 1e6}, "simulation.horizon"),
    (dict(method="rkn4"), {"horizon": 1e6}, "--step"),
    (dict(sample_interval=1e-9), {}, "sample_interval")])
def test_unbounded_work_is_refused_up_front(settings, changes, key):
    """A run needing more than MAX_SAMPLES (5e5) samples is a ValueError before any work; the
    engine refuses on its own also for a Scene built in code past the scene file's ranges."""
    scene = dataclasses.replace(variant(), **changes)
    with pytest.raises(ValueError, match=key.replace(".", r"\.")):
        simulate(scene, ReducedSettings(**settings))


def test_collapsing_adaptive_step_is_bounded():
    """q̈ = −1e30 q: DOP853 needs ~1e15 steps per second. With a budget of 1e4 evaluations
    it stops with STEP_SIZE at once instead of running for hours."""
    with pytest.raises(NumericalFailure) as info:
        solve_adaptive(constant_piece(lambda t, q, v: -1e30 * q), (0.0, 1.0), 1.0, 0.0,
                       max_evaluations=10_000)
    assert info.value.reason == "step-size" and "10000 evaluations" in str(info.value)


def test_a_long_fast_run_that_spends_the_budget_says_what_to_change():
    """long_conservative at 300 rad/s for 24 s: DOP853 at rtol 1e-12 takes ~1e5 evaluations per
    simulated second and spends the 1e6 budget at t ≈ 10.4 s. That is a long run, not a collapsing step:
    the failure says so, with the rate and the keys to change (it used to blame an extreme
    speed, damper or inertia alone)."""
    with open(hard_scene_dir() / "long_conservative.toml", "rb") as f:
        data = tomllib.load(f)
    data["initial"]["qdot"], data["simulation"]["horizon"] = 300.0, 24.0
    with pytest.raises(NumericalFailure) as info:
        simulate(scene_from_dict(data))
    message = str(info.value)
    assert info.value.reason == "step-size" and 5.0 < info.value.time < 24.0
    assert f"spent its budget of {MAX_EVALUATIONS} evaluations" in message
    assert "per simulated second" in message and "loosen rtol" in message and "simulation.horizon" in message
    needed = float(message.split("would need ~")[1].split(":")[0])
    assert MAX_EVALUATIONS < needed < 24.0 / info.value.time * MAX_EVALUATIONS * 1.06  # printed to 2 digits


def test_overflowing_acceleration_is_non_finite():
    """A damper of 1e308 overflows b q̇ to inf at the first evaluation with q̇ > 1."""
    with pytest.raises(NumericalFailure) as info:
        solve_adaptive(constant_piece(lambda t, q, v: -1e308 * v * 10.0), (0.0, 1.0), 0.0, 2.0)
    assert info.value.reason == "non-finite"


def test_initial_speed_beyond_the_limit_is_refused_at_once():
    """(The compiled kernels' SPEED at t0: tests/reduced/kernels/test_kernel_integrators.py.)"""
    with pytest.raises(NumericalFailure) as info:
        solve_adaptive(constant_piece(lambda t, q, v: 0.0), (0.0, 1.0), 0.0, 1e308)
    assert info.value.reason == "unstable" and info.value.time == 0.0
    assert "initial speed" in str(info.value)


def test_energy_imbalance_beyond_the_bound_is_a_failure(monkeypatch):
    """The seed's DOP853 run balances to 1.3e-11 of the work, inside its bound
    max(1000 × rtol, ENERGY_FLOOR) = 1e-8; with the bound cut to 1 × rtol (1e-12) the same run
    is an ENERGY_IMBALANCE, and with check_error off it is returned with the bound recorded."""
    scene = load_scene(SEED_SCENE)
    result = simulate(scene)
    assert result.details.energy_bound == pytest.approx(1e-8)
    assert result.audit.relative_residual < 1e-10
    monkeypatch.setitem(simulate_module.ENERGY_FACTOR, "dop853", 1.0)
    monkeypatch.setattr(simulate_module, "ENERGY_FLOOR", 0.0)
    with pytest.raises(NumericalFailure) as info:
        simulate(scene)
    assert info.value.reason == "energy-imbalance" and "1.0e-12" in str(info.value)
    assert simulate(scene, ReducedSettings(check_error=False)).details.energy_bound == 1e-12


@pytest.mark.slow  # ~9 s: 100 000 samples of the fine run and their energy audit
def test_reference_peak_is_not_limited_by_its_interpolant():
    """Crossed-branch seed (branch −1). With samples only at the solver's steps and the 1 ms
    cuts the peak is off by 2.1e-7 rad/s; with every step cut into at least 4 parts it agrees
    with an independent, much finer evaluation (samples every 20 µs of the dense output) to
    7.2e-10 (measured; the dense output's own noise: two such fine evaluations differ by as
    much, see integrators.SAMPLES_PER_STEP). Bound 3e-9 rad/s (9e-11 of the 33.4 rad/s peak):
    4× the measured, 70× below the error with the steps alone."""
    data = seed_dict()
    data["linkage"]["branch"] = -1
    scene = scene_from_dict(data)
    reference = simulate(scene)
    fine = simulate(scene, ReducedSettings(sample_interval=2e-5, check_error=False))
    assert abs(reference.peak.omega - fine.peak.omega) < 3e-9
    assert abs(reference.peak.time - fine.peak.time) < 1e-6


@pytest.mark.parametrize("patch", [{"torque": {"duration": 1e-12}}, {"torque": {"value": 1e-12}},
                                   {"initial": {"qdot": 1e-9}, "torque": None}])
def test_energy_gate_has_an_absolute_floor(patch):
    """Runs in which almost nothing moves: energy scales of 1e-21 … 1e-26 J, residuals of
    round-off size (measured 1.0, 0.023 and 1e-8 of those scales). Relative to the audit's
    scale they would fail; relative to the floor ½ 𝔍0 (1 rad/s)² (~2 J here) they are
    ≤ 1e-20 and pass. Without the floor all three raise ENERGY_IMBALANCE."""
    data = seed_dict()
    for key, value in patch.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = {**data[key], **value}
    result = simulate(scene_from_dict(data))
    assert result.audit.max_abs_residual < 1e-9 * result.details.energy_scale
    assert result.details.energy_scale > 1.0


