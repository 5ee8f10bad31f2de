"""Where warp or MJWarp is not installed (the extra ``loopcheck[mjwarp]`` left out): the engine's
settings still load (they import neither), and the engine says in one line how to install it.
Runs everywhere: warp is hidden from the import system here, installed or not. (Planted: a bare
``import warp`` at the top of loopcheck/mjwarp/run.py, before the engine's message, makes the import
raise Python's own words instead: the first test fails.)"""

from __future__ import annotations

import sys

import pytest

import loopcheck.mjwarp


@pytest.fixture
def no_warp(monkeypatch):
    for name in ("warp", "mujoco_warp"):
        monkeypatch.setitem(sys.modules, name, None)  # `import warp` raises ModuleNotFoundError
    monkeypatch.delitem(sys.modules, "loopcheck.mjwarp.run", raising=False)
    for name in ("simulate", "simulate_mjwarp", "simulate_batch", "MjwarpDetails", "BATCHED_FIELDS"):
        monkeypatch.delitem(loopcheck.mjwarp.__dict__, name, raising=False)


def test_the_engine_says_how_to_install_it(no_warp):
    with pytest.raises(ModuleNotFoundError) as info:
        loopcheck.mjwarp.simulate  # noqa: B018  (the lazy name imports the run module)
    assert str(info.value) == ("the mjwarp engine needs warp and MJWarp: pip install -e '.[mjwarp]' in loopcheck's checkout, then "
                               "pip install --no-deps mujoco-warp (docs/engines.md, 'MJWarp')")


def test_the_settings_load_without_it(no_warp):
    settings = loopcheck.mjwarp.Settings(timestep=5e-4)
    assert settings.timestep == 5e-4 and settings.integrator == "rk4"
    assert not {"warp", "mujoco_warp"} & {m for m in sys.modules if sys.modules[m] is not None}
