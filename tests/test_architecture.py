"""The import map's contracts hold (pyproject.toml [tool.importlinter]; docs/architecture.md).

import-linter builds the graph of every import inside ``loopcheck`` (function-local ones included)
and checks the contracts, by package: one direction from the API down through the comparison, the
engines (independent of each other) and the engine-neutral core's layers, every package and
module directly under ``loopcheck/`` given a layer (exhaustive: a new one fails until placed, a new
module of a package is covered by its package); nothing importing the command line; the engines'
settings importing no engine library or machinery; the compiled core's layers (exhaustive too);
and no import cycle among the modules of any package. The engines' layer and the settings
contract's sources are the registry's built-in engines (:data:`loopcheck.registry.BUILT_IN`).
Run as ``lint-imports`` in a subprocess, from the checkout (it reads pyproject.toml there); the
plants run it on a copy of the package's sources with violations planted in new and old files.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from loopcheck.registry import BUILT_IN

from helpers import ROOT

CONTRACTS = 5


def _lint(cwd: Path) -> subprocess.CompletedProcess:
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if lint is None:
        pytest.fail("lint-imports is not installed: the `test` extra has import-linter")
    env = {**os.environ, "PYTHONPATH": str(cwd)}
    return subprocess.run([lint, "--no-cache"], cwd=cwd, capture_output=True, text=True, timeout=120, env=env)


def _contracts() -> list[dict]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]["contracts"]


def test_the_import_contracts_hold():
    done = _lint(ROOT)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "0 broken" in done.stdout and f"{CONTRACTS} kept" in done.stdout, done.stdout[-2000:]


def test_the_engines_of_the_contracts_are_the_registrys():
    """The engines' layer (independent packages) and the settings contract's sources are the
    registry's built-in engines: registering a built-in engine without placing it fails here."""
    top = next(c for c in _contracts() if c.get("containers") == ["loopcheck"])
    packages = {e.package for e in BUILT_IN}
    layer = next(layer for layer in top["layers"] if "reduced" in layer.split(" | "))
    assert {f"loopcheck.{name.strip()}" for name in layer.split("|")} == packages
    settings = next(c for c in _contracts() if c["type"] == "forbidden")
    assert set(settings["source_modules"]) == {f"{p}.settings" for p in packages}


def _copy(tmp_path: Path) -> Path:
    """The package's Python sources and pyproject.toml, copied into ``tmp_path``."""
    shutil.copytree(ROOT / "loopcheck", tmp_path / "loopcheck",
                    ignore=lambda folder, names: [n for n in names if not n.endswith(".py")
                                                  and not (Path(folder) / n).is_dir() or n == "__pycache__"])
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


def _plant(root: Path, module: str, line: str) -> None:
    path = root.joinpath(*module.split(".")).with_suffix(".py")
    text = path.read_text(encoding="utf-8") if path.exists() else '"""Planted."""\n'
    path.write_text(text + line + "\n", encoding="utf-8")


def test_each_contract_fails_when_broken_in_a_new_file_or_an_old_one(tmp_path):
    """Planted on a copy: an engine importing the comparison (an old file) and a new module of an
    engine importing the comparison (covered by its package, without editing a list); a new
    module directly under loopcheck/ and a new one in the compiled core (exhaustive: no layer);
    a new module of the comparison importing the command line; an engine's settings importing its
    run; two modules of the comparison importing each other. Each is named."""
    root = _copy(tmp_path)
    _plant(root, "loopcheck.reduced.engine", "from loopcheck.compare import text")
    _plant(root, "loopcheck.pin.planted_helper", "import loopcheck.compare.report")
    _plant(root, "loopcheck.planted_core", "from loopcheck import errors")
    _plant(root, "loopcheck.reduced.kernels.planted_kernel", "from . import problem")
    _plant(root, "loopcheck.compare.planted_study", "from . import cli")
    _plant(root, "loopcheck.mjx.settings", "from loopcheck.mjx import run")
    _plant(root, "loopcheck.compare.plots", "from . import draw")
    done = _lint(root)
    out = " ".join(done.stdout.split())
    assert done.returncode == 1, done.stdout[-3000:] + done.stderr[-2000:]
    assert f"{CONTRACTS} broken" in out, out[-3000:]
    for expected in ("loopcheck.reduced.engine -> loopcheck.compare.text",
                     "loopcheck.pin.planted_helper -> loopcheck.compare.report",
                     "- loopcheck.planted_core", "- loopcheck.reduced.kernels.planted_kernel",
                     "loopcheck.compare.planted_study -> loopcheck.compare.cli",
                     "loopcheck.mjx.settings is not allowed to import loopcheck.mjx.run",
                     "No cycles are allowed in loopcheck.compare", ".plots -> .draw"):
        assert expected in out, (expected, out[-4000:])
