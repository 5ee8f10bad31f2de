"""The MuJoCo reference model of a scene: an open chain closed by an equality constraint."""

from .build import (BASE_BODY, HOME_KEY, ConstraintSettings, ModelHandles, assembled_angles, build_spec,
                    compile_model, initial_qpos_qvel, joint_positions, joint_rates, loop_angles)
from .run import (INTEGRATORS, MAX_ITERATIONS, TIMESTEP_CEILING, TIMESTEP_FLOOR, MujocoSettings,
                  OffGridEdgeWarning, build_model, check_initial_state, control_sequence, mjcf_text,
                  grid_timestep, handles_from_mjcf, simulate_mujoco)

__all__ = ["BASE_BODY", "HOME_KEY", "ConstraintSettings", "INTEGRATORS", "MAX_ITERATIONS", "ModelHandles", "MujocoSettings",
           "OffGridEdgeWarning", "TIMESTEP_CEILING", "TIMESTEP_FLOOR", "assembled_angles", "build_model", "build_spec",
           "check_initial_state", "compile_model", "control_sequence", "mjcf_text", "grid_timestep",
           "handles_from_mjcf", "initial_qpos_qvel", "joint_positions", "joint_rates", "loop_angles",
           "simulate_mujoco"]
