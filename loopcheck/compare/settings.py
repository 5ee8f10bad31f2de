"""Engine settings and gate tolerances resolved once: the flags given, over the scene's
table, over the defaults.

Every command, the comparison and the studies resolve settings here. A scene table that the
engine's own settings refuse is reported as bad input naming the file and the table
(``scene.toml: [mujoco] solimp ...``); a bad flag keeps the settings' own message, which names
the field.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from loopcheck import settings as _settings
from loopcheck.mujoco_model.options import ModelOptions
from loopcheck.registry import ENGINES
from loopcheck.scene import Scene, Tolerances


def engine_settings(engine: str, scene: Scene, **flags: Any):
    """The settings of the engine named ``engine`` (:data:`loopcheck.registry.ENGINES`) for ``scene``:
    ``flags`` (None: not given) over the scene's table of that engine over the defaults.

    MuJoCo's ports (MJX, MJWarp: settings extending the MuJoCo-family model's options) run the
    model the MuJoCo engine builds with the same settings: the scene's ``[mujoco]`` values of
    those options come under the port's own table (``[mujoco] timestep``, the step a scene pins
    for MuJoCo, is the port's step unless ``[mjx] timestep`` says otherwise)."""
    settings_type = ENGINES[engine].settings
    table = dict(scene.engine_table(engine))
    where = f"{scene.source}: [{engine}]"
    if engine != "mujoco" and issubclass(settings_type, ModelOptions):
        shared = {o.name for o in _settings.options(ModelOptions)}
        inherited = {k: v for k, v in scene.engine_table("mujoco").items() if k in shared and k not in table}
        if inherited:
            table = {**inherited, **table}
            where += f" (with [mujoco] {', '.join(sorted(inherited))})"
    return _settings.resolve(settings_type, table, flags, where)


def reduced_settings(scene: Scene, **flags: Any):
    """The reduced reference's settings (a ``ReducedSettings``): ``flags`` over ``[reduced]``."""
    return engine_settings("reduced", scene, **flags)


def mujoco_settings(scene: Scene, **flags: Any):
    """MuJoCo's settings (a ``MujocoSettings``): ``flags`` over ``[mujoco]``."""
    return engine_settings("mujoco", scene, **flags)


def gate_tolerances(scene: Scene, engine: str, **flags: float | None) -> Tolerances:
    """The tolerances the engine named ``engine`` is judged by against the reduced reference:
    ``flags`` (None: not given) over the scene's ``[tolerances.ENGINE]`` over its ``[tolerances]``."""
    return replace(scene.tolerances_for(engine), **{k: v for k, v in flags.items() if v is not None})
