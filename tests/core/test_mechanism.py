"""The general linkage description: value types, joint graph, and malformed descriptions.

The builders here (seed four-bar, offset slider-crank, Watt II six-bar) are reused by
test_loops.py.
"""

from __future__ import annotations

import math

import pytest

from loopcheck.mechanism import (GROUND, Body, Linkage, MechanismError, PrismaticJoint,
                               RevoluteJoint)

SEED = (0.5, 0.9, 0.7, 1.0)  # c1 (crank), c2 (coupler), c3 (rocker), c4 (ground), m


def four_bar(c=SEED, input_joint="O1"):
    """The seed four-bar O1-A-B-O3: each link's frame has its x axis along the link."""
    c1, c2, c3, c4 = c
    return Linkage(
        bodies=[Body(GROUND, {"O1": (0.0, 0.0), "O3": (c4, 0.0)}),
                Body("crank", {"O1": (0.0, 0.0), "A": (c1, 0.0)}),
                Body("coupler", {"A": (0.0, 0.0), "B": (c2, 0.0)}),
                Body("rocker", {"O3": (0.0, 0.0), "B": (c3, 0.0)})],
        joints=[RevoluteJoint("O1", GROUND, "O1", "crank", "O1"),
                RevoluteJoint("A", "crank", "A", "coupler", "A"),
                RevoluteJoint("B", "coupler", "B", "rocker", "B"),
                RevoluteJoint("O3", GROUND, "O3", "rocker", "O3")],
        input_joint=input_joint)


def slider_crank(r=0.1, l=0.35, e=0.03, input_joint="crank"):
    """Offset slider-crank: crank O→A (r), rod A→B (l), B slides on the line y = e."""
    return Linkage(
        bodies=[Body(GROUND, {"O": (0.0, 0.0), "line": (0.0, e)}),
                Body("crank", {"O": (0.0, 0.0), "A": (r, 0.0)}),
                Body("rod", {"A": (0.0, 0.0), "B": (l, 0.0)}),
                Body("slider", {"pin": (0.0, 0.0)})],
        joints=[RevoluteJoint("crank", GROUND, "O", "crank", "O"),
                RevoluteJoint("crank_pin", "crank", "A", "rod", "A"),
                RevoluteJoint("wrist_pin", "rod", "B", "slider", "pin"),
                PrismaticJoint("slide", GROUND, "line", 0.0, "slider", "pin")],
        input_joint=input_joint)


def inverted_slider_crank(r=0.3, d=0.5, line_on_rocker=True):
    """Inverted slider-crank (the core of a crank-and-slotted-lever drive): crank O→A (r), a block
    pinned at A slides along a rocker turning about O2 = (d, 0). The slide is declared with
    the line in the rocker (s = |A − O2|) or, reversed, in the block (s = −|A − O2|)."""
    slide = (PrismaticJoint("slide", "rocker", "O2", 0.0, "block", "A") if line_on_rocker
             else PrismaticJoint("slide", "block", "A", 0.0, "rocker", "O2"))
    return Linkage(
        bodies=[Body(GROUND, {"O": (0.0, 0.0), "O2": (d, 0.0)}),
                Body("crank", {"O": (0.0, 0.0), "A": (r, 0.0)}),
                Body("rocker", {"O2": (0.0, 0.0)}),
                Body("block", {"A": (0.0, 0.0)})],
        joints=[RevoluteJoint("O", GROUND, "O", "crank", "O"),
                RevoluteJoint("O2", GROUND, "O2", "rocker", "O2"),
                slide,
                RevoluteJoint("pin", "crank", "A", "block", "A")],
        input_joint="O")


def watt_ii():
    """Watt II six-bar: the seed four-bar whose rocker (ternary, point D) drives a second
    four-bar D-E-O5 (two loops)."""
    c1, c2, c3, c4 = SEED
    return Linkage(
        bodies=[Body(GROUND, {"O1": (0.0, 0.0), "O3": (c4, 0.0), "O5": (1.6, 0.9)}),
                Body("crank", {"O1": (0.0, 0.0), "A": (c1, 0.0)}),
                Body("coupler", {"A": (0.0, 0.0), "B": (c2, 0.0)}),
                Body("rocker", {"O3": (0.0, 0.0), "B": (c3, 0.0), "D": (0.4, 0.3)}),
                Body("link5", {"D": (0.0, 0.0), "E": (0.8, 0.0)}),
                Body("link6", {"E": (0.0, 0.0), "O5": (0.6, 0.0)})],
        joints=[RevoluteJoint("O1", GROUND, "O1", "crank", "O1"),
                RevoluteJoint("A", "crank", "A", "coupler", "A"),
                RevoluteJoint("B", "coupler", "B", "rocker", "B"),
                RevoluteJoint("O3", GROUND, "O3", "rocker", "O3"),
                RevoluteJoint("D", "rocker", "D", "link5", "D"),
                RevoluteJoint("E", "link5", "E", "link6", "E"),
                RevoluteJoint("O5", "link6", "O5", GROUND, "O5")],
        input_joint="O1")


# Andrews' squeezing mechanism, /work/shared/benchmarks/andrews-testset.md (Hairer & Wanner,
# Solving ODEs II, VII.7; Test Set for IVP Solvers, problem "andrews"), lengths in m.
ANDREWS = dict(d=0.028, e=0.02, rr=0.007, ss=0.035, sc=0.018, sd=0.02, xa=-0.06934,
               ya=-0.00227, xb=-0.03635, yb=0.03273, xc=0.014, yc=0.072, zt=0.04, zf=0.02, u=0.04)


def andrews():
    """Bodies b1…b7 as in the test set; each frame's angle is the test set's absolute angle:
    b1 β, b2 β+Θ, b3 γ, b4 Φ+δ, b5 δ, b6 Ω+ε, b7 ε. Points read off its loop equations:
    P = K − d e(β+Θ) with K = rr e(β) (b1, b2); P = B + R(γ)(0, −ss) (b3, spring point
    D = B + R(γ)(sd, −sc)); P = Q + R(Φ+δ)(0, −e), Q = A + zt e(δ) (b4, b5);
    P = R + zf e(Ω+ε), R = A + R(ε)(0, −u) (b6, b7). Four bodies meet at P: three pins."""
    a = ANDREWS
    return Linkage(
        bodies=[Body(GROUND, {"O": (0.0, 0.0), "A": (a["xa"], a["ya"]), "B": (a["xb"], a["yb"]),
                              "C": (a["xc"], a["yc"])}),
                Body("b1", {"O": (0.0, 0.0), "K": (a["rr"], 0.0)}),
                Body("b2", {"K": (0.0, 0.0), "P": (-a["d"], 0.0)}),
                Body("b3", {"B": (0.0, 0.0), "P": (0.0, -a["ss"]), "D": (a["sd"], -a["sc"])}),
                Body("b4", {"Q": (0.0, 0.0), "P": (0.0, -a["e"])}),
                Body("b5", {"A": (0.0, 0.0), "Q": (a["zt"], 0.0)}),
                Body("b6", {"R": (0.0, 0.0), "P": (a["zf"], 0.0)}),
                Body("b7", {"A": (0.0, 0.0), "R": (0.0, -a["u"])})],
        joints=[RevoluteJoint("O", GROUND, "O", "b1", "O"),
                RevoluteJoint("K", "b1", "K", "b2", "K"),
                RevoluteJoint("B", GROUND, "B", "b3", "B"),
                RevoluteJoint("A5", GROUND, "A", "b5", "A"),
                RevoluteJoint("A7", GROUND, "A", "b7", "A"),
                RevoluteJoint("Q", "b5", "Q", "b4", "Q"),
                RevoluteJoint("R", "b7", "R", "b6", "R"),
                RevoluteJoint("P3", "b2", "P", "b3", "P"),
                RevoluteJoint("P4", "b2", "P", "b4", "P"),
                RevoluteJoint("P6", "b2", "P", "b6", "P")],
        input_joint="O")


# -- graph analysis ----------------------------------------------------------------

def test_four_bar_tree_and_loop():
    lk = four_bar()
    assert lk.moving == ("crank", "coupler", "rocker")
    assert [(e.body, e.joint, e.parent) for e in lk.tree] == [
        ("crank", "O1", GROUND), ("rocker", "O3", GROUND), ("coupler", "A", "crank")]
    assert lk.cut_joints == ("B",)
    assert sorted(lk.loop_of("B")) == ["A", "B", "O1", "O3"]


def test_slider_crank_takes_the_input_then_the_slide_into_the_tree_and_cuts_a_revolute():
    lk = slider_crank()
    assert [e.joint for e in lk.tree[:2]] == ["crank", "slide"]  # the input first, then prismatic
    (cut,) = lk.cut_joints
    assert cut in ("crank_pin", "wrist_pin")  # a revolute: the slide stays in the tree
    assert {e.joint for e in lk.tree} | {cut} == {j.name for j in lk.joints}


def test_slide_input_is_taken_first():
    lk = slider_crank(input_joint="slide")
    assert lk.tree[0].joint == "slide"
    assert lk.cut_joints[0] != "slide"


def test_inverted_slider_crank_hangs_the_block_on_the_slide():
    for line_on_rocker in (True, False):
        lk = inverted_slider_crank(line_on_rocker=line_on_rocker)
        assert [(e.body, e.joint) for e in lk.tree] == [("crank", "O"), ("rocker", "O2"),
                                                        ("block", "slide")]
        assert lk.cut_joints == ("pin",)


def test_watt_ii_has_two_loops_cut_at_revolutes():
    lk = watt_ii()
    assert len(lk.cut_joints) == 2
    assert set(lk.loop_of(lk.cut_joints[0])) | set(lk.loop_of(lk.cut_joints[1])) == {
        j.name for j in lk.joints}


def test_loop_of_a_dyad_between_two_moving_bodies_leaves_out_their_common_path():
    """Watt I: a dyad P-E-Q between the (ternary) crank and coupler. Its loop is
    P, E, Q and the pin A; the crank's pivot O1 is on both tree paths, not in the loop."""
    lk = four_bar()
    bodies = [b for b in lk.bodies if b.name not in ("crank", "coupler")] + [
        Body("crank", {"O1": (0.0, 0.0), "A": (0.5, 0.0), "P": (0.2, 0.2)}),
        Body("coupler", {"A": (0.0, 0.0), "B": (0.9, 0.0), "Q": (0.4, 0.3)}),
        Body("link5", {"P": (0.0, 0.0), "E": (0.3, 0.0)}),
        Body("link6", {"E": (0.0, 0.0), "Q": (0.3, 0.0)})]
    joints = list(lk.joints) + [RevoluteJoint("P", "crank", "P", "link5", "P"),
                                RevoluteJoint("E", "link5", "E", "link6", "E"),
                                RevoluteJoint("Q", "coupler", "Q", "link6", "Q")]
    watt_i = Linkage(bodies, joints, "O1")
    loops = sorted(sorted(watt_i.loop_of(c)) for c in watt_i.cut_joints)
    assert loops == [["A", "B", "O1", "O3"], ["A", "E", "P", "Q"]]


def test_andrews_has_three_loops_closing_at_p():
    lk = andrews()
    assert len(lk.moving) == 7 and len(lk.joints) == 10  # 3·7 − 2·10 = 1
    assert lk.cut_joints == ("P3", "P4", "P6")


def test_body_points_are_read_only_and_converted():
    b = Body("crank", {"A": (1, 2)})
    assert b.points["A"] == (1.0, 2.0)
    with pytest.raises(TypeError):
        b.points["B"] = (0.0, 0.0)


# -- malformed descriptions: each its own one-line message -----------------------------

def _bodies_joints(c=SEED):
    lk = four_bar(c)
    return list(lk.bodies), list(lk.joints)


def _replace_joint(joints, name, new):
    return [new if j.name == name else j for j in joints]


def _unknown_body():
    b, j = _bodies_joints()
    return Linkage(b, _replace_joint(j, "A", RevoluteJoint("A", "crank", "A", "couple", "A")), "O1")


def _unknown_point():
    b, j = _bodies_joints()
    return Linkage(b, _replace_joint(j, "A", RevoluteJoint("A", "crank", "Z", "coupler", "A")), "O1")


def _body_connected_to_nothing():
    b, j = _bodies_joints()
    return Linkage(b + [Body("loose", {"P": (0.0, 0.0)})], j, "O1")


def _disconnected_group():
    # A four-bar plus a pair of bodies pinned to each other twice and to nothing else.
    b, j = _bodies_joints()
    return Linkage(b + [Body("u", {"P": (0.0, 0.0), "Q": (1.0, 0.0)}),
                        Body("v", {"P": (0.0, 0.0), "Q": (1.0, 0.0)})],
                   j + [RevoluteJoint("uvP", "u", "P", "v", "P"),
                        RevoluteJoint("uvQ", "u", "Q", "v", "Q")], "O1")


def _two_dof():
    # A five-bar: ground, crank, two couplers, rocker.
    return Linkage(
        [Body(GROUND, {"O1": (0.0, 0.0), "O4": (1.0, 0.0)}),
         Body("a", {"O": (0.0, 0.0), "P": (0.5, 0.0)}), Body("b", {"O": (0.0, 0.0), "P": (0.5, 0.0)}),
         Body("c", {"O": (0.0, 0.0), "P": (0.5, 0.0)}), Body("d", {"O": (0.0, 0.0), "P": (0.5, 0.0)})],
        [RevoluteJoint("j1", GROUND, "O1", "a", "O"), RevoluteJoint("j2", "a", "P", "b", "O"),
         RevoluteJoint("j3", "b", "P", "c", "O"), RevoluteJoint("j4", "c", "P", "d", "O"),
         RevoluteJoint("j5", "d", "P", GROUND, "O4")], "j1")


def _zero_dof():
    # A triangle truss: two bars pinned to ground and to each other.
    return Linkage(
        [Body(GROUND, {"O1": (0.0, 0.0), "O2": (1.0, 0.0)}),
         Body("a", {"O": (0.0, 0.0), "P": (0.7, 0.0)}), Body("b", {"O": (0.0, 0.0), "P": (0.7, 0.0)})],
        [RevoluteJoint("j1", GROUND, "O1", "a", "O"), RevoluteJoint("j2", GROUND, "O2", "b", "O"),
         RevoluteJoint("j3", "a", "P", "b", "P")], "j1")


def _prismatic_only_loop():
    # A wedge (three sliders in a loop) with a pendulum hung on it: Grübler says 1.
    return Linkage(
        [Body(GROUND, {"O": (0.0, 0.0)}),
         Body("a", {"O": (0.0, 0.0)}), Body("b", {"O": (0.0, 0.0)}),
         Body("p", {"O": (0.0, 0.0), "P": (0.3, 0.0)})],
        [PrismaticJoint("pa", GROUND, "O", 0.0, "a", "O"),
         PrismaticJoint("pb", GROUND, "O", math.pi / 2, "b", "O"),
         PrismaticJoint("ab", "a", "O", math.pi / 4, "b", "O"),
         RevoluteJoint("hinge", "b", "O", "p", "O")], "hinge")


def _duplicate_body():
    b, j = _bodies_joints()
    return Linkage(b + [Body("crank", {"O1": (0.0, 0.0)})], j, "O1")


def _duplicate_joint():
    b, j = _bodies_joints()
    return Linkage(b, j + [RevoluteJoint("A", "crank", "A", "coupler", "A")], "O1")


def _input_missing():
    b, j = _bodies_joints()
    return Linkage(b, j, "O2")


def _joint_to_itself():
    return RevoluteJoint("A", "crank", "A", "crank", "O1")


def _point_not_finite():
    return Body("crank", {"A": (math.nan, 0.0)})


def _point_not_a_pair():
    return Body("crank", {"A": (1.0, 2.0, 3.0)})


def _body_without_points():
    return Body("crank", {})


def _direction_not_finite():
    return PrismaticJoint("s", GROUND, "O", math.inf, "a", "O")


def _no_ground_joint():
    # crank, coupler, rocker pinned in a triangle: connected, but not to ground.
    return Linkage([Body("a", {"P": (0.0, 0.0), "Q": (1.0, 0.0)}),
                    Body("b", {"P": (0.0, 0.0), "Q": (1.0, 0.0)})],
                   [RevoluteJoint("j1", "a", "Q", "b", "P")], "j1")


def _no_moving_body():
    return Linkage([Body(GROUND, {"O": (0.0, 0.0)})], [], "j1")


MALFORMED = {
    "unknown body": (_unknown_body, "joint 'A': unknown body 'couple' (body_b)"),
    "unknown point": (_unknown_point, "joint 'A': body 'crank' has no point 'Z' (point_a)"),
    "body connected to nothing": (_body_connected_to_nothing, "body 'loose' is connected to nothing"),
    "disconnected group": (_disconnected_group, "bodies 'u', 'v' form a group not connected to ground"),
    "two DOF": (_two_dof, "the linkage has 2 degrees of freedom by Grübler's count 3·4 moving bodies − 2·5 joints, not 1"),
    "prismatic-only loop": (_prismatic_only_loop, "has only prismatic joints: no revolute joint to cut it"),
    "duplicate body": (_duplicate_body, "duplicate body name 'crank'"),
    "duplicate joint": (_duplicate_joint, "duplicate joint name 'A'"),
    "input joint missing": (_input_missing, "input joint 'O2' is not one of the joints"),
    "joint to itself": (_joint_to_itself, "joint 'A' joins body 'crank' to itself"),
    "point not finite": (_point_not_finite, "body 'crank': point 'A' must be finite"),
    "point not a pair": (_point_not_a_pair, "body 'crank': point 'A' must be a pair of numbers"),
    "body without points": (_body_without_points, "body 'crank' has no points"),
    "direction not finite": (_direction_not_finite, "joint 's': direction_a must be finite"),
    "no joint to ground": (_no_ground_joint, "no joint connects the linkage to ground"),
    "no moving body": (_no_moving_body, "the linkage has no moving body"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_description_names_its_fault(case):
    build, message = MALFORMED[case]
    with pytest.raises(MechanismError) as info:
        build()
    text = str(info.value)
    assert message in text
    assert "\n" not in text


def test_malformed_messages_are_all_different():
    messages = set()
    for build, _ in MALFORMED.values():
        with pytest.raises(MechanismError) as info:
            build()
        messages.add(str(info.value))
    assert len(messages) == len(MALFORMED)


def test_mechanism_error_is_a_value_error():
    # The CLI maps ValueError to exit 2 (bad input).
    assert issubclass(MechanismError, ValueError)


def test_a_body_pickles_whole():
    """A scene goes to worker processes pickled: every field of a body comes back, its gravity
    compensation too (it was dropped: a worker ran the body with its full weight; planted: fails here)."""
    import pickle

    body = Body("crank", {"O1": (0.0, 0.0), "A": (0.3, 0.0)}, 2.0, (0.1, 0.02), 0.3, gravcomp=0.5)
    back = pickle.loads(pickle.dumps(body))
    assert back == body and back.gravcomp == 0.5 and dict(back.points) == dict(body.points)
