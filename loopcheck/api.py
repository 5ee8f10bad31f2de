"""The Python API that ``import loopcheck`` gives: scenes, the engines behind one ``simulate``, the
comparison and its gate. Each name here is a thin front on the module that holds the concept
(the scene format, an engine, the comparison); the command line uses the same modules."""

from __future__ import annotations

from pathlib import Path

from loopcheck.compare.run import Comparison, compare_engines, judge
from loopcheck.compare.settings import mujoco_settings, reduced_settings
from loopcheck.reduced.settings import ReducedSettings
from loopcheck.reference_models.settings import MujocoSettings
from loopcheck.registry import engine_of
from loopcheck.results import EngineResult
from loopcheck.scene import Scene, SceneError, Tolerances
from loopcheck.scenefile import load_scene as _load_file, scene_from_dict
from loopcheck.shipped_scenes import catalogue, resolve_scene
from loopcheck.toml_reader import parse_toml

Settings = ReducedSettings | MujocoSettings


def load_scene(source: str | Path) -> Scene:
    """A scene from a TOML file, or from the shipped catalogue by name (``"watt2_sixbar"``;
    :func:`catalogue` lists them) when no file of that name exists.

    Raises
    ------
    SceneError
        If neither exists, or the file is not a valid scene (the message names the key).
    """
    return _load_file(resolve_scene(source))


def scene_from_string(text: str, *, source: str = "<string>") -> Scene:
    """A scene from the text of a scene file (TOML); ``source`` names it in error messages."""
    return scene_from_dict(parse_toml(text, Path(source)), source=source)


def simulate(scene: Scene, settings: Settings | None = None) -> EngineResult:
    """Run one engine on ``scene``: the one whose settings are given (:class:`ReducedSettings`,
    Eksergian's equation; :class:`MujocoSettings`, MuJoCo; any engine of
    :data:`loopcheck.registry.ENGINES`), by default the reduced engine with the scene's own
    ``[reduced]`` table over the defaults.

    Raises
    ------
    NumericalFailure
        If the run cannot meet its accuracy (the reason says why and what to change).
    TypeError
        If ``settings`` are no engine's.
    """
    if settings is None:
        settings = reduced_settings(scene)
    return engine_of(settings).simulate(scene, settings)


def compare_results(scene: Scene, reference: EngineResult, other: EngineResult, *,
            tolerances: Tolerances | None = None) -> Comparison:
    """How far ``other`` is from ``reference`` over the scene's horizon (trajectories, peak
    speed, assembly modes), and the gate's verdict at ``tolerances`` (by default the scene's for
    ``other``'s engine: :meth:`loopcheck.scene.Scene.tolerances_for`)."""
    return judge(scene, reference, other, tolerances or scene.tolerances_for(other.engine))


def check(scene: Scene, *, reduced: ReducedSettings | None = None, mujoco: MujocoSettings | None = None,
          tolerances: Tolerances | None = None) -> Comparison:
    """Both engines on ``scene`` (settings from the scene's tables unless given) and the gate:
    ``check(scene).gate.passed`` is what ``loopcheck check`` exits on."""
    return compare_engines(scene, reduced=reduced, mujoco=mujoco, tolerances=tolerances)


__all__ = ["Comparison", "EngineResult", "MujocoSettings", "ReducedSettings", "Scene", "SceneError",
           "Tolerances", "check", "compare_results", "load_scene", "mujoco_settings", "reduced_settings",
           "catalogue", "scene_from_dict", "scene_from_string", "simulate"]
