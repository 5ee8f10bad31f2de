"""Plain-text tables of a comparison, as the CLI prints them (the CLI only prints these lines)."""

from __future__ import annotations

from .diff import GateResult
from .run import Comparison


def comparison_lines(c: Comparison) -> list[str]:
    """The table of both engines' results and their differences, then the gate."""
    r, m, d = c.reduced, c.mujoco, c.diff
    ref = r.settings
    ref_label = f"{ref['solver']} " + (f"h={ref['step']:g}s" if ref["method"] == "rkn4" else f"rtol={ref['rtol']:g}")
    mj = m.settings
    mj_label = f"{mj['integrator']} dt={mj['timestep']:g}s"
    rows = [
        ("", f"reduced ({ref_label})", f"MuJoCo ({mj_label})", "difference"),
        ("peak omega (rad/s)", f"{r.peak.omega:.10g}", f"{m.peak.omega:.10g}",
         f"{d.peak_omega_abs:.3e} ({d.peak_omega_rel:.2e} rel)"),
        ("time of peak (s)", f"{r.peak.time:.8g}", f"{m.peak.time:.8g}", f"{d.t_peak_abs:.3e}"),
        ("energy residual (rel)", f"{r.audit.relative_residual:.2e}", f"{m.audit.relative_residual:.2e}", ""),
        ("loop violation (m)", "-", f"{m.diagnostics['max_constraint_violation']:.2e}", ""),
        ("wall time (s)", f"{r.wall_s:.3f}", f"{m.wall_s:.3f}", ""),
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
    head = (f"gate: {'PASSED' if g.passed else 'FAILED'} (peak_omega_rtol {t.peak_omega_rtol:g}, "
            f"q_atol {t.q_atol:g} rad, omega_atol {t.omega_atol:g} rad/s)")
    return [head, *(f"  {failure}" for failure in g.failures)]
