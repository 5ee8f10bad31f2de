"""Scene validation, systematically: every key of the seed scene broken in every way it can be
broken names itself in one line; the bad-scene files through the CLI's error path; the
default scene is the seed notes' worked example (README, 'The seed notes').

Each bad-scene file goes through the CLI's ``main`` in the test process (exit status 2, one
stderr line naming the key, no traceback); tests/core/test_scenes.py runs the installed ``loopcheck``
script once as a subprocess. Extreme values, names and unreadable files: tests/core/test_scene_input.py.
"""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import pytest

from loopcheck.compare import cli
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.shipped_scenes import default_scene_path

from helpers import DATA, SEED_SCENE, seed_dict

BAD = sorted((DATA / "bad_scenes").glob("*.toml"))


def expected_text(path: Path) -> str:
    first = path.read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith("# expect: "), f"{path.name} must start with '# expect: <text>'"
    return first.removeprefix("# expect: ")


def leaves(node, path=""):
    """(dotted path as the scene messages spell it, value) of every scalar in parsed TOML."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield from leaves(value, f"{path}.{key}" if path else key)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from leaves(value, f"{path}[{i}]")
    else:
        yield path, node


def tables(node, path=""):
    """Dotted path of every table (the top level is '')."""
    if isinstance(node, dict):
        yield path
        for key, value in node.items():
            yield from tables(value, f"{path}.{key}" if path else key)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from tables(value, f"{path}[{i}]")


def locate(data, path):
    """(container, key) of a dotted path inside parsed TOML."""
    parts = re.findall(r"[^.\[\]]+|\[\d+\]", path)
    node = data
    for part in parts[:-1]:
        node = node[int(part[1:-1])] if part.startswith("[") else node[part]
    last = parts[-1]
    return node, int(last[1:-1]) if last.startswith("[") else last


def scene_error(data) -> str:
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    message = str(info.value)
    assert "\n" not in message  # one line, as the CLI prints it
    return message


SEED_LEAVES = list(leaves(seed_dict()))
NUMERIC = [p for p, v in SEED_LEAVES if isinstance(v, (int, float)) and not isinstance(v, bool)]
STRINGS = [p for p, v in SEED_LEAVES if isinstance(v, str)]
# Keys without a default (each point element is not a key: a point with one element left is
# reported as the point, see test_short_point_names_the_point).
REQUIRED = ["linkage", "linkage.c1", "linkage.c2", "linkage.c3", "linkage.c4", "linkage.branch", "bodies",
            "bodies.crank", "bodies.coupler", "bodies.rocker", "bodies.coupler.mass",
            "bodies.coupler.inertia", "bodies.coupler.com", "torque.type", "torque.value",
            "torque.duration", "dampers[0].coefficient", "dampers[0].ground_point", "dampers[0].body",
            "dampers[0].body_point", "initial", "initial.q", "simulation", "simulation.horizon"]


def test_the_seed_has_the_keys_these_tests_break():
    assert len(NUMERIC) == 28 and set(STRINGS) == {"name", "description", "linkage.type", "torque.type",
                                                   "dampers[0].body"}
    scene_from_dict(seed_dict())  # unbroken, it is valid


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("path", [p for p, _ in SEED_LEAVES])
def test_non_finite_value_names_its_key(path, value):
    data = seed_dict()
    node, key = locate(data, path)
    node[key] = value
    assert f"'{path}'" in scene_error(data)


@pytest.mark.parametrize("path", NUMERIC)
def test_string_for_a_number_names_its_key(path):
    data = seed_dict()
    node, key = locate(data, path)
    node[key] = str(node[key])
    message = scene_error(data)
    assert f"'{path}'" in message and ("must be a number" in message or "must be 1 or -1" in message)


@pytest.mark.parametrize("path", REQUIRED)
def test_missing_key_names_it(path):
    data = seed_dict()
    node, key = locate(data, path)
    del node[key]
    assert f"missing key '{path}'" in scene_error(data)


@pytest.mark.parametrize("path", ["bodies.crank.pivot_inertia", "bodies.rocker.pivot_inertia"])
def test_missing_pivot_inertia_asks_for_it_or_a_mass_distribution(path):
    data = seed_dict()
    node, key = locate(data, path)
    del node[key]
    body = path.rsplit(".", 1)[0]
    message = scene_error(data)
    assert f"missing key '{body}.mass'" in message and "pivot_inertia" in message


@pytest.mark.parametrize("path", ["bodies.coupler.com", "dampers[0].ground_point", "dampers[0].body_point"])
def test_short_point_names_the_point(path):
    data = seed_dict()
    node, key = locate(data, path)
    node[key] = node[key][:1]
    assert f"'{path}' must be an array of two numbers" in scene_error(data)


@pytest.mark.parametrize("path", list(tables(seed_dict())))
def test_unknown_key_in_every_table_names_it(path):
    data = seed_dict()
    node = data
    if path:
        container, key = locate(data, path)
        node = container[key]
    node["colour"] = "blue"
    expected = f"{path}.colour" if path else "colour"
    assert f"unknown key '{expected}'" in scene_error(data)


@pytest.mark.parametrize("path", ["linkage.c1", "linkage.c2", "linkage.c3", "linkage.c4",
                                  "bodies.coupler.mass", "bodies.coupler.inertia",
                                  "bodies.crank.pivot_inertia", "bodies.rocker.pivot_inertia",
                                  "dampers[0].coefficient", "simulation.horizon"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_non_positive_physical_quantity_names_its_key(path, value):
    data = seed_dict()
    node, key = locate(data, path)
    node[key] = value
    assert f"'{path}' must be positive" in scene_error(data)


@pytest.mark.parametrize("path", ["torque.start", "torque.duration"])
def test_negative_time_names_its_key(path):
    data = seed_dict()
    node, key = locate(data, path)
    node[key] = -0.25
    assert f"'{path}' must not be negative" in scene_error(data)


@pytest.mark.parametrize("branch", [0, 2, -2, 0.5, True, "1"])
def test_bad_branch_is_refused(branch):
    data = seed_dict()
    data["linkage"]["branch"] = branch
    assert "'linkage.branch' must be 1 or -1" in scene_error(data)


def test_linkage_that_cannot_close_at_q0_names_the_discriminant():
    """c3 = 0.05: B must be 0.05 m from O3 and 0.9 m from A, but |O3 A| ≈ 0.51 m at q0 = 0.2;
    A² + B² − C² < 0."""
    data = seed_dict()
    data["linkage"]["c3"] = 0.05
    message = scene_error(data)
    assert "'initial.q'" in message and "discriminant" in message


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.stem)
def test_cli_main_reports_the_bad_key_in_one_line(path, capsys):
    """``loopcheck reduced FILE`` in-process: exit status 2, nothing on stdout, one stderr line that
    carries load_scene's message (so it names the key), no traceback."""
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert expected_text(path) in str(info.value)
    status = cli.main(["reduced", str(path)])
    out, err = capsys.readouterr()
    assert status == 2 and out == ""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0] == f"loopcheck: error: {info.value}"
    assert "Traceback" not in err


def test_default_scene_is_the_seed_example():
    """The numbers of the seed notes' worked example (README, 'The seed notes'), read back from the default scene."""
    assert default_scene_path() == SEED_SCENE.resolve()
    scene = load_scene(default_scene_path())
    assert scene.effects == ("torque", "damper")
    g = scene.four_bar
    assert (g.c1, g.c2, g.c3, g.c4, g.branch) == (0.5, 0.9, 0.7, 1.0, 1)
    bodies = scene.mechanism.linkage.body_map
    crank, coupler, rocker = (bodies[b] for b in ("crank", "coupler", "rocker"))
    assert (crank.mass, crank.inertia) == (0.0, 1.5) and (rocker.mass, rocker.inertia) == (0.0, 3.5)
    assert (coupler.mass, coupler.inertia, coupler.com) == (40.0, 5.0, (0.5111, 0.1333))
    (damper,) = scene.mechanism.dampers
    assert (damper.coefficient, damper.body_a, damper.body_b) == (55.0, "ground", "coupler")
    assert bodies["ground"].points[damper.point_a] == (1.3, 0.12)
    assert bodies["coupler"].points[damper.point_b] == (0.9, 0.0)
    assert scene.load(0.0) == 250.0 and scene.load(0.999) == 250.0 and scene.load(1.0) == 0.0
    assert scene.load.edges == (0.0, 1.0)
    assert (scene.q0, scene.qdot0, scene.horizon, scene.gravity, scene.mechanism.springs) == (0.2, 0.0, 2.0, None, ())
    assert scene.mode == (1,) and scene.input_unit == "rad"


def test_scene_from_dict_does_not_modify_its_input():
    data = seed_dict()
    before = copy.deepcopy(data)
    scene_from_dict(data)
    assert data == before


@pytest.mark.parametrize("value", [0, 10_001, 2**31])
def test_mujoco_iterations_beyond_the_one_limit_name_the_key(value):
    """The scene file, the CLI and MujocoSettings share MUJOCO_MAX_ITERATIONS (10 000)."""
    data = seed_dict()
    data["mujoco"] = {"iterations": value}
    assert "'mujoco.iterations' must be a whole number from 1 to 10000" in scene_error(data)
