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
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE
from loopcheck.scene import Scene, Tolerances


def engine_settings(engine: str, scene: Scene, **flags: Any):
    """The settings of the engine named ``engine`` (:data:`loopcheck.registry.ENGINES`) for ``scene``:
    ``flags`` (None: not given) over the scene's table of that engine over the defaults.

    An engine that inherits another's table (:attr:`loopcheck.registry.Engine.inherits`: MuJoCo's
    ports, MJX and MJWarp, run the model the MuJoCo engine builds with the same options) takes
    that table's values of the keys it inherits under its own table (``[mujoco] timestep``, the
    step a scene pins for MuJoCo, is the port's step unless ``[mjx] timestep`` says otherwise)."""
    settings_type = ENGINES[engine].settings
    table = dict(scene.engine_table(engine))
    where = f"{scene.source}: [{engine}]"
    inherits = ENGINES[engine].inherits
    if inherits is not None:
        source, shared = inherits
        inherited = {k: v for k, v in scene.engine_table(source).items() if k in shared and k not in table}
        if inherited:
            table = {**inherited, **table}
            where += f" (with [{source}] {', '.join(sorted(inherited))})"
    return _settings.resolve(settings_type, table, flags, where)


def reduced_settings(scene: Scene, **flags: Any):
    """The reduced reference's settings (:data:`loopcheck.registry.REFERENCE`'s): ``flags`` over its
    table."""
    return engine_settings(REFERENCE, scene, **flags)


def mujoco_settings(scene: Scene, **flags: Any):
    """The settings of the default comparison's other engine (MuJoCo,
    :data:`loopcheck.registry.DEFAULT_ENGINES`): ``flags`` over its table."""
    return engine_settings(DEFAULT_ENGINES[1], scene, **flags)


def gate_tolerances(scene: Scene, engine: str, **flags: float | None) -> Tolerances:
    """The tolerances the engine named ``engine`` is judged by against the reduced reference:
    ``flags`` (None: not given) over the scene's ``[tolerances.ENGINE]`` over its ``[tolerances]``."""
    return replace(scene.tolerances_for(engine), **{k: v for k, v in flags.items() if v is not None})
