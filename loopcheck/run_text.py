"""A run's lines as the commands print them, the parts every engine shares: the scene, the peak,
the energy residual, a setting (``loopcheck NAME``'s lines, :meth:`loopcheck.registry.Engine.result_lines`,
and the comparison's tables, :mod:`loopcheck.compare.text`). Imports nothing of the project: it reads
a scene's and a result's attributes."""

from __future__ import annotations


STILL_RISING = "at the end of the horizon, still rising"


def peak_text(peak, unit: str) -> str:
    """A run's peak (:class:`loopcheck.trajectory.Peak`) as every table writes it: signed q̇ in
    ``unit``/s, its time, and when it is the horizon's end with |q̇| still rising, that."""
    return (f"{peak.omega:+.10g} {unit}/s at t = {peak.time:.10g} s"
            + (f", {STILL_RISING}" if peak.still_rising else ""))


def setting_text(settings, name: str, unit: str = "") -> str:
    """A setting as printed: ``automatic`` when unset (None), floats with ``:g``."""
    value = getattr(settings, name)
    return "automatic" if value is None else f"{value:g}{unit}" if isinstance(value, float) else str(value)


def scene_lines(scene) -> list[str]:
    """The scene's three lines: its name and file, the input and assembly mode, the effects."""
    linkage = scene.mechanism.linkage
    mode = "(" + ", ".join(f"{v:+d}" for v in scene.mode) + ")"
    if len(linkage.inputs) > 1:  # several inputs: each with its unit, then the mode
        inputs = ", ".join(f"{name} ({unit})" for name, unit in zip(linkage.inputs, scene.input_units()))
        line = f"inputs           {inputs}, mode {mode} at q0"
    else:
        line = f"input            {linkage.input_joint} (q in {scene.input_unit}, mode {mode} at q0)"
    return [f"scene            {scene.name}  ({scene.source})", line,
            f"effects          {', '.join(scene.effects) or 'none'}"]


def peak_lines(scene, result) -> list[str]:
    """A run's peak line (``peak qdot``, its largest |q̇|), one per input with several inputs
    (named: ``peak qdot O5``), each in its input's unit."""
    if len(result.inputs) == 1:
        return [f"peak qdot        {peak_text(result.peak, scene.input_unit)} (largest |qdot|)"]
    return [f"{f'peak qdot {name}':<17}{peak_text(peak, unit)} (largest |qdot|)"
            for name, unit, (_, peak) in zip(scene.inputs, scene.input_units(), result.inputs)]


def energy_line(result) -> str:
    """A run's energy residual: absolute, and relative to the energy scale."""
    return (f"energy residual  {result.audit.max_abs_residual:.3e} J "
            f"({result.audit.relative_residual:.3e} of {result.audit.scale:.6g} J)")
