"""A sweep's plots, drawn like :mod:`loopcheck.compare.plots` (new_figure, no pyplot) from the staged
``sweep.csv`` read back row by row, but the worst variant's differences (run again): which plots a
sweep draws (:func:`plot_files`) and each one (the module docstring of :mod:`loopcheck.compare.sweep`)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any, Mapping

from .sweep_summary import Summary, values_text
from .sweep_table import read_rows
from loopcheck.sweep_spec import Engines, SweepSpec

PEAK_PLOT, MAP_PLOT, HIST_PLOT = "sweep_peak_omega.png", "sweep_gate_map.png", "sweep_peak_omega_hist.png"
WORST_PLOT = "sweep_worst_differences.png"


def plot_files(spec: SweepSpec) -> tuple[str, ...]:
    """The plots a sweep of ``spec`` draws (a reduced-only sweep: no gate map, no worst differences)."""
    compared = spec.engines is Engines.BOTH
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


def _peaks(csv_path: Path, spec: SweepSpec, names: tuple[str, ...] = ()) -> tuple[dict[str, list], dict]:
    """The columns ``names`` of a sweep.csv, and the peak |ω| of each engine the sweep ran (by
    engine name, in :attr:`Engines.runs` order, NaN where not measured)."""
    cols = _column(csv_path, names + tuple(f"{e}.peak_omega" for e in spec.engines.runs))
    return cols, {e: abs(_nan(cols[f"{e}.peak_omega"])) for e in spec.engines.runs}


def _engine_styles() -> dict[str, dict[str, Any]]:
    """How each engine is drawn in the sweep's plots: its colour, label, marker, line style."""
    from .plots import MUJOCO_STYLE, REDUCED_STYLE

    return {"reduced": {**REDUCED_STYLE, "marker": "o", "markersize": 3, "linestyle": "-"},
            "mujoco": {**MUJOCO_STYLE, "marker": "x", "markersize": 4, "linestyle": "--"}}


def _what(spec: SweepSpec, what: str) -> str:
    """A plot's title text; a reduced-only sweep says so on a second line (one line would not
    fit over the axes with a long key)."""
    return what + ("\n(reduced engine only: no MuJoCo, no gate)" if spec.engines is Engines.REDUCED else "")


def _title_margins(spec: SweepSpec) -> dict[str, float]:
    """new_figure's margins for :func:`_what`'s title (inches)."""
    from .plots import MARGINS

    return {"top": MARGINS["top"] + (0.25 if spec.engines is Engines.REDUCED else 0.0)}


def plot_peak_omega(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str) -> None:
    """Peak |ω| of each engine run against the first varied key (other keys: one line each value)."""
    import numpy as np

    from .plots import PLAIN, new_figure

    key = spec.keys[0]
    cols, peaks = _peaks(csv_path, spec, spec.keys + ("status",))
    x = _nan(cols[key])
    red = peaks["reduced"]
    styles = _engine_styles()
    fig, ax = new_figure((7.0, 4.2), margins=_title_margins(spec))
    others = spec.keys[1:]
    groups: dict[tuple, list[int]] = {}
    for i in range(len(x)):
        groups.setdefault(tuple(cols[k][i] for k in others), []).append(i)
    for n, (label, idx) in enumerate(groups.items()):
        idx = np.array(idx)
        suffix = (" (" + ", ".join(f"{k}={v:g}" for k, v in zip(others, label)) + ")") if others else ""
        for engine, peak in peaks.items():
            style = styles[engine]
            ax.plot(x[idx], peak[idx], marker=style["marker"], markersize=style["markersize"], color=style["color"],
                    linestyle=style["linestyle"], label=style["label"] if n == 0 else None,
                    alpha=1.0 if len(groups) == 1 else 0.6)
        ok = np.flatnonzero(np.isfinite(red[idx]))
        if others and ok.size and (len(groups) <= 10 or n in (0, len(groups) - 1)):
            # name each line by the other keys' values (of many lines, the first and the last)
            last = idx[ok[-1]]
            ax.annotate(suffix.strip(" ()"), (x[last], red[last]), textcoords="offset points", xytext=(-4, 4),
                        ha="right", fontsize=7, **PLAIN)
    bad = np.array([s in ("invalid", "failed") for s in cols["status"]])
    if bad.any():
        for xv in x[bad]:
            ax.axvline(xv, color="tab:red", alpha=0.3, linewidth=1)
        ax.plot([], [], color="tab:red", alpha=0.3, label="invalid / failed variant")
    ax.set_xlabel(key, **PLAIN)
    ax.set_ylabel(f"peak |ω| of the input ({speed_unit})")
    ax.set_title(_title(source, _what(spec, f"peak speed against {key}")), **PLAIN)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


def plot_gate_map(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str) -> None:
    """The gate's worst ratio (largest figure over its tolerance) over the first two grid keys
    (the others: the largest ratio over their values); gray where no comparison ran."""
    import numpy as np
    from matplotlib.colors import LogNorm

    from .plots import PLAIN, new_figure, plain_log_axis

    kx, ky = spec.keys[1], spec.keys[0]
    xs, ys = list(spec.varies[1].values), list(spec.varies[0].values)
    cols = _column(csv_path, (kx, ky, "gate.worst_ratio"))
    grid = np.full((len(ys), len(xs)), np.nan)
    for xv, yv, r in zip(cols[kx], cols[ky], cols["gate.worst_ratio"]):
        if r is None:
            continue
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
    ax.set_xlabel(kx, **PLAIN)
    ax.set_ylabel(ky, **PLAIN)
    ax.set_title(_title(source, "gate's worst figure / tolerance (> 1 fails)"), **PLAIN)
    bar = fig.colorbar(mesh, ax=ax, label="worst ratio")
    if norm is not None:
        plain_log_axis(bar.ax.yaxis)  # the project's plain-text log labels (no mathtext)
    fig.savefig(path)


def plot_worst(data: Mapping[str, Any], source: str, summary: Summary, path: Path) -> None:
    """The differences plot of ``loopcheck run`` (:func:`loopcheck.compare.plots.plot_differences`) for the
    worst variant, the one whose peak-ω difference is the largest multiple of its tolerance, run
    again through both engines (the same scene and settings as its row); a note instead when no
    variant ran through both."""
    from .plots import PLAIN, _save, new_figure, plot_differences
    from .run import compare_engines
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
    with warnings.catch_warnings():  # as run_variant: its warnings were the sweep's to ignore
        warnings.simplefilter("ignore")
        c = compare_engines(scene_from_dict(apply(data, worst["values"]), source))
    values = values_text(worst["values"])
    plot_differences(c, path, subtitle=f"worst of {summary.total} variants: #{worst['index']}, peak-ω difference "
                                       f"{worst['peak_ratio']:.3g}× its tolerance\n{values}")


def plot_peak_histogram(csv_path: Path, spec: SweepSpec, source: str, path: Path, speed_unit: str) -> None:
    """Histogram of each engine run's peak |ω| over a Monte Carlo sample (the reduced engine's
    filled, MuJoCo's outlined)."""
    import numpy as np

    from .plots import PLAIN, new_figure

    _, peaks = _peaks(csv_path, spec)
    peaks = {e: p[np.isfinite(p)] for e, p in peaks.items()}
    styles = _engine_styles()
    fig, ax = new_figure((7.0, 4.2), margins=_title_margins(spec))
    every = np.concatenate(list(peaks.values()))
    if every.size:
        bins = np.histogram_bin_edges(every, bins=min(50, max(5, int(math.sqrt(every.size)))))
        for engine, peak in peaks.items():
            style = styles[engine]
            look = {"alpha": 0.6} if engine == "reduced" else {"histtype": "step", "linestyle": "--", "linewidth": 1.5}
            ax.hist(peak, bins=bins, color=style["color"], label=style["label"], **look)
        ax.legend(fontsize=8)
    ax.set_xlabel(f"peak |ω| of the input ({speed_unit})")
    ax.set_ylabel("variants")
    ax.set_title(_title(source, _what(spec, f"peak speed over {len(peaks['reduced'])} samples (seed {spec.seed})")),
                 **PLAIN)
    ax.grid(True, alpha=0.3)
    fig.savefig(path)


PLOTS = {PEAK_PLOT: plot_peak_omega, MAP_PLOT: plot_gate_map, HIST_PLOT: plot_peak_histogram}
