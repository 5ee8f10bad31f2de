"""Reduced solver: Eksergian's equation 𝔍(q) q̈ + ζ(q) q̇² + dV/dq = Q for one-DOF linkages.

The engine's interface (:mod:`loopcheck.registry`), ``Settings`` and ``simulate``, and its model,
loaded from their submodule on first use (PEP 562); the integrators and the compiled core are
imported from their modules (``loopcheck.reduced.integrators``, ``loopcheck.reduced.kernels``). What it shares with
the MuJoCo engine (scenes, mechanisms and their kinematics, results, errors) lives in the
engine-neutral modules of :mod:`loopcheck` (``loopcheck.scene``, ``loopcheck.mechanism``, ``loopcheck.results``, ...).
"""

from __future__ import annotations

from loopcheck._lazy import lazy_names

_HOMES = {
    "result_lines": ".text",  # what `loopcheck NAME` prints (loopcheck.registry.Engine.result_lines)
    "ReducedSettings": ".settings", "Settings": ".settings", "simulate": ".engine",  # the engine interface
    "check_work": ".engine",  # its refusals before any work (loopcheck.registry.Engine.check_work)
    "MechanismModel": ".dynamics", "Coefficients": ".dynamics",  # the model arrays and K, L, 𝔍, ζ at a q
}
__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES, globals())
