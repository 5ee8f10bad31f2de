"""Every body of every catalogue scene is drawn, by ``loopcheck draw`` and by the mechanism strip
of ``loopcheck run``: each of the body's named points lies inside or on the path of the artist
drawn for it (matplotlib's own paths, in data coordinates). Slider guides are not drawn as
ground pivots, and the strip's tick labels do not overlap.

The strip is drawn from a JointTrajectory held at the scene's assembled x0 (no engine runs):
what is tested is the drawing, not a run.
"""

from __future__ import annotations

import numpy as np
import pytest

from loopcheck.compare.draw import draw_linkage, draw_strip
from loopcheck.scenefile import load_scene
from loopcheck.kinematics import compile_linkage, positions
from loopcheck.mechanism import GROUND, PrismaticJoint
from loopcheck.trajectory import JointTrajectory

from helpers import ROOT

CATALOGUE = sorted((ROOT / "scenes" / "mechanisms").glob("*.toml"))
CATALOGUE_BY_NAME = {p.stem: p for p in CATALOGUE}
# A point is on an artist when it is within this fraction of the drawing's span of the
# artist's path: the paths are built from the same positions, so the measured distances are
# round-off (≤ 1e-16 m on spans of ~0.1–1 m); 1e-9 leaves room and is far below a pixel (~1e-3).
ON_PATH = 1e-9


def _segment_distance(p: np.ndarray, vertices: np.ndarray) -> float:
    """Distance (m) from p to the polyline through ``vertices`` (shape (k, 2))."""
    if len(vertices) == 1:
        return float(np.hypot(*(p - vertices[0])))
    a, b = vertices[:-1], vertices[1:]
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d)
    s = np.clip(np.einsum("ij,ij->i", p - a, d) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return float(np.min(np.hypot(*(a + s[:, None] * d - p).T)))


def covered(artist, point: np.ndarray, tol: float) -> bool:
    """Whether ``point`` (data coordinates) is inside or on ``artist``'s path: a Line2D's
    polyline (or its single marker), a patch's outline or interior."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    if isinstance(artist, Line2D):
        return _segment_distance(point, np.asarray(artist.get_xydata(), dtype=float)) <= tol
    assert isinstance(artist, Patch), type(artist)
    path = artist.get_patch_transform().transform_path(artist.get_path())  # in data coordinates
    if path.contains_point(tuple(point)):
        return True
    return any(_segment_distance(point, poly) <= tol for poly in path.to_polygons(closed_only=False))


def body_points(scene, system, x) -> dict[str, np.ndarray]:
    r = positions(system.points, np.asarray(x, dtype=float))
    linkage = scene.mechanism.linkage
    return {b.name: np.array([r[system.point_index(b.name, p)] for p in b.points])
            for b in linkage.bodies if b.name != GROUND}


def span_of(system, x) -> float:
    return float(np.max(np.ptp(positions(system.points, np.asarray(x, dtype=float)), axis=0)))


@pytest.mark.parametrize("path", CATALOGUE, ids=lambda p: p.stem)
def test_every_body_is_drawn_by_loopcheck_draw(path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scene = load_scene(path)
    system = compile_linkage(scene.mechanism.linkage)
    fig, ax = plt.subplots()
    try:
        art = draw_linkage(ax, scene.mechanism, system, np.asarray(scene.x0))
        tol = ON_PATH * span_of(system, scene.x0)
        for body, points in body_points(scene, system, scene.x0).items():
            artist = art.get(f"body:{body}")
            assert artist is not None, f"{path.stem}: no artist for body {body!r}"
            missing = [k for k, p in enumerate(points) if not covered(artist, p, tol)]
            assert not missing, f"{path.stem}: points {missing} of {body!r} are off its drawing"
    finally:
        plt.close(fig)


def held(system, x0) -> JointTrajectory:
    """A run that stays at x0 for 1 s (two samples)."""
    x = np.vstack([x0, x0]).astype(float)
    return JointTrajectory(system.coordinate_names, np.array([0.0, 1.0]), x, np.zeros_like(x),
                           np.zeros(2, dtype=int), np.ones((2, 1), dtype=int))


@pytest.mark.parametrize("path", CATALOGUE, ids=lambda p: p.stem)
def test_every_body_is_in_the_mechanism_strip_and_guides_are_not_pivots(path, tmp_path, saved_figures):
    scene = load_scene(path)
    linkage = scene.mechanism.linkage
    system = compile_linkage(linkage)
    run = held(system, scene.x0)
    draw_strip(scene, run, run, [("peak speed", 0.2), ("largest |Δq|", 0.7)], tmp_path / "m.png")
    (fig,) = saved_figures
    tol = ON_PATH * span_of(system, scene.x0)
    r = positions(system.points, np.asarray(scene.x0, dtype=float))
    pivots = sorted(tuple(r[system.point_index(GROUND, j.point_a if j.body_a == GROUND else j.point_b)])
                    for j in linkage.joints if GROUND in (j.body_a, j.body_b) and not isinstance(j, PrismaticJoint))
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        drawn = {line.get_gid(): line for line in ax.lines if line.get_gid()}
        for body, points in body_points(scene, system, scene.x0).items():
            artist = drawn.get(f"body:{body}")
            assert artist is not None, f"{path.stem}: body {body!r} is not in the strip"
            missing = [k for k, p in enumerate(points) if not covered(artist, p, tol)]
            assert not missing, f"{path.stem}: points {missing} of {body!r} are off the strip's drawing"
        # the ground pivots as `loopcheck draw` draws them: a white triangle under each, apex at the pivot
        bases = [p.get_xy()[0] for p in ax.patches if type(p).__name__ == "Polygon" and len(p.get_xy()) == 4
                 and p.get_facecolor() == (1.0, 1.0, 1.0, 1.0)]
        assert sorted(map(tuple, np.array(bases).reshape(-1, 2))) == pivots
        low, high = sorted(ax.get_xlim())
        boxes = sorted((label.get_window_extent(renderer) for loc, label in
                        zip(ax.get_xticks(), ax.get_xticklabels())
                        if low <= loc <= high and label.get_visible() and label.get_text()), key=lambda b: b.x0)
        assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:])), \
            f"{path.stem}: x tick labels overlap: {[label.get_text() for label in ax.get_xticklabels()]}"


def scaled_lever(k: float):
    """The oscillating slotted lever with every length scaled by k (masses as they are)."""
    import copy
    import tomllib

    from loopcheck.scenefile import scene_from_dict

    data = copy.deepcopy(tomllib.loads(CATALOGUE_BY_NAME["oscillating_slotted_lever"].read_text(encoding="utf-8")))
    for body in data["bodies"].values():
        body["points"] = {name: [k * v for v in xy] for name, xy in body["points"].items()}
        if "com" in body:
            body["com"] = [k * v for v in body["com"]]
    data["initial"]["guess"]["slot"] *= k
    return scene_from_dict(data, "scaled_lever.toml")


@pytest.mark.parametrize("k", [0.3, *(pytest.param(k, marks=pytest.mark.slow) for k in (0.4, 0.6, 0.8))])  # ~1 s each
def test_strip_tick_labels_do_not_overlap(tmp_path, saved_figures, k):
    """The oscillating slotted lever, its lengths scaled by k, at its peak speed (q = 10.2236
    rad) and at the end of its run (q = 13.8867 rad), reached from q0 by continuation of the
    assembly: with matplotlib's default ticks, labels such as −0.125 at 0.025 m steps ran into
    each other in one panel or the other at each of these scales (found by scanning k from 0.2
    to 1.2). The labels drawn stand apart."""
    from loopcheck.kinematics import assemble

    scene = scaled_lever(k)
    system = compile_linkage(scene.mechanism.linkage)
    x = np.asarray(scene.x0, dtype=float)
    configurations = []
    for target in (10.2236, 13.8867):
        for q in np.linspace(float(system.drive @ x), target, 200)[1:]:
            x = assemble(system, float(q), x)
        configurations.append(x)
    xs = np.array(configurations)
    run = JointTrajectory(system.coordinate_names, np.array([0.0, 1.0]), xs, np.zeros_like(xs),
                          np.zeros(2, dtype=int), np.ones((2, 1), dtype=int))
    draw_strip(scene, run, run, [("peak speed", 0.0), ("largest |Δq|", 1.0)], tmp_path / "m.png")
    (fig,) = saved_figures
    renderer = fig.canvas.get_renderer()
    assert len(fig.axes) == 2
    for ax in fig.axes:
        low, high = sorted(ax.get_xlim())
        boxes = sorted((label.get_window_extent(renderer) for loc, label in
                        zip(ax.get_xticks(), ax.get_xticklabels()) if low <= loc <= high and label.get_text()),
                       key=lambda b: b.x0)
        assert len(boxes) >= 3
        assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:])), [t.get_text() for t in ax.get_xticklabels()]


def test_moments_that_draw_the_same_picture_are_one_panel_that_says_so(tmp_path, saved_figures):
    """A run held still: its peak and its largest difference are the same picture, drawn
    once, the title naming both moments; a run that moves gets one panel per moment."""
    scene = load_scene(CATALOGUE_BY_NAME["seed_fourbar"])
    system = compile_linkage(scene.mechanism.linkage)
    still = held(system, scene.x0)
    draw_strip(scene, still, still, [("peak speed", 0.2), ("largest |Δq|", 0.7)], tmp_path / "a.png")
    (fig,) = saved_figures
    (ax,) = fig.axes
    assert ax.get_title().startswith("peak speed (t = 0.2 s) and largest |Δq| (t = 0.7 s), one picture")
    from loopcheck.kinematics import assemble

    moved = assemble(system, scene.q0 + 1.0, np.asarray(scene.x0, dtype=float))
    xs = np.array([scene.x0, moved], dtype=float)
    run = JointTrajectory(system.coordinate_names, np.array([0.0, 1.0]), xs, np.zeros_like(xs),
                          np.zeros(2, dtype=int), np.ones((2, 1), dtype=int))
    draw_strip(scene, run, run, [("peak speed", 0.0), ("largest |Δq|", 1.0)], tmp_path / "b.png")
    assert [a.get_title().split(",")[0] for a in saved_figures[1].axes] == ["peak speed", "largest |Δq|"]


def _overlap(a, b) -> float:
    """Area (px²) two display boxes share."""
    return max(0.0, min(a.x1, b.x1) - max(a.x0, b.x0)) * max(0.0, min(a.y1, b.y1) - max(a.y0, b.y0))


# ~0.5-1 s each (the drawing is rendered to measure its labels): a four-bar, a slider-crank and
# a six-bar in the fast suite, the rest slow.
FAST_DRAWINGS = ("seed_fourbar", "slider_crank_driven_slider", "stephenson3_sixbar")


@pytest.mark.parametrize("path", [p if p.stem in FAST_DRAWINGS else pytest.param(p, marks=pytest.mark.slow)
                                  for p in CATALOGUE], ids=lambda p: p.stem)
def test_loopcheck_draw_labels_do_not_cover_one_another(path, tmp_path, saved_figures):
    """The drawing's labels (joints, bodies, centres of mass, elements) as ``loopcheck draw`` saves
    them: no two share a pixel. Before
    labels were moved apart, the Andrews squeezer's 'O (input, …)' covered body1's and body2's
    labels, and the slotted lever's 'O2 (input, …)' its crank's. The figure is caught as it is
    saved (the ``saved_figures`` fixture of conftest.py; the drawing itself is not replaced)."""
    from loopcheck.compare.draw import _labels, draw_scene, label_boxes

    draw_scene(load_scene(path), tmp_path / "linkage.png")
    [ax] = [a for a in saved_figures[0].axes if _labels(a)]
    boxes = label_boxes(ax)
    clashes = [(i, j) for i in range(len(boxes)) for j in range(i) if _overlap(boxes[i], boxes[j]) > 0.0]
    assert not clashes, [(_labels(ax)[i].get_text(), _labels(ax)[j].get_text()) for i, j in clashes]
