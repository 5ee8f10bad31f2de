"""``import loopcheck``: the documented names, each the same object or result as the module behind it.

The oracle for every result is the engine or comparison called directly (the API adds no
arithmetic): equal bit for bit. ``import loopcheck`` itself loads neither MuJoCo nor matplotlib.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

import loopcheck
from loopcheck.compare.run import compare_engines
from loopcheck.reduced import ReducedSettings, simulate as simulate_reduced
from loopcheck.scenefile import load_scene as load_file
from loopcheck.reference_models import MujocoSettings, simulate_mujoco

from helpers import ROOT, SEED_SCENE

SHORT = 0.3  # s: the seed's horizon cut, enough for the API's plumbing


@pytest.fixture(scope="module")
def scene():
    return dataclasses.replace(load_file(SEED_SCENE), horizon=SHORT)


def test_the_api_names_are_about_fifteen_and_documented():
    assert 15 <= len(loopcheck.__all__) <= 22
    for name in loopcheck.__all__:
        value = getattr(loopcheck, name)
        assert value.__doc__ and value.__doc__.strip(), name
    with pytest.raises(AttributeError):
        loopcheck.no_such_name  # noqa: B018


def test_import_loopcheck_is_light():
    code = "import sys, loopcheck; loopcheck.__version__; print('mujoco' in sys.modules, 'matplotlib' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.stdout.split() == ["False", "False"], done.stderr


def test_scenes_load_from_a_file_a_name_or_a_string():
    by_file = loopcheck.load_scene(SEED_SCENE)
    assert loopcheck.load_scene("seed_fourbar") == by_file
    from_text = loopcheck.scene_from_string(SEED_SCENE.read_text(), source="seed")
    assert dataclasses.replace(from_text, source=by_file.source) == by_file
    assert loopcheck.catalogue()["watt2_sixbar"].name == "watt2_sixbar.toml"
    with pytest.raises(loopcheck.SceneError, match="horizon"):
        loopcheck.scene_from_string(SEED_SCENE.read_text().replace("horizon = 2.0 ", "horizon = -1.0 "))


def test_simulate_runs_the_engine_whose_settings_it_is_given(scene):
    reduced = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-10))
    assert reduced.trajectory.q.tobytes() == simulate_reduced(scene, ReducedSettings(rtol=1e-10)).trajectory.q.tobytes()
    default = loopcheck.simulate(scene)  # the reduced engine, the scene's own settings
    assert default.peak.omega == simulate_reduced(scene, loopcheck.reduced_settings(scene)).peak.omega
    mujoco = loopcheck.simulate(scene, loopcheck.MujocoSettings(timestep=1e-3))
    assert mujoco.trajectory.q.tobytes() == simulate_mujoco(scene, MujocoSettings(timestep=1e-3)).trajectory.q.tobytes()
    with pytest.raises(TypeError, match="settings of an engine .ReducedSettings, MujocoSettings"):
        loopcheck.simulate(scene, {"rtol": 1e-6})


def test_compare_results_and_check_are_the_comparison_and_the_gate(scene):
    reduced = loopcheck.simulate(scene)
    mujoco = loopcheck.simulate(scene, loopcheck.mujoco_settings(scene))
    by_api = loopcheck.compare_results(scene, reduced, mujoco)
    assert isinstance(by_api, loopcheck.Comparison)
    checked = loopcheck.check(scene)  # the default pair, as `loopcheck check`
    direct = compare_engines(scene)

    def figures(c):
        return c.gate.passed, c.diff.peak_omega_abs, c.diff.q_max_abs, c.diff.omega_max_abs

    assert isinstance(checked, loopcheck.EnginesCheck) and checked.engines == ("reduced", "mujoco")
    assert [type(v) for v in checked.verdicts] == [loopcheck.EngineVerdict]
    assert checked.passed == direct.gate.passed and checked.outlier is None
    compared = checked.comparison("mujoco")
    assert (compared.reference.engine, compared.other.engine) == ("reduced", "mujoco")
    assert figures(compared) == figures(direct)
    assert figures(loopcheck.compare_results(scene, compared.reference, compared.other)) == figures(direct)
    assert figures(by_api)[1:] == figures(loopcheck.compare_results(scene, reduced, mujoco, tolerances=scene.tolerances))[1:]
    tight = dataclasses.replace(scene.tolerances, q_atol=1e-12)
    assert not loopcheck.compare_results(scene, reduced, mujoco, tolerances=tight).gate.passed


def test_check_takes_the_engines_their_settings_and_tolerances(scene):
    """The list, settings by engine (the named ones and any engine's Settings) and tolerances for
    every engine judged reach the runs and the gate (planted: settings ignored, the step is MuJoCo's
    automatic one; tolerances ignored, the check passes)."""
    tight = dataclasses.replace(scene.tolerances, q_atol=1e-12)
    checked = loopcheck.check(scene, ["reduced", "mujoco"], settings=[loopcheck.MujocoSettings(timestep=1e-3)],
                              reduced=loopcheck.ReducedSettings(rtol=1e-10), tolerances=tight)
    c = checked.comparison("mujoco")
    assert c.other.settings.timestep == 1e-3 and c.reference.settings.rtol == 1e-10
    assert not checked.passed and c.gate.tolerances == tight
    assert any(f.startswith("q_max_abs = ") for f in checked.verdict("mujoco").comparison.gate.failures)
    with pytest.raises(KeyError, match="'pin' was not judged in this check .judged: mujoco"):
        checked.comparison("pin")


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(engines=["mujoco"]), ValueError, "must include 'reduced'"),
    (dict(engines=["reduced", "mujco"]), ValueError, "unknown engine 'mujco'"),
    (dict(engines="reduced,mujoco"), TypeError, "a list of engine names"),
    (dict(engines=["reduced", "mujoco"], mujoco=ReducedSettings()), TypeError, "mujoco= takes MujocoSettings"),
    (dict(engines=["reduced", "mujoco"], settings=[{"rtol": 1}]), TypeError, "settings of an engine"),
])
def test_check_refuses_a_bad_list_or_settings_before_any_work(scene, kwargs, error, message):
    with pytest.raises(error, match=message):
        loopcheck.check(scene, **kwargs)


def test_results_are_read_only_arrays(scene):
    """A result cannot be changed by accident after the run (its arrays are the run's record)."""
    for result in (loopcheck.simulate(scene), loopcheck.simulate(scene, loopcheck.MujocoSettings(timestep=1e-3))):
        joints = result.joints
        arrays = (result.trajectory.t, result.trajectory.q, result.trajectory.qdot, result.trajectory.qddot,
                  result.audit.kinetic, result.audit.potential, result.audit.torque_work,
                  result.audit.damper_dissipation, joints.t, joints.x, joints.xdot, joints.mode)
        for a in arrays:
            assert not a.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            joints.x[0, 0] = 0.0
