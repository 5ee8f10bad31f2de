"""The four-bar shorthand's assembly is kept for the next scene of the same lengths, branch, q0 and
loop system (loopcheck.scenefile._ASSEMBLIES: a sweep's variants of the masses and dampers share
it, with its assembly mode); a scene that changes any of them is assembled on its own. Compared exactly
with the uncached assembly: the cache may only return what assembling would."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from loopcheck import scenefile
from loopcheck.scenefile import scene_from_dict

from helpers import seed_dict


def fresh(data: dict):
    """The scene assembled without the cache."""
    saved = dict(scenefile._ASSEMBLIES)
    scenefile._ASSEMBLIES.clear()
    try:
        return scene_from_dict(data)
    finally:
        scenefile._ASSEMBLIES.clear()
        scenefile._ASSEMBLIES.update(saved)


def changed(path: str, value) -> dict:
    data = copy.deepcopy(seed_dict())
    table, key = path.split(".")
    data[table][key] = value
    return data


@pytest.mark.parametrize("path, value", [("initial.q", 0.35), ("initial.q", -0.0), ("linkage.c1", 0.45),
                                         ("linkage.c3", 0.75), ("linkage.branch", -1)])
def test_a_scene_that_changes_the_assembly_is_assembled_on_its_own(path, value):
    seed = scene_from_dict(seed_dict())  # the seed's assembly in the cache first
    other = changed(path, value)
    scene, own = scene_from_dict(other), fresh(other)
    x0 = np.array(scene.x0)
    assert np.array_equal(x0, np.array(own.x0)) and scene.mode == own.mode  # its assembly mode is kept with x0
    if path != "initial.q" or value != -0.0:
        assert not np.array_equal(x0, np.array(seed.x0))
    if path == "linkage.branch":
        assert scene.mode != seed.mode


def test_a_variant_of_a_mass_and_a_damper_shares_the_assembly():
    data = changed("bodies.coupler", {**seed_dict()["bodies"]["coupler"], "mass": 44.0})
    data["dampers"][0]["coefficient"] = 61.0
    first = scene_from_dict(seed_dict())
    n = len(scenefile._ASSEMBLIES)
    second = scene_from_dict(data)
    assert len(scenefile._ASSEMBLIES) == n  # no new entry: the same key
    own = fresh(data)
    assert second.x0 == first.x0 and np.array_equal(np.array(second.x0), np.array(own.x0))
    assert second.mode == first.mode == own.mode


def test_the_cache_is_bounded():
    for k in range(scenefile.ASSEMBLY_CACHE + 5):
        scene_from_dict(changed("initial.q", 0.2 + 1e-3 * k))
    assert len(scenefile._ASSEMBLIES) <= scenefile.ASSEMBLY_CACHE
