"""The reduced engine in several coordinates (issue 40: loopcheck.reduced.several and its compiled
chart loopcheck.reduced.kernels.several) against the independent full-coordinate oracle
(tests/oracles/multibody.py) and against the one-DOF kernel.

Tolerances (issue 40's targets, absolute): 1e-9 rad on each input's angle and 1e-8 rad/s on its
rate at every output sample. Measured on the five-bar robot over 0.8 s at the defaults (DOP853,
rtol 1e-12; five coordinate switches by the hysteresis rule): 6.8e-11 rad and 7.4e-10 rad/s; the
oracle's own rtol-halving differences 1.3e-11 rad and 1.6e-10 rad/s (below a third of the
tolerances, as tests/reduced/test_multibody_oracle.py asks). Energy balance: 4.0e-11 of the run's
scale (bound 1e-9)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import loopcheck
from loopcheck.scenefile import load_scene

from helpers import ROOT
from oracles.multibody import simulate as oracle_simulate
from test_multibody_oracle import five_bar

Q_TOL, RATE_TOL = 1e-9, 1e-8  # rad, rad/s (module docstring)
FIVE_BAR = ROOT / "tests/data/five_bar_robot.toml"


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
    assert result.audit.relative_residual < 1e-9  # measured 4.0e-11
    assert np.max(np.abs(result.audit.torque_work)) > 1.0  # the motors do work
    assert result.joints.x.shape == (len(result.trajectory.t), 4)
    assert len(result.other_inputs) == 1
    # every joint coordinate satisfies the loop: the end effector P of both arms coincides
    x = result.joints.x
    left = 0.4 * np.exp(1j * x[:, 0]) + 0.7 * np.exp(1j * x[:, 1])
    right = 0.6 + 0.4 * np.exp(1j * x[:, 3]) + 0.7 * np.exp(1j * x[:, 2])
    assert np.max(np.abs(left - right)) < 1e-12
