"""The two forms of ``[linkage]``: the four-bar shorthand is expanded into the general planar
description, and the seed written out in the planar form is the same mechanism and assembly.

Oracles: the four-bar's closed-form assembly (loopcheck.four_bar.FourBar, the seed notes'
formula) for the configuration, and the description written by hand in
scenes/mechanisms/seed_fourbar.toml for the expansion.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.four_bar import FourBar
from loopcheck.shipped_scenes import scenes_dir

from helpers import SEED_SCENE, seed_dict

PLANAR_SEED = scenes_dir() / "mechanisms" / "seed_fourbar.toml"
# Both assemblies are Newton's method converged to round-off from nearby guesses: 1e-12 rad is
# a few hundred ulps of the angles (~1 rad).
SAME_RAD = 1e-12


def planar_dict() -> dict:
    return tomllib.loads(PLANAR_SEED.read_text())


def test_shorthand_and_planar_seed_are_the_same_mechanism():
    short, planar = load_scene(SEED_SCENE), load_scene(PLANAR_SEED)
    a, b = short.mechanism.linkage, planar.mechanism.linkage
    assert [j for j in a.joints] == [j for j in b.joints]
    assert a.input_joint == b.input_joint and a.moving == b.moving
    for name in a.moving:
        ba, bb = a.body_map[name], b.body_map[name]
        assert (ba.mass, ba.com, ba.inertia) == (bb.mass, bb.com, bb.inertia)
        for point in ("O1", "A", "B", "O3"):
            if point in ba.points:
                assert ba.points[point] == bb.points[point]
    (da,), (db,) = short.mechanism.dampers, planar.mechanism.dampers
    assert da.coefficient == db.coefficient
    ends = lambda m, e: (m.linkage.body_map[e.body_a].points[e.point_a], m.linkage.body_map[e.body_b].points[e.point_b])
    assert ends(short.mechanism, da) == ends(planar.mechanism, db)
    assert (short.q0, short.qdot0, short.load, short.effects) == (planar.q0, planar.qdot0, planar.load, planar.effects)
    assert short.four_bar is not None and planar.four_bar is None
    np.testing.assert_allclose(short.x0, planar.x0, rtol=0, atol=SAME_RAD)
    assert short.mode == planar.mode == (1,)


@pytest.mark.parametrize("branch, q0", [(1, 0.2), (-1, 0.2), (1, 2.5), (-1, -1.0)])
def test_shorthand_assembles_on_the_closed_form_branch(branch, q0):
    """x0 = (q, φ1, φ2 + π) of the closed form; the assembly mode names the branch (opposite
    modes on opposite branches)."""
    data = seed_dict()
    data["linkage"]["branch"] = branch
    data["initial"]["q"] = q0
    scene = scene_from_dict(data)
    q, phi1, phi2 = FourBar(scene.four_bar).assemble(q0)
    gap = np.angle(np.exp(1j * (np.array(scene.x0) - [q, phi1, phi2 + math.pi])))
    assert np.max(np.abs(gap)) <= SAME_RAD
    assert scene.mode == (branch,)


def test_planar_guess_chooses_the_assembly_and_mode_checks_it():
    """The other branch's closed-form angles as the guess land on branch −1, mode (−1,); asking
    for mode [1] with that guess is refused, naming both keys."""
    q, phi1, phi2 = FourBar(load_scene(SEED_SCENE).four_bar).assemble(0.2, branch=-1)
    data = planar_dict()
    data["initial"]["guess"] = {"coupler": phi1 + 0.05, "rocker": phi2 + math.pi - 0.05}
    data["initial"].pop("mode")
    scene = scene_from_dict(data)
    assert scene.mode == (-1,)
    np.testing.assert_allclose(scene.x0, [q, phi1, phi2 + math.pi], atol=SAME_RAD)
    data["initial"]["mode"] = [1]
    with pytest.raises(SceneError, match=r"'initial.guess' assembles in mode \[-1\], not the 'initial.mode' \[1\]"):
        scene_from_dict(data)


def test_shorthand_refuses_a_guess():
    data = seed_dict()
    data["initial"]["guess"] = {"coupler": 0.7}
    with pytest.raises(SceneError, match="'initial.guess' and 'initial.mode' are for a planar linkage"):
        scene_from_dict(data)


def test_unknown_linkage_type():
    data = seed_dict()
    data["linkage"]["type"] = "six_bar"
    with pytest.raises(SceneError, match="'linkage.type' must be \"planar\" or \"four_bar\", got \"six_bar\""):
        scene_from_dict(data)
