"""Reduced solver: Eksergian's equation 𝔍(q) q̈ + ζ(q) q̇² + dV/dq = Q for one-DOF linkages."""

from .dynamics import Coefficients, MechanismModel
from .errors import FailureReason, IgnoredSettingWarning, NumericalFailure
from .integrators import RKN4, RKN4_AS_PRINTED, RKNTableau, Solution, solve_adaptive, solve_fixed_step
from .linkage import AssemblyError, FourBar, Kinematics, SingularPositionError
from .partition import JointTrajectory
from .result import EngineResult, EnergyAudit
from .scene import Scene, SceneError
from .scenefile import default_scene_path, load_scene, scene_from_dict
from .simulate import ReducedSettings, simulate
from .trajectory import Peak, Trajectory

__all__ = [
    "AssemblyError", "Coefficients", "FailureReason", "EnergyAudit", "EngineResult", "FourBar", "IgnoredSettingWarning",
    "JointTrajectory", "Kinematics",
    "MechanismModel", "NumericalFailure", "Peak", "RKN4", "RKN4_AS_PRINTED", "RKNTableau",
    "ReducedSettings", "Scene", "SceneError", "SingularPositionError", "Solution", "Trajectory",
    "default_scene_path", "load_scene", "scene_from_dict", "simulate", "solve_adaptive",
    "solve_fixed_step",
]
