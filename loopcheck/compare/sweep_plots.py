"""A sweep's plots, drawn like :mod:`loopcheck.compare.plots` (new_figure, no pyplot) from the staged
``sweep.csv`` read back row by row, but the worst variant's differences (run again): which plots a
sweep draws (:func:`plot_files`) and each one (the module docstring of :mod:`loopcheck.compare.sweep`)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any, Mapping

from .sweep_summary import Summary, values_text
from .sweep_engines import judged, judged_scene, sweep_engines
from .sweep_table import diff_column, input_column, read_rows
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE
from loopcheck.sweep_spec import SweepSpec

PEAK_PLOT, MAP_PLOT, HIST_PLOT = "sweep_peak_omega.png", "sweep_gate_map.png", "sweep_peak_omega_hist.png"
WORST_PLOT = "sweep_worst_differences.png"


def plot_files(spec: SweepSpec) -> tuple[str, ...]:
    """The plots a sweep of ``spec`` draws (the reference alone: no gate map, no worst differences)."""
    compared = bool(judged(spec))
    if not spec.is_grid:
        plots = (HIST_PLOT,)
    else:
        plots = (PEAK_PLOT,) + ((MAP_PLOT,) if compared and len(spec.keys) >= 2 else ())
    return plots + ((WORST_PLOT,) if compared else ())


def _column(csv_path: Path, names: tuple[str, ...]) -> dict[str, list]:
    """Some columns of a sweep.csv (None where not measured)."""
    out: dict[str, list] = {n: [] for n in names}
    for row in read_rows(csv_path):
        for n in names:
            out[n].append(row[n])
    return out


def _nan(values: list) -> "np.ndarray":
    import numpy as np

    return np.array([math.nan if v is None else float(v) for v in values], dtype=float)


def _title(source: str, what: str) -> str:
    from .plots import short_name

    return f"{short_name(Path(source).stem if not source.startswith('<') else source)}: {what}"


def _peaks(csv_path: Path, spec: SweepSpec, names: tuple[str, ...] = (),
           input_names: tuple[str | None, ...] = (None,)) -> tuple[dict[str, list], list[dict]]:
    """The columns ``names`` of a sweep.csv, and for each of ``input_names`` (None: the first input;
    a later input's name: its ``NAME:ENGINE.peak_omega``) the peak |ω| of each engine the sweep ran
    (by engine name, the reference first, NaN where not measured): one reading of the file."""
    engines = sweep_engines(spec.engines)

    def at(name: str | None, column: str) -> str:
        return column if name is None else input_column(name, column)

    cols = _column(csv_path, names + tuple(at(n, f"{e}.peak_omega") for n in input_names for e in engines))
    return cols, [{e: abs(_nan(cols[at(n, f"{e}.peak_omega")])) for e in engines} for n in input_names]


def _by_input(spec: SweepSpec, csv_path: Path, names: tuple[str, ...],
              inputs: tuple[tuple[str, str], ...]) -> list[tuple[str, str, dict, dict]]:
    """Each input's (name, speed unit, the columns ``names``, peaks by engine: :func:`_peaks`)."""
    cols, peaks = _peaks(csv_path, spec, names, tuple(None if k == 0 else name for k, (name, _) in enumerate(inputs)))
    return [(name, f"{unit}/s", cols, p) for (name, unit), p in zip(inputs, peaks)]


SUPTITLE_ROOM = 0.45
"""Inches above the first panel of a plot with one panel per input for the figure's title."""

MARKERS = ("o", "x", "s", "^", "v", "D", "P", "*", "h")
LINESTYLES = ("-", "--", ":")


def _engine_styles(engines: tuple[str, ...] = ()) -> dict[str, dict[str, Any]]:
    """How each engine is drawn in the sweep's plots: its colour and label
    (:attr:`loopcheck.registry.Engine.colour`, ``.label``), a marker and a line style in the
    order of ``engines`` (the reference first; by default the design card's pair)."""
    engines = engines or DEFAULT_ENGINES
    return {name: {"color": ENGINES[name].colour, "label": ENGINES[name].label, "marker": MARKERS[k % len(MARKERS)],
                   "markersize": 3 if k == 0 else 4, "linestyle": LINESTYLES[min(k, len(LINESTYLES) - 1)]}
            for k, name in enumerate(engines)}


def _what(spec: SweepSpec, what: str) -> str:
    """A plot's title text; a reduced-only sweep says so on a second line (one line would not
    fit over the axes with a long key)."""
    return what + (f"\n({REFERENCE} engine only: no other engine, no gate)" if not judged(spec) else "")


def _title_margins(spec: SweepSpec) -> dict[str, float]:
    """new_figure's margins for :func:`_what`'s title (inches)."""
    from .plots import MARGINS

    return {"top": MARGINS["top"] + (0.25 if not judged(spec) else 0.0)}


def key_unit(key: str, speed_unit: str = "rad/s", input_units: tuple[str, ...] = ()) -> str | None:
    """The unit of a varied scene-file key, as its axis says it ("" for a ratio, None where not
    known): the engines' settings from their declarations (:func:`loopcheck.settings.options`),
    the scene's keys from docs/scenes.md; the input's q and q̇ (and the tolerances on them) in
    the scene's input unit (``speed_unit`` is its speed: rad/s, or m/s for a prismatic input); a
    scene of several inputs (``input_units``: each input's, rad or m): ``initial.q.K`` and
    ``initial.qdot.K`` in input K's unit, a tolerance on q in "rad or m" when the inputs' differ."""
    from loopcheck.registry import ENGINES

    parts = key.split(".")
    names = [p for p in parts if not p.isdigit()]
    head, name = names[0], names[-1]
    position = speed_unit[:-2] if speed_unit.endswith("/s") else speed_unit
    if head in ENGINES and len(names) == 2:
        from loopcheck.settings import options

        found = [o.unit for o in options(ENGINES[head].settings) if o.name == name]
        return found[0] if found else None
    if len(set(input_units)) > 1:  # mixed inputs: a tolerance on q is in either unit
        position, speed_unit = " or ".join(sorted(set(input_units))), " or ".join(f"{u}/s" for u in sorted(set(input_units)))
    if head == "tolerances":
        return {"peak_omega_rtol": "", "q_atol": position}.get(name, speed_unit if name.endswith("_atol") else None)
    if head == "initial":
        index = [int(p) for p in parts if p.isdigit()]
        if input_units and index and index[0] < len(input_units):
            position, speed_unit = input_units[index[0]], f"{input_units[index[0]]}/s"
        return {"q": position, "qdot": speed_unit}.get(name)
    if head in ("simulation", "torque", "force", "timed_forces") and name in ("horizon", "start", "duration", "times"):
        return "s"
    table = {"linkage": {n: "m" for n in ("c1", "c2", "c3", "c4")},
             "bodies": {"mass": "kg", "inertia": "kg·m²", "pivot_inertia": "kg·m²", "com": "m", "points": "m"},
             "dampers": {"coefficient": "N·s/m"}, "springs": {"stiffness": "N/m", "rest_length": "m"},
             "torque": {"value": "N·m", "values": "N·m"}, "force": {"value": "N", "values": "N"},
             "timed_forces": {"value": "N", "values": "N"}, "point_forces": {"values": "N"},
             "gravity": {"gravity": "m/s²"}}
    return table.get(head, {}).get(name)


def key_label(key: str, speed_unit: str = "rad/s", input_units: tuple[str, ...] = ()) -> str:
    """An axis label of a varied key: the key and its unit (a ratio says so; ``input_units``: :func:`key_unit`)."""
    unit = key_unit(key, speed_unit, input_units)
    return key if unit is None else f"{key} ({unit or 'ratio'})"


LEGEND_ENTRY = 0.065
"""The height of one entry of the peak plot's legend (8-point text), in axes heights."""
LABEL_GAP = 0.06
"""The least distance between two line labels of the peak plot (axes heights, 7-point text)."""


def spread(fractions: list[float], gap: float = LABEL_GAP) -> list[float]:
    """Heights (axes fractions, in the given order) moved apart by at least ``gap``, as little as
    possible, kept within [0, 1] where they fit: the labels at the right of the peak plot."""
    order = sorted(range(len(fractions)), key=lambda i: fractions[i])
    placed = [fractions[i] for i in order]
    for j in range(1, len(placed)):
        placed[j] = max(placed[j], placed[j - 1] + gap)
    overflow = placed[-1] - 1.0 if placed else 0.0
    if overflow > 0:
        placed = [max(y - overflow, 0.0 if j == 0 else placed[j - 1] - overflow + gap) for j, y in enumerate(placed)]
    out = [0.0] * len(fractions)
    for j, i in enumerate(order):
        out[i] = placed[j]
    return out


def plot_peak_omega(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str,
                    inputs: tuple[tuple[str, str], ...] = ()) -> None:
    """Peak |ω| of each engine run against the first varied key (other keys: one line each value,
    named at the right of the axes, outside the points, by the other keys' values). With several
    ``inputs`` (name, unit: rad or m), one panel per input, one above the other, each in its unit."""
    from .plots import MARGINS, _save, new_figure

    key = spec.keys[0]
    right = 1.7 if spec.keys[1:] else MARGINS["right"]
    if len(inputs) < 2:
        cols, (peaks,) = _peaks(csv_path, spec, spec.keys + ("status",))
        fig, ax = new_figure((7.0 + right - MARGINS["right"], 4.2), margins={**_title_margins(spec), "right": right})
        _peak_panel(ax, spec, cols, peaks, speed_unit, "the input")
        ax.set_title(_title(source, _what(spec, f"peak speed against {key}")), **_plain())
        _save(fig, path)
        return
    panels = _by_input(spec, csv_path, spec.keys + ("status",), inputs)
    height = 1.0 + 3.6 * len(panels)
    fig, axes = new_figure((7.0 + right - MARGINS["right"], height), len(panels), 1, squeeze=False,
                           margins={"top": _title_margins(spec)["top"] + SUPTITLE_ROOM, "right": right, "hspace": 0.9})
    for k, (name, unit, cols, peaks) in enumerate(panels):
        _peak_panel(axes[k][0], spec, cols, peaks, unit, name, tuple(u for _, u in inputs))
        axes[k][0].set_title(f"input {name} ({unit})", fontsize=10, **_plain())
    fig.suptitle(_title(source, _what(spec, f"peak speed of each input against {key}")), y=1.0 - 0.12 / height,
                 va="top", **_plain())
    _save(fig, path)


def _plain() -> dict:
    from .plots import PLAIN

    return PLAIN


def _peak_panel(ax, spec: SweepSpec, cols: dict, peaks: dict, speed_unit: str, which: str,
                input_units: tuple[str, ...] = ()) -> None:
    """One panel of the peak plot: each engine's peak |ω| of the input ``which`` against the first key
    (``input_units``: each input's unit, for the keys' labels: :func:`key_unit`)."""
    import numpy as np

    from .plots import PLAIN

    key = spec.keys[0]
    x = _nan(cols[key])
    red = peaks[REFERENCE]
    styles = _engine_styles(tuple(peaks))
    others = spec.keys[1:]
    groups: dict[tuple, list[int]] = {}
    for i in range(len(x)):
        groups.setdefault(tuple(cols[k][i] for k in others), []).append(i)
    labels: list[tuple[float, str]] = []
    for n, (label, idx) in enumerate(groups.items()):
        idx = np.array(idx)
        for engine, peak in peaks.items():
            style = styles[engine]
            ax.plot(x[idx], peak[idx], marker=style["marker"], markersize=style["markersize"], color=style["color"],
                    linestyle=style["linestyle"], label=style["label"] if n == 0 else None,
                    alpha=1.0 if len(groups) == 1 else 0.6)
        ok = np.flatnonzero(np.isfinite(red[idx]))
        if others and ok.size and (len(groups) <= 10 or n in (0, len(groups) - 1)):
            # name each line by the other keys' values (of many lines, the first and the last)
            labels.append((red[idx[ok[-1]]], ", ".join(f"{v:.4g}" for v in label)))
    bad = np.array([s in ("invalid", "failed") for s in cols["status"]])
    if bad.any():
        for xv in x[bad]:
            ax.axvline(xv, color="tab:red", alpha=0.3, linewidth=1)
        ax.plot([], [], color="tab:red", alpha=0.3, label="invalid / failed variant")
    ax.set_xlabel(key_label(key, speed_unit, input_units), **PLAIN)
    ax.set_ylabel(f"peak |ω| of {which} ({speed_unit})", **({} if which == "the input" else PLAIN))
    ax.grid(True, alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    low, high = ax.get_ylim()  # headroom above the points for the legend: it covers none of them
    room = LEGEND_ENTRY * len(handles) + 0.04
    ax.set_ylim(low, high + room * (high - low) / (1.0 - room))
    ax.legend(fontsize=8, loc="upper right")
    if labels:  # in the right margin, at the height of each line's last point, kept apart
        low, high = ax.get_ylim()
        heights = spread([(y - low) / (high - low) for y, _ in labels])
        for (y, text), h in zip(labels, heights):
            ax.annotate(text, xy=(1.0, (y - low) / (high - low)), xycoords="axes fraction", xytext=(1.03, h),
                        textcoords="axes fraction", ha="left", va="center", fontsize=7, annotation_clip=False,
                        arrowprops={"arrowstyle": "-", "color": "0.6", "linewidth": 0.5}, **PLAIN)
        ax.text(1.03, 1.02, "\n".join(key_label(k, speed_unit, input_units).replace(" (", "\n(") for k in others),
                transform=ax.transAxes,
                ha="left", va="bottom", fontsize=7, **PLAIN)


def plot_gate_map(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str,
                  inputs: tuple[tuple[str, str], ...] = ()) -> None:
    """The gate's worst ratio (largest figure over its tolerance) over the first two grid keys
    (the others: the largest ratio over their values; several judged engines: the largest over
    them; several ``inputs``: the row's ``gate.worst_ratio`` is already the largest over every
    input, and the title says so); gray where no comparison ran."""
    import numpy as np
    from matplotlib.colors import LogNorm

    from .plots import PLAIN, _save, new_figure, plain_log_axis

    kx, ky = spec.keys[1], spec.keys[0]
    xs, ys = list(spec.varies[1].values), list(spec.varies[0].values)
    ratios = tuple(diff_column(spec, x, "worst_ratio", "gate") for x in judged(spec))
    cols = _column(csv_path, (kx, ky) + ratios)
    grid = np.full((len(ys), len(xs)), np.nan)
    for xv, yv, *rs in zip(cols[kx], cols[ky], *(cols[r] for r in ratios)):
        rs = [r for r in rs if r is not None]
        if not rs:
            continue
        r = max(rs)
        i, j = ys.index(yv), xs.index(xv)
        grid[i, j] = r if math.isnan(grid[i, j]) else max(grid[i, j], r)
    fig, ax = new_figure((7.0, 5.0), margins={"right": 1.3})
    finite = grid[np.isfinite(grid) & (grid > 0)]
    norm = LogNorm(vmin=min(finite.min(), 0.1), vmax=max(finite.max(), 10.0)) if finite.size else None
    masked = np.ma.masked_invalid(np.where(grid > 0, grid, np.nan))
    mesh = ax.pcolormesh(np.arange(len(xs) + 1), np.arange(len(ys) + 1), masked, cmap="RdYlGn_r", norm=norm,
                         shading="flat")
    ax.set_facecolor("0.8")
    ax.set_xticks(np.arange(len(xs)) + 0.5, [f"{v:.4g}" for v in xs], fontsize=7, rotation=45 if len(xs) > 6 else 0)
    ax.set_yticks(np.arange(len(ys)) + 0.5, [f"{v:.4g}" for v in ys], fontsize=7)
    units = tuple(u for _, u in inputs) if len(inputs) > 1 else ()
    ax.set_xlabel(key_label(kx, speed_unit, units), **PLAIN)
    ax.set_ylabel(key_label(ky, speed_unit, units), **PLAIN)
    over = "" if len(ratios) == 1 else f"\nthe worst of {', '.join(ENGINES[x].label for x in judged(spec))} in each variant"
    if len(inputs) > 1:
        over += f"\nthe worst of the inputs {', '.join(n for n, _ in inputs)}"
    ax.set_title(_title(source, f"gate's worst figure / tolerance (> 1 fails){over}"), **PLAIN)
    bar = fig.colorbar(mesh, ax=ax, label="worst figure / its tolerance (ratio)")
    if norm is not None:
        plain_log_axis(bar.ax.yaxis)  # the project's plain-text log labels (no mathtext)
    _save(fig, path)


def plot_worst(data: Mapping[str, Any], source: str, summary: Summary, path: Path,
               batch_sizes: Mapping[str, int] | None = None) -> None:
    """The differences plot of ``loopcheck run`` (:func:`loopcheck.compare.plots.plot_differences`) for the
    worst variant, the one whose peak-ω difference is the largest multiple of its tolerance, run
    again through the reference and the engine it was worst for (the same scene and settings as
    its row; an engine run in batches, as a batch of its size, whose compiled shape this process
    has); a note instead when no variant ran through two engines."""
    from .plots import PLAIN, _save, new_figure, plot_differences
    from .run import judge
    from .settings import engine_settings
    from loopcheck.sweep_spec import apply
    from loopcheck.scenefile import scene_from_dict


    worst = summary.worst
    if worst is None:
        fig, ax = new_figure((8, 2))
        ax.axis("off")
        ax.text(0.5, 0.5, f"{_title(source, 'no variant ran through both engines: no differences to plot')}",
                ha="center", va="center", **PLAIN)
        _save(fig, path)
        return
    engine = worst.get("engine", summary.judged[0])
    with warnings.catch_warnings():  # as run_variant: its warnings were the sweep's to ignore
        warnings.simplefilter("ignore")
        scene = scene_from_dict(apply(data, worst["values"]), source)
        reference = ENGINES[REFERENCE].simulate(scene, engine_settings(REFERENCE, scene))
        judged_ = judged_scene(scene, engine)
        size = (batch_sizes or {}).get(engine, 1)
        settings = engine_settings(engine, scene)
        other = (ENGINES[engine].simulate_batch([judged_] * size, settings)[0] if size > 1
                 else ENGINES[engine].simulate(judged_, settings))
        c = judge(judged_, reference, other, judged_.tolerances)
    values = values_text(worst["values"])
    by = f" ({ENGINES[engine].label})" if "engine" in worst else ""
    of = f" of {worst['input']}" if "input" in worst else ""
    plot_differences(c, path, subtitle=f"worst of {summary.total} variants{by}: #{worst['index']}, peak-ω difference{of} "
                                       f"{worst['peak_ratio']:.3g}× its tolerance\n{values}")


def plot_peak_histogram(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str,
                        inputs: tuple[tuple[str, str], ...] = ()) -> None:
    """Histogram of each engine run's peak |ω| over a Monte Carlo sample (the reduced engine's
    filled, MuJoCo's outlined); with several ``inputs``, one panel per input, each in its unit."""
    from .plots import PLAIN, _save, new_figure

    if len(inputs) < 2:
        _, (peaks,) = _peaks(csv_path, spec)
        fig, ax = new_figure((7.0, 4.2), margins=_title_margins(spec))
        n = _histogram_panel(ax, peaks, speed_unit, "the input")
        ax.set_title(_title(source, _what(spec, f"peak speed over {n} samples (seed {spec.seed})")), **PLAIN)
        _save(fig, path)
        return
    panels = _by_input(spec, csv_path, (), inputs)
    height = 1.0 + 3.6 * len(panels)
    fig, axes = new_figure((7.0, height), len(panels), 1, squeeze=False,
                           margins={"top": _title_margins(spec)["top"] + SUPTITLE_ROOM, "hspace": 0.9})
    for k, (name, unit, _, peaks) in enumerate(panels):
        n = _histogram_panel(axes[k][0], peaks, unit, name)
        axes[k][0].set_title(f"input {name} ({unit})", fontsize=10, **PLAIN)
    fig.suptitle(_title(source, _what(spec, f"peak speed of each input over {n} samples (seed {spec.seed})")),
                 y=1.0 - 0.12 / height, va="top", **PLAIN)
    _save(fig, path)


def _histogram_panel(ax, peaks: dict, speed_unit: str, which: str) -> int:
    """One panel of the histogram: each engine's peak |ω| of the input ``which``; the reference's count."""
    import numpy as np

    from .plots import PLAIN

    peaks = {e: p[np.isfinite(p)] for e, p in peaks.items()}
    styles = _engine_styles(tuple(peaks))
    every = np.concatenate(list(peaks.values()))
    if every.size:
        bins = np.histogram_bin_edges(every, bins=min(50, max(5, int(math.sqrt(every.size)))))
        for engine, peak in peaks.items():
            style = styles[engine]
            look = {"alpha": 0.6} if engine == REFERENCE else {"histtype": "step", "linestyle": "--", "linewidth": 1.5}
            ax.hist(peak, bins=bins, color=style["color"], label=style["label"], **look)
        ax.legend(fontsize=8)
    ax.set_xlabel(f"peak |ω| of {which} ({speed_unit})", **({} if which == "the input" else PLAIN))
    ax.set_ylabel("variants")
    ax.grid(True, alpha=0.3)
    return len(peaks[REFERENCE])


PLOTS = {PEAK_PLOT: plot_peak_omega, MAP_PLOT: plot_gate_map, HIST_PLOT: plot_peak_histogram}
