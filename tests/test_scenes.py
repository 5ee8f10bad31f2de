"""Malformed scenes: one clear message naming the key, exit status 2, no traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from reduced import SceneError, load_scene

from helpers import ROOT, SEED_SCENE

BAD = sorted((Path(__file__).parent / "data" / "bad_scenes").glob("*.toml"))


def expected_text(path: Path) -> str:
    first = path.read_text().splitlines()[0]
    assert first.startswith("# expect: ")
    return first.removeprefix("# expect: ")


def test_there_are_many_kinds_of_bad_scene():
    assert len(BAD) >= 12


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.stem)
def test_bad_scene_message_names_the_problem(path):
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert expected_text(path) in str(info.value)


def test_each_bad_scene_has_its_own_message():
    messages = set()
    for path in BAD:
        with pytest.raises(SceneError) as info:
            load_scene(path)
        messages.add(str(info.value))
    assert len(messages) == len(BAD)


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.stem)
def test_cli_exits_2_with_one_line(path):
    proc = subprocess.run([sys.executable, "-m", "compare.cli", "reduced", str(path)], capture_output=True,
                          text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("xval: error:")
    assert "Traceback" not in proc.stderr


def test_missing_file_is_bad_input(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "compare.cli", "mujoco", str(tmp_path / "nope.toml")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "cannot read scene file" in proc.stderr


def test_default_scene_loads():
    scene = load_scene(SEED_SCENE)
    assert scene.effects == ("torque", "damper") and scene.name == "seed_fourbar"
    assert scene.linkage.branch == 1 and scene.gravity is None
