"""Engine settings and gate tolerances resolved once: the flags given, over the scene's
table, over the defaults.

Every command, the comparison and the stress catalogue resolve settings here. A scene table
that the engine's own settings refuse is reported as bad input naming the file and the table
(``scene.toml: [mujoco] solimp ...``); a bad flag keeps the settings' own message, which
names the field.
"""

from __future__ import annotations

import warnings
from typing import Any, Callable, Mapping, TypeVar

from dataclasses import replace

from xval.reduced import ReducedSettings
from xval.scene import Scene, SceneError
from xval.scene import Tolerances

S = TypeVar("S")


def _resolve(kind: Callable[..., S], table_name: str, table: Mapping[str, Any], scene: Scene,
             flags: Mapping[str, Any]) -> S:
    with warnings.catch_warnings():  # the combined settings below warn once, not twice
        warnings.simplefilter("ignore")
        try:
            kind(**table)
        except ValueError as exc:
            raise SceneError(f"{scene.source}: [{table_name}] {exc}") from None
    return kind(**{**table, **{k: v for k, v in flags.items() if v is not None}})


def reduced_settings(scene: Scene, **flags: Any) -> ReducedSettings:
    """The reduced reference's settings: ``flags`` (None: not given) over ``[reduced]``."""
    return _resolve(ReducedSettings, "reduced", scene.reduced, scene, flags)


def mujoco_settings(scene: Scene, **flags: Any):
    """MuJoCo's settings (a ``MujocoSettings``): ``flags`` (None: not given) over ``[mujoco]``.

    MuJoCo is imported here, not with this module: ``xval reduced`` does not load it."""
    from xval.reference_models import MujocoSettings

    return _resolve(MujocoSettings, "mujoco", scene.mujoco, scene, flags)


def gate_tolerances(scene: Scene, **flags: float | None) -> Tolerances:
    """The gate's tolerances: ``flags`` (None: not given) over the scene's [tolerances]."""
    return replace(scene.tolerances, **{k: v for k, v in flags.items() if v is not None})
