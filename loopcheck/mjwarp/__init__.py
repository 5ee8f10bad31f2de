"""The MJWarp engine: the scene's MuJoCo model (:mod:`loopcheck.mujoco_model`, as the MuJoCo engine
builds it, with the same options) stepped by MJWarp, MuJoCo's Warp port, in float32 (its only
precision); a batch of variants of one model runs as MJWarp's worlds (``nworld``), one per
variant. MuJoCo C reads the states back (sensors, loop gap, energy audit:
:mod:`loopcheck.mujoco_model.port`).

The engine's interface (:mod:`loopcheck.registry`): ``Settings`` (:class:`MjwarpSettings`, its
``[mjwarp]`` table and flags) and ``simulate(scene, settings) -> EngineResult``;
``simulate_batch(scenes, settings)`` for sweeps. MJWarp is an optional extra (docs/engines.md
says how to install it without changing loopcheck's MuJoCo); names load from their submodule on first
use (PEP 562): reading the settings imports neither warp nor MuJoCo.
"""

from __future__ import annotations

from loopcheck._lazy import lazy_names

_HOMES = {
    "result_lines": "loopcheck.mujoco_model.text",  # what `loopcheck NAME` prints (loopcheck.registry.Engine.result_lines)
    **dict.fromkeys(("MjwarpSettings", "Settings"), ".settings"),
    **dict.fromkeys(("MjwarpDetails", "simulate_mjwarp", "simulate_batch", "BATCHED_FIELDS"), ".run"),
    "simulate": (".run", "simulate_mjwarp"),  # the engine interface's name
}
__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES, globals())
