"""Diff plots of a comparison (PNG, matplotlib's Agg backend: no display needed).

matplotlib is imported only when a plot is drawn. Names from scene files are plain text:
every text element that carries one is drawn with ``parse_math=False`` (a ``$...$`` in a
name is not mathtext), and names are shortened to :data:`NAME_CHARS` characters in titles.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from reduced.scene import MUJOCO_INTEGRATORS

if TYPE_CHECKING:  # the engines are not loaded to draw a plot (``xval draw`` needs neither)
    from .run import Comparison

NAME_CHARS = 60  # longest scene name shown in a title
PLAIN = {"parse_math": False}  # keyword for text elements that carry user text


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def short_name(name: str, limit: int = NAME_CHARS) -> str:
    """``name`` on one line, cut to ``limit`` characters with an ellipsis."""
    name = " ".join(name.split())
    return name if len(name) <= limit else name[:limit - 1] + "…"


REDUCED_STYLE = {"color": "tab:blue", "label": "reduced (Eksergian)"}
MUJOCO_STYLE = {"color": "tab:orange", "label": "MuJoCo", "linestyle": "--"}


def _save(fig, path: Path) -> None:
    plt = _pyplot()
    try:
        fig.tight_layout()
        fig.savefig(path, dpi=110, format="png")
    finally:
        plt.close(fig)


def _units(c: "Comparison") -> tuple[str, str]:
    """The input coordinate's unit and its rate's: ("rad", "rad/s") or ("m", "m/s")."""
    unit = c.scene.input_unit
    return unit, f"{unit}/s"


def plot_trajectories(c: "Comparison", path: Path) -> None:
    unit, rate = _units(c)
    plt = _pyplot()
    fig, (ax_q, ax_w) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for result, style in ((c.reduced, REDUCED_STYLE), (c.mujoco, MUJOCO_STYLE)):
        ax_q.plot(result.trajectory.t, result.trajectory.q, **style)
        ax_w.plot(result.trajectory.t, result.trajectory.qdot, **style)
    for result, style in ((c.reduced, REDUCED_STYLE), (c.mujoco, MUJOCO_STYLE)):
        ax_w.plot([result.peak.time], [result.peak.omega], "o", color=style["color"], markersize=5)
    ax_q.set_ylabel(f"input q ({unit})")
    ax_w.set_ylabel(f"input rate q̇ ({rate})")
    ax_w.set_xlabel("time t (s)")
    ax_q.set_title(f"{short_name(c.scene.name)}: input joint, both engines (dots: peak |q̇|)", **PLAIN)
    ax_q.legend(), ax_w.legend()
    ax_q.grid(alpha=0.3), ax_w.grid(alpha=0.3)
    _save(fig, path)


def plot_differences(c: "Comparison", path: Path) -> None:
    unit, rate = _units(c)
    d = c.diff
    plt = _pyplot()
    fig, (ax_q, ax_w) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax_q.plot(d.times, d.dq, color="tab:red", label="Δq = q_MuJoCo − q_reduced")
    ax_w.plot(d.times, d.domega, color="tab:red", label="Δq̇ = q̇_MuJoCo − q̇_reduced")
    tol = c.gate.tolerances
    for ax, limit in ((ax_q, tol.q_atol), (ax_w, tol.omega_atol)):
        ax.axhline(limit, color="grey", linestyle=":", label="gate tolerance")
        ax.axhline(-limit, color="grey", linestyle=":")
        ax.grid(alpha=0.3)
        ax.legend(loc="best")
    ax_q.set_ylabel(f"Δq ({unit})")
    ax_w.set_ylabel(f"Δq̇ ({rate})")
    ax_w.set_xlabel("time t (s)")
    ax_q.set_title(f"{short_name(c.scene.name)}: MuJoCo minus reduced reference on MuJoCo's sample times",
                   **PLAIN)
    _save(fig, path)


def plot_omega_vs_q(c: "Comparison", path: Path) -> None:
    unit, rate = _units(c)
    plt = _pyplot()
    fig, (ax, ax_d) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for result, style in ((c.reduced, REDUCED_STYLE), (c.mujoco, MUJOCO_STYLE)):
        ax.plot(result.trajectory.q, result.trajectory.qdot, **style)
    ax.set_ylabel(f"q̇ ({rate})")
    ax.set_title(f"{short_name(c.scene.name)}: input rate against input position (phase-free comparison)",
                 **PLAIN)
    ax.legend(), ax.grid(alpha=0.3)
    ax_d.plot(c.diff.q_samples, c.diff.domega_vs_q, ".", markersize=2, color="tab:red",
              label="Δq̇ at equal q")
    ax_d.set_xlabel(f"input q ({unit})")
    ax_d.set_ylabel(f"Δq̇(q) ({rate})")
    ax_d.legend(), ax_d.grid(alpha=0.3)
    _save(fig, path)


def plot_constraint_violation(c: "Comparison", path: Path) -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    times = c.mujoco.diagnostics["times"]
    violation = c.mujoco.diagnostics["constraint_violation"]
    ax.semilogy(times, np.maximum(violation, 1e-18), color="tab:orange", label="largest loop gap")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("loop-closure violation (m)")
    ax.set_title(f"{short_name(c.scene.name)}: MuJoCo equality-constraint violation "
                 f"(max {c.mujoco.diagnostics['max_constraint_violation']:.2e} m)", **PLAIN)
    ax.legend(), ax.grid(alpha=0.3, which="both")
    _save(fig, path)


def plot_energy(c: "Comparison", path: Path) -> None:
    plt = _pyplot()
    fig, (ax, ax_r) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for result, style in ((c.reduced, REDUCED_STYLE), (c.mujoco, MUJOCO_STYLE)):
        a = result.audit
        ls = style.get("linestyle", "-")
        name = style["label"].split()[0]
        ax.plot(a.t, a.kinetic, color="tab:green", linestyle=ls, label=f"kinetic ({name})")
        ax.plot(a.t, a.torque_work, color="tab:purple", linestyle=ls, label=f"{c.scene.load_name} work ({name})")
        ax.plot(a.t, a.damper_dissipation, color="tab:brown", linestyle=ls, label=f"damper dissipation ({name})")
        if np.any(a.potential != a.potential[0]):
            ax.plot(a.t, a.potential - a.potential[0], color="tab:grey", linestyle=ls,
                    label=f"potential − V0 ({name})")
        ax_r.plot(a.t, a.residual, color=style["color"], linestyle=ls, label=f"residual ({name})")
    ax.set_ylabel("energy (J)")
    ax.set_title(f"{short_name(c.scene.name)}: energy audit, T + V − (T0 + V0) − W + D = residual", **PLAIN)
    ax.legend(fontsize=8, ncol=2), ax.grid(alpha=0.3)
    ax_r.set_ylabel("residual (J)")
    ax_r.set_xlabel("time t (s)")
    ax_r.legend(fontsize=8), ax_r.grid(alpha=0.3)
    _save(fig, path)


def strip_moments(c: "Comparison") -> list[tuple[str, float]]:
    """The moments the mechanism strip shows: the reduced run's peak speed (the compared
    peak, ``diff.t_peak_reference``) and the sample of largest |Δq| (s)."""
    d = c.diff
    worst = float(d.times[int(np.argmax(np.abs(d.dq)))]) if len(d.times) else d.span_end
    return [("peak speed", float(d.t_peak_reference)), ("largest |Δq|", worst)]


def plot_mechanism_strip(c: "Comparison", path: Path) -> None:
    """The mechanism at the peak speed and at the largest disagreement, both engines
    overlaid (:func:`compare.draw.draw_strip`)."""
    from .draw import draw_strip

    draw_strip(c.scene, c.reduced.diagnostics["joints"], c.mujoco.diagnostics["joints"],
               strip_moments(c), path)


PLOTS = {
    "trajectories.png": plot_trajectories,
    "differences.png": plot_differences,
    "omega_vs_q.png": plot_omega_vs_q,
    "constraint_violation.png": plot_constraint_violation,
    "energy.png": plot_energy,
    "mechanism.png": plot_mechanism_strip,
}


SERIES_MARKERS = {"RKN4": ("tab:blue", "o", "-"), "DOP853": ("tab:cyan", "s", "-")}
# One colour per MuJoCo integrator, in the order reduced.scene lists them (the one list of names).
INTEGRATOR_COLOURS = dict(zip(MUJOCO_INTEGRATORS, ("tab:red", "tab:purple", "tab:brown", "tab:orange",
                                                   "tab:olive", "tab:pink")))


def plot_work_precision(measurements, front, target: float | None, scene_name: str, path: Path) -> None:
    """Log-log work-precision diagram: peak-ω relative error (x) against wall time (y)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(12, 6.5))
    series: dict[str, list] = {}
    for m in measurements:
        if m.ok and m.peak_omega_rel > 0:
            series.setdefault(m.config.series, []).append(m)
    for name, points in series.items():
        points = sorted(points, key=lambda m: -m.config.parameter)
        if name in SERIES_MARKERS:
            colour, marker, ls = SERIES_MARKERS[name]
        else:  # "MuJoCo <integrator> (<softness>)"
            integrator = name.split()[1]
            colour = INTEGRATOR_COLOURS.get(integrator, "grey")
            marker, ls = ("^", "--") if "(hard)" in name else ("v", ":")
        ax.loglog([m.peak_omega_rel for m in points], [m.wall_median_s for m in points],
                  marker=marker, linestyle=ls, color=colour, label=name, markersize=5)
    if front:
        ax.loglog([m.peak_omega_rel for m in front], [m.wall_median_s for m in front], color="black",
                  linewidth=2.5, alpha=0.35, label="Pareto front", zorder=0)
        ax.scatter([m.peak_omega_rel for m in front], [m.wall_median_s for m in front], s=110,
                   facecolors="none", edgecolors="black", zorder=5)
    if target:
        ax.axvline(target, color="green", linestyle="-.", label=f"target {target:g}")
    ax.set_xlabel("relative error of the peak input speed against the truth")
    ax.set_ylabel("wall time of the simulation (s, median)")
    ax.set_title(f"{short_name(scene_name)}: what accuracy costs (truth: DOP853 rtol 1e-12)", **PLAIN)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.text(0.01, 0.01, "lower left is better: accurate and cheap; circles: Pareto front",
            transform=ax.transAxes, fontsize=8, color="dimgray")
    _save(fig, path)
