"""`[tolerances.ENGINE]`: each engine's own agreement with the reduced reference, in the scene.

The expected values are written here (the tables' numbers), not read from the code: a key an
engine's table leaves out is the scene's `[tolerances]` value, which itself defaults as the
README says (1e-4, 1e-9, 1e-3, 0.1, absent).
"""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from loopcheck.compare.cli import main
from loopcheck.registry import ENGINES
from loopcheck.scene import SceneError, Tolerances
from loopcheck.scene_writer import scene_toml
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.toml_reader import parse_toml
from helpers import SEED_SCENE, seed_dict

JUDGED = ", ".join(name for name in ENGINES if name != "reduced")  # mujoco, pin, and engines registered since
# The scene's [tolerances] at values that are not the defaults, and two engines' tables over it.
SCENE = {"peak_omega_rtol": 3e-4, "q_atol": 5e-3}
PIN = {"peak_omega_rtol": 1e-7, "omega_vs_q_atol": 0.05}
MUJOCO = {"omega_atol": 0.3}


def _scene(**tables):
    data = seed_dict()
    data["tolerances"] = {**SCENE, **tables}
    return scene_from_dict(data)


def test_an_engine_table_over_the_scenes_tolerances():
    """pin's keys over [tolerances]; a key pin leaves out (q_atol) is the scene's 5e-3, one neither gives
    (omega_atol) the default 0.1; mujoco has its own; an engine without a table gets [tolerances]."""
    scene = _scene(pin=PIN, mujoco=MUJOCO)
    assert scene.tolerances == Tolerances(peak_omega_rtol=3e-4, q_atol=5e-3)
    assert scene.tolerances_for("pin") == Tolerances(peak_omega_rtol=1e-7, peak_omega_atol=1e-9, q_atol=5e-3,
                                                     omega_atol=0.1, omega_vs_q_atol=0.05)
    assert scene.tolerances_for("mujoco") == Tolerances(peak_omega_rtol=3e-4, q_atol=5e-3, omega_atol=0.3)
    assert _scene().tolerances_for("pin") == _scene().tolerances == _scene(mujoco=MUJOCO).tolerances_for("pin")
    assert {k: dict(v) for k, v in scene.engine_tolerances.items()} == {"pin": PIN, "mujoco": MUJOCO}


def test_the_engine_tables_are_read_only_and_survive_pickling():
    """The scene is immutable (its tables too) and goes to worker processes whole."""
    scene = _scene(pin=PIN)
    with pytest.raises(TypeError):
        scene.engine_tolerances["mujoco"] = {}  # type: ignore[index]
    with pytest.raises(TypeError):
        scene.engine_tolerances["pin"]["q_atol"] = 1.0  # type: ignore[index]
    back = pickle.loads(pickle.dumps(scene))
    assert back.tolerances_for("pin") == scene.tolerances_for("pin") and back == scene


@pytest.mark.parametrize("table, message", [
    ({"reduced": {"q_atol": 1e-3}}, "'tolerances.reduced': the reduced engine is the reference"),
    ({"bullet": {"q_atol": 1e-3}}, f"'tolerances.bullet' names no engine; [tolerances.ENGINE] is one of {JUDGED}"),
    ({"pin": {"q_atol": -1.0}}, "'tolerances.pin.q_atol' must be positive, got -1.0"),
    ({"pin": {"q_atol": 0.0}}, "'tolerances.pin.q_atol' must be positive, got 0.0"),
    ({"pin": {"q_atol": "1e-3"}}, "'tolerances.pin.q_atol' must be a number, got a string"),
    ({"pin": {"q_atol": float("nan")}}, "'tolerances.pin.q_atol' must be finite"),
    ({"pin": {"peak_rtol": 1e-3}}, "unknown key 'tolerances.pin.peak_rtol'"),
    ({"pin": 1e-3}, "'tolerances.pin' must be a table, got a number"),
    ({"bullet": 1e-3}, "unknown key 'tolerances.bullet'"),
])
def test_a_bad_engine_table_is_refused_naming_its_key(table, message):
    with pytest.raises(SceneError) as err:
        _scene(**table)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_an_unknown_engine_from_a_file_is_one_line_naming_the_file_and_the_engines(tmp_path, capsys):
    path = tmp_path / "bullet.toml"
    path.write_text(SEED_SCENE.read_text() + "\n[tolerances.bullet]\nq_atol = 1e-3\n", encoding="utf-8")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and "'tolerances.bullet'" in err
    assert all(name in err for name in ENGINES if name != "reduced")


def test_engine_tables_read_back():
    """scene_writer writes each engine's table and the reader reads the same tables back."""
    scene = _scene(pin=PIN, mujoco=MUJOCO)
    back = scene_from_dict(parse_toml(scene_toml(scene), Path("written.toml")))
    assert back.engine_tolerances == scene.engine_tolerances and back.tolerances == scene.tolerances
    assert all(back.tolerances_for(name) == scene.tolerances_for(name) for name in ("mujoco", "pin"))
    plain = _scene()
    assert "pin" not in scene_toml(plain) and not scene_from_dict(parse_toml(scene_toml(plain), Path("w.toml"))
                                                                 ).engine_tolerances


def test_the_shipped_engine_tables_are_mjwarps_and_only_widen():
    """The engines pass the catalogue with the plain tables (tests/pin), but for MJWarp's float32:
    the mechanisms where MJWarp was measured carry [tolerances.mjwarp] (docs/engines.md), and each
    of its values is at least the scene's own (float32 never asks for more than float64)."""
    from loopcheck.shipped_scenes import catalogue

    scenes = [load_scene(path) for path in set(catalogue().values())]
    tables = {scene.name: scene.engine_tolerances for scene in scenes if scene.engine_tolerances}
    assert sorted(tables) == ["andrews_squeezer", "oscillating_slotted_lever", "seed_fourbar", "seed_fourbar_planar",
                              "slider_crank_driven_slider", "stephenson3_sixbar", "watt2_sixbar"]
    for scene in scenes:
        if scene.name in tables:
            assert set(tables[scene.name]) == {"mjwarp"}
            own, base = scene.tolerances_for("mjwarp"), scene.tolerances
            assert all(getattr(own, k) >= getattr(base, k) for k in ("peak_omega_rtol", "q_atol", "omega_atol")), scene.name


def test_the_format_reference_lists_each_engine_table():
    from loopcheck.format_reference import tables

    text = tables()
    assert all(f"`[tolerances.{name}]`" in text for name in ENGINES if name != "reduced")
    assert "`[tolerances.reduced]` is refused" in text
