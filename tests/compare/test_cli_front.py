"""The command line's front door: `loopcheck` alone, `--version`, `--quiet`/`--verbose`, and the
shipped scenes by name.

`loopcheck scenes` lists the catalogue; every command takes a listed name where it takes a scene file,
but a file of that name in the working folder comes first.
"""

from __future__ import annotations

import importlib.metadata
import re
import shutil
from pathlib import Path

import pytest

from loopcheck.compare.cli import main
from loopcheck.scene import SceneError
from loopcheck.shipped_scenes import catalogue, resolve_scene, scenes_dir

from helpers import SEED_SCENE


def test_loopcheck_alone_prints_its_help_and_succeeds(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: loopcheck") and "scenes" in out and "run" in out


def test_version_is_the_installed_distributions(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"loopcheck {importlib.metadata.version('loopcheck')}"


def test_scenes_lists_every_shipped_file_once_by_a_name_that_finds_it(capsys):
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    listed = {}
    for line in lines:
        name, path = re.split(r"\s{2,}", line.strip())
        listed[name] = Path(path)
    assert sorted(listed.values()) == sorted(scenes_dir().rglob("*.toml"))  # each file once
    assert len(set(listed)) == len(lines)
    for name, path in listed.items():
        assert resolve_scene(name) == path
    assert listed["watt2_sixbar"].parent.name == "mechanisms"  # a unique file name is shown bare
    assert listed["seed_fourbar"] == scenes_dir() / "seed_fourbar.toml"  # and a shared one by its folder
    assert listed["mechanisms/seed_fourbar"] == scenes_dir() / "mechanisms" / "seed_fourbar.toml"


def test_a_command_takes_a_shipped_scene_by_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["export-mjcf", "watt2_sixbar", "-o", "watt.xml"]) == 0
    assert main(["export-mjcf", str(scenes_dir() / "mechanisms" / "watt2_sixbar.toml"), "-o", "file.xml"]) == 0
    assert (tmp_path / "watt.xml").read_text() == (tmp_path / "file.xml").read_text()


def test_a_file_in_the_working_folder_comes_before_the_catalogue(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shutil.copy(SEED_SCENE, tmp_path / "watt2_sixbar")
    assert resolve_scene("watt2_sixbar") == Path("watt2_sixbar")
    assert catalogue()["watt2_sixbar"] != Path("watt2_sixbar")


def test_an_unknown_name_is_one_line_naming_it(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SceneError, match="loopcheck scenes"):
        resolve_scene("no_such_scene")
    assert main(["reduced", "no_such_scene"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'no_such_scene'" in err[0] and "loopcheck scenes" in err[0]
    assert not list(tmp_path.iterdir())



def tight_seed(folder: Path) -> Path:
    """The seed, 0.2 s of it, with a q tolerance that MuJoCo's automatic step meets only after
    halvings: its search then prints a progress line per failed check (measured: one, max |Δq|
    9.3e-8 rad at 1 ms against the limit 2.5e-8)."""
    text = SEED_SCENE.read_text()
    text = re.sub(r"(?m)^q_atol = .*$", "q_atol = 1e-7", text)
    text = re.sub(r"(?m)^horizon = .*$", "horizon = 0.2", text)
    path = folder / "tight.toml"
    path.write_text(text)
    return path


def test_progress_lines_by_default_none_with_quiet(tmp_path, capsys):
    scene = str(tight_seed(tmp_path))
    assert main(["mujoco", scene]) == 0
    progress = [line for line in capsys.readouterr().err.splitlines() if line.startswith("loopcheck: MuJoCo timestep")]
    assert progress
    assert main(["-q", "mujoco", scene]) == 0
    assert "loopcheck:" not in capsys.readouterr().err


def test_verbose_adds_each_engine_runs_cost(capsys):
    assert main(["reduced", "seed_fourbar"]) == 0
    assert "evaluations of q̈" not in capsys.readouterr().err
    assert main(["--verbose", "reduced", "seed_fourbar"]) == 0
    (line,) = [line for line in capsys.readouterr().err.splitlines() if "evaluations of q̈" in line]
    assert line.startswith("loopcheck: reduced DOP853 on seed_fourbar: 604 steps, 10864 evaluations")
    assert main(["-q", "-v", "reduced"]) == 2  # one or the other
