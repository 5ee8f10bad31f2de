"""Start-up and plotting cost of the command line: what each command imports, and that every
figure is drawn once, without pyplot, with no text cut off by the fixed margins."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT, SEED_SCENE


def modules_after(code: str) -> set[str]:
    """The top-level module names loaded after running ``code`` in a fresh interpreter."""
    probe = code + "\nimport sys\nprint(' '.join(sorted({m.split('.')[0] for m in sys.modules})))"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    return set(done.stdout.split("\n")[-2].split())


def test_the_command_line_loads_neither_matplotlib_nor_mujoco():
    loaded = modules_after("import loopcheck.compare.cli; loopcheck.compare.cli.build_parser()")
    assert "matplotlib" not in loaded and "mujoco" not in loaded


@pytest.mark.parametrize("command", [["reduced", "--method", "rkn4"], ["mujoco"], ["check"]])
def test_commands_without_plots_do_not_load_matplotlib(command):
    args = command + [str(SEED_SCENE)]
    loaded = modules_after(f"from loopcheck.compare.cli import main; assert main({args!r}) == 0")
    assert "matplotlib" not in loaded
    assert ("mujoco" in loaded) == (command[0] != "reduced")


def test_a_fork_waits_for_the_matplotlib_import_started_ahead(tmp_path):
    """A sweep's parent imports matplotlib in a thread while its pool works
    (loopcheck.compare.plots.prefetch_matplotlib): a process forked meanwhile (a replaced worker)
    must not start with that import half done (a module lock held by a thread it does not have).
    Forked at once after the start, the child finds the import complete. (Planted: no fork hook:
    fails here, the child sees matplotlib.figure missing.)"""
    code = ("import os, sys\n"
            "from loopcheck.compare.plots import prefetch_matplotlib\n"
            "prefetch_matplotlib()\n"
            "pid = os.fork()\n"
            "if pid == 0:\n"
            "    done = {'matplotlib.figure', 'matplotlib.backends.backend_agg'} <= set(sys.modules)\n"
            "    os._exit(0 if done else 3)\n"
            "_, status = os.waitpid(pid, 0)\n"
            "assert os.waitstatus_to_exitcode(status) == 0, 'the child started before the import was done'\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""


@pytest.mark.slow  # ~5 s: a whole `loopcheck run`, plots included, in a fresh interpreter
def test_run_does_not_load_pyplot(tmp_path):
    out = tmp_path / "out"
    code = (f"from loopcheck.compare.cli import main; assert main(['run', {str(SEED_SCENE)!r}, '--out', {str(out)!r}]) == 0\n"
            "import sys; assert 'matplotlib.pyplot' not in sys.modules, 'pyplot loaded'\n"
            "assert 'matplotlib' in sys.modules")
    modules_after(code)


# ---------------------------------------------------------------- the figures themselves

@pytest.fixture(params=["seed_comparison", "slider_driven_comparison"], ids=["seed", "slider"])
def comparison(request):
    return request.getfixturevalue(request.param)


def saved_figures(monkeypatch) -> list:
    """(figure, renderer draws) of every figure loopcheck.compare.plots saves from now on (still saved)."""
    import loopcheck.compare.plots
    from matplotlib.figure import Figure

    draws = {"n": 0}
    real_draw = Figure.draw

    def counting_draw(self, renderer):
        draws["n"] += 1
        return real_draw(self, renderer)

    monkeypatch.setattr(Figure, "draw", counting_draw)
    kept = []
    real_save = loopcheck.compare.plots._save

    def keep(fig, path):
        before = draws["n"]
        real_save(fig, path)
        kept.append((fig, draws["n"] - before))

    monkeypatch.setattr(loopcheck.compare.plots, "_save", keep)
    return kept


def text_outside(fig) -> list[str]:
    """What of the (already drawn) figure reaches beyond its edges, and y labels that overlap
    their tick labels."""
    renderer = fig.canvas.get_renderer()
    width, height = fig.canvas.get_width_height()
    bad = []
    box = fig.get_tightbbox(renderer).transformed(fig.dpi_scale_trans)  # everything drawn, in pixels
    if box.x0 < -0.5 or box.y0 < -0.5 or box.x1 > width + 0.5 or box.y1 > height + 0.5:
        bad.append(f"drawn {box.bounds}, figure {width} × {height}")
    for ax in fig.axes:
        low, high = sorted(ax.get_ylim())
        shown = [label.get_window_extent(renderer) for loc, label in
                 zip(ax.yaxis.get_majorticklocs(), ax.yaxis.get_majorticklabels())
                 if low <= loc <= high and label.get_visible() and label.get_text()]
        if ax.yaxis.label.get_text() and shown:
            label = ax.yaxis.label.get_window_extent(renderer)
            if (label.x1 > min(b.x0 for b in shown) + 0.5 if ax.yaxis.get_label_position() == "left"
                    else label.x0 < max(b.x1 for b in shown) - 0.5):  # a colour bar's, on the right
                bad.append(f"y label {ax.yaxis.label.get_text()!r} overlaps its tick labels")
    return bad


def test_every_plot_is_drawn_once_and_nothing_is_cut_off(tmp_path, monkeypatch, comparison):
    from loopcheck.compare.report import PLOTS

    kept = saved_figures(monkeypatch)
    for name, plot in PLOTS.items():
        plot(comparison, tmp_path / name)
    assert len(kept) == len(PLOTS)
    for (fig, draws), name in zip(kept, PLOTS):
        assert draws == 1, f"{name} drawn {draws} times"
        assert text_outside(fig) == [], name


def test_the_engines_plot_is_drawn_once_with_a_line_per_engine(tmp_path, monkeypatch, comparison):
    """engines.png (``loopcheck run --engines``): a log |Δq̇| line per engine that ran, one legend entry per engine
    (one that did not run says so), nothing cut off."""
    from loopcheck.compare.engines import EnginesCheck, EngineVerdict
    from loopcheck.compare.plots import plot_engines

    kept = saved_figures(monkeypatch)
    tolerances = comparison.gate.tolerances
    check = EnginesCheck(comparison.scene, comparison.reference,
                         (EngineVerdict("mujoco", tolerances, comparison),
                          EngineVerdict("pin", tolerances, None, "numerical failure (budget): ...")), "pin", {})
    plot_engines(check, tmp_path / "engines.png")
    (fig, draws), = kept
    assert draws == 1 and text_outside(fig) == []
    ax = fig.axes[0]
    assert ax.get_yscale() == "log" and [len(line.get_xdata()) > 0 for line in ax.get_lines()] == [True, False]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0].startswith("MuJoCo: max ") and legend[1] == "Pinocchio: did not run"
    assert ax.get_ylabel().endswith(f"({comparison.scene.input_unit}/s)")


def test_a_subtitle_of_the_differences_plot_is_not_cut_off(tmp_path, monkeypatch, comparison):
    """Two subtitle lines (a sweep's worst variant), longer than the SUBTITLE_CHARS kept."""
    from loopcheck.compare.plots import plot_differences

    kept = saved_figures(monkeypatch)
    values = ", ".join(f"bodies.coupler{k}.mass = 36.125" for k in range(6))
    plot_differences(comparison, tmp_path / "d.png", subtitle=f"worst of 100000 variants: #99999, {values}\n{values}")
    (fig, draws), = kept
    assert draws == 1 and text_outside(fig) == []
    assert fig.axes[0].get_title().split("\n")[2].endswith("…")


def test_the_drawing_is_drawn_once_and_nothing_is_cut_off(tmp_path, monkeypatch):
    from loopcheck.compare.draw import draw_scene
    from loopcheck.scenefile import load_scene

    kept = saved_figures(monkeypatch)
    # Not the slider crank: its slider's label runs off the right edge, with tight_layout too
    # (a label placed in data coordinates beside the rightmost point; not a margin matter).
    for k, path in enumerate((SEED_SCENE, ROOT / "scenes" / "mechanisms" / "watt2_sixbar.toml")):
        draw_scene(load_scene(path), tmp_path / f"{k}.png")
    for fig, draws in kept:
        assert draws == 1
        assert text_outside(fig) == []


def test_log_tick_labels_are_matplotlib_s_in_plain_text():
    """The plain log labels read as matplotlib's mathtext ones (10⁻⁶, 2×10⁻⁷), ticks unchanged."""
    from matplotlib.ticker import LogFormatterSciNotation

    from loopcheck.compare.plots import new_figure, plain_log_axis, plain_power

    assert plain_power(r"$\mathdefault{10^{-16}}$") == "10⁻¹⁶"
    assert plain_power(r"$\mathdefault{2\times10^{-7}}$") == "2×10⁻⁷"
    assert plain_power(r"$\mathdefault{10^{0}}$") == "10⁰"
    assert plain_power("") == ""
    for low, high in ((1e-16, 1e-6), (2e-7, 9e-7), (0.5, 30.0)):
        labels = []
        for plain in (False, True):
            fig, ax = new_figure((8, 4))
            ax.semilogy([0.0, 1.0], [low, high])
            assert isinstance(ax.yaxis.get_major_formatter(), LogFormatterSciNotation)
            if plain:
                plain_log_axis(ax.yaxis)
            fig.canvas.draw()
            labels.append([(t.get_position()[1], t.get_text()) for t in
                           ax.get_yticklabels() + ax.yaxis.get_minorticklabels()])
        assert [(y, plain_power(s)) for y, s in labels[0]] == labels[1]
        assert np.all([not s.startswith("$") for _, s in labels[1]])
