"""Plain-text tables of a comparison, as the CLI prints them (the CLI only prints these lines).

Each difference the table prints is the exact difference of the two values it prints
beside it: both are written to the same number of decimals (enough for 3 significant
digits of their difference), and the difference is taken of those decimal strings.
"""

from __future__ import annotations

import math
from decimal import Decimal

from typing import TYPE_CHECKING

from loopcheck.registry import engine_of_run
from loopcheck.run_text import STILL_RISING, energy_line, peak_text, scene_lines, setting_text  # noqa: F401 - the tables' words

from .diff import GateResult

if TYPE_CHECKING:
    from .run import Comparison

FLOAT_DIGITS = 17  # decimals beyond a double's precision only print noise


def engine_label(engine: str) -> str:
    """The run named ``engine`` (an engine's, or another run of its package: a user's own model) as
    tables and plots name it (``MuJoCo``, ``Pinocchio``: :attr:`loopcheck.registry.Engine.label`); a
    run of no registered engine by its name."""
    owner = engine_of_run(engine)
    return owner.label if owner is not None else engine


def result_lines(scene, result) -> list[str]:
    """What ``loopcheck NAME`` prints of a run: the engine's own lines
    (:meth:`loopcheck.registry.Engine.result_lines`), else the lines every run has (the scene, the
    peak, the loop gap when recorded, the energy residual, the cost)."""
    owner = engine_of_run(result.engine)
    own = owner.result_lines(scene, result) if owner is not None else None
    if own is not None:
        return own
    gap = result.constraint_violation
    return scene_lines(scene) + [
        f"settings         {settings_label(result)}",
        f"peak qdot        {peak_text(result.peak, scene.input_unit)} (largest |qdot|)",
        *([f"loop violation   {gap.max:.3e} m (largest over the run)"] if gap is not None else []),
        energy_line(result),
        f"cost             {result.n_steps} steps, {result.wall_s:.3f} s"]


def settings_label(result) -> str:
    """A run's settings in a few words, for a table's column head: the engine's own words
    (:meth:`loopcheck.registry.Engine.settings_text`, e.g. the reduced solver's method and step or
    rtol), else an integrator and timestep where the settings have them, else a solver and rtol."""
    used = result.settings
    owner = engine_of_run(result.engine)
    own = owner.settings_text(result) if owner is not None else None
    if own is not None:
        return own
    if getattr(used, "integrator", None) and getattr(used, "timestep", None):
        return f"{used.integrator} dt={used.timestep:g}s"
    solver = getattr(result.details, "solver", None) or getattr(used, "method", "")
    rtol = getattr(used, "rtol", None)
    return f"{solver} rtol={rtol:g}" if rtol is not None else str(solver)


def printed_pair(reference: float, other: float, digits: int = 10) -> tuple[str, str, str]:
    """``reference`` and ``other`` at a common number of decimals, and other − reference.

    The decimals give ``digits`` significant digits of the larger value, or more (up to a
    double's 17) so that a non-zero difference shows at least 3 significant digits. The
    difference is the exact decimal difference of the two printed strings, so a reader
    subtracting the printed values gets the printed difference.
    """
    scale = max(abs(reference), abs(other))
    magnitude = math.floor(math.log10(scale)) if scale > 0.0 else 0
    decimals = digits - 1 - magnitude
    delta = abs(other - reference)
    if delta > 0.0:
        decimals = max(decimals, 2 - math.floor(math.log10(delta)))
    decimals = max(0, min(decimals, FLOAT_DIGITS - 1 - magnitude))
    a, b = f"{reference:.{decimals}f}", f"{other:.{decimals}f}"
    difference = Decimal(b) - Decimal(a)
    return a, b, "0" if difference == 0 else f"{difference.normalize():+e}"


def comparison_lines(c: "Comparison") -> list[str]:
    """The table of both engines' results and their differences, then the gate.

    The peak row holds the compared peak, signed (``Difference.peak_reference`` and
    ``peak_other``: the reduced run's largest |q̇| and the other engine's extremum of the same sign
    nearest in time, one event), followed by a line when it is at the end of the horizon,
    still rising. q is the input coordinate, in ``scene.input_unit`` (rad or m). The other
    engine (``c.other``, MuJoCo's run or another engine's) is named by :func:`engine_label`.
    """
    r, m, d = c.reference, c.other, c.diff
    unit = c.scene.input_unit
    several = c.scene.dof > 1
    other, reference = engine_label(m.engine), engine_label(r.engine)
    gap = "-" if m.constraint_violation is None else f"{m.constraint_violation.max:.2e}"
    head = ("", f"{reference} ({settings_label(r)})", f"{other} ({settings_label(m)})", f"difference ({other} - {reference})")

    def input_rows(d, unit: str, prefix: str = "") -> tuple[list[tuple], list[tuple]]:
        """One input's peak rows and difference rows (``prefix`` names it with several inputs)."""
        rate = f"{unit}/s"
        peak_r, peak_m, peak_d = printed_pair(d.peak_omega_reference, d.peak_omega_other)
        time_r, time_m, time_d = printed_pair(d.t_peak_reference, d.t_peak_other, digits=8)
        return ([(f"{prefix}peak qdot ({rate})", peak_r, peak_m, f"{peak_d} ({d.peak_omega_rel:.2e} rel)"),
                 (f"{prefix}time of peak (s)", time_r, time_m, time_d)],
                [(f"{prefix}max |dq| ({unit})", "", "", f"{d.q_max_abs:.3e} (rms {d.q_rms:.2e})"),
                 (f"{prefix}max |dqdot| ({rate})", "", "", f"{d.omega_max_abs:.3e} (rms {d.omega_rms:.2e})"),
                 (f"{prefix}max |dqdot| at equal q ({rate})", "", "", f"{d.omega_vs_q_max_abs:.3e}")])

    per_input = [input_rows(di, u, f"{name} " if several else "")
                 for di, u, name in zip(c.diffs, c.scene.input_units(), c.scene.inputs)]
    rows = [head, *(row for peaks, _ in per_input for row in peaks),
            ("energy residual (rel)", f"{r.audit.relative_residual:.2e}", f"{m.audit.relative_residual:.2e}", ""),
            ("loop violation (m)", "-", gap, ""),
            ("wall time (s)", f"{r.wall_s:.3f}", f"{m.wall_s:.3f}", ""),
            ("compared span (s)", "", "", f"{d.span_start:g} to {d.span_end:g} (horizon {d.horizon:g})"),
            *(row for _, differences in per_input for row in differences),
            ("assembly mode at q0", "", "", "(" + ", ".join(f"{v:+d}" for v in c.scene.mode) + ")"),
            ("mode mismatches (per loop)", "", "", ", ".join(str(n) for n in c.modes.mismatches) or "-")]
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    inputs = (f"inputs {', '.join(f'{name} ({u})' for name, u in zip(c.scene.inputs, c.scene.input_units()))}"
              if several else f"input {c.scene.mechanism.linkage.input_joint} ({unit})")
    lines = [f"scene: {c.scene.name} ({c.scene.source}); {inputs}; effects: {', '.join(c.scene.effects) or 'none'}"]
    lines += ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
    for name, di in zip(c.scene.inputs, c.diffs):
        rising = [engine for engine, p in ((reference, di.peak_reference), (other, di.peak_other)) if p.still_rising]
        if rising:
            lines.append(f"peak{f' of {name}' if several else ''}: {STILL_RISING} ({' and '.join(rising)}): the horizon "
                         "ends before the speed peaks")
    lines += [f"warning: {note}" for note in getattr(m.details, "edge_warnings", ())]
    return lines + gate_lines(c.gate, gate_unit(c.scene))


def gate_unit(scene) -> str:
    """The unit the gate's tolerances are read in, for its head line: the input's ("rad" or "m"),
    the inputs' when they share one, else "rad or m" (mixed inputs: each value is read in each
    input's own unit, :func:`loopcheck.compare.diff.gate_inputs`)."""
    units = set(scene.input_units())
    return units.pop() if len(units) == 1 else "rad or m"


def gate_lines(g: GateResult, unit: str = "rad") -> list[str]:
    """The gate's verdict with its tolerances (q in ``unit``, rates in it per s), then one
    line per failing figure."""
    t = g.tolerances
    rate = f"{unit}/s"
    extra = f", omega_vs_q_atol {t.omega_vs_q_atol:g} {rate}" if t.omega_vs_q_atol is not None else ""
    head = (f"gate: {'PASSED' if g.passed else 'FAILED'} (peak_omega_rtol {t.peak_omega_rtol:g}, "
            f"peak_omega_atol {t.peak_omega_atol:g} {rate}, q_atol {t.q_atol:g} {unit}, "
            f"omega_atol {t.omega_atol:g} {rate}{extra})")
    return [head, *(f"  {failure}" for failure in g.failures)]


def check_lines(c: "Comparison") -> list[str]:
    """``loopcheck check``'s lines for one scene: status and figures, then each gate failure."""
    t = c.gate.tolerances
    status = "ok  " if c.gate.passed else "FAIL"

    def figures(d, unit: str) -> str:
        return (f"peak_omega_rel {d.peak_omega_rel:.2e} (tol {t.peak_omega_rtol:g}), "
                f"q_max_abs {d.q_max_abs:.2e} {unit} (tol {t.q_atol:g}), "
                f"omega_max_abs {d.omega_max_abs:.2e} {unit}/s (tol {t.omega_atol:g})")

    if c.scene.dof == 1:
        head = [f"{status}  {c.scene.source}: {figures(c.diff, c.scene.input_unit)}"]
    else:  # a line per input, named
        head = [f"{status}  {c.scene.source}: {c.scene.dof} inputs",
                *(f"      {name}: {figures(d, unit)}"
                  for name, unit, d in zip(c.scene.inputs, c.scene.input_units(), c.diffs))]
    return [*head, *(f"      {failure}" for failure in c.gate.failures)]
