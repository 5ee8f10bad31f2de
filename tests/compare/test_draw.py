"""``loopcheck draw``: any scene's mechanism is drawn where an independent closed form puts its
points, the title names q0 with its unit and the assembly mode, and the command writes a
PNG, refusing a bad destination before any work.

Oracles for the positions: closed forms written here (the four-bar's circle intersection,
the offset slider-crank's piston position, the Watt II's link lengths), not the loop tables
the drawing reads.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from loopcheck.compare import cli
from loopcheck.compare.cli import main
from loopcheck.compare.draw import draw_linkage, draw_scene, mode_text
from loopcheck.scenefile import load_scene
from loopcheck.kinematics import assemble, compile_linkage
from loopcheck.scenefile import scene_from_dict

from helpers import SEED_SCENE

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PLANAR_SEED = SEED_SCENE.parent / "mechanisms" / "seed_fourbar.toml"
# The drawing reads the Newton-assembled tables; the closed forms are exact to a few ulps of
# O(1) m: measured worst 4.4e-16 m over these configurations; 2e-15 m is ~5x that.
ROUND_OFF = 2e-15
SLIDER = dict(r=0.1, l=0.35, e=0.03)


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def drawn(scene, x=None):
    """The artists and texts of a drawing of ``scene`` at x (default its x0)."""
    plt = pyplot()
    system = compile_linkage(scene.mechanism.linkage)
    fig, ax = plt.subplots()
    try:
        art = draw_linkage(ax, scene.mechanism, system, np.asarray(scene.x0 if x is None else x))
        return art, [t.get_text() for t in ax.texts]
    finally:
        plt.close(fig)


def marker(artist) -> np.ndarray:
    x, y = artist.get_data()
    return np.array([x[0], y[0]])


def slider_crank_scene(q0=0.8, prismatic_input=False, force_values=(0.0, 500.0, -300.0, 0.0)):
    """Offset slider-crank (crank r, rod l, slider on y = e) with a gas force on the piston
    (tabulated over the crank angle), a spring and a damper on the slider."""
    r, l, e = SLIDER["r"], SLIDER["l"], SLIDER["e"]
    load = {"force" if prismatic_input else "torque": {"type": "constant", "value": 1.0}}
    return scene_from_dict({
        "name": "slider_crank",
        "linkage": {"type": "planar", "input": "slide" if prismatic_input else "crank"},
        "bodies": {"ground": {"points": {"O": [0.0, 0.0], "line": [0.0, e], "wall": [0.6, e]}},
                   "crank": {"points": {"O": [0.0, 0.0], "A": [r, 0.0]}, "pivot_inertia": 0.01,
                             "pivot": "O"},
                   "rod": {"points": {"A": [0.0, 0.0], "B": [l, 0.0]}, "mass": 1.0,
                           "com": [0.1, 0.0], "inertia": 0.01},
                   "slider": {"points": {"pin": [0.0, 0.0]}, "mass": 2.0, "com": [0.0, 0.0],
                              "inertia": 0.001}},
        "joints": [{"name": "crank", "type": "revolute", "a": "ground.O", "b": "crank.O"},
                   {"name": "crank_pin", "type": "revolute", "a": "crank.A", "b": "rod.A"},
                   {"name": "wrist_pin", "type": "revolute", "a": "rod.B", "b": "slider.pin"},
                   {"name": "slide", "type": "prismatic", "a": "ground.line", "b": "slider.pin",
                    "direction": 0.0}],
        "springs": [{"name": "return", "a": "ground.wall", "b": "slider.pin", "stiffness": 100.0,
                     "rest_length": 0.2}],
        "dampers": [{"name": "drag", "a": "ground.wall", "b": "slider.pin", "coefficient": 3.0}],
        "point_forces": [{"name": "gas", "point": "slider.pin", "direction": math.pi,
                          "q": [0.0, 1.0, 2.0, 3.0], "values": list(force_values)}],
        **load,
        "initial": {"q": q0, "guess": {"crank": q0, "rod": 0.0, "slider": 0.0, "slide": l}}
        if not prismatic_input else {"q": q0, "guess": {"crank": 0.8, "rod": -0.2, "slider": 0.0}},
        "simulation": {"horizon": 0.1},
    })


def watt_ii_scene(mode=(1, 1)):
    """Watt II six-bar (the seed four-bar whose ternary rocker drives a second four-bar)."""
    guess = {"coupler": 0.7, "rocker": 1.3, "link5": 0.3, "link6": -1.4 if mode[1] > 0 else 1.4}
    return scene_from_dict({
        "name": "watt_ii",
        "linkage": {"type": "planar", "input": "O1"},
        "bodies": {"ground": {"points": {"O1": [0.0, 0.0], "O3": [1.0, 0.0], "O5": [1.6, 0.9]}},
                   "crank": {"points": {"O1": [0.0, 0.0], "A": [0.5, 0.0]}, "pivot_inertia": 1.5,
                             "pivot": "O1"},
                   "coupler": {"points": {"A": [0.0, 0.0], "B": [0.9, 0.0]}, "mass": 40.0,
                               "com": [0.5111, 0.1333], "inertia": 5.0},
                   "rocker": {"points": {"O3": [0.0, 0.0], "B": [0.7, 0.0], "D": [0.4, 0.3]},
                              "pivot_inertia": 3.5, "pivot": "O3"},
                   "link5": {"points": {"D": [0.0, 0.0], "E": [0.8, 0.0]}, "mass": 2.0,
                             "com": [0.4, 0.0], "inertia": 0.1},
                   "link6": {"points": {"E": [0.0, 0.0], "O5": [0.6, 0.0]}, "pivot_inertia": 0.2,
                             "pivot": "O5"}},
        "joints": [{"name": n, "type": "revolute", "a": a, "b": b} for n, a, b in (
            ("O1", "ground.O1", "crank.O1"), ("A", "crank.A", "coupler.A"),
            ("B", "coupler.B", "rocker.B"), ("O3", "ground.O3", "rocker.O3"),
            ("D", "rocker.D", "link5.D"), ("E", "link5.E", "link6.E"),
            ("O5", "link6.O5", "ground.O5"))],
        "torque": {"type": "constant", "value": 10.0},
        "initial": {"q": 0.2, "guess": guess, "mode": list(mode)},
        "simulation": {"horizon": 0.1},
    })


def four_bar_closed_form(q, branch, c1=0.5, c2=0.9, c3=0.7, c4=1.0):
    """A and B of the seed four-bar: B where the circles about A (c2) and O3 (c3) meet, on
    the side of the line A→O3 that ``branch`` picks (+1: B above the ground line here)."""
    A = np.array([c1 * math.cos(q), c1 * math.sin(q)])
    O3 = np.array([c4, 0.0])
    d = O3 - A
    dist = float(np.hypot(*d))
    along = (c2 * c2 - c3 * c3 + dist * dist) / (2 * dist)
    h = math.sqrt(c2 * c2 - along * along)
    u = d / dist
    n = np.array([-u[1], u[0]])
    return A, A + along * u + branch * h * n


@pytest.mark.parametrize("path", [SEED_SCENE, PLANAR_SEED])
def test_seed_joints_sit_at_the_closed_form(path):
    scene = load_scene(path)
    art, texts = drawn(scene)
    A, B = four_bar_closed_form(scene.q0, 1)
    worst = max(np.max(np.abs(np.array(art["joint:A"].center) - A)),
                np.max(np.abs(np.array(art["joint:B"].center) - B)),
                np.max(np.abs(marker(art["point:rocker.B"]) - B)),
                np.max(np.abs(marker(art["point:coupler.B"]) - B)))
    assert worst < ROUND_OFF, worst
    assert np.allclose(art["joint:O3"].center, [1.0, 0.0], rtol=0.0, atol=ROUND_OFF)
    # The coupler's centre of mass: (0.5111, 0.1333) m in the frame at A along A→B.
    u = (B - A) / np.hypot(*(B - A))
    G = A + 0.5111 * u + 0.1333 * np.array([-u[1], u[0]])
    assert np.max(np.abs(marker(art["com:coupler"]) - G)) < ROUND_OFF
    assert {"ground:O1", "ground:O3", "body:crank", "body:coupler", "body:rocker"} <= set(art)
    assert "com:crank" not in art and "com:rocker" not in art  # given by pivot inertia: no mass
    for name in ("O1 (input)", "A", "B", "O3", "crank", "coupler", "rocker",
                 "damper0 55 N·s/m", "G coupler, 40 kg"):
        assert texts.count(name) == 1, (name, texts)


@pytest.mark.parametrize("q0", [0.0, 0.8, 2.5, -1.9])
def test_slider_crank_block_spring_and_gas_force(q0):
    r, l, e = SLIDER["r"], SLIDER["l"], SLIDER["e"]
    scene = slider_crank_scene(q0)
    art, texts = drawn(scene)
    piston = np.array([r * math.cos(q0) + math.sqrt(l * l - (r * math.sin(q0) - e) ** 2), e])
    assert np.allclose(art["joint:slide"].get_center(), piston, rtol=0.0, atol=ROUND_OFF)
    assert np.allclose(art["joint:wrist_pin"].center, piston, rtol=0.0, atol=ROUND_OFF)
    assert np.allclose(art["joint:crank_pin"].center, [r * math.cos(q0), r * math.sin(q0)],
                       rtol=0.0, atol=ROUND_OFF)
    xs, ys = art["spring:return"].get_data()
    assert np.allclose([xs[0], ys[0], xs[-1], ys[-1]], [0.6, e, *piston], rtol=0.0, atol=ROUND_OFF)
    gas = art["force:gas"]
    assert np.allclose(gas.xy, piston, rtol=0.0, atol=ROUND_OFF)  # the arrow ends on the piston
    # F(q) along (cos π, sin π) = −x: a positive value pushes the piston left, so the tail
    # lies to its right; a negative one the other way round.
    from loopcheck.loads import TabulatedForce

    value = TabulatedForce((0.0, 1.0, 2.0, 3.0), (0.0, 500.0, -300.0, 0.0))(q0)
    tail = np.array(gas.xyann)
    assert abs(tail[1] - e) < ROUND_OFF
    assert np.sign(tail[0] - piston[0]) == (1.0 if value >= 0.0 else -1.0)
    assert f"gas F(q0) = {value:g} N" in texts
    assert "G slider, 2 kg" in texts and "drag 3 N·s/m" in texts


def test_watt_ii_closes_both_loops_in_the_drawing():
    """Two loops: every link keeps its length between the drawn joint centres, in both
    assembly modes of the second loop, and the title names the mode."""
    sides = []
    for mode in ((1, 1), (1, -1)):
        scene = watt_ii_scene(mode)
        assert scene.mode == mode
        art, texts = drawn(scene)
        c = {j: np.array(art[f"joint:{j}"].center) for j in ("O1", "A", "B", "O3", "D", "E", "O5")}
        for a, b, length in (("O1", "A", 0.5), ("A", "B", 0.9), ("B", "O3", 0.7), ("D", "O3", 0.5),
                             ("D", "E", 0.8), ("E", "O5", 0.6)):
            assert abs(np.hypot(*(c[a] - c[b])) - length) < 1e-14, (mode, a, b)
        assert np.allclose(c["O5"], [1.6, 0.9], atol=ROUND_OFF)
        assert art["body:rocker"].get_xy().shape[0] >= 3  # a ternary link is a plate
        # The mode's sign of loop 2 is which side of the line D→O5 the pin E lies on.
        u, v = c["O5"] - c["D"], c["E"] - c["D"]
        sides.append(np.sign(u[0] * v[1] - u[1] * v[0]))
    assert sides[0] == -sides[1] != 0  # the two modes draw E on either side of D→O5
    assert mode_text((1, -1)) == "(+1, −1)" and mode_text(()) == "()"


def test_draw_scene_titles_q0_with_its_unit_and_the_mode(tmp_path, monkeypatch):
    """A slider-driven scene gives q0 in m; the Watt II its two-loop mode."""
    import loopcheck.compare.plots

    titles = keep_titles(monkeypatch)
    slider = slider_crank_scene(0.4, prismatic_input=True)
    draw_scene(slider, tmp_path / "slider.png")
    draw_scene(watt_ii_scene((1, -1)), tmp_path / "watt.png")
    assert titles[0] == f"slider_crank: linkage at q0 = 0.4 m, mode {mode_text(slider.mode)}"
    assert titles[1] == "watt_ii: linkage at q0 = 0.2 rad, mode (+1, −1)"
    assert png_size(tmp_path / "watt.png") == (990, 715)


def png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_draw_writes_a_png_of_the_seed(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["draw", str(SEED_SCENE)]) == 0
    out = tmp_path / "linkage.png"
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    assert png_size(out) == (990, 715)  # 9 × 6.5 in at 110 dpi (loopcheck/compare/plots.py's _save)
    assert [p.name for p in tmp_path.iterdir()] == ["linkage.png"]  # no staging left behind


def test_draw_default_scene_and_named_output(tmp_path):
    out = tmp_path / "seed drawing.png"
    assert main(["draw", "--out", str(out)]) == 0
    assert png_size(out) == (990, 715)


def test_draw_a_planar_scene_file(tmp_path):
    out = tmp_path / "planar.png"
    assert main(["draw", str(PLANAR_SEED), "--out", str(out)]) == 0
    assert png_size(out) == (990, 715)


@pytest.mark.parametrize("dest, message", [
    ("missing/x.png", "does not exist"), ("", "is empty"), (".", "is a folder"),
    ("folder/", "is a folder")])
def test_bad_out_is_refused_before_any_work(tmp_path, monkeypatch, capsys, dest, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    monkeypatch.setattr(cli, "_scene", lambda path: pytest.fail("the scene was read"))
    assert main(["draw", "--out", dest]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "Traceback" not in captured.err
    line, = captured.err.strip().splitlines()
    assert line.startswith("loopcheck: error: --out") and message in line, line


def test_bad_scene_leaves_an_existing_drawing_as_it_was(tmp_path, capsys):
    out = tmp_path / "linkage.png"
    out.write_bytes(b"before")
    bad = tmp_path / "bad.toml"
    bad.write_text(SEED_SCENE.read_text().replace("c2 = 0.9", "c2 = -0.9"))
    assert main(["draw", str(bad), "--out", str(out)]) == 2
    line, = capsys.readouterr().err.strip().splitlines()
    assert "linkage.c2" in line and "Traceback" not in line, line
    assert out.read_bytes() == b"before"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "linkage.png"]


def test_a_drawing_that_fails_midway_leaves_the_old_file(tmp_path, monkeypatch, capsys):
    """Written through loopcheck.compare.output: a failure while the PNG is being written (here a
    writer that writes half a file and raises) leaves the previous file untouched."""
    import loopcheck.compare.draw

    def half_then_fail(scene, path):
        with open(path, "wb") as f:
            f.write(PNG_SIGNATURE)
        raise ValueError("the drawing failed")

    out = tmp_path / "linkage.png"
    out.write_bytes(b"before")
    monkeypatch.setattr(loopcheck.compare.draw, "draw_scene", half_then_fail)
    assert main(["draw", "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip() == "loopcheck: error: the drawing failed"
    assert out.read_bytes() == b"before"
    assert [p.name for p in tmp_path.iterdir()] == ["linkage.png"]


def test_a_bare_linkage_is_drawn_at_the_slider_crank_s_closed_form():
    """A linkage without masses or elements (draw_linkage takes a Linkage too)."""
    from core.test_mechanism import slider_crank

    plt = pyplot()
    r, l, e = SLIDER["r"], SLIDER["l"], SLIDER["e"]
    linkage = slider_crank(r, l, e)
    system = compile_linkage(linkage)
    q = 2.5
    x = assemble(system, q, np.array([q, 0.0, 0.0, l]))
    fig, ax = plt.subplots()
    try:
        art = draw_linkage(ax, linkage, system, x)
    finally:
        plt.close(fig)
    want = [r * math.cos(q) + math.sqrt(l * l - (r * math.sin(q) - e) ** 2), e]
    assert np.allclose(art["joint:slide"].get_center(), want, rtol=0.0, atol=ROUND_OFF)


def test_user_names_are_plain_text_and_cut(tmp_path, monkeypatch, capsys):
    """A scene name with broken mathtext draws as text (a mathtext parse would fail at save),
    cut to loopcheck.compare.plots.NAME_CHARS in the title."""
    plt = pyplot()

    import loopcheck.compare.plots

    name = r"seed $\notacommand{x}$ " + "x" * 70
    scene = tmp_path / "odd.toml"
    scene.write_text(SEED_SCENE.read_text().replace('name = "seed_fourbar"', f"name = '{name}'"))
    titles = keep_titles(monkeypatch)
    out = tmp_path / "odd.png"
    assert main(["draw", str(scene), "--out", str(out)]) == 0, capsys.readouterr().err
    assert png_size(out) == (990, 715)
    title, = titles
    assert title.startswith(r"seed $\notacommand{x}$ xxx"), title
    assert title.index(": linkage at") == loopcheck.compare.plots.NAME_CHARS and "…:" in title
    assert title.endswith("q0 = 0.2 rad, mode (+1)")
    assert plt.get_fignums() == []


def keep_titles(monkeypatch) -> list:
    """The titles of the figures the plots module saves from now on (it still saves them)."""
    import loopcheck.compare.plots

    titles = []
    real_save = loopcheck.compare.plots._save

    def keep_title(fig, path):
        titles.append(fig.axes[0].get_title())
        real_save(fig, path)

    monkeypatch.setattr(loopcheck.compare.plots, "_save", keep_title)
    return titles


@pytest.mark.parametrize("name,magic", [("l.png", b"\x89PNG\r\n\x1a\n"), ("l.pdf", b"%PDF-"), ("L.SVG", b"<?xml")])
def test_draw_writes_the_format_its_suffix_names(name, magic, tmp_path, capsys):
    """Issue 24: --out l.pdf wrote PNG bytes. The file starts with its format's signature."""
    from loopcheck.compare.cli import main

    assert main(["draw", "--out", str(tmp_path / name)]) == 0
    data = (tmp_path / name).read_bytes()
    assert data.startswith(magic), data[:16]
    if name.endswith("SVG"):
        assert b"<svg" in data[:2000]


@pytest.mark.parametrize("name", ["l.txt", "l.jpg", "linkage"])
def test_draw_refuses_other_suffixes_before_any_work(name, tmp_path, capsys):
    """Refused before the scene is read: with a scene that does not exist, the suffix is named."""
    from loopcheck.compare.cli import main

    assert main(["draw", str(tmp_path / "missing.toml"), "--out", str(tmp_path / name)]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured.err
    assert "--out" in captured.err and ".png, .pdf, .svg" in captured.err
    assert list(tmp_path.iterdir()) == []


def test_the_run_s_mechanism_strip_is_the_drawing_with_its_labels(tmp_path, saved_figures):
    """Issue: the strip of `loopcheck run` (mechanism.png) had no point labels while `loopcheck draw`
    had them: one drawing now. A run held at q0: each panel carries every label of the drawing
    (bodies, joints, elements, centres of mass; the input's without the drawing's q0) and the
    dashed outline of the other engine over it. (Planted: the strip's outlines alone fail it.)"""
    from loopcheck.compare.draw import draw_strip
    from loopcheck.reduced.charts import JointTrajectory

    scene = load_scene(SEED_SCENE)
    system = compile_linkage(scene.mechanism.linkage)
    x = np.vstack([scene.x0, scene.x0]).astype(float)
    held = JointTrajectory(system.coordinate_names, np.array([0.0, 1.0]), x, np.zeros_like(x),
                           np.zeros(2, dtype=int), np.ones((2, 1), dtype=int))
    draw_scene(scene, tmp_path / "d.png")
    draw_strip(scene, held, held, [("peak speed", 0.2)], tmp_path / "m.png")
    drawing, strip = saved_figures

    def labels(ax) -> set[str]:
        return {t.get_text().split(" (")[0] for t in ax.texts if t.get_text()}

    (drawn,) = drawing.axes
    assert {"crank", "coupler", "rocker", "O1", "O3", "A", "B"} <= labels(drawn)
    for ax in strip.axes:
        assert labels(ax) == labels(drawn)
        assert any(line.get_linestyle() == "--" and (line.get_gid() or "").startswith("body:") for line in ax.lines)
