"""Pinocchio on the hand-written two-finger gripper (tests/data/mjcf/two_finger_gripper.xml, issue 41),
imported: every input against the reduced reference.

The gripper as written couples its knuckles by a joint equality, which the pin engine refuses (no
Pinocchio form for a polynomial between two joints: said in one line). Its uncoupled variant (the
equality removed: 4 DOF, the servo on the tendon over both knuckles) runs: by the model's symmetry
the servo moves both knuckles alike, so the motion is the coupled gripper's. Measured over 1 s
(DOP853 at rtol 1e-12 against pin's default settings): every q within 5.1e-11 rad, q̇ within
1.3e-8 rad/s, the fingertips' peaks 1.9e-9 apart relative. Asserted over 0.15 s: q within 1e-9 rad,
q̇ within 1e-6 rad/s (20×, 80× the measured).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

pytest.importorskip("pinocchio", reason="the pin engine's extra is not installed (pip install -e '.[pin]' in loopcheck's checkout)")

import loopcheck  # noqa: E402
from loopcheck.compare.run import judge  # noqa: E402
from loopcheck.registry import ENGINES  # noqa: E402
from loopcheck.reference_models.mjcf_import import import_mjcf  # noqa: E402

GRIPPER = Path(__file__).parent.parent / "data" / "mjcf" / "two_finger_gripper.xml"


def _uncoupled(tmp_path) -> Path:
    text = GRIPPER.read_text()
    start = text.index('<joint name="knuckles"')
    path = tmp_path / "uncoupled.xml"
    path.write_text(text[:start] + text[text.index("/>", start) + 2:])
    return path


@pytest.fixture
def pin():
    engine = ENGINES["pin"]
    if not engine.several_dof:
        pytest.skip("the pin engine of several DOF is not merged in this tree")
    return engine


def test_pin_follows_the_reduced_gripper_on_every_input(pin, tmp_path):
    scene = dataclasses.replace(import_mjcf(_uncoupled(tmp_path)).scene, horizon=0.15)
    assert scene.dof == 4
    reference = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-12))
    run = pin.simulate(scene, pin.settings())
    comparison = judge(scene, reference, run, scene.tolerances)  # every input, on the comparison's own grid
    assert len(comparison.diffs) == 4
    for diff in comparison.diffs:
        assert diff.q_max_abs <= 1e-9 and diff.omega_max_abs <= 1e-6


def test_pin_refuses_the_knuckles_coupling_in_one_line(pin):
    with pytest.raises(ValueError, match="coupling 'knuckles'") as caught:
        pin.simulate(import_mjcf(GRIPPER).scene, pin.settings())
    assert "\n" not in str(caught.value)
