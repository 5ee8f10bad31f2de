"""Bad scene input as data: each case is a patch of the seed scene (or a file's bytes) and the
text its one-line message must carry. Families: values out of their physical range, derived
quantities out of range, names and descriptions, sizes, and files that are not UTF-8 TOML text.

The ranges are loopcheck.scene.LIMITS, one table for both engines; the corners of that table are
checked against MuJoCo's own compiler below (no mock: the model is built and compiled).
"""

from __future__ import annotations

import dataclasses
import math
import os

import pytest

from loopcheck.compare import cli
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.scene import LIMITS, MAX_NAME_CHARS, MAX_SCENE_BYTES, MAX_TABLE_ENTRIES

from helpers import DELETE, SEED_SCENE, patched

HUGE, TINY = 1e308, 1e-30
SPRING = {"stiffness": 100.0, "rest_length": 0.5, "ground_point": [1.3, 0.12], "body": "coupler",
          "body_point": [0.9, 0.0]}
TABLE = {"type": "table", "times": [0.0, 0.5], "values": [10.0, 0.0]}


def spring(**changes):
    return [dict(SPRING, **changes)]


def out_of_range(key: str, value: float, kind: str) -> str:
    return f"'{key}' = {value:g} is out of range: {kind} must be in {LIMITS[kind].text()}"


# (id, patch of the seed scene, text the message must contain)
RANGE_CASES = [
    ("length_huge", {"linkage.c1": HUGE}, out_of_range("linkage.c1", HUGE, "length")),
    ("length_tiny", {"linkage.c4": TINY}, out_of_range("linkage.c4", TINY, "length")),
    ("com_huge", {"bodies.coupler.com": [HUGE, 0.0]}, out_of_range("bodies.coupler.com[0]", HUGE, "position")),
    ("com_huge_negative", {"bodies.coupler.com": [0.1, -HUGE]},
     out_of_range("bodies.coupler.com[1]", -HUGE, "position")),
    ("ground_point_huge", {"dampers[0].ground_point": [HUGE, 0.0]},
     out_of_range("dampers[0].ground_point[0]", HUGE, "position")),
    ("body_point_huge", {"dampers[0].body_point": [0.0, HUGE]},
     out_of_range("dampers[0].body_point[1]", HUGE, "position")),
    ("mass_huge", {"bodies.coupler.mass": HUGE}, out_of_range("bodies.coupler.mass", HUGE, "mass")),
    ("mass_tiny", {"bodies.coupler.mass": TINY}, out_of_range("bodies.coupler.mass", TINY, "mass")),
    ("inertia_tiny", {"bodies.coupler.inertia": TINY}, out_of_range("bodies.coupler.inertia", TINY, "inertia")),
    ("inertia_huge", {"bodies.coupler.inertia": HUGE}, out_of_range("bodies.coupler.inertia", HUGE, "inertia")),
    ("pivot_inertia_tiny", {"bodies.crank.pivot_inertia": TINY},
     out_of_range("bodies.crank.pivot_inertia", TINY, "inertia")),
    ("pivot_inertia_below_mujoco", {"bodies.rocker.pivot_inertia": 1e-16},
     out_of_range("bodies.rocker.pivot_inertia", 1e-16, "inertia")),
    ("damper_huge", {"dampers[0].coefficient": HUGE}, out_of_range("dampers[0].coefficient", HUGE, "damping")),
    ("damper_tiny", {"dampers[0].coefficient": TINY}, out_of_range("dampers[0].coefficient", TINY, "damping")),
    ("stiffness_huge", {"springs": spring(stiffness=HUGE)}, out_of_range("springs[0].stiffness", HUGE, "stiffness")),
    ("actuator_gain_huge", {"actuators": [{"joint": "O1", "gain": HUGE}]},
     out_of_range("actuators[0].gain", HUGE, "actuator value")),
    ("actuator_control_huge", {"actuators": [{"joint": "O1", "control": {"type": "constant", "value": -HUGE}}]},
     out_of_range("actuators[0].control.value", -HUGE, "actuator value")),
    ("rest_length_huge", {"springs": spring(rest_length=HUGE)},
     out_of_range("springs[0].rest_length", HUGE, "position")),
    ("joint_damper_huge", {"joint_dampers": [{"joint": "B", "coefficient": HUGE}]},
     out_of_range("joint_dampers[0].coefficient", HUGE, "rotational damping")),
    ("joint_stiffness_tiny", {"joint_springs": [{"joint": "B", "stiffness": TINY, "rest_angle": 0.0}]},
     out_of_range("joint_springs[0].stiffness", TINY, "rotational stiffness")),
    ("torque_huge", {"torque.value": HUGE}, out_of_range("torque.value", HUGE, "torque")),
    ("torque_huge_negative", {"torque.value": -HUGE}, out_of_range("torque.value", -HUGE, "torque")),
    ("pulse_start_huge", {"torque.start": HUGE}, out_of_range("torque.start", HUGE, "time")),
    ("pulse_duration_huge", {"torque.duration": HUGE}, out_of_range("torque.duration", HUGE, "time")),
    ("table_time_huge", {"torque": dict(TABLE, times=[0.0, HUGE])}, out_of_range("torque.times[1]", HUGE, "time")),
    ("table_value_huge", {"torque": dict(TABLE, values=[HUGE, 0.0])},
     out_of_range("torque.values[0]", HUGE, "torque")),
    ("q0_huge", {"initial.q": HUGE}, out_of_range("initial.q", HUGE, "angle")),
    ("qdot0_huge", {"initial.qdot": HUGE}, out_of_range("initial.qdot", HUGE, "speed")),
    ("qdot0_huge_negative", {"initial.qdot": -HUGE}, out_of_range("initial.qdot", -HUGE, "speed")),
    ("horizon_huge", {"simulation.horizon": HUGE}, out_of_range("simulation.horizon", HUGE, "horizon")),
    ("horizon_tiny", {"simulation.horizon": 1e-12}, out_of_range("simulation.horizon", 1e-12, "horizon")),
    ("gravity_huge", {"gravity": [0.0, -HUGE]}, out_of_range("gravity[1]", -HUGE, "gravity")),
    ("mujoco_timestep_tiny", {"mujoco": {"timestep": 1e-12}}, out_of_range("mujoco.timestep", 1e-12, "step")),
    ("mujoco_timestep_huge", {"mujoco": {"timestep": HUGE}}, out_of_range("mujoco.timestep", HUGE, "step")),
    ("reduced_step_tiny", {"reduced": {"step": 1e-12}}, out_of_range("reduced.step", 1e-12, "step")),
    ("integer_beyond_float", {"linkage.c1": 10 ** 400}, "'linkage.c1' must be finite, got an integer of about 401 digits"),
]

OTHER_CASES = [
    # derived: the centroidal inertia left by pivot_inertia − mass·|com|² (MuJoCo's I_zz of the body)
    ("centroidal_left_tiny", {"bodies.rocker.pivot_inertia": 0.3 * 0.25 + 1e-12, "bodies.rocker.mass": 0.3,
                              "bodies.rocker.com": [0.5, 0.0]},
     "'bodies.rocker.pivot_inertia' − mass·|com|² = 1.00001e-12 is out of range: inertia must be in [1e-09"),
    ("all_inertias_tiny", {"bodies.crank.pivot_inertia": TINY, "bodies.rocker.pivot_inertia": TINY,
                           "bodies.coupler.inertia": TINY, "bodies.coupler.mass": TINY},
     out_of_range("bodies.crank.pivot_inertia", TINY, "inertia")),
    # names and descriptions stay short, printable plain text
    ("name_1MB", {"name": "x" * 1_000_000}, f"'name' has 1000000 characters; at most {MAX_NAME_CHARS}"),
    ("name_newline", {"name": "two\nlines"}, "'name' must be printable text, got the control character '\\n'"),
    ("name_nul", {"name": "a\x00b"}, "'name' must be printable text, got the control character '\\x00'"),
    ("name_escape", {"name": "\x1b[31mred"}, "'name' must be printable text"),
    ("description_long", {"description": "d" * 5000}, "'description' has 5000 characters"),
    ("name_not_string", {"name": 3}, "'name' must be a string, got an integer"),
    # sizes
    ("timestep_beyond_horizon", {"mujoco": {"timestep": 0.5}, "simulation.horizon": 0.1},
     "'mujoco.timestep' = 0.5 s is longer than 'simulation.horizon' = 0.1 s"),
    ("step_beyond_horizon", {"reduced": {"step": 0.5}, "simulation.horizon": 0.1},
     "'reduced.step' = 0.5 s is longer than 'simulation.horizon' = 0.1 s"),
    ("table_too_long", {"torque": dict(TABLE, times=[float(i) for i in range(MAX_TABLE_ENTRIES + 1)],
                                       values=[1.0] * (MAX_TABLE_ENTRIES + 1))},
     f"'torque.times' has {MAX_TABLE_ENTRIES + 1} entries; at most {MAX_TABLE_ENTRIES}"),
    # gravity needs every moving link's mass and centre of mass: name both missing keys
    ("gravity_coupler_without_com", {"gravity": [0.0, -9.81], "bodies.coupler.com": DELETE,
                                     "bodies.crank.mass": 1.0, "bodies.crank.com": [0.25, 0.0],
                                     "bodies.rocker.mass": 1.0, "bodies.rocker.com": [0.35, 0.0]},
     "missing key 'bodies.coupler.com'"),
    ("gravity_crank_without_mass_and_com", {"gravity": [0.0, -9.81]},
     "missing keys 'bodies.crank.mass' and 'bodies.crank.com'"),
    ("gravity_crank_without_com", {"gravity": [0.0, -9.81], "bodies.crank.mass": 1.0},
     "'bodies.crank.mass' and 'bodies.crank.com' go together"),
]

CASES = RANGE_CASES + OTHER_CASES


@pytest.mark.parametrize("patch, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_value_is_one_line_naming_key_value_and_range(patch, expected):
    with pytest.raises(SceneError) as info:
        scene_from_dict(patched(patch))
    message = str(info.value)
    assert expected in message and "\n" not in message


def test_point_force_beyond_the_force_range_is_refused():
    """The planar seed with a tabulated point force of 1e308 N on the coupler."""
    import tomllib

    from loopcheck.shipped_scenes import scenes_dir

    data = tomllib.loads((scenes_dir() / "mechanisms" / "seed_fourbar.toml").read_text())
    data["point_forces"] = [{"point": "coupler.B", "direction": 0.0, "q": [0.0, 1.0], "values": [HUGE, 0.0]}]
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    assert FORCE_MESSAGE in str(info.value)


FORCE_MESSAGE = out_of_range("point_forces[0].values[0]", HUGE, "force")


def test_gravcomp_beyond_its_range_is_refused():
    """A body's gravcomp (the general description's key) of 1e308 on a shipped planar scene."""
    import tomllib

    from loopcheck.shipped_scenes import scenes_dir

    data = tomllib.loads((scenes_dir() / "mechanisms" / "drag_link.toml").read_text())
    body = next(name for name, t in data["bodies"].items() if "mass" in t)
    data["bodies"][body]["gravcomp"] = HUGE
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    assert out_of_range(f"bodies.{body}.gravcomp", HUGE, "gravity compensation") in str(info.value)


GRAVCOMP_MESSAGE = out_of_range("bodies.*.gravcomp", HUGE, "gravity compensation")  # its kind, for the check below


def test_every_kind_of_range_is_exercised():
    messages = [c[2] for c in CASES] + [FORCE_MESSAGE, GRAVCOMP_MESSAGE]
    kinds = {k for k in LIMITS if any(f": {k} must be in" in m for m in messages)}
    assert kinds == set(LIMITS)


# The ranges' corners are valid scenes, and MuJoCo compiles them: the lower limits of mass and
# inertia sit above MuJoCo's mjMINVAL (1e-15) and their product terms stay finite.
LOW, HIGH = {k: r.low for k, r in LIMITS.items()}, {k: r.high for k, r in LIMITS.items()}
CORNERS = {
    "light": {"bodies.crank.pivot_inertia": LOW["inertia"], "bodies.rocker.pivot_inertia": LOW["inertia"],
              "bodies.coupler.mass": LOW["mass"], "bodies.coupler.inertia": LOW["inertia"],
              "dampers[0].coefficient": LOW["damping"], "springs": spring(stiffness=LOW["stiffness"]),
              "torque.value": 1e-9, "simulation.horizon": LOW["horizon"]},
    "heavy": {"bodies.crank.pivot_inertia": HIGH["inertia"], "bodies.rocker.pivot_inertia": HIGH["inertia"],
              "bodies.coupler.mass": HIGH["mass"], "bodies.coupler.inertia": HIGH["inertia"],
              "bodies.coupler.com": [HIGH["position"], -HIGH["position"]],
              "dampers[0].coefficient": HIGH["damping"], "torque.value": -HIGH["torque"],
              "springs": spring(stiffness=HIGH["stiffness"], rest_length=HIGH["position"]),
              "torque.start": HIGH["time"], "gravity": [HIGH["gravity"], 0.0], "simulation.horizon": 1.0,
              "bodies.crank.mass": 1.0, "bodies.crank.com": [0.25, 0.0],
              "bodies.rocker.mass": 1.0, "bodies.rocker.com": [0.35, 0.0]},
    "large": {"linkage.c1": 500.0, "linkage.c2": 900.0, "linkage.c3": 700.0, "linkage.c4": HIGH["length"]},
    "small": {"linkage.c1": 0.5e-3 * 2, "linkage.c2": 1.8e-3, "linkage.c3": 1.4e-3, "linkage.c4": 2e-3},
}


@pytest.mark.parametrize("patch", CORNERS.values(), ids=CORNERS.keys())
def test_corners_of_the_ranges_load_and_mujoco_compiles_them(patch):
    from loopcheck.reference_models.run import build_model

    scene = scene_from_dict(patched(patch))
    handles = build_model(scene)
    assert handles.model.nbody == 5 and all(math.isfinite(m) for m in handles.model.body_mass)


def test_below_the_inertia_range_mujoco_itself_refuses():
    """The reason for the lower limits: MuJoCo refuses mass or inertia below mjMINVAL = 1e-15. The
    scene is built past the validator (dataclasses.replace) to reach MuJoCo's compiler."""
    from loopcheck.reference_models.run import build_model

    from loopcheck.mechanism import Linkage

    scene = scene_from_dict(patched({}))
    linkage = scene.mechanism.linkage
    bodies = tuple(dataclasses.replace(b, inertia=1e-16) if b.name == "crank" else b for b in linkage.bodies)
    mechanism = dataclasses.replace(scene.mechanism, linkage=Linkage(bodies, linkage.joints, linkage.input_joint))
    with pytest.raises(ValueError, match="mjMINVAL"):
        build_model(dataclasses.replace(scene, mechanism=mechanism))


def test_names_are_plain_text():
    """A name with TeX-like dollars is valid and kept as it is (the plots escape it)."""
    assert scene_from_dict(patched({"name": "cost $5$ \\alpha"})).name == "cost $5$ \\alpha"


# --- files ------------------------------------------------------------------------------------

SEED_BYTES = SEED_SCENE.read_bytes()
FILE_CASES = [
    ("nested_arrays", b"x = " + b"[" * 100_000 + b"]" * 100_000 + b"\n", "nested too deeply"),
    ("utf16", SEED_BYTES.decode().encode("utf-16"), "is UTF-16 text (byte-order mark); save it as UTF-8"),
    ("latin1", 'name = "café"\n'.encode("latin-1"), "is not UTF-8 text (byte 0xe9 at offset 11)"),
    ("binary", bytes(range(256)) * 4, "is not UTF-8 text (byte 0x80 at offset 128)"),
    ("nul_bytes", b"\x00" * 64, "is not valid TOML"),
    ("too_large", b"# " + b"x" * MAX_SCENE_BYTES + b"\n", f"is larger than {MAX_SCENE_BYTES} bytes"),
    ("integer_past_python_limit", b"name = 1" + b"0" * 5000 + b"\n", "is not valid TOML: Exceeds the limit"),
    ("invalid_toml", b"name = \n", "is not valid TOML: Invalid value (at line 1, column 8)"),
]


@pytest.mark.parametrize("content, expected", [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_bad_file_names_itself_in_one_line_through_the_cli(tmp_path, capsys, content, expected):
    path = tmp_path / "scene.toml"
    path.write_bytes(content)
    assert cli.main(["reduced", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert str(path) in err and expected in err


def test_utf8_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + SEED_BYTES)
    assert load_scene(path) == dataclasses.replace(load_scene(SEED_SCENE), source=str(path))


def test_key_message_from_a_file_names_the_file(tmp_path, capsys):
    path = tmp_path / "wide.toml"
    path.write_bytes(SEED_BYTES.replace(b"c1 = 0.5 ", b"c1 = 1e308"))
    assert cli.main(["check", str(SEED_SCENE), str(path)]) == 2
    err = capsys.readouterr().err
    assert err == f"loopcheck: error: {path}: {out_of_range('linkage.c1', 1e308, 'length')}\n"


@pytest.mark.parametrize("where", ["/dev/zero", "folder", "fifo"])
def test_only_regular_files_are_read(tmp_path, capsys, where):
    """/dev/zero would be read for ever, a FIFO would wait for a writer: both are refused up front."""
    if where == "folder":
        path = tmp_path
    elif where == "fifo":
        path = tmp_path / "pipe.toml"
        os.mkfifo(path)
    else:
        path = where
    assert cli.main(["reduced", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"cannot read scene file '{path}': it is" in err


# Scenes that a bound on their motion once refused (it could not be tight: 500x the truth on a
# swinging crank): they are valid input now, and a run that turns out too long is stopped by
# its engine's work budget (tests/compare/test_swinging_cranks.py, test_reduced_integrators.py).
TINY_INERTIAS = {"bodies.crank.pivot_inertia": 1e-9, "bodies.rocker.pivot_inertia": 1e-9,
                 "bodies.coupler.inertia": 1e-9, "bodies.coupler.mass": 1e-6}
ONCE_REFUSED = {
    "qdot0_fast": {"initial.qdot": 1e4},
    "torque_large": {"torque.value": 1e6},
    "all_inertias_at_their_floor": TINY_INERTIAS,
    "table_torque_long": {"torque": dict(TABLE, values=[1e4, 1e4]), "simulation.horizon": 10.0},
    "stiff_spring_long": {"springs": spring(stiffness=1e8, rest_length=0.0), "simulation.horizon": 1e3},
    "horizon_long": {"simulation.horizon": 1e3},
}


@pytest.mark.parametrize("patch", ONCE_REFUSED.values(), ids=ONCE_REFUSED.keys())
def test_a_scene_is_not_refused_for_how_far_it_might_move(patch):
    scene = scene_from_dict(patched(patch))
    assert scene.horizon > 0.0
