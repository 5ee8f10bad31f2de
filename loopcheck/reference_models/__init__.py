"""The MuJoCo engine: a scene's linkage as MuJoCo's spanning tree closed by ``connect``
equalities, dampers and springs as tendons, loads as actuators (the model built by the
MuJoCo-family layer, :mod:`loopcheck.mujoco_model`, which MJX and MJWarp run too).

The engine's interface (:mod:`loopcheck.registry`): ``Settings`` (:class:`MujocoSettings`, its
``[mujoco]`` table and flags) and ``simulate(scene, settings) -> EngineResult``. Names load from
their submodule on first use (PEP 562): reading the settings does not import MuJoCo.
"""

from __future__ import annotations

from loopcheck._lazy import lazy_names

_HOMES = {
    "result_lines": ".text",  # what `loopcheck mujoco` prints (loopcheck.registry.Engine.result_lines)
    **dict.fromkeys(("BASE_BODY", "HOME_KEY", "INPUT_MOTOR", "ConstraintSettings", "ModelHandles", "assembled_angles",
                     "build_spec", "compile_model", "coordinate_map", "initial_qpos_qvel", "joint_order",
                     "joint_positions", "joint_rates", "loop_angles", "loop_rates", "site_name"), "loopcheck.mujoco_model.build"),
    **dict.fromkeys(("OffGridEdgeWarning", "build_model", "mjcf_text", "handles_from_mjcf",
                     "simulate_mujoco"), ".run"),
    **dict.fromkeys(("CheckOutcome", "FailedCheck", "MeasuredCheck"), ".timestep"),
    "check_initial_state": "loopcheck.mujoco_model.record",
    **dict.fromkeys(("TIMESTEP_CEILING", "TIMESTEP_FLOOR", "grid_timestep"), "loopcheck.mujoco_model.steps"),
    **dict.fromkeys(("control_sequence", "point_force_callback"), "loopcheck.mujoco_model.loads"),
    **dict.fromkeys(("INTEGRATORS", "MAX_ITERATIONS", "MujocoSettings", "Settings"), ".settings"),
    "simulate": (".run", "simulate_mujoco"),  # the engine interface's name
}
__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES, globals())
