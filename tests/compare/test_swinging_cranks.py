"""Valid scenes with a small input inertia and large torques that swing without running away.

Non-Grashof four-bars whose crank cannot turn fully are driven by torques of hundreds of N·m on
a crank of 0.005–0.05 kg·m² (the issue's example: 150 N·m on 0.02 kg·m², swinging between 0.67
and 4.20 rad at up to 24.8 rad/s). A bound on the motion from the crank's own inertia put such
scenes at ~1e4 rad/s and refused them; they are generated here from a seeded random draw (not
chosen to pass anything) and must be accepted, run, and stay where the linkage can assemble:
for every sample, the distance d(q) = |c1 e(q) − c4 e(0)| between the crank pin and the
rocker's pivot lies in [|c2 − c3|, c2 + c3] (closed form, independent of the solver), to
1e-9 m (the loop closes to ~1e-15 m; the samples are q of the solver, exact to its rtol).
Measured on the draw below: the old bound's impulse term alone (∫|T|dt / I_crank × horizon)
exceeded its 2e4 rad limit on 5 of the 8 (up to 1.2e5 rad); they sweep 0.5–5.8 rad at peaks of
0.8–60 rad/s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopcheck.compare.run import compare_engines
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scene import SceneError
from loopcheck.scenefile import scene_from_dict

N_SCENES = 8
SLACK = 1e-9  # m


def _non_grashof(rng) -> dict | None:
    """A four-bar shorthand scene whose crank swings, or None when the draw does not assemble."""
    while True:
        c1, c2, c3, c4 = rng.uniform(0.3, 1.2, 4)
        s, l = min(c1, c2, c3, c4), max(c1, c2, c3, c4)
        if s + l > c1 + c2 + c3 + c4 - s - l + 0.05 and c1 + c4 > abs(c2 - c3) and abs(c1 - c4) < c2 + c3:
            break  # non-Grashof: no link turns fully
    lo, hi = abs(c2 - c3), c2 + c3
    qs = [q for q in np.linspace(0.0, 2 * np.pi, 721) if lo + 0.02 < math.hypot(c1 * math.cos(q) - c4, c1 * math.sin(q)) < hi - 0.02]
    if not qs:
        return None
    torque = float(rng.choice([-1.0, 1.0]) * rng.uniform(100.0, 600.0))
    data = {
        "name": "swinging", "linkage": {"type": "four_bar", "c1": c1, "c2": c2, "c3": c3, "c4": c4,
                                         "branch": int(rng.choice([-1, 1]))},
        "bodies": {"crank": {"pivot_inertia": float(rng.uniform(0.005, 0.05)), "mass": 0.1,
                             "com": [0.1 * c1, 0.02]},
                   "coupler": {"mass": float(rng.uniform(2.0, 10.0)), "inertia": float(rng.uniform(0.2, 1.0)),
                               "com": [0.5 * c2, -0.1]},
                   "rocker": {"pivot_inertia": float(rng.uniform(1.0, 6.0)), "mass": 5.0, "com": [0.5 * c3, 0.1]}},
        "torque": {"type": "pulse", "value": torque, "start": 0.0, "duration": 0.8},
        "dampers": [{"coefficient": float(rng.uniform(10.0, 100.0)), "ground_point": [c4 / 2, -0.2],
                     "body": "crank", "body_point": [-0.1, 0.1]}],
        "initial": {"q": float(qs[len(qs) // 2]), "qdot": 0.0},
        "simulation": {"horizon": 1.5},
    }
    return data


def _family() -> list[dict]:
    rng = np.random.default_rng(20261126)
    out = []
    while len(out) < N_SCENES:
        data = _non_grashof(rng)
        if data is None:
            continue
        try:
            scene_from_dict(data)
        except SceneError as exc:  # a draw that does not assemble at q0 is not a valid scene
            assert "assemble" in str(exc) or "dead" in str(exc) or "singular" in str(exc), exc
            continue
        out.append(data)
    return out


# The example, refused once with "could move up to 2.52e+04 rad" (the truth: 3.5 rad)
SWINGING_CRANK = {
    "name": "swinging_crank", "linkage": {"type": "four_bar", "c1": 0.4, "c2": 1.0, "c3": 0.75, "c4": 0.35, "branch": 1},
    "bodies": {"crank": {"pivot_inertia": 0.02, "mass": 0.6, "com": [0.07, -0.12]},
               "coupler": {"mass": 8.0, "inertia": 0.9, "com": [0.22, -0.35]},
               "rocker": {"pivot_inertia": 5.5, "mass": 9.0, "com": [0.73, 0.21]}},
    "torque": {"type": "pulse", "value": -150.0, "start": 0.0, "duration": 1.6},
    "dampers": [{"coefficient": 80.0, "ground_point": [0.85, -0.12], "body": "crank", "body_point": [-0.065, 0.11]}],
    "initial": {"q": 3.6, "qdot": 0.0}, "simulation": {"horizon": 2.1},
}
FAMILY = [SWINGING_CRANK] + _family()


@pytest.mark.parametrize("k", range(len(FAMILY)))
def test_a_swinging_crank_is_accepted_and_stays_where_it_assembles(k):
    data = FAMILY[k]
    scene = scene_from_dict(data)
    run = simulate(scene, ReducedSettings())
    L = data["linkage"]
    q = run.trajectory.q
    d = np.hypot(L["c1"] * np.cos(q) - L["c4"], L["c1"] * np.sin(q))
    assert np.all(d >= abs(L["c2"] - L["c3"]) - SLACK) and np.all(d <= L["c2"] + L["c3"] + SLACK)
    assert np.ptp(q) < 2 * np.pi  # it swings: never a whole turn
    assert np.any(np.diff(np.sign(run.trajectory.qdot[1:])) != 0)  # and reverses


@pytest.mark.slow  # ~15 s: MuJoCo's automatic step on three of them
@pytest.mark.parametrize("k", [0, 3, 4])  # the issue's, and two the old bound refused
def test_loopcheck_defaults_pass_their_own_gate_on_a_swinging_crank(k):
    c = compare_engines(scene_from_dict(FAMILY[k]))
    assert c.gate.passed, c.gate.failures
