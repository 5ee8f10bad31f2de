"""The two-motor five-bar robot of scenes/mechanisms/five_bar_robot.toml in the multibody oracle
(:mod:`oracles.multibody`; ``five_bar()`` of tests/reduced/test_multibody_oracle.py describes the
same robot from its own physics), started from the scene's initial state: every input's angle and
rate at given times, for the tests of the engines on several degrees of freedom (not shipped)."""

from __future__ import annotations

import os

import numpy as np

from oracles.multibody import simulate

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "mechanisms", "five_bar_robot.toml")
BODIES = {"O1": "left_crank", "O5": "right_crank"}  # each input joint: the crank it turns against the ground
NAMES = ("left_crank", "left_arm", "right_arm", "right_crank")  # the scene's coordinates, in its order


def start(scene, model, rates=None) -> tuple[np.ndarray, np.ndarray]:
    """The oracle's (q, q̇) at the scene's assembled pose with every input at its initial value and
    rate (or at ``rates``, in the inputs' order)."""
    return model.assemble(dict(zip(NAMES, scene.x0)), dict(zip(BODIES.values(), scene.initial_q())),
                          dict(zip(BODIES.values(), scene.initial_qdot() if rates is None else rates)))


def inputs_at(scene, times, rtol: float) -> tuple[dict, tuple[float, float]]:
    """Every input's (q, q̇) at ``times`` (sorted) by the oracle at ``rtol``, by input name, and the
    oracle's accuracy (its rtol-halving differences: rad, rad/s)."""
    from reduced.test_multibody_oracle import five_bar

    model = five_bar()
    run, accuracy = simulate(model, *start(scene, model), np.asarray(times, dtype=float), rtol=rtol)
    return {name: (run.angle(model, body), run.rate(model, body)) for name, body in BODIES.items()}, accuracy


def assert_inputs_follow(scene, result, q_tol: float, rate_tol: float) -> None:
    """Every input of ``result`` (a port's run of the five-bar robot ``scene``) recorded on the run's
    grid from its initial state, within ``q_tol`` rad and ``rate_tol`` rad/s of the oracle (whose own
    accuracy must be a hundredth of those), each with its own peak; the two motors' peaks differ."""
    import pytest

    assert len(result.inputs) == len(scene.inputs) == 2
    oracle, accuracy = inputs_at(scene, result.trajectory.t, rtol=1e-10)
    assert accuracy[0] < q_tol / 100 and accuracy[1] < rate_tol / 100
    for name, (trajectory, peak), q0, qdot0 in zip(scene.inputs, result.inputs, scene.initial_q(),
                                                   scene.initial_qdot()):
        np.testing.assert_array_equal(trajectory.t, result.trajectory.t)
        assert trajectory.q[0] == pytest.approx(q0, abs=1e-12) and trajectory.qdot[0] == pytest.approx(qdot0, abs=1e-12)
        q, qdot = oracle[name]
        assert np.max(np.abs(trajectory.q - q)) < q_tol, name
        assert np.max(np.abs(trajectory.qdot - qdot)) < rate_tol, name
        assert peak == trajectory.peak_rate(), name
    assert result.other_inputs[0][1].omega < -3.0 < 7.0 < result.peak.omega  # two different peaks, not one twice
