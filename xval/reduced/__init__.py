"""Reduced solver: Eksergian's equation 𝔍(q) q̈ + ζ(q) q̇² + dV/dq = Q for one-DOF linkages.

The engine's own names, loaded from their submodule on first use (PEP 562). What it shares with
the MuJoCo engine (scenes, mechanisms and their kinematics, results, errors) lives in the
engine-neutral modules of :mod:`xval` (``xval.scene``, ``xval.mechanism``, ``xval.results``, ...).
"""

from __future__ import annotations

import importlib

_HOMES = {
    "Coefficients": "dynamics", "MechanismModel": "dynamics",
    "RKN4": "kernels.fixed_step", "RKN4_AS_PRINTED": "kernels.fixed_step", "RKNTableau": "kernels.fixed_step",
    "Solution": "integrators", "solve_adaptive": "integrators",
    "ReducedSettings": "settings", "Settings": "settings", "simulate": "engine",
}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'xval.reduced' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{home}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
