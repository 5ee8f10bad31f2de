"""The reduced engine in several coordinates (issue 40: loopcheck.reduced.several and its compiled
chart loopcheck.reduced.kernels.several) against the independent full-coordinate oracle
(tests/oracles/multibody.py) and against the one-DOF kernel.

Tolerances (issue 40's targets, absolute): 1e-9 rad on each input's angle and 1e-8 rad/s on its
rate at every output sample. Measured on the five-bar robot over 0.8 s at the defaults (the
compiled DOP853 in n coordinates, rtol 1e-12; two coordinate switches by the hysteresis rule,
where the elbows A and B pass within 0.4 mm of each other: the inputs' own singular point):
2.2e-11 rad and 3.7e-10 rad/s (scipy's DOP853 on the same chart the same, 2.2e-11 and 3.7e-10;
Radau 2.4e-11 and 2.7e-10); the oracle's own rtol-halving differences 1.3e-11 rad and 1.6e-10
rad/s (below a third of the tolerances, as tests/reduced/test_multibody_oracle.py asks). Energy
balance: 2.5e-11 of the run's scale (bound 1e-9). RKN4: see its convergence test.

Plants (each made in the source, the file run, then removed), every one failing the five-bar
tests both by the engine's own energy gate and by the oracle (run with check_error=False):
𝔍's off-diagonal terms × (1 + 1e-7): energy 1.3e-6, oracle 2.1e-6 rad; c × (1 + 1e-6): energy
3.2e-6, oracle 6.5e-6 rad (the compiled DOP853; RKN4 the same, 2.2e-6 and 6.6e-6 rad, and its
convergence test fails, its fitted order 0.5 with c planted: the energy gate of RKN4, 10 × rtol,
is too loose to see them); the coordinate switch
re-expressing q̇' = R' ẋ × (1 + 1e-7): energy 3.4e-7, oracle 8.3e-7 rad (the fold's test fails
too); the compiled run handing the switch its q̇ × (1 + 1e-7) at a stop: the same on DOP853, 9.0e-7
rad on RKN4, and the bit-for-bit test with scipy's DOP853 fails; the compiled run's work done
before a switch dropped from its samples: energy 0.34; RKN4's stability check off: the stiff
damper's run fails "singular" instead of "unstable"."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import loopcheck
from loopcheck.scenefile import load_scene

from helpers import ROOT
from oracles.multibody import GROUND, Body, Model, Pin, Torque, pulse
from oracles.multibody import simulate as oracle_simulate
from test_multibody_oracle import FIVE_BAR_START, five_bar, five_bar_pendulum

Q_TOL, RATE_TOL = 1e-9, 1e-8  # rad, rad/s (module docstring)
FIVE_BAR = ROOT / "scenes/mechanisms/five_bar_robot.toml"


@pytest.fixture(scope="module")
def five_bar_run():
    scene = load_scene(FIVE_BAR)
    return scene, loopcheck.simulate(scene)


def oracle_at(t: np.ndarray, q=(1.8, 1.3), qdot=(0.5, -0.3), guess=(0.8, 2.3)):
    """The oracle's five-bar from the scene's initial state, at the times t (unique, sorted):
    the run and its own stated accuracy."""
    model = five_bar()
    q0, qd0 = model.assemble({"left_crank": q[0], "left_arm": guess[0], "right_arm": guess[1], "right_crank": q[1]},
                             {"left_crank": q[0], "right_crank": q[1]},
                             {"left_crank": qdot[0], "right_crank": qdot[1]})
    run, accuracy = oracle_simulate(model, q0, qd0, t)
    return model, run, accuracy


def test_the_five_bar_agrees_with_the_oracle_on_both_inputs(five_bar_run):
    scene, result = five_bar_run
    (left, _), (right, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    model, run, accuracy = oracle_at(t)
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    for body, tr in (("left_crank", left), ("right_crank", right)):
        assert np.max(np.abs(run.angle(model, body) - tr.q[idx])) < Q_TOL, body
        assert np.max(np.abs(run.rate(model, body) - tr.qdot[idx])) < RATE_TOL, body
    assert left.q[0] == 1.8 and right.qdot[0] == -0.3
    assert np.ptp(right.q) > 0.1 and np.ptp(left.q) > 0.1


def test_the_five_bar_balances_its_energy_and_reports_every_joint(five_bar_run):
    scene, result = five_bar_run
    assert result.audit.relative_residual < 1e-9  # measured 2.5e-11
    assert np.max(np.abs(result.audit.torque_work)) > 1.0  # the motors do work
    assert result.joints.x.shape == (len(result.trajectory.t), 4)
    assert len(result.other_inputs) == 1
    # every joint coordinate satisfies the loop: the end effector P of both arms coincides
    x = result.joints.x
    left = 0.4 * np.exp(1j * x[:, 0]) + 0.7 * np.exp(1j * x[:, 1])
    right = 0.6 + 0.4 * np.exp(1j * x[:, 3]) + 0.7 * np.exp(1j * x[:, 2])
    assert np.max(np.abs(left - right)) < 1e-12


SCENE_PATHS = {"five_bar_robot": ROOT / "scenes/mechanisms/five_bar_robot.toml",
               "five_bar_fold": ROOT / "scenes/hard/five_bar_fold.toml",
               "five_bar_pendulum": ROOT / "tests/data/five_bar_pendulum.toml"}


@pytest.mark.parametrize("name", ["five_bar_robot", "five_bar_fold", "five_bar_pendulum"])
def test_the_compiled_dop853_is_scipys_dop853_on_the_same_chart_to_the_bit(name):
    """The default method (the compiled DOP853 in n coordinates, the chart called from compiled code)
    and ``scipy-dop853`` (scipy's solve_ivp on the same chart through Python) are one algorithm: with
    numpy summing in the kernel's order (the BLAS's order depends on the CPU), every sample, joint,
    energy flow and switch is the same to the bit, through the five-bar's two switches, the fold's
    load edges and switch, and the 3-DOF scene's switch. With numpy's own sums the step sequences
    part in the last bits (the error estimate at rtol 1e-12 is a difference of O(1) stages): on
    the five-bar the runs then agree to 1e-11 rad and 1e-10 rad/s at the compiled run's samples,
    the other interpolated (measured: 7.3e-14 rad, 1.3e-12 rad/s; the steps, 188, are as many;
    fold 1.8e-14 rad, 3.5e-13 rad/s; 3-DOF 1.3e-13 rad, 1.5e-12 rad/s)."""
    from helpers import scipy_in_vector_kernel_order
    from loopcheck.reduced.settings import ReducedSettings

    scene = load_scene(SCENE_PATHS[name])
    compiled = loopcheck.simulate(scene, ReducedSettings())
    with scipy_in_vector_kernel_order():
        scipy = loopcheck.simulate(scene, ReducedSettings(method="scipy-dop853"))
    assert compiled.details.solver == "DOP853" and scipy.details.solver == "scipy DOP853"
    assert compiled.details.switches == scipy.details.switches and compiled.details.switches
    assert (compiled.n_steps, compiled.n_evaluations) == (scipy.n_steps, scipy.n_evaluations)
    for (a, _), (b, _) in zip(compiled.inputs, scipy.inputs):
        for field in ("t", "q", "qdot", "qddot"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert np.array_equal(compiled.joints.x, scipy.joints.x) and np.array_equal(compiled.joints.xdot, scipy.joints.xdot)
    for field in ("kinetic", "potential", "torque_work", "damper_dissipation"):
        assert np.array_equal(getattr(compiled.audit, field), getattr(scipy.audit, field)), field
    if name == "five_bar_robot":
        plain = loopcheck.simulate(scene, ReducedSettings(method="scipy-dop853"))
        for (a, _), (b, _) in zip(compiled.inputs, plain.inputs):
            t = np.unique(a.t)
            q, qdot, _ = b.interpolate(t)
            q0, qdot0, _ = a.interpolate(t)
            assert np.max(np.abs(q - q0)) < 1e-11 and np.max(np.abs(qdot - qdot0)) < 1e-10


RKN4_STEPS = (2e-3, 1e-3, 5e-4)  # s


def test_rkn4_on_the_five_bar_converges_to_the_oracle_at_fourth_order():
    """The compiled RKN4 in n coordinates on the five-bar robot over 0.8 s (two switches, each after
    the step where the chart's margin crossed zero) at three steps, against the oracle at every
    sample: the largest errors fall at the method's order (fitted slope of log error on log h, both
    coordinates and rates: 4 ± 0.3), the engine's step-doubling estimate is within a factor 2 of the
    oracle's error, and the energy drift falls with the step too. Measured (h = 2, 1, 0.5 ms):
    2.0e-5, 1.3e-6, 8.1e-8 rad and 2.5e-4, 1.7e-5, 1.1e-6 rad/s (orders 3.99 and 3.92); the estimate
    1.9e-5, 1.3e-6, 8.0e-8 rad; energy 5.9e-6, 4.1e-7, 2.7e-8 of the run's scale. The default step
    (0.5 ms) passes the engine's own gates (rtol 1e-5: estimate 4.5e-8; energy bound 1e-4)."""
    from loopcheck.reduced.settings import ReducedSettings

    scene = load_scene(FIVE_BAR)
    runs = [loopcheck.simulate(scene, ReducedSettings(method="rkn4", step=h, check_error=False)) for h in RKN4_STEPS]
    times = np.unique(np.concatenate([r.trajectory.t for r in runs]))
    model, oracle, accuracy = oracle_at(times)
    errors, estimates, energy = [], [], []
    for run in runs:
        assert run.details.solver.startswith("RKN4") and len(run.details.switches) == 2
        q_error = rate_error = 0.0
        for body, (tr, _) in zip(("left_crank", "right_crank"), run.inputs):
            at = np.searchsorted(times, tr.t)
            q_error = max(q_error, np.max(np.abs(oracle.angle(model, body)[at] - tr.q)))
            rate_error = max(rate_error, np.max(np.abs(oracle.rate(model, body)[at] - tr.qdot)))
        errors.append((q_error, rate_error))
        estimates.append((run.details.error_estimate.q_abs, run.details.error_estimate.qdot_abs))
        energy.append(run.audit.relative_residual)
    errors, estimates = np.array(errors), np.array(estimates)
    assert accuracy[0] < errors[-1, 0] / 100 and accuracy[1] < errors[-1, 1] / 100
    for column in (0, 1):
        order = np.polyfit(np.log(RKN4_STEPS), np.log(errors[:, column]), 1)[0]
        assert 3.7 < order < 4.3, (column, order, errors)
    assert np.all(estimates > errors / 2) and np.all(estimates < 2 * errors), (estimates, errors)
    assert energy[0] > 8 * energy[1] > 64 * energy[2] and energy[2] < 1e-7
    default = loopcheck.simulate(scene, ReducedSettings(method="rkn4"))
    assert default.settings.step == 5e-4 and default.details.error_estimate.relative < 1e-5


@pytest.mark.parametrize("coefficient, reason, named", [
    (2000.0, "unstable", "outside RKN4's stability region at t = 0 s (h·λ = -6.08"),
    (200.0, "inaccurate", "estimates its own error (step doubling) at 4.20e-05"),
])
def test_rkn4_with_several_inputs_refuses_a_step_too_stiff_or_too_coarse(coefficient, reason, named):
    """RKN4 at its default step (0.5 ms) on the five-bar with a stiff joint damper at A: the
    stability check finds the stiff mode (2000 N·m·s/rad: h·λ = −6.08, measured), or, where the step
    is stable (200), its step-doubling estimate exceeds rtol 1e-5 (measured 4.2e-5: 5.6e-4 rad/s);
    each a one-line failure saying what to change, as with one DOF."""
    from loopcheck.api import scene_from_string
    from loopcheck.errors import NumericalFailure
    from loopcheck.reduced.settings import ReducedSettings

    text = FIVE_BAR.read_text().replace(
        "[initial]", f'[[joint_dampers]]\njoint = "A"\ncoefficient = {coefficient}\n\n[initial]')
    with pytest.raises(NumericalFailure) as failed:
        loopcheck.simulate(scene_from_string(text), ReducedSettings(method="rkn4"))
    message = str(failed.value)
    assert failed.value.reason.value == reason and named in message and "\n" not in message
    assert "smaller step" in message


FOLD = ROOT / "scenes/hard/five_bar_fold.toml"


def five_bar_fold() -> Model:
    """scenes/hard/five_bar_fold.toml, by hand: the five-bar with a 0.5 m right arm, no gravity."""
    return Model(
        bodies=(Body("left_crank", 2.0, (0.2, 0.0), 0.03), Body("left_arm", 1.5, (0.35, 0.02), 0.07),
                Body("right_arm", 1.2, (0.25, -0.01), 0.05), Body("right_crank", 2.5, (0.2, 0.0), 0.04)),
        pins=(Pin("O1", GROUND, (0.0, 0.0), "left_crank", (0.0, 0.0)),
              Pin("A", "left_crank", (0.4, 0.0), "left_arm", (0.0, 0.0)),
              Pin("P", "left_arm", (0.7, 0.0), "right_arm", (0.5, 0.0)),
              Pin("B", "right_arm", (0.0, 0.0), "right_crank", (0.4, 0.0)),
              Pin("O5", GROUND, (0.6, 0.0), "right_crank", (0.0, 0.0))),
        torques=(Torque("O1", pulse(8.0, 0.0, 0.3)), Torque("O5", pulse(-5.0, 0.1, 0.3))),
        gravity=0.0, edges=(0.1, 0.3, 0.4))


def test_a_five_bar_through_its_inputs_singular_configuration_switches_and_agrees_with_the_oracle():
    """The elbows reach |A − B| = 0.2 m (the arms fold parallel: the inputs' set is singular there,
    its conditioning → 0); the run leaves the inputs' coordinates before and stays within the
    tolerances of the oracle through it. Measured: one switch (O1, O5 → P, B at 0.054 s), |A − B|
    down to 0.2 + 3e-7 m at 0.175 s, 2.4e-12 rad and 2.3e-11 rad/s from the oracle (its own
    accuracy 1.2e-12 rad, 2.5e-11 rad/s), energy 3.6e-12."""
    scene = load_scene(FOLD)
    result = loopcheck.simulate(scene)
    switches = result.details.switches
    assert switches and switches[0].old == "O1, O5"
    x = result.joints.x
    gap = np.abs(0.4 * np.exp(1j * x[:, 0]) - (0.6 + 0.4 * np.exp(1j * x[:, 3])))
    assert np.min(gap) < 0.2 + 1e-5  # the fold is reached (it cannot be passed: |A − B| ≥ 0.2)
    (left, _), (right, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    model = five_bar_fold()
    q0, qd0 = model.assemble({"left_crank": 1.25, "left_arm": 0.81, "right_arm": 1.41, "right_crank": 1.75},
                             {"left_crank": 1.25, "right_crank": 1.75}, {"left_crank": -5.0, "right_crank": 5.0})
    run, accuracy = oracle_simulate(model, q0, qd0, t)
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    for body, tr in (("left_crank", left), ("right_crank", right)):
        assert np.max(np.abs(run.angle(model, body) - tr.q[idx])) < Q_TOL, body
        assert np.max(np.abs(run.rate(model, body) - tr.qdot[idx])) < RATE_TOL, body
    assert result.audit.relative_residual < 1e-9


SEED = ROOT / "scenes/seed_fourbar.toml"


def test_the_several_coordinate_chart_at_one_input_gives_the_one_dof_kernels_acceleration():
    """The seed four-bar (damper, torque pulse) through the n-DOF chart with its one input against
    today's one-DOF chart in the input's coordinate: q̈ at 200 crank angles over a turn × 3 speeds
    × both load pieces, to 1e-13 of the equation's scale (the largest of |q̈| and the sum of its
    terms' magnitudes over 𝔍: q̈ near 0 is a difference of large terms). Measured: 6.9e-15."""
    from loopcheck.reduced.dynamics import MechanismModel
    from loopcheck.reduced.kernels import physics
    from loopcheck.reduced.several import SeveralModel, start_chart

    scene = load_scene(SEED)
    one = MechanismModel(scene)
    chart1 = one.new_chart()
    assert chart1.start(np.array(scene.x0), one.input_coordinate)
    fields = chart1.arrays()["fields"]
    many = SeveralModel(scene)
    chart = start_chart(many, many.inputs, np.array(scene.x0))
    a = np.zeros(1)
    worst = 0.0
    for q in np.linspace(0.2, 0.2 + 2 * np.pi, 200):
        for v in (0.0, 3.0, -20.0):
            for load in (0, 1):
                expected = chart1.acceleration(load, 0.0, q, v)
                assert chart.acceleration(load, 0.0, np.array([q]), np.array([v]), a) == 0
                terms = (abs(fields[physics.CENTRIFUGAL]) * v * v + abs(fields[physics.POTENTIAL_GRADIENT])
                         + abs(fields[physics.DAMPING] * v) + 250.0 * abs(fields[physics.INPUT_RATE]))
                scale = max(abs(expected), terms / fields[physics.INERTIA])
                worst = max(worst, abs(a[0] - expected) / scale)
    assert worst < 1e-13


def test_a_one_input_run_through_the_several_coordinate_engine_follows_todays():
    """The seed over 1.5 s (through the pulse's end at 1 s) by the n-DOF run (its chart switches
    to joint A's coordinate at 0.63 s by the hysteresis rule) against today's engine, both the
    compiled DOP853 at rtol 1e-12 (in n coordinates, and the one-DOF kernel's): at the load edge and
    the horizon, sampled by both, 1e-10 rad and 1e-9 rad/s; at every sample of the n-DOF run
    (today's interpolated: its interpolant's own error in q̇ is ~1.1e-8 rad/s,
    loopcheck.reduced.integrators) 1e-10 rad and 3e-8 rad/s. Measured: 2.5e-11 rad, 9.3e-9 rad/s on
    the samples; 1.2e-11 rad and 1.4e-10 rad/s at the shared times."""
    from loopcheck.reduced.settings import ReducedSettings
    from loopcheck.reduced.several import SeveralModel, integrate

    scene = replace(load_scene(SEED), horizon=1.5)
    today = loopcheck.simulate(scene).trajectory
    record, switches, *_ = integrate(SeveralModel(scene), ReducedSettings())
    t = np.concatenate(record.t)
    x, xdot = np.concatenate(record.x), np.concatenate(record.xdot)
    q, qdot, _ = today.interpolate(t)
    assert np.max(np.abs(x[:, 0] - q)) < 1e-10
    assert np.max(np.abs(xdot[:, 0] - qdot)) < 3e-8
    for when in (1.0, 1.5):
        mine, theirs = np.flatnonzero(t == when)[-1], np.flatnonzero(today.t == when)[-1]
        assert abs(x[mine, 0] - today.q[theirs]) < 1e-10
        assert abs(xdot[mine, 0] - today.qdot[theirs]) < 1e-9


PENDULUM = ROOT / "tests/data/five_bar_pendulum.toml"


def test_a_three_dof_five_bar_with_a_pendulum_agrees_with_the_oracle():
    """tests/data/five_bar_pendulum.toml (the five-bar robot with a pendulum on a free wrist at P:
    3 DOF) against the oracle on all three inputs, the wrist's a relative angle, over 0.4 s. Measured
    (one switch, O1, O5, wrist → A, B, wrist at 0.29 s): 3.9e-12 rad and 7.2e-11 rad/s; the oracle's
    own accuracy 2.3e-12 rad, 2.6e-11 rad/s; energy 4.6e-12. (Over the scene's 0.8 s, the wrist up
    to 70 rad/s, with scipy's DOP853 before the compiled one: 9.1e-12 rad, 1.5e-10 rad/s.)"""
    scene = replace(load_scene(PENDULUM), horizon=0.4)  # through its switch at 0.29 s (the oracle's cost)
    result = loopcheck.simulate(scene)
    model, q0, qd0 = five_bar_pendulum(result.joints.x[0], result.joints.xdot[0])
    (left, _), (right, _), (wrist, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    run, accuracy = oracle_simulate(model, q0, qd0, t)
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    oracle = {"left": (run.angle(model, "left_crank"), run.rate(model, "left_crank")),
              "right": (run.angle(model, "right_crank"), run.rate(model, "right_crank")),
              "wrist": (run.angle(model, "pendulum") - run.angle(model, "left_arm"),
                        run.rate(model, "pendulum") - run.rate(model, "left_arm"))}
    for name, tr in (("left", left), ("right", right), ("wrist", wrist)):
        q, qdot = oracle[name]
        assert np.max(np.abs(q - tr.q[idx])) < Q_TOL, name
        assert np.max(np.abs(qdot - tr.qdot[idx])) < RATE_TOL, name
    assert np.ptp(wrist.q) > 1.0
    assert result.audit.relative_residual < 1e-9


def test_the_several_coordinate_chart_runs_as_plain_python_with_the_compiled_numbers():
    """LOOPCHECK_PURE_PYTHON=1 (a subprocess: the switch is read at import) runs the chart's .py
    source: q̈ of the five-bar at its start and along 20 jumps of its inputs, and the conditionings,
    equal to the compiled kernel's bit for bit (the same arithmetic in the same order)."""
    import json
    import os
    import subprocess
    import sys

    probe = f"""
import json, numpy as np
from loopcheck.reduced import kernels
from loopcheck.reduced.kernels import several
from loopcheck.scenefile import load_scene
from loopcheck.reduced.several import SeveralModel, start_chart
assert several.__file__.endswith(".py") == kernels.PURE_PYTHON
scene = load_scene({str(FIVE_BAR)!r})
model = SeveralModel(scene)
chart = start_chart(model, model.inputs, np.array(scene.x0))
out, a = [], np.zeros(2)
for s in range(20):
    q = np.array([1.8 + 0.05 * s, 1.3 - 0.03 * s])
    v = np.array([0.5 + s, -0.3])
    chart.acceleration(s % 3, 0.1 * s, q, v, a)
    out.append(a.tolist() + [chart.power(s % 3, v), chart.kinetic(v), chart.stop_margin(0.0, q, v)])
print(json.dumps(out))
"""
    runs = []
    for pure in ("1", "0"):
        env = dict(os.environ, LOOPCHECK_PURE_PYTHON=pure, PYTHONPATH=str(ROOT))
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, cwd=ROOT,
                              timeout=120)
        assert done.returncode == 0, done.stderr[-2000:]
        runs.append(json.loads(done.stdout))
    assert runs[0] == runs[1]


def test_a_run_at_a_singular_configuration_of_the_mechanism_stops_with_its_time_and_conditioning():
    """The five-bar robot at rest 1e-6 rad from its flat configuration (q = (π, 0): every link on the
    ground line, where Φ_x loses rank and no set of joints can drive it; at the start: the inputs'
    conditioning 7.6e-7, the best set's 3.1e-6): the run cannot follow it through and stops at once,
    saying when and how well conditioned the coordinates were at the last configuration closed.
    Measured: the compiled DOP853 at t = 6.2e-5 s (conditioning 2.6e-6, of the best set too); scipy's
    DOP853 at t = 0 s (its step collapses: 7.6e-7 and 3.1e-6)."""
    import re

    from loopcheck.api import scene_from_string
    from loopcheck.errors import NumericalFailure
    from loopcheck.reduced.settings import ReducedSettings

    text = (FIVE_BAR.read_text().replace("q = [1.8, 1.3]", f"q = [{np.pi - 1e-6!r}, 1e-6]")
            .replace("guess = { left_arm = 0.8, right_arm = 2.3 }", "guess = { left_arm = 0.05, right_arm = 3.09 }")
            .replace("qdot = [0.5, -0.3]", "qdot = [0.0, 0.0]"))
    for method in ("dop853", "scipy-dop853"):
        with pytest.raises(NumericalFailure) as stopped:
            loopcheck.simulate(scene_from_string(text), ReducedSettings(method=method))
        failure = stopped.value
        message = str(failure)
        assert "\n" not in message and 0.0 <= failure.time < 1e-4, method
        when = re.search(r"at t = (\S+) s", message)
        assert when and float(when.group(1)) == pytest.approx(failure.time, rel=1e-8, abs=1e-12), message
        found = re.search(r"O1, O5 have conditioning ([-+.e0-9]+) and the best set ([-+.e0-9]+)", message)
        assert found and float(found.group(1)) < 1e-5 and float(found.group(2)) < 1e-5, message


@pytest.mark.parametrize("name", ["andrews_squeezer", "oscillating_slotted_lever", "seed_fourbar_geared_flywheel",
                                  "servo_fourbar", "stephenson3_sixbar", "watt2_sixbar"])
def test_the_several_coordinate_chart_at_one_input_matches_the_one_dof_kernel_on_shipped_scenes(name):
    """The same comparison over shipped one-DOF scenes with the effects the n-DOF chart computes
    (springs, a slider, gravity, a geared flywheel's joint inertia, an actuator, two loops): q̈ at 300
    states of each scene's own run, in order, to 1e-13 of the equation's scale. Measured: 4.8e-16
    (slotted lever) to 1.8e-14 (servo). (Near a dead centre of the input the two differ by round-off
    amplified by the conditioning: 4e-11 and 9e-11 on scenes/hard's near_change_point and
    dead_centre; not asserted.)"""
    from loopcheck.reduced.dynamics import MechanismModel
    from loopcheck.reduced.kernels import physics
    from loopcheck.reduced.several import SeveralModel, start_chart

    scene = load_scene(ROOT / "scenes" / "mechanisms" / f"{name}.toml")
    trajectory = loopcheck.simulate(scene).trajectory
    one = MechanismModel(scene)
    chart1 = one.new_chart()
    assert chart1.start(np.array(scene.x0), one.input_coordinate)
    fields = chart1.arrays()["fields"]
    many = SeveralModel(scene)
    chart = start_chart(many, many.inputs, np.array(scene.x0))
    edges, a, worst = one.piece_edges, np.zeros(1), 0.0
    for i in np.linspace(0, len(trajectory.t) - 1, 300).astype(int):
        t, q, v = trajectory.t[i], trajectory.q[i], trajectory.qdot[i]
        load = int(min(max(np.searchsorted(edges, t, side="right") - 1, 0), len(edges) - 2))
        expected = chart1.acceleration(load, t, q, v)
        assert chart.acceleration(load, t, np.array([q]), np.array([v]), a) == 0
        terms = (abs(fields[physics.CENTRIFUGAL]) * v * v + abs(fields[physics.POTENTIAL_GRADIENT])
                 + abs(fields[physics.DAMPING] * v))
        worst = max(worst, abs(a[0] - expected) / max(abs(expected), terms / abs(fields[physics.INERTIA])))
    assert worst < 1e-13


def test_a_damped_five_bar_agrees_with_the_oracle_and_audits_the_dissipation():
    """The five-bar robot with a line damper (5 N·s/m) from a ground point to the end effector P:
    the damping matrix B (off-diagonal terms too) and the dissipation of the audit, against the
    oracle. Measured: 9.7e-12 rad and 3.2e-10 rad/s (one switch); 48.5 J dissipated; energy 5.1e-12."""
    from loopcheck.api import scene_from_string
    from oracles.multibody import Damper

    text = (FIVE_BAR.read_text().replace("points = { O1 = [0.0, 0.0], O5 = [0.6, 0.0] }",
                                         "points = { O1 = [0.0, 0.0], O5 = [0.6, 0.0], D = [0.3, 1.2] }")
            + '\n[[dampers]]\na = "ground.D"\nb = "left_arm.P"\ncoefficient = 5.0\n')
    result = loopcheck.simulate(scene_from_string(text))
    (left, _), (right, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    model = replace(five_bar(), dampers=(Damper(GROUND, (0.3, 1.2), "left_arm", (0.7, 0.0), 5.0),))
    q0, qd0 = model.assemble(*FIVE_BAR_START)
    run, accuracy = oracle_simulate(model, q0, qd0, t)
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    for body, tr in (("left_crank", left), ("right_crank", right)):
        assert np.max(np.abs(run.angle(model, body) - tr.q[idx])) < Q_TOL, body
        assert np.max(np.abs(run.rate(model, body) - tr.qdot[idx])) < RATE_TOL, body
    assert result.audit.damper_dissipation[-1] > 10.0
    assert result.audit.relative_residual < 1e-9


def test_a_five_bar_with_joint_elements_and_a_timed_force_balances_its_energy():
    """Joint spring (P), joint damper (A), joint inertia (B) and a timed force at the end effector on
    the five-bar: their potential, dissipation, kinetic energy (𝔍 and c) and power against the
    integrated state. A wrong K_u in Q against V's u, or the joint inertia in 𝔍 without its c, opens
    the balance (planted: the joint inertia's term dropped from c, 6.5e-2). Measured: 4.3e-11."""
    from loopcheck.api import scene_from_string

    extra = '''
[[joint_springs]]
joint = "P"
stiffness = 3.0
rest_angle = 1.2

[[joint_dampers]]
joint = "A"
coefficient = 0.2

[[joint_inertias]]
joint = "B"
inertia = 0.02

[[timed_forces]]
point = "left_arm.P"
direction = -1.0
type = "pulse"
value = 6.0
start = 0.2
duration = 0.25
'''
    result = loopcheck.simulate(scene_from_string(FIVE_BAR.read_text().replace("[initial]", extra + "\n[initial]")))
    audit = result.audit
    assert audit.relative_residual < 1e-9
    assert audit.damper_dissipation[-1] > 1e-3 and np.ptp(audit.potential) > 1.0


def test_a_coupled_joint_in_a_two_dof_linkage_follows_its_polynomial_and_balances_the_energy():
    """The five-bar with a pendulum whose wrist follows joint A by a quadratic (a coupling: one more
    closure row, a polynomial one, so 2 DOF with the inputs O1, O5): the coupling holds to round-off
    along the run, and the energy balances (the polynomial row's −γ = p''(s) (r_x·ẋ)² in ẍ0; planted
    with the wrong sign: 0.48). Measured: 2.2e-15 rad, energy 6.4e-12, two switches."""
    from loopcheck.api import scene_from_string

    text = (PENDULUM.read_text().replace('inputs = ["O1", "O5", "wrist"]', 'inputs = ["O1", "O5"]')
            .replace("q = [1.8, 1.3, -1.0]", "q = [1.8, 1.3]").replace("qdot = [0.5, -0.3, 2.0]", "qdot = [0.5, -0.3]")
            .replace("[initial]", '[[couplings]]\nname = "cam"\njoint = "wrist"\ndriver = "A"\n'
                     'polycoef = [-1.0, 0.5, 0.3]\nreference = [-0.8, 0.0]\n\n[initial]'))
    scene = scene_from_string(text)
    assert scene.dof == 2
    result = loopcheck.simulate(scene)
    x = result.joints.x
    s = x[:, 1] - x[:, 0] + 0.8  # joint A's coordinate from its reference
    assert np.max(np.abs((x[:, 4] - x[:, 1]) - (-1.0 + 0.5 * s + 0.3 * s * s))) < 1e-12
    assert result.audit.relative_residual < 1e-9


@pytest.mark.parametrize("method", ["dop853", "rkn4"])
def test_a_joint_range_ends_a_several_dof_run_where_the_oracle_reaches_the_bound(method):
    """A range [−2, 0] rad on joint A of the five-bar robot: the run ends, as the one-DOF engine's
    does, with "range-reached" naming the joint, the bound and the time; the oracle's joint A is at
    the bound then, to 1e-9 rad (measured: 0.198771617 s, 2.6e-13 rad off; RKN4, the bound's root
    located in its step, 3.5e-13 s later than DOP853)."""
    from loopcheck.api import scene_from_string
    from loopcheck.errors import FailureReason, NumericalFailure
    from loopcheck.reduced.settings import ReducedSettings

    text = FIVE_BAR.read_text().replace('b = "left_arm.A"', 'b = "left_arm.A"\nrange = [-2.0, 0.0]')
    with pytest.raises(NumericalFailure) as stopped:
        loopcheck.simulate(scene_from_string(text), ReducedSettings(method=method))
    failure = stopped.value
    assert failure.reason is FailureReason.RANGE_REACHED and failure.joint == "A"
    assert "lower bound -2 rad" in str(failure) and 0.1 < failure.time < 0.3
    model, run, accuracy = oracle_at(np.array([0.0, failure.time]))
    u = run.angle(model, "left_arm")[-1] - run.angle(model, "left_crank")[-1]
    assert abs(u - (-2.0)) < Q_TOL


# The five-bar robot with a redundantly closed parallelogram on its left crank: a coupler pinned at
# the crank's elbow A and carried by two more cranks of the same 0.4 m from the ground pivots G1
# (−0.3, 0) and G2 (−0.6, 0). The coupler translates; the second extra crank's two pin rows are
# dependent (Grübler's count 1, the rank 2: consistent at every configuration).
REDUNDANT_BODIES = """
[bodies.coupler]
points = { A = [0.0, 0.0], C1 = [-0.3, 0.0], C2 = [-0.6, 0.0] }
mass = 0.8
com = [-0.3, 0.01]
inertia = 0.02

[bodies.aux1]
points = { G = [0.0, 0.0], C = [0.4, 0.0] }
mass = 0.6
com = [0.2, 0.0]
inertia = 0.01

[bodies.aux2]
points = { G = [0.0, 0.0], C = [0.4, 0.0] }
mass = 0.7
com = [0.2, 0.0]
inertia = 0.012
"""
REDUNDANT_JOINTS = "".join(f'[[joints]]\nname = "{name}"\ntype = "revolute"\na = "{a}"\nb = "{b}"\n\n' for name, a, b in (
    ("K", "left_crank.A", "coupler.A"), ("C1", "coupler.C1", "aux1.C"), ("G1", "ground.G1", "aux1.G"),
    ("C2", "coupler.C2", "aux2.C"), ("G2", "ground.G2", "aux2.G")))


def redundant_five_bar_scene(extra_toml: str = "", horizon: float | None = None):
    import warnings

    from loopcheck.api import scene_from_string
    from loopcheck.mechanism import GrublerCountWarning

    text = FIVE_BAR.read_text()
    for old, new in (("O5 = [0.6, 0.0] }", "O5 = [0.6, 0.0], G1 = [-0.3, 0.0], G2 = [-0.6, 0.0] }"),
                     ("[[joints]]", REDUNDANT_BODIES + "\n" + REDUNDANT_JOINTS + "[[joints]]"),
                     ("guess = { left_arm = 0.8, right_arm = 2.3 }",
                      "guess = { left_crank = 1.8, right_crank = 1.3, left_arm = 0.8, right_arm = 2.3, coupler = 0.0, "
                      "aux1 = 1.8, aux2 = 1.8 }"),
                     ("[simulation]", extra_toml + "[simulation]")):
        assert old in text
        text = text.replace(old, new, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GrublerCountWarning)
        scene = scene_from_string(text)
    return scene if horizon is None else replace(scene, horizon=horizon)


def redundant_five_bar() -> Model:
    """The oracle's redundant five-bar (:func:`redundant_five_bar_scene`), by hand."""
    base = five_bar()
    return replace(base, bodies=base.bodies + (Body("coupler", 0.8, (-0.3, 0.01), 0.02),
                                               Body("aux1", 0.6, (0.2, 0.0), 0.01),
                                               Body("aux2", 0.7, (0.2, 0.0), 0.012)),
                   pins=base.pins + (Pin("K", "left_crank", (0.4, 0.0), "coupler", (0.0, 0.0)),
                                     Pin("C1", "coupler", (-0.3, 0.0), "aux1", (0.4, 0.0)),
                                     Pin("G1", GROUND, (-0.3, 0.0), "aux1", (0.0, 0.0)),
                                     Pin("C2", "coupler", (-0.6, 0.0), "aux2", (0.4, 0.0)),
                                     Pin("G2", GROUND, (-0.6, 0.0), "aux2", (0.0, 0.0))),
                   redundant=True)


@pytest.mark.parametrize("method", ["dop853", "rkn4"])
def test_a_redundantly_closed_two_dof_five_bar_runs_on_its_independent_rows_and_agrees_with_the_oracle(method):
    """The chart runs on the n − k = 5 independent of the 6 loop rows (7 body angles), chosen at the start;
    the dropped row stays closed (checked at every sample, to DROPPED_TOL 1e-9 m); both inputs agree
    with the oracle (its KKT system on an orthonormal basis of the pins' rows: they are dependent)
    to Q_TOL, RATE_TOL and the energy balances to 1e-9, by DOP853 and by RKN4 at 1 ms. Measured:
    DOP853 3.5e-12 rad, 3.5e-11 rad/s, energy 1.7e-12; RKN4 1.2e-11 rad, 3.1e-10 rad/s, energy
    7.0e-11; the oracle's own 4.6e-12 rad, 4.5e-11 rad/s; aux2 turns with the left crank to 2e-16
    rad. (Over 0.8 s the cranks pass π at 0.33 s, where the parallelogram lies flat and its rows
    lose rank: the engine stays on its branch, energy 8e-11, but the oracle's unstabilized rows
    cannot: the horizon stops short of it.)"""
    from loopcheck.reduced.settings import ReducedSettings

    scene = redundant_five_bar_scene(horizon=0.25)  # before the cranks lie flat (π at 0.33 s)
    settings = ReducedSettings(method=method) if method == "dop853" else ReducedSettings(method=method, step=1e-3)
    result = loopcheck.simulate(scene, settings)
    (left, _), (right, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    model = redundant_five_bar()
    q0, qd0 = model.assemble({"left_crank": 1.8, "left_arm": 0.8, "right_arm": 2.3, "right_crank": 1.3,
                              "coupler": 0.0, "aux1": 1.8, "aux2": 1.8},
                             {"left_crank": 1.8, "right_crank": 1.3}, {"left_crank": 0.5, "right_crank": -0.3})
    run, accuracy = oracle_simulate(model, q0, qd0, t)
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    for body, tr in (("left_crank", left), ("right_crank", right)):
        assert np.max(np.abs(run.angle(model, body) - tr.q[idx])) < Q_TOL, body
        assert np.max(np.abs(run.rate(model, body) - tr.qdot[idx])) < RATE_TOL, body
    assert np.ptp(left.q) > 0.1
    # the dropped pin stays closed: aux2 turns with the crank (a parallelogram)
    names = result.joints.names
    assert np.max(np.abs(result.joints.x[:, names.index("aux2.angle")] - left.q)) < 1e-9
    assert result.audit.relative_residual < 1e-9


def test_a_redundant_loops_dropped_row_that_opens_fails_the_run_with_its_time():
    """check_dropped at every sample: the dropped row (one of the 6 loop rows; the 5 others
    select) opened to 9e-9 m (aux1 turned by 1e-7 rad off the parallelogram from the sample at 0.1 s) fails "singular" in one line naming the row, the gap and
    the time (the selection lost rank there); the run's own samples pass. Plant: check_dropped
    returning at once fails this test."""
    from loopcheck.errors import NumericalFailure
    from loopcheck.reduced import several

    scene = redundant_five_bar_scene(horizon=0.2)
    run = several.run_several(scene)
    model = several.SeveralModel(scene)
    model.select_rows(np.array(scene.x0))
    assert len(model.dropped) == 1 and len(model.select) == model.system.n - 2
    t, x = run.joints.t, np.array(run.joints.x)
    several.check_dropped(model, t, x)  # the run's samples: closed
    i = int(np.searchsorted(t, 0.1))
    x[i:, run.joints.names.index("aux1.angle")] += 1e-7  # the dropped row: the loop through aux1's pins
    with pytest.raises(NumericalFailure) as failed:
        several.check_dropped(model, t, x)
    message = str(failed.value)
    assert failed.value.reason.value == "singular" and failed.value.time == t[i] and "\n" not in message
    assert f"t = {t[i]:.9g} s" in message and "lost rank" in message


KP, KV, TARGET, LIMIT = 40.0, 2.0, 2.4, 6.0  # the left servo: N·m/rad, N·m·s/rad, rad, N·m
SERVO_OLD = '''name = "left_motor"
joint = "O1"
[actuators.control]          # the torque (N·m)
type = "pulse"
value = 8.0
start = 0.0
duration = 0.3
'''
SERVO_NEW = '''name = "left_motor"
joint = "O1"
gain = {kp}
bias = [0.0, {mkp}, {mkv}]
forcerange = [{lo}, {hi}]
[actuators.control]
type = "{control}"
value = {target}
{timing}'''


@pytest.mark.parametrize("control", ["constant", "pulse"])
def test_a_two_dof_five_bar_with_a_clamped_position_servo_agrees_with_the_oracle(control):
    """The left motor a position servo (gain kp, bias [0, −kp, −kv], target 2.4 rad) whose force
    −6 … 6 N·m clamps: it starts at its upper bound (f_u = 23 N·m) and leaves it as the crank
    nears the target. The clamp's mode switches at the chart's stop event (CLAMP_HYSTERESIS, as
    the one-DOF engine), the run going on in the same coordinates; both inputs agree with the
    oracle given the same clamped law (its own code: τ(t, u, u̇)) to Q_TOL, RATE_TOL, and the
    energy (the servo's work by its power) balances to 1e-9. Measured (constant target): the modes
    switch at 0.110 s (hi → free) and 0.168 s (free → lo; f_u then falls to −206 N·m), one
    coordinate switch at 0.497 s; 5.2e-12 rad and 9.1e-11 rad/s from the oracle (its own accuracy
    at rtol 5e-14, 4.9e-13 rad and 1.0e-11 rad/s: at its default 1e-12 the clamp's kinks, which it
    does not locate, leave it 8e-10 rad); energy 3.9e-12. With the target a pulse (2.4 rad from
    0.2 s to 0.5 s, 0 besides: the force steps past its bounds at load edges, where the modes are
    set anew), scipy's DOP853 on the same chart ends where the compiled run does to 1e-12 rad (3.3
    rad off before its pieces' modes were set at their starts). Plant: the clamp margin left out of
    the chart's stop event (the modes never switch): 1.19 rad off."""
    from loopcheck.api import scene_from_string
    from loopcheck.reduced.settings import ReducedSettings

    text = FIVE_BAR.read_text()
    assert SERVO_OLD in text
    timing = "start = 0.2\nduration = 0.3\n" if control == "pulse" else ""
    scene = scene_from_string(text.replace(SERVO_OLD, SERVO_NEW.format(
        kp=KP, mkp=-KP, mkv=-KV, lo=-LIMIT, hi=LIMIT, control=control, target=TARGET, timing=timing)))
    result = loopcheck.simulate(scene)
    (left, _), (right, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    base = five_bar()
    target = pulse(TARGET, 0.2, 0.3) if control == "pulse" else (lambda _: TARGET)
    servo = Torque("O1", lambda t, u, rate: float(np.clip(KP * (target(t) - u) - KV * rate, -LIMIT, LIMIT)),
                   state=True)
    model = replace(base, torques=(servo, base.torques[1]),
                    edges=(0.1, 0.2, 0.3, 0.4, 0.5) if control == "pulse" else base.edges)
    q0, qd0 = model.assemble(*FIVE_BAR_START)
    run, accuracy = oracle_simulate(model, q0, qd0, t, rtol=5e-14)
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    for body, tr in (("left_crank", left), ("right_crank", right)):
        assert np.max(np.abs(run.angle(model, body) - tr.q[idx])) < Q_TOL, body
        assert np.max(np.abs(run.rate(model, body) - tr.qdot[idx])) < RATE_TOL, body
    force = KP * (np.array([target(s) for s in left.t]) - left.q) - KV * left.qdot
    assert np.max(force) > LIMIT and np.min(force) < -LIMIT  # the force clamps at both bounds
    assert result.audit.relative_residual < 1e-9
    if control == "pulse":
        scipy_run = loopcheck.simulate(scene, ReducedSettings(method="scipy-dop853"))
        assert abs(scipy_run.inputs[0][0].q[-1] - left.q[-1]) < 1e-12


@pytest.mark.parametrize("friction", [0.3, 2.0])
def test_a_two_dof_five_bar_with_joint_friction_slipping_agrees_with_the_oracle(friction):
    """Coulomb friction on the elbow A of the five-bar robot (its force −f s on the joint's relative
    angle, s = ±1 the way it slips, the run's mode), the rate's zero the chart's stop event: at it
    the joint slips on the way its acceleration takes it against the friction. Both inputs agree
    with the oracle given the same law (τ = −f sign(u̇) across its pin A) to Q_TOL, RATE_TOL and
    the energy (the friction's f |u̇| among the dissipation) balances to 1e-9. Measured (f = 0.3,
    2.0 N·m; one reversal each): 6.8e-11, 1.0e-10 rad and 1.1e-9, 8.5e-10 rad/s from the oracle
    (its own accuracy at rtol 5e-14, 3.5e-12 rad and 6.0e-11 rad/s; it does not locate the
    friction's jump, the engine does); energy 7.6e-12, 9.3e-12 (2.1 J, 12.5 J dissipated).
    Plant: the friction's work left out of the dissipation: the energy fails."""
    from loopcheck.api import scene_from_string

    text = FIVE_BAR.read_text().replace(
        "[simulation]", f'[[joint_frictions]]\nname = "rub"\njoint = "A"\nfriction = {friction}\n\n[simulation]')
    result = loopcheck.simulate(scene_from_string(text))
    (left, _), (right, _) = result.inputs
    t, idx = np.unique(left.t, return_index=True)
    base = five_bar()
    rub = Torque("A", lambda t, u, rate: -friction * float(np.sign(rate)), state=True)
    model = replace(base, torques=base.torques + (rub,))
    q0, qd0 = model.assemble(*FIVE_BAR_START)
    run, accuracy = oracle_simulate(model, q0, qd0, t, rtol=5e-14)
    names = result.joints.names
    u_rate = result.joints.xdot[:, names.index("left_arm.angle")] - result.joints.xdot[:, names.index("left_crank.angle")]
    errors = [(np.max(np.abs(run.angle(model, body) - tr.q[idx])), np.max(np.abs(run.rate(model, body) - tr.qdot[idx])))
              for body, tr in (("left_crank", left), ("right_crank", right))]
    assert int(np.sum(np.diff(np.sign(u_rate)) != 0)) == 1  # the elbow reverses once, slipping through
    assert accuracy[0] < Q_TOL / 3 and accuracy[1] < RATE_TOL / 3
    for q_error, rate_error in errors:
        assert q_error < Q_TOL and rate_error < RATE_TOL
    assert result.audit.relative_residual < 1e-9
