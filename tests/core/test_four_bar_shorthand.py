"""The four-bar shorthand against the general planar description of the same bodies.

A grounded link of the shorthand may be given by its inertia about its fixed pivot with its
mass and centre of mass; the parser turns that into the inertia about the centre of mass by the
parallel-axis theorem, I_G = I_O − m |com|². Here the same linkage is written in the general
form with the centroidal inertias worked out by hand below, so a slip in the shorthand's
conversion (the sign of m |com|², the pivot's position) shows as different bodies and a
different motion. Both engines read the parsed inertia, so comparing the engines cannot see it.
"""

from __future__ import annotations

import numpy as np

from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import scene_from_dict

GRAVITY = [0.0, -9.81]  # gravity makes the masses and centres of mass matter as well as the inertias
SHORTHAND = {
    "gravity": GRAVITY,
    "linkage": {"type": "four_bar", "c1": 0.5, "c2": 0.9, "c3": 0.7, "c4": 1.0, "branch": 1},
    "bodies": {"crank": {"pivot_inertia": 1.5, "mass": 2.0, "com": [0.25, 0.05]},
               "coupler": {"mass": 40.0, "inertia": 5.0, "com": [0.5111, 0.1333]},
               "rocker": {"pivot_inertia": 3.5, "mass": 4.0, "com": [0.35, -0.04]}},
    "torque": {"type": "pulse", "value": 250.0, "start": 0.0, "duration": 0.5},
    "initial": {"q": 0.2},
    "simulation": {"horizon": 0.8},
}
# I_G = I_O − m (x² + y²), by hand:
CRANK_IG = 1.5 - 2.0 * (0.25 ** 2 + 0.05 ** 2)  # 1.5 − 2·0.065 = 1.37 kg·m²
ROCKER_IG = 3.5 - 4.0 * (0.35 ** 2 + 0.04 ** 2)  # 3.5 − 4·0.1241 = 3.0036 kg·m²


def _planar(guess: dict) -> dict:
    """The same linkage in the general form: frames as the shorthand's (crank at O1 along O1→A,
    coupler at A along A→B, rocker at O3 along O3→B), centroidal inertias by hand."""
    return {
        "gravity": GRAVITY,
        "linkage": {"type": "planar", "input": "O1"},
        "bodies": {"ground": {"points": {"O1": [0.0, 0.0], "O3": [1.0, 0.0]}},
                   "crank": {"points": {"O1": [0.0, 0.0], "A": [0.5, 0.0]}, "mass": 2.0, "com": [0.25, 0.05],
                             "inertia": CRANK_IG},
                   "coupler": {"points": {"A": [0.0, 0.0], "B": [0.9, 0.0]}, "mass": 40.0,
                               "com": [0.5111, 0.1333], "inertia": 5.0},
                   "rocker": {"points": {"O3": [0.0, 0.0], "B": [0.7, 0.0]}, "mass": 4.0, "com": [0.35, -0.04],
                              "inertia": ROCKER_IG}},
        "joints": [{"name": "O1", "type": "revolute", "a": "ground.O1", "b": "crank.O1"},
                   {"name": "A", "type": "revolute", "a": "crank.A", "b": "coupler.A"},
                   {"name": "B", "type": "revolute", "a": "coupler.B", "b": "rocker.B"},
                   {"name": "O3", "type": "revolute", "a": "ground.O3", "b": "rocker.O3"}],
        "torque": SHORTHAND["torque"],
        "initial": {"q": 0.2, "guess": guess, "mode": [1]},
        "simulation": SHORTHAND["simulation"],
    }


def _scenes():
    shorthand = scene_from_dict(SHORTHAND)
    x0 = dict(zip(("crank", "coupler", "rocker"), shorthand.x0))
    planar = scene_from_dict(_planar({"coupler": x0["coupler"], "rocker": x0["rocker"]}))
    return shorthand, planar


def test_the_shorthand_bodies_are_the_planar_bodies():
    """Same mass, centre of mass and centroidal inertia, to round-off (rel 1e-15: one subtraction)."""
    shorthand, planar = _scenes()
    a, b = shorthand.mechanism.linkage.body_map, planar.mechanism.linkage.body_map
    for name in ("crank", "coupler", "rocker"):
        assert a[name].mass == b[name].mass and a[name].com == b[name].com, name
        assert abs(a[name].inertia - b[name].inertia) <= 1e-15 * b[name].inertia, (name, a[name].inertia)
    assert np.allclose(shorthand.x0, planar.x0, rtol=0.0, atol=1e-12)


def test_the_shorthand_moves_as_the_planar_description():
    """DOP853 at rtol 1e-12 on both over 0.8 s: the same equation, so the same steps. Measured max
    |Δq| 7.1e-15 rad, |Δq̇| 6.0e-14 rad/s, Δ peak 7e-15 rad/s (round-off); bounds 1e-12 rad,
    1e-11 rad/s and 1e-11 rad/s, the runs' own accuracy, in case a last bit moves a step. The
    parallel-axis sign flipped (I_O + m |com|²) moves q by 0.36 rad and the peak by 0.89 rad/s."""
    shorthand, planar = _scenes()
    settings = ReducedSettings(method="dop853", rtol=1e-12)
    a, b = simulate(shorthand, settings), simulate(planar, settings)
    q_b, v_b, _ = b.trajectory.interpolate(a.trajectory.t)
    assert np.max(np.abs(a.trajectory.q - q_b)) < 1e-12
    assert np.max(np.abs(a.trajectory.qdot - v_b)) < 1e-11
    assert abs(a.peak.omega - b.peak.omega) < 1e-11
