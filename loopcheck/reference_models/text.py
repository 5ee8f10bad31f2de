"""What ``loopcheck mujoco`` prints of a run (:meth:`loopcheck.registry.Engine.result_lines`)."""

from __future__ import annotations

from loopcheck.run_text import energy_line, peak_lines, scene_lines, setting_text


def result_lines(scene, result) -> list[str]:
    """What ``loopcheck mujoco`` prints: the settings as run, peak input rate (every input's),
    loop violation, energy residual and cost."""
    used = result.settings  # as run (an automatic timestep resolved)
    return scene_lines(scene) + [
        f"settings         {used.integrator}, timestep {setting_text(used, 'timestep', ' s')}"
        f"{' (automatic)' if result.details.timestep_automatic else ''}, "
        f"solref {tuple(used.effective_solref or ())}, solimp {tuple(used.solimp)}, "
        f"refsafe {'on' if used.refsafe else 'off'}, diagexact {'on' if used.diagexact else 'off'}, "
        f"iterations {used.iterations}, tolerance {setting_text(used, 'tolerance')}, "
        f"MuJoCo {result.details.mujoco_version}",
        *peak_lines(scene, result),
        f"loop violation   {result.constraint_violation.max:.3e} m (largest over the run)",
        energy_line(result),
        f"cost             {result.n_steps} steps, {result.wall_s:.3f} s"]
