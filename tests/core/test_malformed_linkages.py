"""Malformed general (``type = "planar"``) linkage descriptions: each is refused with one
SceneError whose message names the key, body or joint at fault and the reason.

Every case is a patch of one small valid planar four-bar (BASE, below): the patch's effect is
the only thing wrong, so the message checked is the one for that fault. One case goes through
the installed ``loopcheck`` entry point (exit 2, one line, no traceback).
"""

from __future__ import annotations

import copy
import tomllib

import pytest

from loopcheck.scene import SceneError
from loopcheck.scenefile import scene_from_dict

# A valid planar four-bar: ground O1 (0,0), O3 (1,0); crank 0.5, coupler 0.9, rocker 0.7.
BASE_TOML = """
name = "base"
[linkage]
type = "planar"
input = "O1"
[bodies.ground]
points = { O1 = [0.0, 0.0], O3 = [1.0, 0.0] }
[bodies.crank]
points = { O1 = [0.0, 0.0], A = [0.5, 0.0] }
pivot_inertia = 1.5
pivot = "O1"
[bodies.coupler]
points = { A = [0.0, 0.0], B = [0.9, 0.0] }
mass = 40.0
com = [0.5, 0.1]
inertia = 5.0
[bodies.rocker]
points = { O3 = [0.0, 0.0], B = [0.7, 0.0] }
pivot_inertia = 3.5
pivot = "O3"
[[joints]]
name = "O1"
type = "revolute"
a = "ground.O1"
b = "crank.O1"
[[joints]]
name = "A"
type = "revolute"
a = "crank.A"
b = "coupler.A"
[[joints]]
name = "B"
type = "revolute"
a = "coupler.B"
b = "rocker.B"
[[joints]]
name = "O3"
type = "revolute"
a = "ground.O3"
b = "rocker.O3"
[torque]
type = "constant"
value = 10.0
[initial]
q = 0.2
guess = { coupler = 0.7, rocker = 1.3 }
mode = [1]
[simulation]
horizon = 1.0
"""
BASE = tomllib.loads(BASE_TOML)


def joint(name, a, b, kind="revolute", **extra) -> dict:
    return dict({"name": name, "type": kind, "a": a, "b": b}, **extra)


def scene(edit) -> dict:
    """A deep copy of BASE changed in place by ``edit``."""
    data = copy.deepcopy(BASE)
    edit(data)
    return data


def _set_joint(data, index, **changes):
    data["joints"][index].update(changes)


def _add_body(data, name, **body):
    data["bodies"][name] = body


def _slider_crank(data):
    """BASE turned into a slider-crank: the rocker replaced by a piston on a prismatic joint."""
    del data["bodies"]["rocker"]
    data["bodies"]["piston"] = {"points": {"P": [0.0, 0.0]}, "mass": 1.0, "com": [0.0, 0.0], "inertia": 0.01}
    data["bodies"]["ground"]["points"]["line"] = [0.0, 0.0]
    data["joints"][2:] = [joint("B", "coupler.B", "piston.P"),
                          joint("cyl", "ground.line", "piston.P", "prismatic", direction=0.0)]
    data["initial"]["guess"] = {"coupler": -0.1, "cyl": 1.3}
    data["initial"]["mode"] = [-1]


def _two_dof(data):  # a five-bar: one more body and joint than a four-bar
    data["bodies"]["rocker"]["points"]["C"] = [0.7, 0.0]
    data["bodies"]["link"] = {"points": {"C": [0.0, 0.0], "D": [0.3, 0.0]}, "mass": 1.0, "com": [0.1, 0.0],
                              "inertia": 0.01}
    data["joints"][3] = joint("O3", "ground.O3", "link.D")
    data["joints"].append(joint("C", "rocker.O3", "link.C"))


def _zero_dof(data):  # a structure: a brace between the coupler and ground
    data["bodies"]["brace"] = {"points": {"E": [0.0, 0.0], "F": [0.5, 0.0]}, "mass": 1.0, "com": [0.2, 0.0],
                               "inertia": 0.01}
    data["bodies"]["coupler"]["points"]["E"] = [0.45, 0.0]
    data["bodies"]["ground"]["points"]["F"] = [0.3, 1.0]
    data["joints"] += [joint("E", "coupler.E", "brace.E"), joint("F", "ground.F", "brace.F")]


def _prismatic_loop(data):
    """BASE plus a wedge: two blocks and three prismatic joints in a loop with ground (Grübler
    still counts one DOF), a loop with no revolute joint to cut."""
    data["bodies"]["ground"]["points"]["rail"] = [0.0, -1.0]
    for name in ("wedge", "block"):
        data["bodies"][name] = {"points": {"S": [0.0, 0.0]}, "mass": 1.0, "com": [0.0, 0.0], "inertia": 0.01}
    data["joints"] += [joint("s1", "ground.rail", "wedge.S", "prismatic", direction=0.0),
                       joint("s2", "wedge.S", "block.S", "prismatic", direction=0.8),
                       joint("s3", "ground.rail", "block.S", "prismatic", direction=1.5707963267948966)]


def _mode_elsewhere(data):
    data["initial"]["guess"] = {"coupler": -1.0, "rocker": -2.0}  # the other assembly (B below)
    data["initial"]["mode"] = [1]


def _torque_on_slider(data):
    _slider_crank(data)
    data["linkage"]["input"] = "cyl"
    data["initial"] = {"q": 1.3, "guess": {"crank": 0.2, "coupler": -0.1}}


CASES = [
    ("unknown_body_in_joint", lambda d: _set_joint(d, 1, b="coupling.A"),
     ["joint 'A'", "unknown body 'coupling'"]),
    ("unknown_point", lambda d: _set_joint(d, 2, a="coupler.C"),
     ["joint 'B'", "body 'coupler' has no point 'C'"]),
    ("disconnected_body", lambda d: _add_body(d, "spare", points={"X": [0.0, 0.0]}, mass=1.0, com=[0.0, 0.0],
                                             inertia=0.1),
     ["body 'spare'", "connected to nothing"]),
    ("two_dof", _two_dof, ["2 degrees of freedom", "not 1"]),
    # Grübler's count 0 is no refusal by itself (a redundant loop may move): this brace does not let
    # the loops close at q = 0.2, and the message says what the count is
    ("zero_dof", _zero_dof, ["'initial.q' = 0.2", "the loops do not close",
                             "0 degrees of freedom by Grübler's count: a structure"]),
    ("loop_cannot_close", lambda d: d["bodies"]["rocker"]["points"].update(B=[0.2, 0.0]),
     ["'initial.q'", "the loops do not close"]),
    ("prismatic_only_loop", _prismatic_loop, ["only prismatic", "s1", "s2", "s3"]),
    ("guess_in_other_mode", _mode_elsewhere,
     ["'initial.guess' assembles in mode [-1]", "'initial.mode' [1]"]),
    ("body_without_mass_or_inertia", lambda d: d["bodies"]["coupler"].update(mass=0.0),
     ["'bodies.coupler.mass'", "positive"]),
    ("massless_body_not_at_fixed_pivot",
     lambda d: d["bodies"].__setitem__("coupler", {"points": {"A": [0.0, 0.0], "B": [0.9, 0.0]},
                                                   "pivot_inertia": 1.0, "pivot": "A"}),
     ["body 'coupler' has no mass", "fixed pivot"]),
    ("duplicate_joint_names", lambda d: _set_joint(d, 2, name="A"), ["duplicate joint name 'A'"]),
    ("joint_to_itself", lambda d: _set_joint(d, 2, b="coupler.A"), ["'joints[2]'", "joint 'B'", "joins body 'coupler' to itself"]),
    ("unknown_key_in_joint", lambda d: _set_joint(d, 0, axis=[0.0, 0.0, 1.0]), ["unknown key 'joints[0].axis'"]),
    ("point_force_table_not_increasing",
     lambda d: d.update(point_forces=[{"point": "coupler.B", "direction": 0.0, "q": [0.0, 2.0, 1.0],
                                       "values": [1.0, 2.0, 3.0]}]),
     ["'point_forces[0].q'", "strictly increasing"]),
    ("torque_on_prismatic_input", _torque_on_slider,
     ["'torque' does not fit the prismatic input joint 'cyl'", "[force]"]),
    ("guess_names_neither", lambda d: d["initial"]["guess"].update(B=0.3),
     ["'initial.guess.B'", "neither"]),
    ("input_joint_unknown", lambda d: d["linkage"].update(input="O2"), ["'linkage.input'", "O2", "not one of the joints"]),
    ("mode_not_signs", lambda d: d["initial"].update(mode=[2]), ["'initial.mode'", "1 or -1"]),
]


def test_the_base_scene_is_valid():
    """Each case below breaks exactly one thing of a valid scene (and the slider-crank variant
    used by two of them is valid too)."""
    s = scene_from_dict(BASE)
    assert s.mode == (1,) and len(s.x0) == 3
    s = scene_from_dict(scene(_slider_crank))
    assert s.mode == (-1,) and s.input_unit == "rad"


@pytest.mark.parametrize("edit, parts", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_a_malformed_linkage_is_refused_with_its_own_message(edit, parts):
    with pytest.raises(SceneError) as info:
        scene_from_dict(scene(edit))
    message = str(info.value)
    assert "\n" not in message
    for part in parts:
        assert part in message, message


def test_the_messages_differ():
    """Twelve or more faults, and no two share a message."""
    messages = set()
    for _, edit, _ in CASES:
        try:
            scene_from_dict(scene(edit))
        except Exception as exc:  # the type is checked case by case above
            messages.add(str(exc))
    assert len(messages) == len(CASES) >= 12


def test_the_cli_refuses_a_malformed_linkage_in_one_line(tmp_path, capsys):
    """`loopcheck reduced bad.toml`: exit 2, one line on stderr naming the file and the joint (in this
    process: an exception would fail the test; the installed entry point's exit 2 with one line
    and no traceback is tests/core/test_scenes.py's subprocess)."""
    from loopcheck.compare.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text(BASE_TOML.replace('b = "coupler.A"', 'b = "coupling.A"'), encoding="utf-8")
    assert main(["reduced", str(bad)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    assert str(bad) in lines[0] and "joint 'A'" in lines[0] and "unknown body 'coupling'" in lines[0]
