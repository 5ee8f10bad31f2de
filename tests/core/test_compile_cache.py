"""compile_linkage compiles each Linkage object once (loopcheck.kinematics._SYSTEMS): a scene
file's assembly and the reduced engine's model share the system; another linkage object, of
the same structure with another geometry, or made after the first is gone (its id reused),
never gets the first one's system. Linkage objects of one geometry (a sweep's variants that
change masses) share one system (loopcheck.kinematics._BY_GEOMETRY), but not one with a −0.0
where the other has 0.0. Compared exactly with a fresh compilation: the cache may only return
what compiling would. (Planted: the geometry key with the masses; no −0.0 check: each fails
here.)"""

from __future__ import annotations

import gc

import numpy as np

from loopcheck import kinematics
from loopcheck.kinematics import compile_linkage
from loopcheck.mechanism import Body, Linkage

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


def _with(linkage, body: str, **changes) -> Linkage:
    """``linkage`` with body ``body``'s mass properties or points replaced."""
    bodies = [Body(b.name, changes.get("points", dict(b.points)), changes.get("mass", b.mass),
                   changes.get("com", b.com), changes.get("inertia", b.inertia)) if b.name == body else b
              for b in linkage.bodies]
    return Linkage(bodies, linkage.joints, linkage.input_joint)


def test_linkages_of_one_geometry_share_a_system_whatever_their_masses():
    base = four_bar((0.31, 1.02, 0.83, 0.94))
    heavy = _with(base, "coupler", mass=7.0, inertia=0.2)
    assert heavy != base
    system = compile_linkage(base)
    assert compile_linkage(heavy) is system
    assert same_system(system, kinematics._compile_linkage(heavy))
    # another centre of mass or another point is another geometry
    moved = _with(base, "coupler", mass=7.0, com=(0.4, 0.1))
    longer = _with(base, "coupler", points={"A": (0.0, 0.0), "B": (1.03, 0.0)})
    for other in (moved, longer):
        assert compile_linkage(other) is not system
        assert same_system(compile_linkage(other), kinematics._compile_linkage(other))


def test_a_negative_zero_is_not_shared_with_a_zero():
    """−0.0 == 0.0 as a key, not to the bit: the two compile apart, each as compiling gives it."""
    plus = _with(four_bar((0.32, 1.01, 0.84, 0.93)), "coupler", points={"A": (0.0, 0.0), "B": (1.01, 0.0)})
    minus = _with(plus, "coupler", points={"A": (0.0, 0.0), "B": (1.01, -0.0)})
    a, b = compile_linkage(plus), compile_linkage(minus)
    assert a is not b
    fresh = kinematics._compile_linkage(minus)
    for t in ("loops", "points"):
        for f in ("offset", "coef", "phase"):
            assert getattr(getattr(b, t), f).tobytes() == getattr(getattr(fresh, t), f).tobytes()
    # the bits differ somewhere: a shared system would have been wrong
    assert any(getattr(getattr(a, t), f).tobytes() != getattr(getattr(b, t), f).tobytes()
               for t in ("loops", "points") for f in ("offset", "coef", "phase"))


def test_the_geometry_cache_keeps_its_latest_systems_only():
    for k in range(kinematics.GEOMETRIES + 3):
        compile_linkage(four_bar((0.3 + 0.002 * k, 1.0, 0.8, 0.9)))
    assert len(kinematics._BY_GEOMETRY) <= kinematics.GEOMETRIES


def test_the_same_geometry_with_other_inputs_is_compiled_on_its_own():
    # (a five-bar's export and import hold the same geometry; another choice of inputs has another
    # tree and other input rows: planted, the key without the inputs gave the import's second input
    # as joint A's angle)
    from pathlib import Path

    from loopcheck.scenefile import load_scene

    linkage = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "mechanisms" / "five_bar_robot.toml").mechanism.linkage
    other = Linkage(linkage.bodies, linkage.joints, "O1", inputs=("O1", "A"))
    a, b = compile_linkage(linkage), compile_linkage(other)
    assert a.inputs == ("O1", "O5") and b.inputs == ("O1", "A")
    assert not np.array_equal(a.input_rows, b.input_rows)
