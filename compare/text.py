"""Plain-text tables of a comparison, as the CLI prints them (the CLI only prints these lines).

Each difference the table prints is the exact difference of the two values it prints
beside it: both are written to the same number of decimals (enough for 3 significant
digits of their difference), and the difference is taken of those decimal strings.
"""

from __future__ import annotations

import math
from decimal import Decimal

from .diff import GateResult
from .run import Comparison

FLOAT_DIGITS = 17  # decimals beyond a double's precision only print noise


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


def comparison_lines(c: Comparison) -> list[str]:
    """The table of both engines' results and their differences, then the gate.

    The peak row holds the compared peaks of |ω| (``Difference.peak_omega_reference`` and
    ``peak_omega_other``: the same event in both runs, as magnitudes), not each engine's
    own signed extremum.
    """
    r, m, d = c.reduced, c.mujoco, c.diff
    ref = r.settings
    ref_label = f"{ref['solver']} " + (f"h={ref['step']:g}s" if ref["method"] == "rkn4" else f"rtol={ref['rtol']:g}")
    mj = m.settings
    mj_label = f"{mj['integrator']} dt={mj['timestep']:g}s"
    peak_r, peak_m, peak_d = printed_pair(d.peak_omega_reference, d.peak_omega_other)
    time_r, time_m, time_d = printed_pair(d.t_peak_reference, d.t_peak_other, digits=8)
    rows = [
        ("", f"reduced ({ref_label})", f"MuJoCo ({mj_label})", "difference (MuJoCo - reduced)"),
        ("peak |omega| (rad/s)", peak_r, peak_m, f"{peak_d} ({d.peak_omega_rel:.2e} rel)"),
        ("time of peak (s)", time_r, time_m, time_d),
        ("energy residual (rel)", f"{r.audit.relative_residual:.2e}", f"{m.audit.relative_residual:.2e}", ""),
        ("loop violation (m)", "-", f"{m.diagnostics['max_constraint_violation']:.2e}", ""),
        ("wall time (s)", f"{r.wall_s:.3f}", f"{m.wall_s:.3f}", ""),
        ("compared span (s)", "", "", f"{d.span_start:g} to {d.span_end:g} (horizon {d.horizon:g})"),
        ("max |dq| (rad)", "", "", f"{d.q_max_abs:.3e} (rms {d.q_rms:.2e})"),
        ("max |domega| (rad/s)", "", "", f"{d.omega_max_abs:.3e} (rms {d.omega_rms:.2e})"),
        ("max |domega| at equal q", "", "", f"{d.omega_vs_q_max_abs:.3e}"),
        ("branch mismatches", "", "", f"{c.branches.mismatches}"),
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = [f"scene: {c.scene.name} ({c.scene.source}); effects: {', '.join(c.scene.effects) or 'none'}"]
    lines += ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
    lines += [f"warning: {note}" for note in m.diagnostics.get("edge_warnings", [])]
    return lines + gate_lines(c.gate)


def gate_lines(g: GateResult) -> list[str]:
    """The gate's verdict with its tolerances, then one line per failing figure."""
    t = g.tolerances
    extra = f", omega_vs_q_atol {t.omega_vs_q_atol:g} rad/s" if t.omega_vs_q_atol is not None else ""
    head = (f"gate: {'PASSED' if g.passed else 'FAILED'} (peak_omega_rtol {t.peak_omega_rtol:g}, "
            f"peak_omega_atol {t.peak_omega_atol:g} rad/s, q_atol {t.q_atol:g} rad, "
            f"omega_atol {t.omega_atol:g} rad/s{extra})")
    return [head, *(f"  {failure}" for failure in g.failures)]
