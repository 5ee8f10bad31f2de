"""The MuJoCo reference model of a scene: an open chain closed by an equality constraint."""

from .build import ConstraintSettings, ModelHandles, build_spec, compile_model, initial_qpos_qvel
from .run import (INTEGRATORS, MujocoSettings, OffGridEdgeWarning, build_model, control_sequence,
                  export_mjcf, handles_from_mjcf, simulate_mujoco)

__all__ = ["ConstraintSettings", "INTEGRATORS", "ModelHandles", "MujocoSettings", "OffGridEdgeWarning",
           "build_model", "build_spec", "compile_model", "control_sequence", "export_mjcf",
           "handles_from_mjcf", "initial_qpos_qvel", "simulate_mujoco"]
