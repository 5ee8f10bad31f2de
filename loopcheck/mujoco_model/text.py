"""What ``loopcheck mjx`` and ``loopcheck mjwarp`` print of a port's run (:meth:`loopcheck.registry.Engine.result_lines`)."""

from __future__ import annotations

from loopcheck.run_text import energy_line, peak_lines, scene_lines


def result_lines(scene, result) -> list[str]:
    """What ``loopcheck mjx`` and ``loopcheck mjwarp`` print: the settings as run, peak input rate
    (every input's, named, with several), loop gap and energy residual (MuJoCo C's, at the port's
    states), cost, and the port's known defects."""
    used, details = result.settings, result.details
    device = getattr(details, "backend", None) or getattr(details, "device", None)
    return scene_lines(scene) + [
        f"settings         {used.integrator}, timestep {used.timestep:g} s, solref {list(used.effective_solref)}, "
        f"{details.precision} on {device}, " + ", ".join(f"{k} {v}" for k, v in details.versions.items()),
        *peak_lines(scene, result),
        f"loop violation   {result.constraint_violation.max:.3e} m (largest over the run)",
        energy_line(result),
        f"cost             {result.n_steps} steps, compiled in {details.compile_s:.1f} s, run in {result.wall_s:.3f} s",
        *(f"known defect     {caveat}" for caveat in result.caveats)]
