"""What ``loopcheck pin`` prints of a run (:meth:`loopcheck.registry.Engine.result_lines`)."""

from __future__ import annotations

from loopcheck.run_text import energy_line, peak_lines, scene_lines


def result_lines(scene, result) -> list[str]:
    """What ``loopcheck pin`` prints: the settings as run, peak input rate (every input's, named,
    with several), loop gap, energy residual and cost."""
    used = result.settings
    return scene_lines(scene) + [
        f"settings         {result.details.solver}, rtol {used.rtol:g}, atol {used.atol:g}, Baumgarte Kp {used.baumgarte_kp:g} "
        f"Kd {used.kd:g}, Pinocchio {result.details.pinocchio_version}",
        *peak_lines(scene, result),
        f"loop violation   {result.constraint_violation.max:.3e} m (largest over the run)",
        energy_line(result),
        f"cost             {result.n_steps} steps, {result.n_evaluations} evaluations, {result.wall_s:.3f} s"]
