"""`xval check --engines`: each engine against the reduced reference; the outlier named."""

from __future__ import annotations

import importlib.util

import pytest

from xval.compare.engines import check_engines, parse_engines
from xval.compare.settings import engine_settings
from xval.reference_models import MujocoSettings
from xval.scenefile import load_scene

HAS_PIN = importlib.util.find_spec("pinocchio") is not None
# MuJoCo's own default softness on the loop at RK4 1 ms: it runs (its gap and energy bounds opened)
# with the seed's peak 3.2e-2 low (tests/compare/test_model_check.py measures the same model)
SOFT = dict(timestep=0.001, solref=(0.02, 1.0), solimp=(0.9, 0.95, 0.001, 0.5, 2.0), max_constraint_violation=0.01,
            max_energy_residual=1.0)


@pytest.mark.parametrize("text, message", [("reduced,nope", "unknown engine 'nope'"), ("mujoco,pin", "must include 'reduced'"),
                                           ("reduced,mujoco,reduced", "named twice"), ("reduced", "at least one other")])
def test_the_engine_list_is_checked(text, message):
    with pytest.raises(ValueError, match=message):
        parse_engines(text)


def _settings(scene, engines, **mujoco):
    return {name: MujocoSettings(**mujoco) if name == "mujoco" else engine_settings(name, scene) for name in engines}


def test_two_engines_name_no_outlier():
    """With only MuJoCo beside the reference, a failing MuJoCo (MuJoCo's default softness: the
    seed's peak 3.2e-2 off) fails the check, and nobody is called an outlier."""
    scene = load_scene("scenes/seed_fourbar.toml")
    check = check_engines(scene, ("reduced", "mujoco"), _settings(scene, ("reduced", "mujoco"), **SOFT),
                          scene.tolerances)
    assert not check.passed and check.outlier is None


@pytest.mark.skipif(not HAS_PIN, reason="Pinocchio (the extra xval[pin]) is not installed")
def test_the_engine_farthest_from_the_others_is_named():
    """MuJoCo with its default softness against the reduced solution and Pinocchio, which agree to 4e-11 on the
    seed's peak: MuJoCo is named."""
    scene = load_scene("scenes/seed_fourbar.toml")
    engines = ("reduced", "mujoco", "pin")
    check = check_engines(scene, engines, _settings(scene, engines, **SOFT), scene.tolerances)
    assert not check.passed and check.outlier == "mujoco"
    assert check.spread[("reduced", "pin")] < 1e-9 < min(check.spread[("reduced", "mujoco")], check.spread[("mujoco", "pin")])


@pytest.mark.skipif(not HAS_PIN, reason="Pinocchio (the extra xval[pin]) is not installed")
def test_cli_check_with_three_engines(capsys):
    from xval.compare.cli import main

    assert main(["check", "seed_fourbar", "--engines", "reduced,mujoco,pin"]) == 0
    out = capsys.readouterr().out
    assert "      mujoco   ok" in out and "      pin      ok" in out and "farthest" not in out


def test_cli_engines_do_not_apply_to_a_model(capsys):
    from xval.compare.cli import main

    assert main(["check", "tests/data/mjcf/fourbar_xz_degrees.xml", "--engines", "reduced,mujoco"]) == 2
    assert "--engines checks scenes" in capsys.readouterr().err
