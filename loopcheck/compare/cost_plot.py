"""cost.png: the work-precision diagram of ``loopcheck cost``, every engine's series on one diagram.

Each engine has a colour family of its own (its series in shades of it, told apart by marker and
line), and the legend groups the series under the engine's label (:attr:`loopcheck.registry.Engine.label`).
"""

from __future__ import annotations

import math
from pathlib import Path

from loopcheck.registry import ENGINES

from . import plots
from .plots import PLAIN, new_figure, plain_log_axis, short_name

FAMILIES = ("Blues", "Oranges", "Greens", "Purples", "Reds", "Greys", "YlOrBr", "PuRd")  # one per engine, in order
MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*")
LINESTYLES = ("-", "--", "-.", ":")


def _log_limits(values, pad: float = 0.25) -> tuple[float, float]:
    """Limits of a log axis around positive ``values``, ``pad`` decades beyond them."""
    lo, hi = math.log10(min(values)), math.log10(max(values))
    return 10.0 ** (lo - pad), 10.0 ** (hi + pad)


def series_styles(measurements) -> dict[tuple[str, str], tuple[str, dict]]:
    """Each (engine, series) of ``measurements``, in order: its engine's label and its line style
    (colour: a shade of the engine's family; marker and line: the series' place in its engine)."""
    from matplotlib import colormaps

    engines: dict[str, list[str]] = {}
    for m in measurements:
        names = engines.setdefault(m.config.engine, [])
        if m.config.series not in names:
            names.append(m.config.series)
    styles = {}
    for i, (engine, names) in enumerate(engines.items()):
        family = colormaps[FAMILIES[i % len(FAMILIES)]]
        label = ENGINES[engine].label if engine in ENGINES else engine
        for j, name in enumerate(names):
            shade = 0.9 - 0.35 * (j / (len(names) - 1)) if len(names) > 1 else 0.75
            styles[(engine, name)] = (label, {"color": family(shade), "marker": MARKERS[j % len(MARKERS)],
                                              "linestyle": LINESTYLES[(j // 2) % len(LINESTYLES)]})
    return styles


def plot_cost(measurements, front, target: float | None, scene_name: str, path: Path, *,
              truth: str = "", headline: str | None = None) -> None:
    """Log-log work-precision diagram: peak-ω relative error (x) against wall time (y, the
    median with a bar from the repeats' min to max), one series per engine's series. A point that
    ``loopcheck run`` fails is drawn hollow; a point not measured (a failure, a refusal) is absent
    from the axes (its verdict is in the table and the files); ``headline`` (the cost ratios'
    intervals, a line each) is written under the title."""
    from matplotlib.lines import Line2D

    fig, ax = new_figure((12.5, 7.0), margins={"right": 3.3, "top": 0.45 + 0.18 * (headline or "").count("\n")})
    # Scales set once, before the plain labels: every set_*scale puts matplotlib's mathtext formatters back.
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log_axis(ax.xaxis)
    plain_log_axis(ax.yaxis)
    styles = series_styles(measurements)
    handles, labels = [], []
    xs, ys, heading = [], [], None
    for (engine, name), (engine_label, style) in styles.items():
        if engine_label != heading:  # the engine's label above its series in the legend
            heading = engine_label
            handles.append(Line2D([], [], linestyle="none"))
            labels.append(engine_label)
        points = sorted((m for m in measurements if m.config.engine == engine and m.config.series == name
                         and m.ok and m.peak_omega_rel > 0),
                        key=lambda m: -m.config.parameter if not math.isnan(m.config.parameter) else 0.0)
        handles.append(Line2D([], [], markersize=5, **style))
        labels.append(f"  {name}" if points else f"  {name} (not measured)")
        if not points:
            continue
        x = [m.peak_omega_rel for m in points]
        y = [m.wall_median_s for m in points]
        ax.plot(x, y, markersize=5, markevery=[i for i, m in enumerate(points) if m.passed], **style)
        failing = [m for m in points if not m.passed]
        if failing:
            ax.plot([m.peak_omega_rel for m in failing], [m.wall_median_s for m in failing], linestyle="none",
                    marker=style["marker"], markersize=6, markerfacecolor="white", markeredgecolor=style["color"],
                    zorder=4)
        ax.vlines(x, [m.wall_min_s for m in points], [m.wall_max_s for m in points], color=style["color"],
                  linewidth=1.0, alpha=0.6)
        xs += x
        ys += [m.wall_min_s for m in points] + [m.wall_max_s for m in points]
    if front:
        line, = ax.plot([m.peak_omega_rel for m in front], [m.wall_median_s for m in front], color="black",
                        linewidth=2.5, alpha=0.35, zorder=0)
        ax.scatter([m.peak_omega_rel for m in front], [m.wall_median_s for m in front], s=110,
                   facecolors="none", edgecolors="black", zorder=5)
        handles.append(line)
        labels.append("Pareto front (run passes)")
    if target:
        handles.append(ax.axvline(target, color="green", linestyle="-."))
        labels.append(f"target {target:g}")
        xs.append(target)
    if xs and ys:
        ax.set_xlim(*_log_limits(xs))
        ax.set_ylim(*_log_limits(ys, pad=0.15))
    handles.append(Line2D([], [], linestyle="none", marker="o", markerfacecolor="white", markeredgecolor="black"))
    labels.append("hollow: loopcheck run fails it")
    ax.set_xlabel("relative error of the peak input speed against the truth, |Δ peak q̇| / |peak q̇| "
                  "(dimensionless)", **PLAIN)
    ax.set_ylabel("wall time of the simulation (s; median, bar: min to max of the repeats)", **PLAIN)
    title = f"{short_name(scene_name)}: what accuracy costs" + (f" (truth: {truth})" if truth else "")
    if headline:
        title += f"\n{headline}"
    ax.set_title(title, fontsize=10, **PLAIN)
    ax.grid(alpha=0.3, which="both")
    legend = ax.legend(handles, labels, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    for text in legend.get_texts():
        if not text.get_text().startswith(" ") and text.get_text() in {s[0] for s in styles.values()}:
            text.set_fontweight("bold")
    ax.text(0.01, 0.01, "lower left is better: accurate and cheap; circles: Pareto front",
            transform=ax.transAxes, fontsize=8, color="dimgray")
    plots._save(fig, path)  # through the module: the tests' saved_figures sees it
