"""Both engines agree beyond the seed's effects: each variant of the seed scene changes one
thing (a torque profile, a spring or damper on another body, a late pulse, a negative
initial speed, the other assembly branch) and runs through both engines with fixed
settings, so the figures do not depend on any automatic choice of step.

Settings: reduced DOP853 at rtol 1e-12 (the default reference); MuJoCo RK4 at 1 ms, the
step every variant's load edges fall on. Horizon 1 s. Every tolerance below is 3-10x the
difference measured with these settings (listed beside it), and both energy audits (the
relative residual of T + V − W_torque + E_damper) stay under bounds 3-10x their measurements.
"""

from __future__ import annotations

import pytest

from loopcheck.compare.run import compare_engines
from loopcheck.reduced import ReducedSettings
from loopcheck.scene import Tolerances
from loopcheck.reference_models import MujocoSettings

from helpers import seed_dict, variant

REDUCED = ReducedSettings(method="dop853", rtol=1e-12)
MUJOCO = MujocoSettings(integrator="rk4", timestep=1e-3)
HORIZON = {"horizon": 1.0}
SEED_DAMPER = seed_dict()["dampers"][0]


def spring(body: str, point, ground, k: float = 400.0, rest: float = 0.3) -> dict:
    return {"stiffness": k, "rest_length": rest, "ground_point": ground, "body": body, "body_point": point}


def damper(body: str, point, ground, b: float = 30.0) -> dict:
    return {"coefficient": b, "ground_point": ground, "body": body, "body_point": point}


VARIANTS = {
    "constant_torque": dict(torque={"type": "constant", "value": 120.0}),
    "table_torque": dict(torque={"type": "table", "times": [0.0, 0.2, 0.5], "values": [150.0, -80.0, 250.0]}),
    "spring_on_crank": dict(springs=[spring("crank", [0.5, 0.0], [0.0, 0.6])]),
    "spring_on_rocker": dict(springs=[spring("rocker", [0.7, 0.0], [1.6, 0.5])]),
    "damper_on_crank": dict(dampers=[damper("crank", [0.5, 0.0], [0.0, 0.6])]),
    "damper_on_rocker": dict(dampers=[damper("rocker", [0.7, 0.0], [1.6, 0.5])]),
    "late_pulse": dict(torque={"type": "pulse", "value": 250.0, "start": 0.3, "duration": 0.4}),
    "negative_qdot0": dict(initial={"q": 0.2, "qdot": -6.0}),
    "other_branch": dict(linkage={**seed_dict()["linkage"], "branch": -1}),
}

# Measured with the settings above: relative peak difference, max |Δq| (rad), max |Δω|
# (rad/s), max |Δω| at equal q (rad/s), reduced and MuJoCo relative energy residuals.
MEASURED = {
    "constant_torque": (4.40e-6, 5.53e-7, 3.01e-4, 3.00e-4, 1.03e-11, 1.55e-5),
    "table_torque": (8.65e-7, 4.16e-7, 1.93e-4, 1.93e-4, 9.69e-12, 4.18e-6),
    "spring_on_crank": (4.02e-5, 1.10e-5, 2.86e-3, 3.02e-3, 1.88e-11, 3.11e-5),
    "spring_on_rocker": (6.42e-7, 5.09e-6, 1.45e-3, 1.50e-3, 5.02e-12, 2.63e-5),
    "damper_on_crank": (4.30e-6, 4.14e-6, 1.28e-3, 1.33e-3, 1.18e-11, 8.34e-6),
    "damper_on_rocker": (7.42e-6, 4.95e-6, 1.32e-3, 1.36e-3, 5.30e-12, 1.25e-5),
    "late_pulse": (1.67e-6, 4.14e-7, 2.55e-4, 2.55e-4, 2.55e-12, 1.45e-5),
    "negative_qdot0": (3.14e-6, 3.03e-7, 2.61e-4, 2.61e-4, 6.55e-12, 7.49e-6),
    "other_branch": (1.45e-5, 3.15e-6, 1.98e-3, 2.07e-3, 7.05e-12, 9.09e-6),
}
FACTOR = 5.0  # every tolerance and energy bound: 5x its measurement


def test_every_variant_is_measured():
    assert MEASURED.keys() == VARIANTS.keys()


@pytest.mark.parametrize("name", list(VARIANTS))
def test_engines_agree_on_a_seed_variant(name):
    peak, q, omega, omega_vs_q, energy_reduced, energy_mujoco = (FACTOR * m for m in MEASURED[name])
    scene = variant(drop=("tolerances",), simulation=HORIZON, **VARIANTS[name])
    tolerances = Tolerances(peak_omega_rtol=peak, q_atol=q, omega_atol=omega, omega_vs_q_atol=omega_vs_q)
    c = compare_engines(scene, reduced=REDUCED, mujoco=MUJOCO, tolerances=tolerances)
    assert c.gate.passed, c.gate.failures
    assert c.diff.covers_horizon and c.modes.total == 0
    assert not c.other.details.edge_warnings  # every load edge is on the 1 ms grid
    assert c.reference.audit.relative_residual < energy_reduced
    assert c.other.audit.relative_residual < energy_mujoco
    # The variant really has the effect it is about (a dropped load would agree trivially).
    assert set(scene.effects) >= {"torque"} | ({"spring"} if "spring" in name else set())
    if "damper" in name:
        assert scene.mechanism.dampers[0].body_b == name.split("_")[-1]
    if name == "other_branch":
        assert set(map(tuple, c.reference.joints.mode)) == {(-1,)}
