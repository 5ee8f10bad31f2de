"""The import map's contracts hold (pyproject.toml [tool.importlinter]; docs/architecture.md).

import-linter builds the graph of every import inside ``loopcheck`` (function-local ones included)
and checks the contracts: one direction from the API down through the comparison, the two
engines (independent of each other) and the engine-neutral core's layers; nothing importing the
command line; the compiled core's layers; and no import cycle among the modules of the engines
or of the comparison. (Planted: ``loopcheck.reduced.engine`` importing ``loopcheck.compare.text`` fails
the first, naming the line; ``loopcheck.compare.plots`` importing ``loopcheck.compare.draw`` at its top,
the last, naming the cycle.)
Run as ``lint-imports`` in a subprocess, from the checkout (it reads pyproject.toml there).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import ROOT


def test_the_import_contracts_hold():
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if lint is None:
        pytest.fail("lint-imports is not installed: the `test` extra has import-linter")
    done = subprocess.run([lint, "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "0 broken" in done.stdout and "6 kept" in done.stdout, done.stdout[-2000:]
