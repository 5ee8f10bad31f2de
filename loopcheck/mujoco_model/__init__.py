"""The MuJoCo-family model layer, shared by the engines that run MuJoCo's model of a scene
(MuJoCo C, :mod:`loopcheck.reference_models`; MJX, :mod:`loopcheck.mjx`; MJWarp, :mod:`loopcheck.mjwarp`):

- ``options``: the model's options (integrator, timestep, loop softness, solver), the base of
  each such engine's ``Settings`` (imports nothing of MuJoCo);
- ``steps``: the step grid (the grid step that puts load edges on it, the step count);
- ``build``: the scene as an ``MjSpec`` (spanning tree, ``connect`` loops, tendons, the motor,
  sensors), its MJCF text, the map between qpos/qvel and the scene's coordinates;
- ``layout``: that map for a compiled model; ``loads``: the controls and forces per step;
- ``record``: what a run's stored states say, by MuJoCo C's own functions (sensors, the initial
  state's residuals, the loop gap, q̈, the trajectory with its load-edge samples);
- ``energy``: the energy audit from those sensors;
- ``warning_handler``: MuJoCo's warnings, the one handler for loading, runs and the MJCF importer
  (kept and logged in loopcheck's words, never printed nor written to ``MUJOCO_LOG.TXT``).

An engine of the family steps the model its own way and hands its states to ``record``.
"""
