"""Reduced solver: Eksergian's equation 𝔍(q) q̈ + ζ(q) q̇² + dV/dq = Q for one-DOF linkages.

The names below load their submodule on first use (PEP 562), so that ``import xval.reduced.scene``
or ``xval.reduced.errors`` does not load the compiled kernels.
"""

from __future__ import annotations

import importlib

_HOMES = {
    "Coefficients": "dynamics", "MechanismModel": "dynamics",
    "FailureReason": "errors", "IgnoredSettingWarning": "errors", "NumericalFailure": "errors",
    "RKN4": "kernels.fixed_step", "RKN4_AS_PRINTED": "kernels.fixed_step", "RKNTableau": "kernels.fixed_step",
    "Solution": "integrators", "solve_adaptive": "integrators",
    "AssemblyError": "linkage", "FourBar": "linkage", "Kinematics": "linkage", "SingularPositionError": "linkage",
    "JointTrajectory": "partition",
    "EngineResult": "result", "EnergyAudit": "result",
    "Scene": "scene", "SceneError": "scene",
    "default_scene_path": "scenefile", "load_scene": "scenefile", "scene_from_dict": "scenefile",
    "ReducedSettings": "engine", "simulate": "engine",
    "Peak": "trajectory", "Trajectory": "trajectory",
}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'reduced' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{home}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
