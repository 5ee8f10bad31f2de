"""The Python API that ``import loopcheck`` gives: scenes, the engines behind one ``simulate``, the
comparison and its gate. Each name here is a thin front on the module that holds the concept
(the scene format, an engine, the comparison); the command line uses the same modules."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from loopcheck.compare.engines import EnginesCheck, EngineVerdict, check_engines, engine_list
from loopcheck.compare.run import Comparison, judge
from loopcheck.compare.settings import mujoco_settings, reduced_settings
from loopcheck.reduced.settings import ReducedSettings
from loopcheck.reference_models.settings import MujocoSettings
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE, engine_of
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


def check(scene: Scene, engines: Sequence[str] = DEFAULT_ENGINES, *, settings: Iterable[Any] = (),
          reduced: ReducedSettings | None = None, mujoco: MujocoSettings | None = None,
          tolerances: Tolerances | Mapping[str, Tolerances] | None = None) -> EnginesCheck:
    """Every engine of ``engines`` on ``scene``, each judged against the reduced reference by its
    own tolerances, and the outlier when they disagree: what ``loopcheck check --engines`` prints.
    By default the reduced reference against MuJoCo (``loopcheck check``'s pair); any engine of
    :data:`loopcheck.registry.ENGINES` may be listed (``["reduced", "mujoco", "pin", "mjx",
    "mjwarp"]`` runs them all; the reduced reference must be among them).

    ``check(scene).passed`` is what ``loopcheck check`` exits on; ``.verdicts`` has one verdict per
    engine judged (an engine that failed or refused the scene has its reason, not an exception);
    ``.outlier`` names the engine farthest from the others (three engines or more that disagree);
    ``.comparison("pin")`` is that engine's :class:`Comparison` with the reference.

    Each engine runs with the scene's table over its defaults unless ``settings`` has settings of
    it (any engine's ``Settings``, e.g. ``loopcheck.registry.ENGINES["pin"].settings(rtol=1e-10)``;
    ``reduced=`` and ``mujoco=`` name those two). ``tolerances``: one :class:`Tolerances` for
    every engine judged, or one per engine by name; by default the scene's for each engine
    (:meth:`loopcheck.scene.Scene.tolerances_for`).

    Raises
    ------
    ValueError
        If the list names an unknown engine, one twice, or lacks the reference; or settings are
        given for an engine not listed.
    ImportError
        If a listed engine's optional extra is not installed (before any work).
    NumericalFailure
        If the reduced reference fails (another engine's failure is its verdict).
    """
    names = engine_list(engines)
    given = {engine_of(s).name: s for s in settings}
    for name, s in ((REFERENCE, reduced), ("mujoco", mujoco)):  # the named settings
        if s is not None:
            if engine_of(s).name != name:
                raise TypeError(f"{name}= takes {ENGINES[name].settings.__name__}, not {type(s).__name__}")
            given[name] = s
    unlisted = [name for name in given if name not in names]
    if unlisted:
        raise ValueError(f"settings of '{unlisted[0]}', an engine not in the list ({', '.join(names)})")
    for name in names:
        ENGINES[name].load()
    if isinstance(tolerances, Tolerances):
        tolerances = {name: tolerances for name in names if name != REFERENCE}
    return check_engines(scene, names, given, tolerances)


__all__ = ["Comparison", "EngineResult", "EngineVerdict", "EnginesCheck", "MujocoSettings", "ReducedSettings", "Scene", "SceneError",
           "Tolerances", "check", "compare_results", "load_scene", "mujoco_settings", "reduced_settings",
           "catalogue", "scene_from_dict", "scene_from_string", "simulate"]
