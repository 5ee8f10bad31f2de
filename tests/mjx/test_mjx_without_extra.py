"""Where JAX or MJX is not installed (the extra ``loopcheck[mjx]`` left out): the scene format knows the
``[mjx]`` table (its settings import neither JAX nor MuJoCo), and ``loopcheck check --engines
reduced,mjx`` says in one line how to install it (exit 2) before any work, no traceback. Runs
everywhere: JAX is hidden from the import system here, installed or not. (Planted: a bare
``import jax`` at the top of loopcheck/mjx/run.py, before the extra's message, makes the command print
Python's own words instead: the first test fails.)"""

from __future__ import annotations

import sys

import pytest

import loopcheck.mjx
from loopcheck.compare.cli import main
from loopcheck.scenefile import scene_from_dict

from helpers import seed_dict


@pytest.fixture
def no_jax(monkeypatch):
    monkeypatch.setitem(sys.modules, "jax", None)  # `import jax` raises ModuleNotFoundError
    monkeypatch.delitem(sys.modules, "loopcheck.mjx.run", raising=False)
    for name in ("simulate", "simulate_mjx", "simulate_batch", "MjxDetails", "KNOWN_DEFECT"):
        monkeypatch.delitem(loopcheck.mjx.__dict__, name, raising=False)


def test_check_engines_says_how_to_install_it_before_any_work(no_jax, capsys):
    assert main(["check", "seed_fourbar", "--engines", "reduced,mjx"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == ("loopcheck: error: the mjx engine needs JAX and MJX: pip install -e '.[mjx]' in loopcheck's checkout, then pip install "
                            "--no-deps mujoco-mjx (docs/engines.md, 'Installing MJX and MJWarp')\n")


def test_the_scene_table_is_read_without_it(no_jax):
    data = seed_dict()
    data["mjx"] = {"timestep": 5e-4, "precision": "float32"}
    settings = loopcheck.mjx.Settings(**scene_from_dict(data).engine_table("mjx"))
    assert (settings.timestep, settings.precision, settings.effective_solref) == (5e-4, "float32", (1e-3, 1.0))
    with pytest.raises(ValueError, match="precision must be one of float64, float32"):
        loopcheck.mjx.Settings(precision="float16")
