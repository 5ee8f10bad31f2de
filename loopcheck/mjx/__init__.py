"""The MJX engine: the scene's MuJoCo model (:mod:`loopcheck.mujoco_model`, as the MuJoCo engine
builds it, with the same options) stepped by MJX, MuJoCo's JAX port, in float64 by default; a
batch of variants of one model runs as one ``jax.vmap``. MuJoCo C reads the states back (sensors,
loop gap, energy audit: :mod:`loopcheck.mujoco_model.port`).

The engine's interface (:mod:`loopcheck.registry`): ``Settings`` (:class:`MjxSettings`, its ``[mjx]``
table and flags) and ``simulate(scene, settings) -> EngineResult``; ``simulate_batch(scenes,
settings)`` for sweeps. MJX is an optional extra (docs/engines.md says how to install it without
changing loopcheck's MuJoCo); names load from their submodule on first use (PEP 562): reading the
settings imports neither JAX nor MuJoCo.
"""

from __future__ import annotations

from loopcheck._lazy import lazy_names

_HOMES = {
    "result_lines": "loopcheck.mujoco_model.text",  # what `loopcheck NAME` prints (loopcheck.registry.Engine.result_lines)
    **dict.fromkeys(("MjxSettings", "Settings", "PRECISIONS"), ".settings"),
    **dict.fromkeys(("MjxDetails", "simulate_mjx", "simulate_batch", "KNOWN_DEFECT"), ".run"),
    "simulate": (".run", "simulate_mjx"),  # the engine interface's name
}
__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES, globals())
