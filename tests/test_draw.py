"""``xval draw``: the drawing puts every artist where the closed form puts the point, and the
command writes a PNG, refusing a bad destination before any work.

Oracle for the positions: the four-bar closed form (reduced.linkage.FourBar and its phasor
sums), not the loop tables the drawing reads.
"""

from __future__ import annotations

import dataclasses
import struct

import numpy as np
import pytest

from compare import cli
from compare.cli import main
from compare.draw import draw_linkage
from reduced import load_scene
from reduced.expand import four_bar_elements, four_bar_linkage, four_bar_masses
from reduced.linkage import FourBar

from helpers import SEED_SCENE
from test_expand import rich_scene

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# The drawing reads the Newton-assembled tables; the closed form is exact to a few ulps of
# O(1) m: measured worst 4.4e-16 m over these configurations; 2e-15 m is ~5x that.
ROUND_OFF = 2e-15


def closed_form(scene, q, body, local):
    fb = FourBar(scene.linkage)
    ref = fb.kinematics(q)
    return np.array(fb.bodies[body].point(local).evaluate(ref.x, ref.K, ref.L)[:2])


def drawn(scene):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    linkage, system, x0 = four_bar_linkage(scene)
    fig, ax = plt.subplots()
    try:
        return draw_linkage(ax, linkage, system, x0, elements=four_bar_elements(scene),
                            masses=four_bar_masses(scene))
    finally:
        plt.close(fig)


def marker(artist) -> np.ndarray:
    x, y = artist.get_data()
    return np.array([x[0], y[0]])


@pytest.mark.parametrize("branch", [1, -1])
@pytest.mark.parametrize("q0", [0.2, 2.0, -2.5])
def test_artists_sit_at_the_closed_form_s_points(branch, q0):
    scene = dataclasses.replace(rich_scene(branch), q0=q0)
    g = scene.linkage
    art = drawn(scene)
    B = closed_form(scene, q0, "rocker", (g.c3, 0.0))
    A = closed_form(scene, q0, "crank", (g.c1, 0.0))
    worst = max(
        np.max(np.abs(marker(art["point:rocker.B"]) - B)),
        np.max(np.abs(marker(art["point:coupler.B"]) - B)),
        np.max(np.abs(np.array(art["joint:B"].center) - B)),
        np.max(np.abs(np.array(art["joint:A"].center) - A)),
        np.max(np.abs(marker(art["com:coupler"]) - closed_form(scene, q0, "coupler",
                                                               scene.bodies["coupler"].com))),
        np.max(np.abs(marker(art["com:rocker"]) - closed_form(scene, q0, "rocker",
                                                              scene.bodies["rocker"].com))))
    for kind, items in (("damper", scene.dampers), ("spring", scene.springs)):
        for k, item in enumerate(items):
            xs, ys = art[f"{kind}:{kind}{k}"].get_data()
            ends = np.array([[xs[0], ys[0]], [xs[-1], ys[-1]]])
            want = np.array([item.ground_point, closed_form(scene, q0, item.body, item.body_point)])
            worst = max(worst, np.max(np.abs(ends - want)))
    assert np.allclose(art["joint:O3"].center, [g.c4, 0.0], rtol=0.0, atol=ROUND_OFF)
    assert {"ground:O1", "ground:O3", "body:crank", "body:coupler", "body:rocker"} <= set(art)
    assert worst < ROUND_OFF, worst


def png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_draw_writes_a_png_of_the_seed(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["draw", str(SEED_SCENE)]) == 0
    out = tmp_path / "linkage.png"
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    assert png_size(out) == (990, 715)  # 9 × 6.5 in at 110 dpi (compare/plots.py's _save)
    assert [p.name for p in tmp_path.iterdir()] == ["linkage.png"]  # no staging left behind


def test_draw_default_scene_and_named_output(tmp_path):
    out = tmp_path / "seed drawing.png"
    assert main(["draw", "--out", str(out)]) == 0
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
    assert line.startswith("xval: error: --out") and message in line, line


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


def test_seed_drawing_has_one_label_per_joint_and_element():
    """The labels a user checks the geometry by: each joint once, the damper with its b."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scene = load_scene(SEED_SCENE)
    linkage, system, x0 = four_bar_linkage(scene)
    fig, ax = plt.subplots()
    try:
        draw_linkage(ax, linkage, system, x0, elements=four_bar_elements(scene),
                     masses=four_bar_masses(scene))
        texts = [t.get_text() for t in ax.texts]
    finally:
        plt.close(fig)
    for name in ("O1 (input)", "A", "B", "O3", "crank", "coupler", "rocker",
                 "damper0 55 N·s/m", "G coupler, 40 kg"):
        assert texts.count(name) == 1, (name, texts)


def test_a_drawing_that_fails_midway_leaves_the_old_file(tmp_path, monkeypatch, capsys):
    """Written through compare.output: a failure while the PNG is being written (here a
    writer that writes half a file and raises) leaves the previous file untouched."""
    import compare.draw

    def half_then_fail(scene, path):
        with open(path, "wb") as f:
            f.write(PNG_SIGNATURE)
        raise ValueError("the drawing failed")

    out = tmp_path / "linkage.png"
    out.write_bytes(b"before")
    monkeypatch.setattr(compare.draw, "draw_scene", half_then_fail)
    assert main(["draw", "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip() == "xval: error: the drawing failed"
    assert out.read_bytes() == b"before"
    assert [p.name for p in tmp_path.iterdir()] == ["linkage.png"]


def test_a_slider_is_drawn_at_the_slider_crank_s_closed_form():
    """The general description with a prismatic joint (no masses, no elements): the block
    sits at x = r cos q + √(l² − (r sin q − e)²), y = e, the offset slider-crank's closed form."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from reduced.loops import assemble, compile_linkage
    from test_mechanism import slider_crank

    r, l, e = 0.1, 0.35, 0.03
    linkage = slider_crank(r, l, e)
    system = compile_linkage(linkage)
    for q in (0.0, 0.8, 2.5, -1.9):
        x = assemble(system, q, np.array([q, 0.0, 0.0, l]))
        fig, ax = plt.subplots()
        try:
            art = draw_linkage(ax, linkage, system, x)
        finally:
            plt.close(fig)
        want = [r * math.cos(q) + math.sqrt(l * l - (r * math.sin(q) - e) ** 2), e]
        assert np.allclose(art["joint:slide"].get_center(), want, rtol=0.0, atol=ROUND_OFF)
        assert np.allclose(art["joint:wrist_pin"].center, want, rtol=0.0, atol=ROUND_OFF)
        assert np.allclose(art["joint:crank_pin"].center, [r * math.cos(q), r * math.sin(q)],
                           rtol=0.0, atol=ROUND_OFF)


def test_user_names_are_plain_text_and_cut(tmp_path, monkeypatch, capsys):
    """A scene name with broken mathtext draws as text (a mathtext parse would fail at save),
    cut to compare.plots.NAME_CHARS in the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import compare.plots

    name = r"seed $\notacommand{x}$ " + "x" * 70
    scene = tmp_path / "odd.toml"
    scene.write_text(SEED_SCENE.read_text().replace('name = "seed_fourbar"', f"name = '{name}'"))
    titles = []
    real_save = compare.plots._save

    def keep_title(fig, path):
        titles.append(fig.axes[0].get_title())
        real_save(fig, path)

    monkeypatch.setattr(compare.plots, "_save", keep_title)
    out = tmp_path / "odd.png"
    assert main(["draw", str(scene), "--out", str(out)]) == 0, capsys.readouterr().err
    assert png_size(out) == (990, 715)
    title, = titles
    assert title.startswith(r"seed $\notacommand{x}$ xxx"), title
    assert title.index(": linkage at") == compare.plots.NAME_CHARS and "…:" in title
    assert plt.get_fignums() == []
