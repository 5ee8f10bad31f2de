"""A drawing of any planar linkage in one configuration (``loopcheck draw``, and the mechanism
strip of ``loopcheck run``), to check a scene's geometry.

Bodies are drawn as thick lines (two points) or filled polygons (three or more) through all
their named points (joint and attachment points and any other), a body of one point as the
block of the prismatic joint it slides in (in its colour) or a disc; revolute joints as
labelled circles, ground pivots with a hatched base, prismatic joints as a guide line and a
block, dampers as dashed lines and springs as zigzags with their coefficients, point forces as arrows F(q) along their
direction (ending at the point they act on), centres of mass as crossed circles; the title
gives q0 with its unit, the assembly mode (one sign per loop) and gravity. ``loopcheck draw`` moves
labels apart (:func:`declutter_labels`). Every position
is taken from the compiled loop kinematics (:mod:`loopcheck.kinematics`) at the general
coordinates x (``scene.x0`` for ``loopcheck draw``); nothing is recomputed here. Lengths in m,
equal axis scales.

matplotlib is imported only when a drawing is made. User names are plain text
(``parse_math=False``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from loopcheck.loads import TabulatedForce
from loopcheck.kinematics import LoopSystem, compile_linkage, positions
from loopcheck.mechanism import GROUND, Linkage, Mechanism, PrismaticJoint
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE

from .text import STILL_RISING, engine_label

if TYPE_CHECKING:
    from .run import Comparison

PLAIN = {"parse_math": False}
BODY_COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:brown", "tab:purple", "tab:olive",
                "tab:cyan", "tab:pink")
ELEMENT_STYLE = {"damper": {"color": "tab:purple", "linestyle": "--", "linewidth": 1.5},
                 "spring": {"color": "tab:green", "linestyle": "-", "linewidth": 1.2}}
ELEMENT_UNIT = {"damper": "N·s/m", "spring": "N/m"}
LABEL_BOX = {"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none", "alpha": 0.8}


def _zigzag(p: np.ndarray, q: np.ndarray, turns: int, width: float) -> np.ndarray:
    """A spring's polyline from p to q: straight ends and ``turns`` zigzags between (m)."""
    d = q - p
    length = float(np.hypot(*d))
    if length == 0.0:
        return np.array([p, q])
    u = d / length
    n = np.array([-u[1], u[0]])
    s = np.linspace(0.2, 0.8, 2 * turns + 1)
    off = np.zeros_like(s)
    off[1:-1:2], off[2:-1:2] = width, -width
    zig = p + np.outer(s * length, u) + np.outer(off, n)
    return np.vstack([p, zig, q])


def _polygon_order(points: np.ndarray) -> np.ndarray:
    """The points ordered by angle about their centroid (a simple outline of a plate)."""
    c = points.mean(axis=0)
    return points[np.argsort(np.arctan2(points[:, 1] - c[1], points[:, 0] - c[0]))]


def _distinct(points: list[np.ndarray], tol: float) -> np.ndarray:
    out: list[np.ndarray] = []
    for p in points:
        if all(np.hypot(*(p - o)) > tol for o in out):
            out.append(p)
    return np.array(out).reshape(-1, 2)


def _parts(mechanism: Mechanism | Linkage):
    """(linkage, line elements, point forces) of a mechanism, or of a bare linkage."""
    if isinstance(mechanism, Linkage):
        return mechanism, (), ()
    return mechanism.linkage, mechanism.elements, mechanism.point_forces


def mode_text(mode: Sequence[int]) -> str:
    """An assembly mode as the title shows it: ``(+1)``, ``(+1, −1)``; ``()`` without a loop."""
    return "(" + ", ".join("0" if m == 0 else f"{'+' if m > 0 else '−'}1" for m in mode) + ")"


def body_outlines(linkage: Linkage, system: LoopSystem, x: np.ndarray) -> dict[str, np.ndarray]:
    """Each moving body's outline at coordinates x: its distinct named points (joint and
    attachment points and any other the scene names; m), shape (k, 2), ordered round their
    centroid when k ≥ 3. Every point of a body lies on its outline."""
    r = positions(system.points, np.asarray(x, dtype=float))
    span = float(np.max(np.ptp(r, axis=0))) if len(r) > 1 else 1.0
    span = span if span > 0.0 else 1.0
    bodies = linkage.body_map
    out = {}
    for name in linkage.moving:
        pts = [r[system.point_index(name, p)] for p in sorted(bodies[name].points)]
        shape = _distinct(pts, 1e-9 * span)
        out[name] = _polygon_order(shape) if len(shape) >= 3 else shape
    return out


def _guide(r: np.ndarray, system: LoopSystem, x: np.ndarray, j: PrismaticJoint, span: float) -> np.ndarray:
    """A prismatic joint's guide: the segment of its line from point_a to point_b, 0.1 span
    beyond each (m), shape (2, 2)."""
    th = (0.0 if j.body_a == GROUND else float(x[system.coordinate(f"{j.body_a}.angle")])) + j.direction_a
    u = np.array([math.cos(th), math.sin(th)])
    a, b = r[system.point_index(j.body_a, j.point_a)], r[system.point_index(j.body_b, j.point_b)]
    ends = sorted((float(u @ (a - b)), 0.0))
    return np.array([b + (ends[0] - 0.1 * span) * u, b + (ends[1] + 0.1 * span) * u])


def draw_outline(ax, linkage: Linkage, system: LoopSystem, x: np.ndarray, *, colour: str,
                 linestyle: str = "-", label: str | None = None, alpha: float = 1.0, width: float = 2.2) -> list:
    """A light drawing of the linkage at x (bodies as closed outlines through all their
    points, a body of one point as a square, joints as dots, prismatic joints as a thin guide
    line and a square block), for overlaying several configurations (the mechanism strip of
    ``loopcheck run``). Returns the Line2D artists, bodies first in :attr:`Linkage.moving` order
    (each with gid ``body:<name>``), then the joints."""
    x = np.asarray(x, dtype=float)
    r = positions(system.points, x)
    span = float(np.max(np.ptp(r, axis=0))) if len(r) > 1 else 1.0
    span = span if span > 0.0 else 1.0
    artists = []
    for k, (name, shape) in enumerate(body_outlines(linkage, system, x).items()):
        path = np.vstack([shape, shape[:1]]) if len(shape) >= 3 else shape
        if len(path) == 0:
            continue
        (line,) = ax.plot(path[:, 0], path[:, 1], color=colour, linestyle=linestyle, linewidth=width,
                          alpha=alpha, marker="s" if len(path) == 1 else None, markersize=8,
                          markerfacecolor="none", label=label if k == 0 else None, zorder=2,
                          gid=f"body:{name}")
        artists.append(line)
    centres = np.array([r[system.point_index(j.body_a, j.point_a)] for j in linkage.joints
                        if not isinstance(j, PrismaticJoint)]).reshape(-1, 2)
    (dots,) = ax.plot(centres[:, 0], centres[:, 1], "o", markersize=4, markerfacecolor="white",
                      markeredgecolor=colour, alpha=alpha, zorder=3)
    artists.append(dots)
    for j in linkage.joints:
        if isinstance(j, PrismaticJoint):  # the guide line and the slider's block, a square
            g = _guide(r, system, x, j, span)
            (guide,) = ax.plot(g[:, 0], g[:, 1], color=colour, linewidth=0.8, alpha=0.6 * alpha,
                               linestyle=linestyle, zorder=1, gid=f"guide:{j.name}")
            b = r[system.point_index(j.body_b, j.point_b)]
            (block,) = ax.plot([b[0]], [b[1]], "s", markersize=7, markerfacecolor="none",
                               markeredgecolor=colour, alpha=alpha, zorder=3)
            artists += [guide, block]
    return artists


def draw_linkage(ax, mechanism: Mechanism | Linkage, system: LoopSystem, x: np.ndarray, *,
                 q: float | None = None, input_label: str = "input",
                 input_labels: dict[str, str] | None = None) -> dict[str, object]:
    """Draw the mechanism (or a bare linkage) at coordinates ``x`` (shape (n,), assembled)
    on the axes ``ax``. ``q`` is the input coordinate there (rad or m), at which the point
    forces' tables F(q) are read; default drive·x. The input joint's label adds ``input_label``;
    ``input_labels`` (joint name → text), where given, label every input joint instead (several
    inputs).

    Returns
    -------
    The artists by name: ``"body:<body>"``, ``"joint:<joint>"`` (a Circle for a revolute,
    the block Rectangle for a prismatic), ``"ground:<joint>"`` (hatched base of a ground
    pivot), ``"point:<body>.<point>"`` (marker of every named point), ``"<kind>:<name>"``
    for dampers and springs (a Line2D from its a end to its b end), ``"force:<name>"`` for
    point forces (an Annotation whose ``xy`` is the point acted on) and ``"com:<body>"``.
    """
    from matplotlib.colors import to_rgba
    from matplotlib.patches import Circle, Polygon, Rectangle

    linkage, elements, point_forces = _parts(mechanism)
    x = np.asarray(x, dtype=float)
    q_in = float(system.drive @ x) if q is None else float(q)
    r = positions(system.points, x)
    com = positions(system.centres, x)

    def at(body: str, point: str) -> np.ndarray:
        return r[system.point_index(body, point)]

    def angle_of(body: str) -> float:
        return 0.0 if body == GROUND else float(x[system.coordinate(f"{body}.angle")])

    span = float(np.max(np.ptp(r, axis=0))) if len(r) > 1 else 1.0
    span = span if span > 0.0 else 1.0
    radius = 0.018 * span
    artists: dict[str, object] = {}
    colour = {name: BODY_COLOURS[k % len(BODY_COLOURS)] for k, name in enumerate(linkage.moving)}
    joint_points = {(j.body_a, j.point_a) for j in linkage.joints} | {
        (j.body_b, j.point_b) for j in linkage.joints}
    element_points = {(e.body_a, e.point_a) for e in elements} | {(e.body_b, e.point_b) for e in elements}
    force_points = {(f.body, f.point) for f in point_forces}

    centre = r.mean(axis=0)
    shapes = body_outlines(linkage, system, x)
    # A moving body of one point that is a prismatic joint's sliding end is drawn as that
    # joint's block, in the body's colour; any other body of one point as a disc.
    blocks = {j.body_b: j.name for j in linkage.joints
              if isinstance(j, PrismaticJoint) and j.body_b in colour and len(shapes[j.body_b]) == 1}

    # Bodies: the outline of all their named points (not the centre of mass).
    for name in linkage.moving:
        shape = shapes[name]
        if len(shape) >= 3:
            patch = Polygon(shape, closed=True, facecolor=colour[name], alpha=0.25,
                            edgecolor=colour[name], linewidth=3, zorder=1)
            ax.add_patch(patch)
            artists[f"body:{name}"] = patch
        elif len(shape) == 2:
            (line,) = ax.plot(shape[:, 0], shape[:, 1], color=colour[name], linewidth=4,
                              solid_capstyle="round", zorder=1)
            artists[f"body:{name}"] = line
        elif len(shape) == 1 and name not in blocks:
            disc = Circle(tuple(shape[0]), 2.0 * radius, facecolor=colour[name], alpha=0.35,
                          edgecolor=colour[name], linewidth=2, zorder=1)
            ax.add_patch(disc)
            artists[f"body:{name}"] = disc
        if len(shape):
            # The name beside the body, on the side away from the whole linkage's centre.
            mid = shape.mean(axis=0)
            d = shape[-1] - shape[0] if len(shape) >= 2 else np.array([1.0, 0.0])
            normal = np.array([-d[1], d[0]]) / (np.hypot(*d) or 1.0)
            if normal @ (mid - centre) < 0.0:
                normal = -normal
            ax.annotate(name, mid, xytext=tuple(16 * normal), textcoords="offset points",
                        ha="center", va="center", color=colour[name], fontsize=9,
                        fontweight="bold", bbox=LABEL_BOX, **PLAIN)

    # Dampers and springs.
    for e in elements:
        p, q = at(e.body_a, e.point_a), at(e.body_b, e.point_b)
        path = _zigzag(p, q, 6, 0.6 * radius) if e.kind == "spring" else np.array([p, q])
        (line,) = ax.plot(path[:, 0], path[:, 1], zorder=2, **ELEMENT_STYLE[e.kind])
        artists[f"{e.kind}:{e.name}"] = line
        mid = 0.5 * (p + q)
        text = f"{e.name} {e.coefficient:g} {ELEMENT_UNIT[e.kind]}"
        if e.kind == "spring":
            text += f", D0 {e.rest_length:g} m"
        ax.annotate(text, mid, xytext=(6, 0), textcoords="offset points", fontsize=8,
                    color=ELEMENT_STYLE[e.kind]["color"], bbox=LABEL_BOX, **PLAIN)
        for body, point in ((e.body_a, e.point_a), (e.body_b, e.point_b)):
            if body == GROUND and (body, point) not in joint_points:
                c = at(body, point)
                anchor = Rectangle((c[0] - radius, c[1] - radius), 2 * radius, 2 * radius,
                                   facecolor="white", edgecolor="black", hatch="////", zorder=3)
                ax.add_patch(anchor)
                artists[f"anchor:{e.name}"] = anchor

    # Point forces: an arrow of length 0.15 span ending at the point, along F(q)·direction.
    for f in point_forces:
        value = float(TabulatedForce(f.coordinate, f.values, f.period)(q_in))
        p = at(f.body, f.point)
        u = np.array([math.cos(f.direction), math.sin(f.direction)]) * (1.0 if value >= 0.0 else -1.0)
        tail = p - 0.15 * span * u
        arrow = ax.annotate("", xy=tuple(p), xytext=tuple(tail), textcoords="data",
                            arrowprops={"arrowstyle": "-|>", "color": "tab:red", "linewidth": 2},
                            zorder=6)
        artists[f"force:{f.name}"] = arrow
        ax.update_datalim([tail])  # the whole arrow inside the axes
        ax.annotate(f"{f.name} F(q0) = {value:g} N", tuple(0.5 * (p + tail)), xytext=(0, -26),
                    textcoords="offset points", ha="center", fontsize=8, color="tab:red",
                    bbox=LABEL_BOX, **PLAIN)

    # Joints; labels of joints at one place are stacked, 13 points apart.
    labelled: list[np.ndarray] = []

    def stacked(p: np.ndarray) -> float:
        k = sum(1 for o in labelled if np.hypot(*(p - o)) <= 1e-9 * span)
        labelled.append(p)
        return 13.0 * k

    anchors = [at(j.body_a, j.point_a) for j in linkage.joints]
    for j in linkage.joints:
        c = at(j.body_a, j.point_a)
        if input_labels is not None:
            label = j.name + (f" ({input_labels[j.name]})" if j.name in input_labels else "")
        else:
            label = j.name + (f" ({input_label})" if j.name == linkage.input_joint else "")
        if isinstance(j, PrismaticJoint):
            th = angle_of(j.body_a) + j.direction_a
            u = np.array([math.cos(th), math.sin(th)])
            b = at(j.body_b, j.point_b)
            guide = _guide(r, system, x, j, span)
            ax.plot(guide[:, 0], guide[:, 1], color="0.3", linewidth=1, zorder=2)
            w, h = 4 * radius, 2.5 * radius
            corner = b - 0.5 * w * u - 0.5 * h * np.array([-u[1], u[0]])
            block_of = next((body for body, joint in blocks.items() if joint == j.name), None)
            patch = Rectangle(tuple(corner), w, h, angle=math.degrees(th),
                              facecolor="white" if block_of is None else to_rgba(colour[block_of], 0.45),
                              edgecolor="black", linewidth=1.5, zorder=4)
            ax.add_patch(patch)
            artists[f"joint:{j.name}"] = patch
            if block_of is not None:
                artists[f"body:{block_of}"] = patch
            ax.annotate(label, b, xytext=(10, 8 - stacked(b)), textcoords="offset points",
                        fontsize=9, bbox=LABEL_BOX, **PLAIN)
            continue
        if GROUND in (j.body_a, j.body_b):
            base = Polygon([c, c + [-1.6 * radius, -2.8 * radius], c + [1.6 * radius, -2.8 * radius]],
                           closed=True, facecolor="white", edgecolor="black", zorder=3)
            ax.add_patch(base)
            hatch = Rectangle((c[0] - 2.4 * radius, c[1] - 3.8 * radius), 4.8 * radius, radius,
                              facecolor="none", edgecolor="black", hatch="////", linewidth=0, zorder=3)
            ax.add_patch(hatch)
            ax.plot([c[0] - 2.4 * radius, c[0] + 2.4 * radius], [c[1] - 2.8 * radius] * 2,
                    color="black", linewidth=1, zorder=3)
            artists[f"ground:{j.name}"] = base
        circle = Circle(tuple(c), radius, facecolor="white", edgecolor="black", linewidth=1.5,
                        zorder=5)
        ax.add_patch(circle)
        artists[f"joint:{j.name}"] = circle
        # written leftwards where another joint stands just to the right on its level
        crowded = any(abs(o[1] - c[1]) <= 0.03 * span and 0.0 < o[0] - c[0] <= 0.3 * span for o in anchors)
        ax.annotate(label, c, xytext=(-10 if crowded else 10, (-16 if GROUND in (j.body_a, j.body_b) else 8)
                                      - (0.0 if crowded else stacked(c))),
                    textcoords="offset points", fontsize=10, bbox=LABEL_BOX,
                    **{**PLAIN, "ha": "right"} if crowded else PLAIN)

    # Every named point, small; labelled when nothing else explains it.
    for body in linkage.bodies:
        for point in body.points:
            c = at(body.name, point)
            (mark,) = ax.plot([c[0]], [c[1]], "o", markersize=2.5, color="black", zorder=6)
            artists[f"point:{body.name}.{point}"] = mark
            key = (body.name, point)
            near_com = body.name in linkage.moving and np.hypot(
                *(c - com[linkage.moving.index(body.name)])) <= 1e-9 * span
            if key not in joint_points | element_points | force_points and not near_com:
                ax.annotate(f"{body.name}.{point}", c, xytext=(4, -10), textcoords="offset points",
                            fontsize=8, color="0.3", **PLAIN)

    # Centres of mass of the bodies given a mass, crossed circles (a body given by its
    # inertia about a fixed pivot has its centre there and no mass of its own: not drawn).
    bodies = linkage.body_map
    for k, name in enumerate(linkage.moving):
        mass = getattr(bodies[name], "mass", 0.0) or 0.0
        if mass <= 0.0:
            continue
        c = com[k]
        for p in shapes.get(name, ()):  # thin ties to the body it belongs to
            ax.plot([c[0], p[0]], [c[1], p[1]], color=colour[name], linewidth=0.8,
                    linestyle=":", zorder=1)
        (mark,) = ax.plot([c[0]], [c[1]], "o", markersize=11, markerfacecolor="white",
                          markeredgecolor="black", zorder=6)
        ax.plot([c[0]], [c[1]], "+", markersize=11, color="black", zorder=7)
        artists[f"com:{name}"] = mark
        ax.annotate(f"G {name}, {mass:g} kg", c, xytext=(9, 6), textcoords="offset points",
                    fontsize=8, bbox=LABEL_BOX, **PLAIN)

    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.12)
    ax.grid(True, color="0.9", linewidth=0.6)
    ax.set_axisbelow(True)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return artists


DRAWING_FORMATS = ("png", "pdf", "svg")  # what ``loopcheck draw --out`` writes, named by the file's suffix


def drawing_format(path: str | Path, flag: str = "--out") -> str:
    """The format the suffix of ``path`` names (one of :data:`DRAWING_FORMATS`, any case);
    OutputError (exit status 2) for any other suffix, before any work."""
    from .output import OutputError

    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in DRAWING_FORMATS:
        shown = f"'.{suffix}'" if suffix else "no suffix"
        raise OutputError(f"{flag} '{path}': a drawing is written as "
                          f"{', '.join('.' + f for f in DRAWING_FORMATS)} (its suffix names the format), got {shown}")
    return suffix


def write_drawing(scene, path: str | Path) -> Path:
    """``loopcheck draw``: :func:`draw_scene` into the file ``path``, in the format its suffix names
    (:func:`drawing_format`), through the atomic writer (:func:`loopcheck.compare.output.write_folder`);
    returns the path written."""
    from .output import write_folder

    drawing_format(path)
    target = Path(path).absolute()
    return write_folder(target.parent, {target.name: lambda p: draw_scene(scene, p)}, flag="--out")[0]


def start_labels(scene) -> tuple[str, dict[str, str] | None]:
    """The start as a drawing's title says it ("q0 = 1.8 rad"; with several inputs every input's
    name and q0 in its unit, "q0 = (O1 1.8 rad, O5 1.3 rad)"), and with several inputs each input
    joint's label ("input 2, q0 = 1.3 rad"; None with one, whose label is ``input_label``)."""
    if scene.dof == 1:
        return f"q0 = {scene.q0:g} {scene.input_unit}", None
    starts = list(zip(scene.inputs, scene.initial_q(), scene.input_units()))
    return (f"q0 = ({', '.join(f'{name} {q0:g} {u}' for name, q0, u in starts)})",
            {name: f"input {k + 1}, q0 = {q0:g} {u}" for k, (name, q0, u) in enumerate(starts)})


def draw_scene(scene, path: str | Path) -> None:
    """Draw any scene's mechanism at its assembled q0 (``scene.x0``) into ``path``, in the
    format its suffix names (:data:`DRAWING_FORMATS`).

    The title gives q0 in the input's unit (``scene.input_unit``; with several inputs, every
    input's name and q0 in its unit, and each input joint's label its number and q0), the
    assembly mode (one sign per loop, ``scene.mode``) and gravity.
    """
    from . import plots

    system = compile_linkage(scene.mechanism.linkage)
    unit = scene.input_unit
    fig, ax = plots.new_figure((9, 6.5), margins=DRAWING_MARGINS)
    at, labels = start_labels(scene)
    draw_linkage(ax, scene.mechanism, system, np.asarray(scene.x0, dtype=float), q=scene.q0,
                 input_label=f"input, q0 = {scene.q0:g} {unit}", input_labels=labels)
    gravity = ("" if scene.gravity is None
               else f", gravity ({scene.gravity[0]:g}, {scene.gravity[1]:g}) m/s²")
    ax.set_title(f"{plots.short_name(scene.name)}: linkage at {at}, "
                 f"mode {mode_text(scene.mode)}{gravity}", **plots.PLAIN)
    declutter_labels(ax)
    plots._save(fig, Path(path))


LEADER_POINTS = 12.0  # a label moved further than this from where it was put gets a leader line
# Offsets (points) a label may move by from where it was put, nearest first: rings of 8 directions.
_LABEL_MOVES = [(0.0, 0.0)] + [(r * math.cos(a), r * math.sin(a)) for r in (10.0, 18.0, 28.0, 40.0, 54.0)
                               for a in np.linspace(0.0, 2 * math.pi, 8, endpoint=False)]


def label_boxes(ax) -> list:
    """The display-space boxes (matplotlib Bbox, pixels) of the axes' labels: every annotation
    with text, placed in points from its anchor."""
    renderer = ax.figure.canvas.get_renderer()
    return [t.get_window_extent(renderer) for t in _labels(ax)]


def _labels(ax) -> list:
    from matplotlib.text import Annotation

    return [t for t in ax.texts if isinstance(t, Annotation) and t.get_text() and t.anncoords == "offset points"]


def _shared_area(a, b, pad: float = 0.0) -> float:
    """Area (px²) display boxes ``a`` and ``b`` share, ``b`` grown by ``pad`` px on every side."""
    return (max(0.0, min(a.x1, b.x1 + pad) - max(a.x0, b.x0 - pad))
            * max(0.0, min(a.y1, b.y1 + pad) - max(a.y0, b.y0 - pad)))


def declutter_labels(ax) -> None:
    """Move labels that would cover one another or a labelled mark: each label, in the order
    drawn, keeps its place if it overlaps no label placed before it and no mark (a joint, a
    centre of mass, a point: every label's anchor), else takes the nearest offset
    (:data:`_LABEL_MOVES`) with the least overlap, inside the axes where one is. A label stays
    beside its anchor (at most 54 points from where it was put)."""
    from matplotlib.transforms import Bbox

    ax.figure.canvas.draw()  # lays out the limits and the texts
    renderer = ax.figure.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    placed: list = []
    # the marks labels are anchored at (joints, centres of mass, points): no label covers one
    marks = [Bbox.from_bounds(x - 7.0, y - 7.0, 14.0, 14.0)
             for x, y in ax.transData.transform([t.xy for t in _labels(ax) if t.xycoords == "data"])]

    def cost(box) -> float:
        overlap = sum(_shared_area(box, b, pad=2.0) for b in placed) + 0.5 * sum(_shared_area(box, b) for b in marks)
        outside = (max(0.0, frame.x0 - box.x0) + max(0.0, box.x1 - frame.x1)
                   + max(0.0, frame.y0 - box.y0) + max(0.0, box.y1 - frame.y1))
        return overlap + 100.0 * outside

    for text in _labels(ax):
        home = tuple(text.xyann)
        best, best_cost = home, math.inf
        for dx, dy in _LABEL_MOVES:
            text.xyann = (home[0] + dx, home[1] + dy)
            c = cost(text.get_window_extent(renderer))
            if c < best_cost:
                best, best_cost = text.xyann, c
            if c == 0.0:
                break
        text.xyann = best
        placed.append(text.get_window_extent(renderer))
        if math.dist(best, home) > LEADER_POINTS:  # moved away: a thin line back to its anchor
            ax.annotate("", xy=text.xy, xycoords=text.xycoords, xytext=best, textcoords="offset points",
                        arrowprops=dict(arrowstyle="-", color="0.55", linewidth=0.6, shrinkA=0.0, shrinkB=3.0),
                        zorder=1)


# -- configurations along a run: the mechanism strip and the animation of ``loopcheck run`` ----

def configuration_at(joints, t: float) -> np.ndarray:
    """The general coordinates x (shape (n,)) of a JointTrajectory at time t (s), clamped to the
    run's span (:meth:`loopcheck.reduced.charts.JointTrajectory.interpolate`: cubic Hermite, O(h⁴); at
    ≤ 1 ms samples far below a pixel)."""
    return joints.interpolate(t)[0][0]


def _checked_system(scene, *runs) -> LoopSystem:
    system = compile_linkage(scene.mechanism.linkage)
    for joints in runs:
        if tuple(joints.names) != system.coordinate_names:
            raise ValueError(f"the run's coordinates {list(joints.names)} are not the scene's "
                             f"{list(system.coordinate_names)}")
    return system


# Fixed margins (inches, see loopcheck.compare.plots.new_figure) of the drawing, of the strip (a
# suptitle above two-line panel titles) and of the animation's frames.
DRAWING_MARGINS = {"left": 0.85, "right": 0.3, "top": 0.45, "bottom": 0.6}
STRIP_MIN_WIDTH = 7.0  # inches: room for the title above a single panel
STRIP_MARGINS = {"left": 0.95, "right": 0.2, "top": 0.85, "bottom": 0.55, "wspace": 0.6}
ANIMATION_MARGINS = {"left": 0.8, "right": 0.2, "top": 0.4, "bottom": 0.55}

REFERENCE_LOOK = {"colour": ENGINES[REFERENCE].colour, "linestyle": "-", "label": ENGINES[REFERENCE].label}
OTHER_LOOK = {"colour": ENGINES[DEFAULT_ENGINES[1]].colour, "linestyle": "--", "label": ENGINES[DEFAULT_ENGINES[1]].label}


def _frame(ax, mechanism: Mechanism, system: LoopSystem, xs: Sequence[np.ndarray], title: str,
           other_label: str = OTHER_LOOK["label"], q: float | None = None) -> None:
    """Both engines' configurations on ``ax``: the reduced one drawn as ``loopcheck draw`` draws a
    scene (:func:`draw_linkage`: bodies, joints, ground pivots, elements, named points and their
    labels, at its input coordinate ``q``), the other (``other_label``) as a dashed outline over it,
    with a thin solid outline of the reduced one beside it in the legend."""
    linkage = mechanism.linkage
    inputs = mechanism.linkage.inputs
    draw_linkage(ax, mechanism, system, np.asarray(xs[0], dtype=float), q=q,
                 input_labels={name: f"input {k + 1}" for k, name in enumerate(inputs)} if len(inputs) > 1 else None)
    for x, look in zip(xs, (REFERENCE_LOOK, {**OTHER_LOOK, "label": other_label})):
        draw_outline(ax, linkage, system, x, colour=look["colour"], linestyle=look["linestyle"],
                     label=look["label"], width=1.2)
    declutter_labels(ax)
    ax.set_title(title, fontsize=9, **PLAIN)
    ax.set_ylabel("")
    ax.set_xlabel("x (m)")
    _few_ticks(ax)


def _outline_frame(ax, linkage: Linkage, system: LoopSystem, xs: Sequence[np.ndarray], title: str,
                   other_label: str = OTHER_LOOK["label"]) -> None:
    """Both engines' configurations as light outlines (reduced solid, the other, ``other_label``,
    dashed) and the ground pivots as triangles: a frame of the animation, redrawn ~100 times
    (labels would jump from frame to frame)."""
    for x, look in zip(xs, (REFERENCE_LOOK, {**OTHER_LOOK, "label": other_label})):
        draw_outline(ax, linkage, system, x, colour=look["colour"], linestyle=look["linestyle"],
                     label=look["label"])
    ground = [system.point_index(j.body_a if j.body_a == GROUND else j.body_b,
                                 j.point_a if j.body_a == GROUND else j.point_b)
              for j in linkage.joints if GROUND in (j.body_a, j.body_b) and not isinstance(j, PrismaticJoint)]
    g = positions(system.points, np.asarray(xs[0], dtype=float))[ground].reshape(-1, 2)
    ax.plot(g[:, 0], g[:, 1], "^", color="black", markersize=7, zorder=4)
    ax.set_title(title, fontsize=9, **PLAIN)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="0.9", linewidth=0.6)
    ax.set_xlabel("x (m)")
    _few_ticks(ax)


def _few_ticks(ax) -> None:
    """At most five x ticks (and y ticks): a narrow panel of equal scales has room for no more
    labels side by side."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]))


# Of the drawing's span: two configurations closer than this are the same picture (a panel is
# about 4 in × 110 dpi = 440 pixels across the span: less than a pixel apart).
SAME_PICTURE = 1.0 / 440.0


def same_pictures(system: LoopSystem, reference, other, moments: Sequence[tuple[str, float]]
                  ) -> list[list[tuple[str, float]]]:
    """``moments`` grouped into panels: a moment joins the previous panel when no point of
    either run moves by more than SAME_PICTURE of the drawing's span between the two times
    (the two panels would be the same picture)."""
    def points(t: float) -> np.ndarray:
        return np.vstack([positions(system.points, configuration_at(run, t)) for run in (reference, other)])

    groups: list[list[tuple[str, float]]] = []
    last = None
    for label, t in moments:
        here = points(t)
        span = float(np.max(np.ptp(here, axis=0))) or 1.0
        if last is not None and float(np.max(np.hypot(*(here - last).T))) <= SAME_PICTURE * span:
            groups[-1].append((label, t))
        else:
            groups.append([(label, t)])
            last = here
    return groups


def draw_strip(scene, reference, other, moments: Sequence[tuple[str, float]], path: str | Path,
               other_label: str = OTHER_LOOK["label"]) -> None:
    """A strip of the mechanism at the given moments ((label, t s), one panel each, or one
    panel for moments that draw the same picture, :func:`same_pictures`), both engines
    overlaid: ``reference`` (the reduced solver's JointTrajectory) solid, ``other`` (MuJoCo's, or
    the engine ``other_label`` names) dashed, into the PNG ``path``.

    Raises ValueError when a run's coordinate names are not the scene's.
    """
    from . import plots

    system = _checked_system(scene, reference, other)
    linkage = scene.mechanism.linkage
    unit = scene.input_unit
    panels = same_pictures(system, reference, other, moments)
    fig, axes = plots.new_figure((max(4.5 * len(panels), STRIP_MIN_WIDTH), 4.2), 1, len(panels),
                                 squeeze=False, margins=STRIP_MARGINS)
    for ax, group in zip(axes[0], panels):
        label, t = group[0]
        xs = [configuration_at(run, t) for run in (reference, other)]
        q = [float(system.drive @ x) for x in xs]
        times = {f"{when:.6g}" for _, when in group}
        if len(times) == 1:  # one moment, or several at the same time: drawn once
            head = f"{' and '.join(name for name, _ in group)}, t = {t:.6g} s"
        else:  # moments that would draw the same picture: said, and drawn once
            head = " and ".join(f"{name} (t = {when:.6g} s)" for name, when in group) + ", one picture"
        if scene.dof > 1:  # every input's q, each engine on its line
            values = [", ".join(f"{name} {float(row @ x):.5g} {u}" for name, u, row in
                                zip(scene.inputs, scene.input_units(), system.input_rows)) for x in xs]
            where = f"reduced {values[0]}\n{other_label} {values[1]}"
        else:
            where = f"q reduced {q[0]:.6g} {unit}, {other_label} {q[1]:.6g} {unit}"
        _frame(ax, scene.mechanism, system, xs, f"{head}\n{where}", other_label, q=q[0])
    axes[0][0].set_ylabel("y (m)")
    axes[0][0].legend(loc="best", fontsize=8)
    fig.suptitle(f"{plots.short_name(scene.name)}: reduced (solid) and {other_label} (dashed)", y=0.975,
                 va="top", **plots.PLAIN)
    plots._save(fig, Path(path))


def gif_writer_available() -> bool:
    """Whether matplotlib can write a GIF here (its PillowWriter needs pillow, a dependency
    of matplotlib)."""
    try:
        from matplotlib.animation import PillowWriter
    except ImportError:
        return False
    return bool(PillowWriter.isAvailable())


ANIMATION_FRAMES = 60  # frames of mechanism.gif, at 15 per second: a 4 s loop


def animate_run(scene, reference, other, path: str | Path, *, frames: int | None = None,
                fps: int = 15, other_label: str = OTHER_LOOK["label"]) -> None:
    """An animated GIF of both engines' mechanism over the run (reduced solid, MuJoCo or the
    engine ``other_label`` names dashed), ``frames`` (default :data:`ANIMATION_FRAMES`) frames at
    equal time steps over the span both runs cover.

    Raises RuntimeError when no GIF writer is available (:func:`gif_writer_available`);
    ValueError when a run's coordinate names are not the scene's.
    """
    from matplotlib.animation import FuncAnimation, PillowWriter

    from .plots import new_figure, short_name

    if not gif_writer_available():
        raise RuntimeError("matplotlib's PillowWriter is not available (pillow missing): no GIF")
    system = _checked_system(scene, reference, other)
    linkage = scene.mechanism.linkage
    start = max(float(reference.t[0]), float(other.t[0]))
    end = min(float(reference.t[-1]), float(other.t[-1]))
    times = np.linspace(start, end, max(int(ANIMATION_FRAMES if frames is None else frames), 2))
    configs = [[configuration_at(run, t) for run in (reference, other)] for t in times]
    every = positions(system.points, np.asarray(configs[0][0]))
    for pair in configs:
        for x in pair:
            every = np.vstack([every, positions(system.points, x)])
    lo, hi = every.min(axis=0), every.max(axis=0)
    pad = 0.08 * float(np.max(hi - lo) or 1.0)
    fig, ax = new_figure((6, 5), margins=ANIMATION_MARGINS)

    def show(k: int):
        ax.clear()
        _outline_frame(ax, linkage, system, configs[k],
               f"{short_name(scene.name)}: t = {times[k]:.4f} s (reduced solid, {other_label} dashed)", other_label)
        ax.set_aspect("equal", adjustable="box")  # fixed limits: the same view in every frame
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        return []

    FuncAnimation(fig, show, frames=len(times), blit=False).save(str(path), writer=PillowWriter(fps=fps))


def strip_moments(c: "Comparison") -> list[tuple[str, float]]:
    """The moments the mechanism strip shows: the reduced run's peak speed (the compared
    peak, ``diff.t_peak_reference``, said to be at the end of the horizon when it is) and the
    sample of largest |Δq| (s). With several inputs, each input's peak speed, and the largest |Δq|
    of the input whose q_max_abs is largest (named). (The strip draws moments that look the same
    as one panel.)"""
    d = c.diff
    if c.other_diffs:  # several inputs: every input's peak speed, and the largest |Δq| of the inputs
        moments = [(f"peak speed of {name}" + (f" ({STILL_RISING})" if di.peak_still_rising else ""),
                    float(di.t_peak_reference)) for name, di in zip(c.scene.inputs, c.diffs)]
        k = int(np.argmax([di.q_max_abs for di in c.diffs]))
        di = c.diffs[k]
        worst = float(di.times[int(np.argmax(np.abs(di.dq)))]) if len(di.times) else di.span_end
        return [*moments, (f"largest |Δq| (of {c.scene.inputs[k]})", worst)]
    peak = "peak speed" + (f" ({STILL_RISING})" if d.peak_still_rising else "")
    worst = float(d.times[int(np.argmax(np.abs(d.dq)))]) if len(d.times) else d.span_end
    return [(peak, float(d.t_peak_reference)), ("largest |Δq|", worst)]


def plot_mechanism_strip(c: "Comparison", path: Path) -> None:
    """The mechanism at the peak speed and at the largest disagreement, both engines
    overlaid (:func:`draw_strip`)."""
    draw_strip(c.scene, c.reference.joints, c.other.joints,
               strip_moments(c), path, other_label=engine_label(c.other.engine))
