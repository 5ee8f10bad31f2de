"""The scenes ship inside the package: a wheel holds every scene of the repository, and the
functions that locate scenes go through importlib.resources, not the source tree's layout.
(.ci/run installs the wheel in a fresh venv and runs ``loopcheck reduced`` and ``loopcheck stress`` from
outside the repository.)"""

from __future__ import annotations

import importlib.resources
import shutil
import subprocess
import sys
import zipfile

import pytest

from loopcheck.shipped_scenes import default_scene_path, hard_scene_dir, scenes_dir

from helpers import ROOT

REPO_SCENES = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "scenes").rglob("*.toml"))


def test_scene_folders_come_from_the_scenes_package():
    assert scenes_dir() == importlib.resources.files("loopcheck.scenes")
    assert default_scene_path().is_file() and default_scene_path().parent == scenes_dir()
    shipped = sorted(p.relative_to(scenes_dir().parent).as_posix() for p in scenes_dir().rglob("*.toml"))
    assert shipped == REPO_SCENES and hard_scene_dir().name == "hard"


def test_every_package_folder_is_installed():
    """pyproject.toml lists the packages a wheel holds: every folder of loopcheck/ with an __init__.py
    must be there (planted: loopcheck.mujoco_model left out of the list, as it once was, fails here,
    where the wheel's own import of the MuJoCo engine would fail only in .ci/run)."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "loopcheck").rglob("__init__.py")}
    assert sorted(folders - listed) == []


@pytest.mark.slow
def test_wheel_contains_every_scene(tmp_path):
    """Build a wheel from a copy of the sources (the checkout stays clean) and list it. pip builds
    in an isolated environment with the setuptools and Cython that pyproject.toml asks for. Everything
    installs under the one name ``loopcheck``: nothing else at the top of the wheel but its metadata.
    The build happens out of the source tree: no build/ folder, egg-info or generated C is left in it
    (planted: setup.py's in-tree build folders, as before, leaves build/ and loopcheck.egg-info)."""
    src = tmp_path / "src"
    for name in ("pyproject.toml", "README.md", "setup.py"):
        shutil.copy2(ROOT / name, src / name if src.exists() else (src.mkdir() or src / name))
    for package in ("loopcheck", "scenes"):
        shutil.copytree(ROOT / package, src / package, ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.c"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                    "-w", str(tmp_path / "dist"), str(src)], check=True, capture_output=True, timeout=300)
    left = sorted(p.relative_to(src).as_posix() for p in src.rglob("*")
                  if p.name in ("build", "loopcheck.egg-info") or p.suffix in (".c", ".so"))
    assert left == []
    (wheel,) = (tmp_path / "dist").glob("loopcheck-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {n.split("/")[0] for n in names} == {"loopcheck", wheel.name.split("-")[0] + "-" + wheel.name.split("-")[1]
                                                + ".dist-info"}
    assert "loopcheck/scenes/__init__.py" in names
    assert [n for n in REPO_SCENES if "loopcheck/" + n not in names] == []
    assert "loopcheck/scenes/hard/gravity.toml" in names  # loopcheck stress --case gravity, as .ci/run runs it
    assert any(n.startswith("loopcheck/reduced/kernels/physics.") and n.endswith(".so") for n in names)
    assert any(n.startswith("loopcheck/kernels/loops.") and n.endswith(".so") for n in names)  # the kinematics' kernel
    packages = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "loopcheck").rglob("__init__.py")}
    assert sorted(p for p in packages if p.replace(".", "/") + "/__init__.py" not in names) == []
    # Imported from the unpacked wheel, away from the checkout, the shipped scenes are found.
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    code = ("from loopcheck.shipped_scenes import default_scene_path, hard_scene_dir; from loopcheck.scenefile import load_scene; "
            "print(default_scene_path()); print(load_scene(default_scene_path()).name); "
            "print(len([load_scene(p) for p in hard_scene_dir().glob('*.toml')]))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path, env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"}, check=True)
    path, name, n_hard = proc.stdout.split("\n")[:3]
    assert path == str(site / "loopcheck" / "scenes" / "seed_fourbar.toml") and name == "seed_fourbar"
    assert int(n_hard) == sum(n.startswith("scenes/hard/") for n in REPO_SCENES)
