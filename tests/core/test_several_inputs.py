"""Scenes with several inputs (issue 40): the format, the assembly at every input's value, and the
one-line refusals of what a one-DOF path cannot take."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loopcheck import kinematics
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene
from tests.oracles.multibody import Body, GROUND, Model, Pin

FIVE_BAR = Path(__file__).resolve().parents[2] / "scenes" / "mechanisms" / "five_bar_robot.toml"


def _text(**replace: str) -> str:
    text = FIVE_BAR.read_text()
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    return text


def test_the_five_bar_assembles_at_both_inputs_as_the_oracle_does():
    scene = load_scene(FIVE_BAR)
    assert scene.inputs == ("O1", "O5") and scene.dof == 2
    assert scene.initial_q() == (1.8, 1.3) and scene.initial_qdot() == (0.5, -0.3)
    assert (scene.q0, scene.qdot0) == (1.8, 0.5)  # the first input's
    system = kinematics.compile_linkage(scene.mechanism.linkage)
    x0 = np.array(scene.x0)
    np.testing.assert_array_equal(system.input_rows @ x0, [1.8, 1.3])
    # The oracle (full coordinates, its own kinematics) closes its loop with the same body angles: its
    # residual at our angles, each body's centre placed from its pins, is round-off (1e-15 m measured).
    model = Model(
        bodies=(Body("left_crank", 2.0, (0.2, 0.0), 0.03), Body("left_arm", 1.5, (0.35, 0.02), 0.07),
                Body("right_arm", 1.2, (0.35, -0.01), 0.05), Body("right_crank", 2.5, (0.2, 0.0), 0.04)),
        pins=(Pin("O1", GROUND, (0.0, 0.0), "left_crank", (0.0, 0.0)),
              Pin("A", "left_crank", (0.4, 0.0), "left_arm", (0.0, 0.0)),
              Pin("P", "left_arm", (0.7, 0.0), "right_arm", (0.7, 0.0)),
              Pin("B", "right_arm", (0.0, 0.0), "right_crank", (0.4, 0.0)),
              Pin("O5", GROUND, (0.6, 0.0), "right_crank", (0.0, 0.0))),
        torques=(), gravity=9.81, edges=())
    angles = dict(zip(("left_crank", "left_arm", "right_arm", "right_crank"), x0))
    q, _ = model.assemble(angles, {"left_crank": 1.8, "right_crank": 1.3}, {})
    np.testing.assert_allclose([q[3 * i + 2] for i in range(4)], x0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("replace, message", [
    ({'inputs = ["O1", "O5"]': 'inputs = ["O1", "O5"]\ninput = "O1"'}, "'linkage' needs 'input' (one joint) or 'inputs'"),
    ({'inputs = ["O1", "O5"]': 'inputs = ["O1"]'}, "must be an array of two joint names or more"),
    ({'inputs = ["O1", "O5"]': 'inputs = ["O1", "O1"]'}, "names a joint twice"),
    ({'inputs = ["O1", "O5"]': 'inputs = ["O1", "Q"]'}, "'linkage.inputs' = \"Q\" is not one of the joints"),
    ({"q = [1.8, 1.3]": "q = 1.8"}, "'initial.q' must be an array of 2 numbers"),
    ({"qdot = [0.5, -0.3]": "qdot = [0.5]"}, "'initial.qdot' must be an array of 2 numbers"),
    ({"q = [1.8, 1.3]": "q = [1.8, nan]"}, "initial.q[1]"),
    ({'inputs = ["O1", "O5"]': 'input = "O1"', "q = [1.8, 1.3]": "q = 1.8", "qdot = [0.5, -0.3]": "qdot = 0.5"},
     "2 degrees of freedom by Grübler's count"),
    ({"[simulation]": "[torque]\ntype = \"constant\"\nvalue = 1.0\n\n[simulation]"},
     "'torque': a linkage with several inputs takes each input's load as an actuator"),
    ({"guess = { left_arm = 0.8, right_arm = 2.3 }": "guess = { left_arm = nan }"}, "initial.guess.left_arm"),
])
def test_a_malformed_several_input_scene_is_refused_naming_its_key(replace, message, tmp_path):
    path = tmp_path / "five_bar.toml"
    path.write_text(_text(**replace))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_every_built_in_engine_runs_several_dof():
    # (an engine that does not declare it refuses such a scene in one line:
    # tests/core/test_engine_declarations.py)
    from loopcheck.registry import BUILT_IN

    assert all(engine.several_dof for engine in BUILT_IN)


def test_the_sweep_takes_a_two_dof_scene(tmp_path):
    # a sweep's rows hold every input (tests/compare/test_sweep_several_dof.py: its rows against runs
    # made apart); its check of the specification no longer refuses the scene
    from loopcheck.compare.sweep_scene import check, load_sweep
    from loopcheck.sweep_spec import spec_from_args

    data, _ = load_sweep(str(FIVE_BAR))
    check(data, spec_from_args(["bodies.left_arm.mass=1:2:2"], None, None), str(FIVE_BAR))
    with pytest.raises(ValueError, match="bodies.left_arm.mass"):  # and still refuses what does not fit
        check(data, spec_from_args(["bodies.left_arm.mass=-1:2:2"], None, None), str(FIVE_BAR))


def test_a_two_dof_scene_written_and_read_back_is_the_same_scene(tmp_path):
    from loopcheck.scene_writer import scene_data, toml_text

    scene = load_scene(FIVE_BAR)
    path = tmp_path / "again.toml"
    path.write_text(toml_text(scene_data(scene)))
    again = load_scene(path)
    assert again.inputs == scene.inputs
    assert (again.initial_q(), again.initial_qdot()) == (scene.initial_q(), scene.initial_qdot())
    assert again.mechanism == scene.mechanism
    np.testing.assert_allclose(again.x0, scene.x0, rtol=0, atol=1e-12)  # re-assembled from the written guess
