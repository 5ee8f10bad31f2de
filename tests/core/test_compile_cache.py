"""compile_linkage compiles each Linkage object once (loopcheck.kinematics._SYSTEMS): a scene
file's assembly and the reduced engine's model share the system; another linkage object, of
the same structure with another geometry, or made after the first is gone (its id reused),
never gets the first one's system. Compared exactly with a fresh compilation: the cache may
only return what compiling would."""

from __future__ import annotations

import gc

import numpy as np

from loopcheck import kinematics
from loopcheck.kinematics import compile_linkage

from test_mechanism import four_bar


def same_system(a, b) -> bool:
    """The tables and rows of two systems equal exactly."""
    tables = ("loops", "points", "centres")
    arrays = ("linear", "drive", "mode_pairs", "joint_rows")
    return (all(np.array_equal(getattr(getattr(a, t), f), getattr(getattr(b, t), f))
                for t in tables for f in ("offset", "row", "coef", "mag", "angle", "phase"))
            and all(np.array_equal(getattr(a, f), getattr(b, f)) for f in arrays)
            and a.coordinate_names == b.coordinate_names and a.point_names == b.point_names)


def test_one_linkage_is_compiled_once():
    linkage = four_bar()
    assert compile_linkage(linkage) is compile_linkage(linkage)


def test_another_geometry_of_the_same_structure_is_compiled_on_its_own():
    first, second = four_bar((0.3, 1.0, 0.8, 0.9)), four_bar((0.35, 1.1, 0.75, 0.95))
    a, b = compile_linkage(first), compile_linkage(second)
    assert a is not b
    assert same_system(a, kinematics._compile_linkage(first))
    assert same_system(b, kinematics._compile_linkage(second))
    assert not same_system(a, b)


def test_a_linkage_made_after_another_is_gone_is_compiled_on_its_own():
    # CPython often gives the new linkage the dead one's id: the cache's key; its entry goes
    # with the linkage, and a look-up checks the linkage itself
    for k in range(20):
        lengths = (0.3 + 0.001 * k, 1.0, 0.8, 0.9)
        linkage = four_bar(lengths)
        assert same_system(compile_linkage(linkage), kinematics._compile_linkage(four_bar(lengths)))
        del linkage
        gc.collect()
    assert not any(ref() is None for ref, _ in kinematics._SYSTEMS.values())
