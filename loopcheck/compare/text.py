"""Plain-text tables of a comparison, as the CLI prints them (the CLI only prints these lines).

Each difference the table prints is the exact difference of the two values it prints
beside it: both are written to the same number of decimals (enough for 3 significant
digits of their difference), and the difference is taken of those decimal strings.
"""

from __future__ import annotations

import math
from decimal import Decimal

from typing import TYPE_CHECKING

from .diff import GateResult

if TYPE_CHECKING:
    from .run import Comparison

FLOAT_DIGITS = 17  # decimals beyond a double's precision only print noise
# MuJoCo's runs: the scene's model ("mujoco") and a user's own as written (loopcheck.reference_models.user_model.ENGINE).
MUJOCO_RUNS = ("mujoco", "model")
# How tables and plots name an engine (loopcheck.registry.ENGINES by name); another engine by its name.
ENGINE_LABELS = {"reduced": "reduced", **{name: "MuJoCo" for name in MUJOCO_RUNS}, "pin": "Pinocchio", "mjx": "MJX",
                 "mjwarp": "MJWarp"}


def engine_label(engine: str) -> str:
    """The engine named ``engine`` as tables and plots name it (``MuJoCo``, ``Pinocchio``)."""
    return ENGINE_LABELS.get(engine, engine)


def settings_label(result) -> str:
    """A run's settings in a few words, for a table's column head: the reduced solver's method and
    step or rtol, a MuJoCo-family engine's integrator and timestep, another engine's solver and rtol."""
    used = result.settings
    if result.engine == "reduced":
        return f"{result.details.solver} " + (f"h={used.step:g}s" if used.method == "rkn4" else f"rtol={used.rtol:g}")
    if result.engine in MUJOCO_RUNS or getattr(used, "integrator", None) and getattr(used, "timestep", None):
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


STILL_RISING = "at the end of the horizon, still rising"


def peak_text(peak, unit: str) -> str:
    """A run's peak (:class:`loopcheck.trajectory.Peak`) as every table writes it: signed q̇ in
    ``unit``/s, its time, and when it is the horizon's end with |q̇| still rising, that."""
    return (f"{peak.omega:+.10g} {unit}/s at t = {peak.time:.10g} s"
            + (f", {STILL_RISING}" if peak.still_rising else ""))


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
    rate = f"{unit}/s"
    other = engine_label(m.engine)
    peak_r, peak_m, peak_d = printed_pair(d.peak_omega_reference, d.peak_omega_other)
    time_r, time_m, time_d = printed_pair(d.t_peak_reference, d.t_peak_other, digits=8)
    gap = "-" if m.constraint_violation is None else f"{m.constraint_violation.max:.2e}"
    rows = [
        ("", f"reduced ({settings_label(r)})", f"{other} ({settings_label(m)})", f"difference ({other} - reduced)"),
        (f"peak qdot ({rate})", peak_r, peak_m, f"{peak_d} ({d.peak_omega_rel:.2e} rel)"),
        ("time of peak (s)", time_r, time_m, time_d),
        ("energy residual (rel)", f"{r.audit.relative_residual:.2e}", f"{m.audit.relative_residual:.2e}", ""),
        ("loop violation (m)", "-", gap, ""),
        ("wall time (s)", f"{r.wall_s:.3f}", f"{m.wall_s:.3f}", ""),
        ("compared span (s)", "", "", f"{d.span_start:g} to {d.span_end:g} (horizon {d.horizon:g})"),
        (f"max |dq| ({unit})", "", "", f"{d.q_max_abs:.3e} (rms {d.q_rms:.2e})"),
        (f"max |dqdot| ({rate})", "", "", f"{d.omega_max_abs:.3e} (rms {d.omega_rms:.2e})"),
        (f"max |dqdot| at equal q ({rate})", "", "", f"{d.omega_vs_q_max_abs:.3e}"),
        ("assembly mode at q0", "", "", "(" + ", ".join(f"{v:+d}" for v in c.scene.mode) + ")"),
        ("mode mismatches (per loop)", "", "", ", ".join(str(n) for n in c.modes.mismatches) or "-"),
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = [f"scene: {c.scene.name} ({c.scene.source}); input {c.scene.mechanism.linkage.input_joint} "
             f"({unit}); effects: {', '.join(c.scene.effects) or 'none'}"]
    lines += ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
    rising = [name for name, p in (("reduced", d.peak_reference), (other, d.peak_other)) if p.still_rising]
    if rising:
        lines.append(f"peak: {STILL_RISING} ({' and '.join(rising)}): the horizon ends before the speed peaks")
    lines += [f"warning: {note}" for note in getattr(m.details, "edge_warnings", ())]
    return lines + gate_lines(c.gate, unit)


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


def setting_text(settings, name: str, unit: str = "") -> str:
    """A setting as printed: ``automatic`` when unset (None), floats with ``:g``."""
    value = getattr(settings, name)
    return "automatic" if value is None else f"{value:g}{unit}" if isinstance(value, float) else str(value)


def _scene_lines(scene) -> list[str]:
    linkage = scene.mechanism.linkage
    return [f"scene            {scene.name}  ({scene.source})",
            f"input            {linkage.input_joint} (q in {scene.input_unit}, mode "
            + "(" + ", ".join(f"{v:+d}" for v in scene.mode) + ") at q0)",
            f"effects          {', '.join(scene.effects) or 'none'}"]


def _energy_line(result) -> str:
    return (f"energy residual  {result.audit.max_abs_residual:.3e} J "
            f"({result.audit.relative_residual:.3e} of {result.audit.scale:.6g} J)")


def reduced_lines(scene, result) -> list[str]:
    """What ``loopcheck reduced`` prints: the run's settings, peak input rate, error estimate,
    energy residual and cost (q in ``scene.input_unit``)."""
    used, unit = result.settings, scene.input_unit
    lines = _scene_lines(scene) + [
        f"solver           {result.details.solver}  "
        + (f"step = {setting_text(used, 'step', ' s')}" if used.method == "rkn4"
           else f"rtol = {setting_text(used, 'rtol')}"),
        f"peak qdot        {peak_text(result.peak, unit)} (largest |qdot|)"]
    estimate = result.details.error_estimate
    if estimate is not None:
        lines.append(f"error estimate   {estimate.q_abs:.3e} {unit} in q, {estimate.qdot_abs:.3e} "
                     f"{unit}/s in q̇: {estimate.relative:.3e} of the run's scale (tolerance rtol = "
                     f"{estimate.tolerance:g}; {estimate.method})")
    return lines + [_energy_line(result),
                    f"cost             {result.n_steps} steps, {result.n_evaluations} evaluations, "
                    f"{result.wall_s:.3f} s"]


def mujoco_lines(scene, result) -> list[str]:
    """What ``loopcheck mujoco`` prints: the settings as run, peak input rate, loop violation,
    energy residual and cost."""
    used, unit = result.settings, scene.input_unit  # as run (an automatic timestep resolved)
    return _scene_lines(scene) + [
        f"settings         {used.integrator}, timestep {setting_text(used, 'timestep', ' s')}"
        f"{' (automatic)' if result.details.timestep_automatic else ''}, "
        f"solref {tuple(used.effective_solref or ())}, solimp {tuple(used.solimp)}, "
        f"refsafe {'on' if used.refsafe else 'off'}, diagexact {'on' if used.diagexact else 'off'}, "
        f"iterations {used.iterations}, tolerance {setting_text(used, 'tolerance')}, "
        f"MuJoCo {result.details.mujoco_version}",
        f"peak qdot        {peak_text(result.peak, unit)} (largest |qdot|)",
        f"loop violation   {result.constraint_violation.max:.3e} m (largest over the run)",
        _energy_line(result),
        f"cost             {result.n_steps} steps, {result.wall_s:.3f} s"]


def pin_lines(scene, result) -> list[str]:
    """What ``loopcheck pin`` prints: the settings as run, peak input rate, loop gap, energy residual
    and cost."""
    used, unit = result.settings, scene.input_unit
    return _scene_lines(scene) + [
        f"settings         {result.details.solver}, rtol {used.rtol:g}, atol {used.atol:g}, Baumgarte Kp {used.baumgarte_kp:g} "
        f"Kd {used.kd:g}, Pinocchio {result.details.pinocchio_version}",
        f"peak qdot        {peak_text(result.peak, unit)} (largest |qdot|)",
        f"loop violation   {result.constraint_violation.max:.3e} m (largest over the run)",
        _energy_line(result),
        f"cost             {result.n_steps} steps, {result.n_evaluations} evaluations, {result.wall_s:.3f} s"]


def port_lines(scene, result) -> list[str]:
    """What ``loopcheck mjx`` and ``loopcheck mjwarp`` print: the settings as run, peak input rate, loop gap
    and energy residual (MuJoCo C's, at the port's states), cost, and the port's known defects."""
    used, unit, details = result.settings, scene.input_unit, result.details
    device = getattr(details, "backend", None) or getattr(details, "device", None)
    return _scene_lines(scene) + [
        f"settings         {used.integrator}, timestep {used.timestep:g} s, solref {list(used.effective_solref)}, "
        f"{details.precision} on {device}, " + ", ".join(f"{k} {v}" for k, v in details.versions.items()),
        f"peak qdot        {peak_text(result.peak, unit)} (largest |qdot|)",
        f"loop violation   {result.constraint_violation.max:.3e} m (largest over the run)",
        _energy_line(result),
        f"cost             {result.n_steps} steps, compiled in {details.compile_s:.1f} s, run in {result.wall_s:.3f} s",
        *(f"known defect     {caveat}" for caveat in result.caveats)]


def check_lines(c: "Comparison") -> list[str]:
    """``loopcheck check``'s lines for one scene: status and figures, then each gate failure."""
    d, t, unit = c.diff, c.gate.tolerances, c.scene.input_unit
    status = "ok  " if c.gate.passed else "FAIL"
    return [f"{status}  {c.scene.source}: peak_omega_rel {d.peak_omega_rel:.2e} (tol {t.peak_omega_rtol:g}), "
            f"q_max_abs {d.q_max_abs:.2e} {unit} (tol {t.q_atol:g}), "
            f"omega_max_abs {d.omega_max_abs:.2e} {unit}/s (tol {t.omega_atol:g})",
            *(f"      {failure}" for failure in c.gate.failures)]
