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

from xval import settings as _settings
from xval.registry import ENGINES
from xval.scene import Scene, Tolerances


def engine_settings(engine: str, scene: Scene, **flags: Any):
    """The settings of the engine named ``engine`` (:data:`xval.registry.ENGINES`) for ``scene``:
    ``flags`` (None: not given) over the scene's table of that engine over the defaults."""
    return _settings.resolve(ENGINES[engine].settings, scene.engine_table(engine), flags,
                             f"{scene.source}: [{engine}]")


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
