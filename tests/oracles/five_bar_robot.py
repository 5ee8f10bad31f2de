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
