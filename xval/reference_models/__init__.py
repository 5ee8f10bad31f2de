"""The MuJoCo reference model of a scene: its linkage's spanning tree closed by ``connect`` equalities."""

from .build import (BASE_BODY, HOME_KEY, INPUT_MOTOR, ConstraintSettings, ModelHandles, assembled_angles, build_spec,
                    compile_model, coordinate_map, initial_qpos_qvel, joint_order, joint_positions, joint_rates,
                    loop_angles, loop_rates, site_name)
from .run import (INTEGRATORS, MAX_ITERATIONS, TIMESTEP_CEILING, TIMESTEP_FLOOR, MujocoSettings,
                  OffGridEdgeWarning, build_model, check_initial_state, control_sequence, mjcf_text,
                  grid_timestep, handles_from_mjcf, point_force_callback, simulate_mujoco)

__all__ = ["BASE_BODY", "HOME_KEY", "INPUT_MOTOR", "ConstraintSettings", "INTEGRATORS", "MAX_ITERATIONS",
           "ModelHandles", "MujocoSettings", "OffGridEdgeWarning", "TIMESTEP_CEILING", "TIMESTEP_FLOOR",
           "assembled_angles", "build_model", "build_spec", "check_initial_state", "compile_model",
           "control_sequence", "coordinate_map", "mjcf_text", "grid_timestep", "handles_from_mjcf",
           "initial_qpos_qvel", "joint_order", "joint_positions", "joint_rates", "loop_angles", "loop_rates",
           "point_force_callback", "simulate_mujoco", "site_name"]
