"""The sweep's plots (loopcheck.compare.sweep_plots): the peak plot's line labels, in the right
margin, cover none of its points, nor each other, and its legend covers no point; every axis of
the sweep plots says its unit (the varied keys' from the engines' declarations and the scene
format). (Planted: the labels drawn at each line's last point, as before, overlap points here;
an axis labelled by its key alone fails the unit checks.)"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.text import Text

from loopcheck.compare.cli import main
from loopcheck.compare.sweep_plots import key_label, plot_gate_map, spread
from loopcheck.sweep_spec import spec_from_args

from helpers import short_seed_file


def _points(ax) -> np.ndarray:
    """Every plotted point of the axes, in pixels."""
    xy = [line.get_xydata() for line in ax.get_lines() if len(line.get_xydata())]
    xy = np.concatenate(xy)
    xy = xy[np.isfinite(xy).all(axis=1)]
    return ax.transData.transform(xy)


def _covers(box, points, pad=3.0) -> np.ndarray:
    """Which points lie inside ``box`` (pixels), grown by a marker's radius ``pad``."""
    x, y = points[:, 0], points[:, 1]
    return (x > box.x0 - pad) & (x < box.x1 + pad) & (y > box.y0 - pad) & (y < box.y1 + pad)


def test_the_peak_plots_labels_and_legend_cover_no_point_and_its_axes_have_units(tmp_path, saved_figures, capsys):
    """A reduced-only grid of 3 × 5 × 2 variants of the short seed (10 lines, each named)."""
    scene = short_seed_file(tmp_path)
    status = main(["sweep", str(scene), "--out", str(tmp_path / "sw"), "--vary", "dampers.0.coefficient=[40, 50, 60]",
                   "--vary", "bodies.coupler.mass=35:45:5", "--vary", "torque.value=[240, 250]",
                   "--engines", "reduced", "--workers", "1"])
    assert status == 0, capsys.readouterr()
    fig = saved_figures[0]
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    points = _points(ax)
    assert len(points) == 30
    labels = [t for t in ax.texts if "," in t.get_text()]
    assert len(labels) == 10 and {t.get_text() for t in labels} >= {"35, 240", "45, 250"}
    boxes = [Text.get_window_extent(t, renderer) for t in labels]  # the text, not its leader line
    for t, box in zip(labels, boxes):
        assert not _covers(box, points).any(), t.get_text()
    for i, a in enumerate(boxes):  # nor each other
        for b in boxes[i + 1:]:
            assert not a.overlaps(b)
    legend = ax.get_legend().get_window_extent(renderer)
    assert not _covers(legend, points).any()
    width, height = fig.canvas.get_width_height()
    drawn = fig.get_tightbbox(renderer).transformed(fig.dpi_scale_trans)
    assert drawn.x0 >= -0.5 and drawn.y0 >= -0.5 and drawn.x1 <= width + 0.5 and drawn.y1 <= height + 0.5
    assert ax.get_xlabel() == "dampers.0.coefficient (N·s/m)"
    assert ax.get_ylabel() == "peak |ω| of the input (rad/s)"
    header = [t.get_text() for t in ax.texts if t not in labels]
    assert header == ["bodies.coupler.mass\n(kg)\ntorque.value\n(N·m)"]


def test_the_gate_maps_axes_have_units(tmp_path, saved_figures):
    spec = spec_from_args(["bodies.coupler.mass=[38, 42]", "mujoco.timestep=[1e-3, 5e-4]"])
    csv = tmp_path / "sweep.csv"
    csv.write_text("index,bodies.coupler.mass,mujoco.timestep,gate.worst_ratio\n"
                   "0,38.0,0.001,0.5\n1,38.0,0.0005,0.1\n2,42.0,0.001,2.0\n3,42.0,0.0005,0.2\n")
    plot_gate_map(csv, spec, "short.toml", tmp_path / "map.png", "rad/s")
    ax = saved_figures[0].axes[0]
    assert ax.get_xlabel() == "mujoco.timestep (s)" and ax.get_ylabel() == "bodies.coupler.mass (kg)"
    assert saved_figures[0].axes[1].get_ylabel() == "worst figure / its tolerance (ratio)"


@pytest.mark.parametrize("key, speed, label", [
    ("linkage.c2", "rad/s", "linkage.c2 (m)"),
    ("bodies.coupler.mass", "rad/s", "bodies.coupler.mass (kg)"),
    ("bodies.crank.pivot_inertia", "rad/s", "bodies.crank.pivot_inertia (kg·m²)"),
    ("dampers.0.coefficient", "rad/s", "dampers.0.coefficient (N·s/m)"),
    ("torque.value", "rad/s", "torque.value (N·m)"),
    ("initial.q", "m/s", "initial.q (m)"),  # a prismatic input
    ("initial.qdot", "rad/s", "initial.qdot (rad/s)"),
    ("simulation.horizon", "rad/s", "simulation.horizon (s)"),
    ("reduced.step", "rad/s", "reduced.step (s)"),  # from the engine's declared options
    ("mujoco.timestep", "rad/s", "mujoco.timestep (s)"),
    ("reduced.rtol", "rad/s", "reduced.rtol (ratio)"),
    ("tolerances.peak_omega_rtol", "rad/s", "tolerances.peak_omega_rtol (ratio)"),
    ("tolerances.q_atol", "m/s", "tolerances.q_atol (m)"),
    ("tolerances.omega_atol", "rad/s", "tolerances.omega_atol (rad/s)"),
])
def test_a_varied_keys_axis_label_has_its_unit(key, speed, label):
    assert key_label(key, speed) == label


def test_labels_are_spread_apart_in_their_order_within_the_axes():
    assert spread([0.5, 0.5, 0.5], gap=0.1) == pytest.approx([0.5, 0.6, 0.7])
    assert spread([0.95, 0.99], gap=0.1) == pytest.approx([0.9, 1.0])
    assert spread([0.2, 0.9]) == [0.2, 0.9]  # apart already: not moved
