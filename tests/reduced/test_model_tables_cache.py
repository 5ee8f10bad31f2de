"""The kernel arrays' kinematic part (loopcheck.reduced.dynamics._kinematic_tables: the term tables
of the loops, the centres, the elements' end points and the forces' points, packed with the
kinematics' header, and the closed form's plans) is made once per loop system, moving bodies and
points, and kept with the system: a sweep's variants of one geometry share it. A request for
other points on the same system gets its own; a model built after others equals one built on an
empty cache. Compared exactly with what packing anew gives: the cache may only return that.
(Planted: the key without the end points; a packer copy that shares the cached header: each
fails here.)"""

from __future__ import annotations

import numpy as np

from loopcheck.kinematics import compile_linkage
from loopcheck.reduced import dynamics
from loopcheck.reduced.dynamics import MechanismModel, _kinematic_tables

from helpers import seed_dict
from loopcheck.scenefile import scene_from_dict


def uncached(system, *args):
    """_kinematic_tables(system, *args) made on an empty cache (the system's own put back after)."""
    saved = system.__dict__.pop("_physics_tables", None)
    try:
        return _kinematic_tables(system, *args)
    finally:
        if saved is None:
            system.__dict__.pop("_physics_tables", None)
        else:
            system.__dict__["_physics_tables"] = saved


def same(a, b) -> bool:
    (pa, plans_a), (pb, plans_b) = a, b
    fa, ia = pa.copy().arrays()
    fb, ib = pb.copy().arrays()
    return np.array_equal(fa, fb) and np.array_equal(ia, ib) and plans_a == plans_b


def test_other_points_on_one_system_get_their_own_tables():
    scene = scene_from_dict(seed_dict())
    system = compile_linkage(scene.mechanism.linkage)
    n_moving = len(scene.mechanism.linkage.moving)
    points = len(system.point_names)
    requests = [([0, 1], []), ([1, 0], []), ([0, points - 1], []), ([0, 1], [2]), ([], [])]
    for ends, forces in requests:  # each after the others are in the cache
        _kinematic_tables(system, n_moving, ends, forces)
    for ends, forces in requests:
        assert same(_kinematic_tables(system, n_moving, ends, forces), uncached(system, n_moving, ends, forces))
    first, second = (_kinematic_tables(system, n_moving, *r)[0] for r in requests[:2])
    assert not np.array_equal(first.copy().arrays()[0], second.copy().arrays()[0])  # the ends are in the arrays


def test_a_model_built_after_others_equals_one_built_anew():
    data = seed_dict()
    scenes = []
    for mass in (40.0, 30.0, 50.0):  # one geometry: one system, one cached packing
        data["bodies"]["coupler"]["mass"] = mass
        scenes.append(scene_from_dict(data))
    models = [MechanismModel(s) for s in scenes]
    assert models[0].system is models[1].system
    for scene, model in zip(scenes, models):
        saved = model.system.__dict__.pop("_physics_tables")
        try:
            fresh = dynamics.build_arrays(scene, model.system)
        finally:
            model.system.__dict__["_physics_tables"] = saved
        assert np.array_equal(model.arrays.F, fresh.F) and np.array_equal(model.arrays.I, fresh.I)
    assert not np.array_equal(models[0].arrays.F, models[1].arrays.F)  # the masses are in the arrays
    for key, (packed, _) in models[0].system.__dict__["_physics_tables"].items():  # untouched by the builds
        fresh, _ = uncached(models[0].system, *key[:1], list(key[1]), list(key[2]))
        assert np.array_equal(packed.header, fresh.header) and packed.nf == fresh.nf and packed.ni == fresh.ni
