"""What ``loopcheck reduced`` prints of a run (:meth:`loopcheck.registry.Engine.result_lines`)."""

from __future__ import annotations

from loopcheck.run_text import energy_line, peak_text, scene_lines, setting_text


def result_lines(scene, result) -> list[str]:
    """What ``loopcheck reduced`` prints: the run's settings, peak input rate, error estimate,
    energy residual and cost (q in ``scene.input_unit``)."""
    used, unit = result.settings, scene.input_unit
    lines = scene_lines(scene) + [
        f"solver           {result.details.solver}  "
        + (f"step = {setting_text(used, 'step', ' s')}" if used.method == "rkn4"
           else f"rtol = {setting_text(used, 'rtol')}"),
        f"peak qdot        {peak_text(result.peak, unit)} (largest |qdot|)"]
    if len(result.inputs) > 1:  # several inputs: each one's peak, and the coordinate switches
        units = scene.input_units()
        lines[-1] = f"peak qdot        {scene.inputs[0]}: {peak_text(result.peak, units[0])} (largest |qdot|)"
        lines += [f"                 {name}: {peak_text(peak, u)}"
                  for name, (_, peak), u in zip(scene.inputs[1:], result.other_inputs, units[1:])]
        switches = result.details.switches
        lines.append(f"coordinates      {len(switches)} switch{'es' if len(switches) != 1 else ''}"
                     + "".join(f"; {s.old} → {s.new} at t = {s.time:.6g} s" for s in switches[:3])
                     + ("; …" if len(switches) > 3 else ""))
    estimate = result.details.error_estimate
    if estimate is not None:
        lines.append(f"error estimate   {estimate.q_abs:.3e} {unit} in q, {estimate.qdot_abs:.3e} "
                     f"{unit}/s in q̇: {estimate.relative:.3e} of the run's scale (tolerance rtol = "
                     f"{estimate.tolerance:g}; {estimate.method})")
    return lines + [energy_line(result),
                    f"cost             {result.n_steps} steps, {result.n_evaluations} evaluations, "
                    f"{result.wall_s:.3f} s"]
