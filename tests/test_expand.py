"""The four-bar shorthand expanded into the general description gives today's numbers.

Oracles, independent of reduced/expand.py and reduced/loops.py: the four-bar closed form
(reduced.linkage.FourBar: positions and K, L of its own phasor sums) and the Eksergian
coefficients of reduced.dynamics.MechanismModel (its own mass terms).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from reduced import MechanismModel, load_scene
from reduced.expand import COM, four_bar_elements, four_bar_linkage, four_bar_masses
from reduced.linkage import FourBar
from reduced.loops import coefficients, point_kinematics

from helpers import SEED_SCENE, seed_dict, variant

QS = np.linspace(0.0, 2 * np.pi, 73)[:-1]  # a full crank revolution, every 5°
# Round-off of two exact computations of O(1) quantities (closed form against Newton's
# polished solution): measured worst 2.9e-15 for points and rates over a revolution on both
# branches; 1e-14 is 3.4x that.
ROUND_OFF = 1e-14
# 𝔍 is 15-30 kg·m² here: measured worst |Δ𝔍| 2.0e-14 kg·m² (7e-16 relative) over a
# revolution; 1e-13 is 5x that, within the 1e-12 ("the same numbers as today").
INERTIA_ATOL = 1e-13


def rich_scene(branch=1):
    """The seed with masses on every link, gravity, a damper on the crank and a spring on the
    rocker besides the seed's damper on the coupler: every kind of point the expansion adds."""
    data = seed_dict()
    data["linkage"]["branch"] = branch
    data["gravity"] = [0.0, -9.81]
    data["bodies"] = {"crank": {"mass": 2.0, "inertia": 0.05, "com": [0.25, 0.01]},
                      "coupler": {"mass": 40.0, "inertia": 5.0, "com": [0.5111, 0.1333]},
                      "rocker": {"mass": 3.0, "inertia": 0.12, "com": [0.35, 0.02]}}
    data["dampers"].append({"coefficient": 7.0, "ground_point": [-0.3, 0.4], "body": "crank",
                            "body_point": [0.3, -0.05]})
    data["springs"] = [{"stiffness": 300.0, "rest_length": 0.5, "ground_point": [1.2, 0.8],
                        "body": "rocker", "body_point": [0.6, 0.1]}]
    return variant(**{k: data[k] for k in ("linkage", "gravity", "bodies", "dampers", "springs")})


def with_q0(scene, q0):
    return dataclasses.replace(scene, q0=float(q0))


def closed_form_point(fb, ref, body, local):
    """(r, K_r, L_r) of a body point through linkage.py's own phasor sums."""
    e = np.array(fb.bodies[body].point(local).evaluate(ref.x, ref.K, ref.L))
    return e[0:2], e[2:4], e[4:6]


@pytest.mark.parametrize("branch", [1, -1])
def test_points_match_the_closed_form_over_a_revolution(branch):
    scene = rich_scene(branch)
    fb = FourBar(scene.linkage)
    # (body, point name in the expansion, point in the closed form's body frame)
    checked = [("rocker", "B", (scene.linkage.c3, 0.0)), ("coupler", "B", (scene.linkage.c2, 0.0)),
               ("crank", "A", (scene.linkage.c1, 0.0))]
    checked += [(name, COM, b.com) for name, b in scene.bodies.items()]
    checked += [(d.body, f"damper{k}", d.body_point) for k, d in enumerate(scene.dampers)]
    checked += [(s.body, f"spring{k}", s.body_point) for k, s in enumerate(scene.springs)]
    assert len(checked) == 9
    worst = 0.0
    for q in QS:
        _, system, x = four_bar_linkage(with_q0(scene, q))
        ref = fb.kinematics(q)
        K, L = coefficients(system, x)
        r, kr, lr = point_kinematics(system, x, K, L)
        for body, name, local in checked:
            i = system.point_index(body, name)
            for got, want in zip((r[i], kr[i], lr[i]), closed_form_point(fb, ref, body, local)):
                worst = max(worst, float(np.max(np.abs(got - want))))
    assert worst < ROUND_OFF, worst


def test_ground_points_are_the_scene_s():
    scene = rich_scene()
    _, system, x = four_bar_linkage(scene)
    r = point_kinematics(system, x, *coefficients(system, x))[0]
    # Ground points pass through the tables' polar form (hypot, atan2): round-off only.
    want = {"O3": (scene.linkage.c4, 0.0), "damper0": scene.dampers[0].ground_point,
            "damper1": scene.dampers[1].ground_point, "spring0": scene.springs[0].ground_point}
    for name, point in want.items():
        assert np.allclose(r[system.point_index("ground", name)], point, rtol=0.0, atol=ROUND_OFF)
    assert [e.name for e in four_bar_elements(scene)] == ["damper0", "damper1", "spring0"]


def generalized_inertia(system, masses, x):
    """𝔍 = Σ m |K_G|² + I K_ω² from the expanded description (kg·m²)."""
    K, L = coefficients(system, x)
    kr = point_kinematics(system, x, K, L)[1]
    total = 0.0
    for m in masses:
        k_g = kr[system.point_index(m.body, m.point)]
        k_w = K[system.coordinate(f"{m.body}.angle")]
        total += m.mass * float(k_g @ k_g) + m.inertia * k_w * k_w
    return total


@pytest.mark.parametrize("scene", [load_scene(SEED_SCENE), rich_scene(1), rich_scene(-1)],
                         ids=["seed", "rich+", "rich-"])
def test_generalized_inertia_equals_today_s_model(scene):
    model = MechanismModel(scene)
    masses = four_bar_masses(scene)
    worst = 0.0
    for q in QS:
        _, system, x = four_bar_linkage(with_q0(scene, q))
        J = generalized_inertia(system, masses, x)
        worst = max(worst, abs(J - model.coefficients(q).generalized_inertia))
    assert worst < INERTIA_ATOL, worst


def test_seed_masses_use_the_pivot_inertia_where_no_centre_of_mass_is_given():
    masses = {m.body: m for m in four_bar_masses(load_scene(SEED_SCENE))}
    assert (masses["crank"].point, masses["crank"].mass, masses["crank"].inertia) == ("O1", 0.0, 1.5)
    assert (masses["coupler"].point, masses["coupler"].mass) == (COM, 40.0)
    assert (masses["rocker"].point, masses["rocker"].inertia) == ("O3", 3.5)


def test_assembly_is_on_the_scene_s_branch():
    for branch in (1, -1):
        scene = rich_scene(branch)
        _, system, x = four_bar_linkage(scene)
        q, p1, p2 = FourBar(scene.linkage).assemble(scene.q0)
        assert np.allclose(x, [q, p1, p2 + math.pi], rtol=0.0, atol=ROUND_OFF)
        assert x[0] == pytest.approx(scene.q0, abs=ROUND_OFF)
