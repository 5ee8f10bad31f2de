"""Diff plots of a comparison (PNG, matplotlib's Agg backend: no display needed).

matplotlib is imported only when a plot is drawn, and pyplot never: each figure is a
``matplotlib.figure.Figure`` on its own Agg canvas (:func:`new_figure`), so no global figure
state is kept and nothing needs closing. The layout is fixed margins in inches
(:func:`new_figure`), not ``tight_layout``: a layout engine makes ``savefig`` draw every
figure twice. The margins leave room for the labels these plots carry (tests/compare/test_startup.py
checks that no text leaves the image). Names from scene files are plain text:
every text element that carries one is drawn with ``parse_math=False`` (a ``$...$`` in a
name is not mathtext), and names are shortened to :data:`NAME_CHARS` characters in titles.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np


from loopcheck.registry import engine_of_run

from .text import STILL_RISING, engine_label

if TYPE_CHECKING:  # the engines are not loaded to draw a plot (``loopcheck draw`` needs neither)
    from .engines import EnginesCheck
    from .run import Comparison

NAME_CHARS = 60  # longest scene name shown in a title
SUBTITLE_CHARS = 76  # longest line under a title (the title is centred over the axes, not the figure)
PLAIN = {"parse_math": False}  # keyword for text elements that carry user text


DPI = 110  # every PNG: figure inches × 110 pixels
# Fixed margins (inches) of a plot with a title above and an x label below; wide enough for
# tick labels like "−0.0010" or "1e-06" and a y label beside them.
MARGINS = {"left": 1.0, "right": 0.25, "bottom": 0.6, "top": 0.45, "hspace": 0.3, "wspace": 0.3}


# matplotlib imported ahead of a plot by a thread (:func:`prefetch_matplotlib`), while it runs
_PREFETCH: list = []


def prefetch_matplotlib() -> None:
    """Start importing what :func:`new_figure` and :func:`_save` import (matplotlib's figure, its Agg
    canvas, PIL's image plugins: ~0.35 s) in a thread of this process, for a caller that waits on
    other processes meanwhile (a sweep's parent on its pool: the import then runs while the
    parent would sit idle, not after the rows). Nothing else changes: the plots draw as before.

    Every fork of this process waits for the import first (``os.register_at_fork``), so that no
    child (a replaced pool worker, a file writer) starts with an import lock held by a thread
    it does not have (the one module of those imports that registers fork hooks itself,
    matplotlib's font manager, registers one for the child only; logging's, a pair, are
    registered before the thread starts); :func:`finish_prefetch` waits for it before a plot
    imports matplotlib itself. An import that fails here is left to the plot's own import to
    report."""
    if _PREFETCH:
        return
    import logging  # noqa: F401 - its fork hooks come in pairs: registered here, not mid-fork by the thread
    import os
    import threading

    def load() -> None:
        try:
            import matplotlib.backends.backend_agg  # noqa: F401
            import matplotlib.figure  # noqa: F401
            from PIL import Image

            Image.preinit()  # the plugins savefig's PNG writer loads
        except Exception:  # noqa: BLE001 - the plot's own import raises it again, in its place
            pass

    thread = threading.Thread(target=load, name="loopcheck-matplotlib", daemon=True)
    _PREFETCH.append(thread)
    os.register_at_fork(before=finish_prefetch)
    thread.start()


def finish_prefetch() -> None:
    """Wait for :func:`prefetch_matplotlib`'s import, if one was started and still runs."""
    import threading

    for thread in _PREFETCH:
        if thread.is_alive() and thread is not threading.current_thread():
            thread.join()


def new_figure(figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, *, squeeze: bool = True,
               margins: dict | None = None, **subplots):
    """A figure of ``figsize`` inches on an Agg canvas (no pyplot), with fixed margins.

    ``margins`` overrides :data:`MARGINS` (left, right, bottom, top in inches; hspace and
    wspace in inches between axes). Returns (figure, axes) like ``pyplot.subplots``."""
    finish_prefetch()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=DPI)
    FigureCanvasAgg(fig)
    m = {**MARGINS, **(margins or {})}
    width, height = figsize
    ax_w = (width - m["left"] - m["right"] - (ncols - 1) * m["wspace"]) / ncols
    ax_h = (height - m["bottom"] - m["top"] - (nrows - 1) * m["hspace"]) / nrows
    fig.subplots_adjust(left=m["left"] / width, right=1.0 - m["right"] / width,
                        bottom=m["bottom"] / height, top=1.0 - m["top"] / height,
                        wspace=m["wspace"] / ax_w, hspace=m["hspace"] / ax_h)
    return fig, fig.subplots(nrows, ncols, squeeze=squeeze, **subplots)


def short_name(name: str, limit: int = NAME_CHARS) -> str:
    """``name`` on one line, cut to ``limit`` characters with an ellipsis."""
    name = " ".join(name.split())
    return name if len(name) <= limit else name[:limit - 1] + "…"


REDUCED_STYLE = {"color": "tab:blue", "label": "reduced (Eksergian)"}
MUJOCO_STYLE = {"color": "tab:orange", "label": "MuJoCo", "linestyle": "--"}


def engine_colour(engine: str) -> str:
    """The colour of the run named ``engine`` (:attr:`loopcheck.registry.Engine.colour`: declared,
    else the registry's palette); black for a run of no registered engine."""
    owner = engine_of_run(engine)
    return owner.colour if owner is not None else "black"


def other_style(c: "Comparison") -> dict:
    """The style of the engine compared with the reference (``c.other``: MuJoCo's run or another's):
    dashed, in its colour, labelled by its name."""
    return {**MUJOCO_STYLE, "color": engine_colour(c.other.engine), "label": engine_label(c.other.engine)}


def engine_colours(engines) -> dict[str, str]:
    """A colour for each engine name of ``engines``: its own (:func:`engine_colour`)."""
    return {name: engine_colour(name) for name in engines}


_SUPERSCRIPT = str.maketrans("0123456789-−+", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁻⁺")


def plain_power(label: str) -> str:
    """A log-axis tick label of matplotlib's ``LogFormatterSciNotation`` (mathtext such as
    ``$\\mathdefault{2\\times10^{-7}}$``) as plain text (``2×10⁻⁷``): the same label without
    loading the mathtext parser, which costs more than a whole plot."""
    import re

    if not label.startswith("$"):
        return label
    text = label.strip("$")
    text = re.sub(r"\\mathdefault\{(.*)\}$", r"\1", text)
    text = text.replace("\\times", "×").replace("\\cdot", "·").replace("\\minus", "-")
    text = re.sub(r"\^\{([^}]*)\}", lambda m: m.group(1).translate(_SUPERSCRIPT), text)
    return text.replace("{", "").replace("}", "").replace("\\", "")


def plain_log_axis(axis) -> None:
    """Label a log-scaled axis (``ax.xaxis``/``ax.yaxis``) as matplotlib does, in plain text
    (:func:`plain_power`): the same ticks and labels, major and minor."""
    from matplotlib.ticker import Formatter

    class Plain(Formatter):
        """matplotlib's formatter ``inner`` (which decides what is labelled), its labels in plain text."""

        def __init__(self, inner):
            self.inner = inner

        def set_axis(self, axis):
            super().set_axis(axis)
            self.inner.set_axis(axis)

        def set_locs(self, locs):
            super().set_locs(locs)
            self.inner.set_locs(locs)

        def __call__(self, x, pos=None):
            return plain_power(self.inner(x, pos))

        def format_data(self, value):
            return plain_power(self.inner.format_data(value))

    axis.set_major_formatter(Plain(axis.get_major_formatter()))
    axis.set_minor_formatter(Plain(axis.get_minor_formatter()))


def _save(fig, path: Path) -> None:
    """Render ``fig`` once into ``path`` (at :data:`DPI`) in the format its suffix names (png,
    or pdf and svg for ``loopcheck draw``). PNG at zlib level 1: a third less time compressing than
    the default 6, for files ~6 % larger (plots are mostly white)."""
    fmt = Path(path).suffix.lower().lstrip(".")
    with open(path, "wb") as f:  # closed however savefig ends (a signal mid-write left PIL's file open)
        fig.savefig(f, dpi=DPI, format=fmt, **({"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}))


def _units(c: "Comparison") -> tuple[str, str]:
    """The input coordinate's unit and its rate's: ("rad", "rad/s") or ("m", "m/s")."""
    unit = c.scene.input_unit
    return unit, f"{unit}/s"


def plot_trajectories(c: "Comparison", path: Path) -> None:
    """q and q̇ of both engines against time; dots mark the compared peak, one event in both
    (``diff.peak_reference`` and ``peak_other``: the reduced run's largest |q̇| and the other
    engine's extremum of the same sign nearest in time), and the title says when it is the end of the
    horizon with the speed still rising. With several inputs, one column per input
    (:func:`_trajectories_by_input`)."""
    if c.scene.dof > 1:
        return _trajectories_by_input(c, path)
    unit, rate = _units(c)
    rising = c.diff.peak_still_rising
    fig, (ax_q, ax_w) = new_figure((8, 6 + 0.25 * rising), 2, 1, sharex=True,
                                   margins={"top": 0.45 + 0.25 * rising})
    other = other_style(c)
    for result, style in ((c.reference, REDUCED_STYLE), (c.other, other)):
        ax_q.plot(result.trajectory.t, result.trajectory.q, **style)
        ax_w.plot(result.trajectory.t, result.trajectory.qdot, **style)
    # The reduced run's dot larger: where the two coincide, both show.
    for peak, style, size in ((c.diff.peak_reference, REDUCED_STYLE, 8), (c.diff.peak_other, other, 4.5)):
        ax_w.plot([peak.time], [peak.omega], "o", color=style["color"], markersize=size)
    ax_q.set_ylabel(f"input q ({unit})")
    ax_w.set_ylabel(f"input rate q̇ ({rate})")
    ax_w.set_xlabel("time t (s)")
    title = f"{short_name(c.scene.name)}: input joint, both engines (dots: the compared peak q̇)"
    if rising:
        title += f"\npeak {STILL_RISING}: the horizon ends before the speed peaks"
    ax_q.set_title(title, **PLAIN)
    ax_q.legend(), ax_w.legend()
    ax_q.grid(alpha=0.3), ax_w.grid(alpha=0.3)
    _save(fig, path)


TOLERANCE_DECADE = 10.0  # a tolerance band is drawn when within this factor of the largest difference
DATA_MARGIN = 0.08  # y-axis padding beyond the plotted values, a fraction of their range
LEGEND_ROOM = 0.45  # inches above each axes of the differences plot for its two-line legend


def tolerance_band(largest: float, tolerance: float, unit: str) -> tuple[bool, str]:
    """Whether a tolerance ±``tolerance`` is drawn as a band on an axis scaled to differences
    whose largest magnitude is ``largest`` (both in ``unit``), and its legend text.

    The band is drawn when it is within a decade of the data (largest/10 ≤ tolerance ≤
    10·largest); otherwise the legend says how far off scale it is, e.g. ``tolerance ±0.1
    rad/s: off scale, 80× the largest difference``.
    """
    text = f"gate tolerance ±{tolerance:g} {unit}"
    if largest > 0.0 and largest / TOLERANCE_DECADE <= tolerance <= TOLERANCE_DECADE * largest:
        return True, text
    if largest == 0.0:
        return False, f"{text}: off scale, every difference is 0"
    ratio = tolerance / largest
    where = "off scale" if ratio > 1.0 else "too narrow to show"
    return False, f"{text}: {where}, {ratio:.3g}× the largest difference"


def scaled_limits(values: np.ndarray, band: float | None = None) -> tuple[float, float]:
    """y limits enclosing ``values`` (and ±``band`` when given), padded by DATA_MARGIN of their
    range; a flat or empty series gets a range of ±1 % of its magnitude (±1 when zero)."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    lo = float(values.min()) if values.size else 0.0
    hi = float(values.max()) if values.size else 0.0
    if band is not None:
        lo, hi = min(lo, -band), max(hi, band)
    span = hi - lo
    if span <= 0.0:
        half = 0.01 * abs(hi) or 1.0
        return lo - half, hi + half
    return lo - DATA_MARGIN * span, hi + DATA_MARGIN * span


def plot_differences(c: "Comparison", path: Path, subtitle: str | None = None) -> None:
    """Δq and Δq̇ (MuJoCo or the other engine minus reduced) against time, each axis scaled to its data; the
    gate's tolerance is a grey band only where it is within a decade of the data, and the
    legend says so otherwise (:func:`tolerance_band`). ``subtitle`` (plain text, lines of up
    to SUBTITLE_CHARS characters: longer ones are cut) goes under the title, e.g. which variant
    of a sweep this is. With several inputs, one column per input (:func:`_differences_by_input`)."""
    from matplotlib.lines import Line2D

    if c.scene.dof > 1:
        return _differences_by_input(c, path, subtitle)
    unit, rate = _units(c)
    d = c.diff
    extra = [short_name(line, SUBTITLE_CHARS) for line in subtitle.splitlines()] if subtitle else []
    # Each legend stands above its axes (the data fill the axes: no corner is free of them).
    fig, (ax_q, ax_w) = new_figure((8, 6.9 + 0.25 * len(extra)), 2, 1, sharex=True,
                                   margins={"top": 0.45 + LEGEND_ROOM + 0.25 * len(extra),
                                            "hspace": 0.3 + LEGEND_ROOM})
    tol = c.gate.tolerances
    other = engine_label(c.other.engine)
    for ax, values, limit, u, label in (
            (ax_q, d.dq, tol.q_atol, unit, f"Δq = q_{other} − q_reduced"),
            (ax_w, d.domega, tol.omega_atol, rate, f"Δq̇ = q̇_{other} − q̇_reduced")):
        ax.plot(d.times, values, color="tab:red", label=label)
        largest = float(np.max(np.abs(values))) if len(values) else 0.0
        drawn, text = tolerance_band(largest, limit, u)
        if drawn:
            ax.axhspan(-limit, limit, color="0.85", alpha=0.6, zorder=0, label=text)
        else:  # a legend entry without a mark: the tolerance is named, not drawn
            ax.add_line(Line2D([], [], linestyle="none", label=text))
        ax.set_ylim(*scaled_limits(values, limit if drawn else None))
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=8.5, frameon=False,
                  borderaxespad=0.2, handlelength=1.5)  # right: the axis' offset (1e-6) is at the left
    ax_q.set_ylabel(f"Δq ({unit})")
    ax_w.set_ylabel(f"Δq̇ ({rate})")
    ax_w.set_xlabel("time t (s)")
    title = f"{short_name(c.scene.name)}: {other} minus reduced reference on {other}'s sample times"
    ax_q.set_title("\n".join([title, *extra]), pad=6 + 72 * LEGEND_ROOM, **PLAIN)  # above the legend
    _save(fig, path)


def plot_omega_vs_q(c: "Comparison", path: Path) -> None:
    """q̇ against q of both engines, and Δq̇ at equal q; with several inputs, one column per input
    (:func:`_omega_vs_q_by_input`)."""
    if c.scene.dof > 1:
        return _omega_vs_q_by_input(c, path)
    unit, rate = _units(c)
    fig, (ax, ax_d) = new_figure((8, 6), 2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for result, style in ((c.reference, REDUCED_STYLE), (c.other, other_style(c))):
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


# Several inputs: small multiples, one column per input, each with its own unit and scale.
COLUMN_INCHES = 5.2  # width of one input's column (room for a tolerance legend beside the axis offset)


def _columns(c: "Comparison", height: float, rows: int, *, top: float = 0.75, hspace: float = 0.3, **subplots):
    """A figure of ``rows`` rows and one column per input of ``c``'s scene, and each column's input
    (name, unit, its trajectories' pair (reference, other) and its Difference)."""
    n = c.scene.dof
    fig, axes = new_figure((COLUMN_INCHES * n + 1.0, height), rows, n, squeeze=False,
                           margins={"top": top, "hspace": hspace, "wspace": 1.0}, **subplots)
    inputs = [(name, unit, (ref, oth), d) for name, unit, (ref, _), (oth, _), d in
              zip(c.scene.inputs, c.scene.input_units(), c.reference.inputs, c.other.inputs, c.diffs)]
    return fig, axes, inputs


def _trajectories_by_input(c: "Comparison", path: Path) -> None:
    other = other_style(c)
    fig, axes, inputs = _columns(c, 6.2, 2, sharex=True)
    rising = []
    for k, (name, unit, runs, d) in enumerate(inputs):
        ax_q, ax_w = axes[0][k], axes[1][k]
        for trajectory, style in zip(runs, (REDUCED_STYLE, other)):
            ax_q.plot(trajectory.t, trajectory.q, **style)
            ax_w.plot(trajectory.t, trajectory.qdot, **style)
        for peak, style, size in ((d.peak_reference, REDUCED_STYLE, 8), (d.peak_other, other, 4.5)):
            ax_w.plot([peak.time], [peak.omega], "o", color=style["color"], markersize=size)
        ax_q.set_title(f"input {name} ({unit})", fontsize=10, **PLAIN)
        ax_q.set_ylabel(f"q of {name} ({unit})", **PLAIN)
        ax_w.set_ylabel(f"q̇ of {name} ({unit}/s)", **PLAIN)
        ax_w.set_xlabel("time t (s)")
        ax_q.grid(alpha=0.3), ax_w.grid(alpha=0.3)
        if d.peak_still_rising:
            rising.append(name)
    axes[0][0].legend(fontsize=8)
    title = f"{short_name(c.scene.name)}: every input, both engines (dots: each input's compared peak q̇)"
    if rising:
        title += f"; peak of {', '.join(rising)} {STILL_RISING}"
    fig.suptitle(title, y=1.0 - 0.12 / 6.2, fontsize=11, **PLAIN)
    _save(fig, path)


def _differences_by_input(c: "Comparison", path: Path, subtitle: str | None = None) -> None:
    from matplotlib.lines import Line2D

    extra = [short_name(line, SUBTITLE_CHARS) for line in subtitle.splitlines()] if subtitle else []
    height = 7.2 + 0.25 * len(extra)
    fig, axes, inputs = _columns(c, height, 2, sharex=True, top=0.75 + LEGEND_ROOM + 0.25 * len(extra),
                                 hspace=0.3 + LEGEND_ROOM)
    tol = c.gate.tolerances
    other = engine_label(c.other.engine)
    for k, (name, unit, _, d) in enumerate(inputs):
        for ax, values, limit, u, label in (
                (axes[0][k], d.dq, tol.q_atol, unit, f"Δq = q_{other} − q_reduced"),
                (axes[1][k], d.domega, tol.omega_atol, f"{unit}/s", f"Δq̇ = q̇_{other} − q̇_reduced")):
            ax.plot(d.times, values, color="tab:red", label=label)
            largest = float(np.max(np.abs(values))) if len(values) else 0.0
            drawn, text = tolerance_band(largest, limit, u)
            if drawn:
                ax.axhspan(-limit, limit, color="0.85", alpha=0.6, zorder=0, label=text)
            else:
                ax.add_line(Line2D([], [], linestyle="none", label=text))
            ax.set_ylim(*scaled_limits(values, limit if drawn else None))
            ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))  # short ticks: an offset (1e-5) instead
            ax.grid(alpha=0.3)
            ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=7.5, frameon=False,
                      borderaxespad=0.2, handlelength=1.5)
        axes[0][k].set_ylabel(f"Δq of {name} ({unit})", **PLAIN)
        axes[1][k].set_ylabel(f"Δq̇ of {name} ({unit}/s)", **PLAIN)
        axes[1][k].set_xlabel("time t (s)")
        axes[0][k].set_title(f"input {name}", pad=6 + 72 * LEGEND_ROOM, fontsize=10, **PLAIN)
    title = f"{short_name(c.scene.name)}: {other} minus reduced reference, every input, on {other}'s sample times"
    fig.suptitle("\n".join([title, *extra]), y=1.0 - 0.12 / height, fontsize=11, **PLAIN)
    _save(fig, path)


def _omega_vs_q_by_input(c: "Comparison", path: Path) -> None:
    fig, axes, inputs = _columns(c, 6.2, 2, gridspec_kw={"height_ratios": [2, 1]})
    for k, (name, unit, runs, d) in enumerate(inputs):
        ax, ax_d = axes[0][k], axes[1][k]
        ax.sharex(ax_d)
        for trajectory, style in zip(runs, (REDUCED_STYLE, other_style(c))):
            ax.plot(trajectory.q, trajectory.qdot, **style)
        ax.set_ylabel(f"q̇ of {name} ({unit}/s)", **PLAIN)
        ax.set_title(f"input {name}", fontsize=10, **PLAIN)
        ax.grid(alpha=0.3)
        ax_d.plot(d.q_samples, d.domega_vs_q, ".", markersize=2, color="tab:red", label="Δq̇ at equal q")
        ax_d.set_xlabel(f"q of {name} ({unit})", **PLAIN)
        ax_d.set_ylabel(f"Δq̇(q) ({unit}/s)")
        ax_d.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8), axes[1][0].legend(fontsize=8)
    fig.suptitle(f"{short_name(c.scene.name)}: each input's rate against its position (phase-free comparison)",
                 y=1.0 - 0.12 / 6.2, fontsize=11, **PLAIN)
    _save(fig, path)


def plot_constraint_violation(c: "Comparison", path: Path) -> None:
    """The other engine's largest loop gap over time (MuJoCo's equality constraints, Pinocchio's
    point constraints); an engine that records none says so."""
    fig, ax = new_figure((8, 4))
    violation = c.other.constraint_violation
    what = f"{engine_label(c.other.engine)} loop-closure violation"
    if violation is None:
        ax.text(0.5, 0.5, f"{engine_label(c.other.engine)} records no loop gap", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_title(f"{short_name(c.scene.name)}: {what}", **PLAIN)
        _save(fig, path)
        return
    ax.semilogy(violation.t, np.maximum(violation.gap, 1e-18), color="tab:orange", label="largest loop gap")
    plain_log_axis(ax.yaxis)
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("loop-closure violation (m)")
    ax.set_title(f"{short_name(c.scene.name)}: {what} (max {violation.max:.2e} m)", **PLAIN)
    ax.legend(), ax.grid(alpha=0.3, which="both")
    _save(fig, path)


def plot_energy(c: "Comparison", path: Path) -> None:
    fig, (ax, ax_r) = new_figure((8, 6), 2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    mech = c.scene.mechanism
    # the audit's work is every load's (the input's, the actuators'), its dissipation the dampers' and the friction's
    work = "loads' work" if mech.actuators else f"{c.scene.load_name} work"
    dissipation = "dissipation (dampers, friction)" if mech.joint_frictions else "damper dissipation"
    for result, style in ((c.reference, REDUCED_STYLE), (c.other, other_style(c))):
        a = result.audit
        ls = style.get("linestyle", "-")
        name = style["label"].split()[0]
        ax.plot(a.t, a.kinetic, color="tab:green", linestyle=ls, label=f"kinetic ({name})")
        ax.plot(a.t, a.torque_work, color="tab:purple", linestyle=ls, label=f"{work} ({name})")
        ax.plot(a.t, a.damper_dissipation, color="tab:brown", linestyle=ls, label=f"{dissipation} ({name})")
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


def partial_difference(reference, partial, until: float | None) -> tuple[np.ndarray, np.ndarray]:
    """|q̇_partial − q̇_reference| at the partial run's sample times up to ``until`` (s; all of
    them when None): the reference interpolated there (its dense output)."""
    t = np.asarray(partial.trajectory.t)
    keep = t <= until if until is not None else np.ones(len(t), dtype=bool)
    keep &= (t >= reference.trajectory.t[0]) & (t <= reference.trajectory.t[-1])
    _, rate, _ = reference.trajectory.interpolate(t[keep])
    return t[keep], np.abs(np.asarray(partial.trajectory.qdot)[keep] - rate)


def plot_engines(check: "EnginesCheck", path: Path) -> None:
    """|Δq̇| = |q̇_engine − q̇_reduced| of every engine judged (``loopcheck run --engines``) against
    time, on a log scale, one line per engine on its own sample times (the differences of
    ``differences.png``; a sample where it is exactly 0 is left out); the legend gives each
    engine's largest |Δq̇|, its tolerance and verdict; an engine that failed part-way (a loop gap
    beyond its bound) is drawn up to the failure's time and said to have failed there; one that
    did not run at all is said so."""
    rate = f"{check.scene.input_unit}/s"
    fig, ax = new_figure((8, 4.8), margins={"left": 1.05})
    ax.set_yscale("log")  # before the plain labels: set_yscale puts matplotlib's mathtext formatter back
    plain_log_axis(ax.yaxis)
    colours = engine_colours([v.engine for v in check.verdicts])
    for v in check.verdicts:
        label = engine_label(v.engine)
        if v.comparison is None and v.partial is not None:  # failed part-way: drawn up to the failure
            t, size = partial_difference(check.reference, v.partial, v.failed_at)
            when = "" if v.failed_at is None else f" at t = {v.failed_at:.4g} s"
            ax.plot(t, np.where(size > 0.0, size, np.nan), color=colours[v.engine], linewidth=1.2,
                    label=f"{label}: FAILED{when} ({v.failure.split(':')[0]}); max {np.max(size, initial=0.0):.2e} "
                          f"{rate} up to it")
            if v.failed_at is not None:
                ax.axvline(v.failed_at, color=colours[v.engine], linestyle=":", linewidth=1.0)
            continue
        if v.comparison is None:
            ax.plot([], [], color=colours[v.engine], label=f"{label}: did not run")
            continue
        d = v.comparison.diff
        size = np.abs(d.domega)
        ax.plot(d.times, np.where(size > 0.0, size, np.nan), color=colours[v.engine], linewidth=1.2,
                label=f"{label}: max {d.omega_max_abs:.2e} {rate} (tolerance {v.tolerances.omega_atol:g} {rate}), "
                      f"{'passed' if v.passed else 'FAILED'}")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel(f"|Δq̇| against reduced ({rate})")
    ax.set_title(f"{short_name(check.scene.name)}: each engine's input rate minus the reduced reference's", **PLAIN)
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3, which="both")
    _save(fig, path)


