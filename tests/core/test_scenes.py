"""The bad-scene files: each has its own message; the console script's error path, once.

Each file's message and exit status through ``loopcheck reduced FILE`` are checked in-process in
tests/core/test_reduced_scenes.py (``test_cli_main_reports_the_bad_key_in_one_line``); here a single
subprocess runs the installed ``loopcheck`` script to show that the entry point maps a SceneError to
exit status 2 and one line, as ``main`` does in-process.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from loopcheck.compare import cli
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene

from helpers import DATA

BAD = sorted((DATA / "bad_scenes").glob("*.toml"))


def test_each_bad_scene_has_its_own_message():
    messages = set()
    for path in BAD:
        with pytest.raises(SceneError) as info:
            load_scene(path)
        messages.add(str(info.value).removeprefix(f"{path}: "))  # the file's path alone would differ
    assert len(messages) == len(BAD)


def test_missing_file_is_bad_input(tmp_path, capsys):
    missing = tmp_path / "nope.toml"
    assert cli.main(["mujoco", str(missing)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == f"loopcheck: error: cannot read scene file '{missing}': No such file or directory\n"


def test_console_script_exits_2_with_one_line(tmp_path):
    """The one subprocess: the ``loopcheck`` entry point installed beside this Python."""
    script = Path(sys.executable).with_name("loopcheck")
    script = str(script) if script.exists() else shutil.which("loopcheck")
    assert script, "the loopcheck console script is not installed (pip install -e .)"
    path = BAD[0]
    proc = subprocess.run([script, "reduced", str(path)], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"loopcheck: error: {path}: ") and "Traceback" not in proc.stderr
