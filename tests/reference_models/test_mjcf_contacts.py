"""Collidable geoms (issue 37, "contacts present but inactive"): accepted; a contact during any
MuJoCo run of the model fails the check (exit 1) naming both geoms, the time and the distance;
geoms already touching at the start are refused (exit 2). MuJoCo's own collision finds them."""

from __future__ import annotations

import re
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest

from loopcheck.compare.cli import main
from loopcheck.compare.model_check import check_model
from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf
from loopcheck.reference_models.user_model import run_model

# One finger of a gripper in the style of Menagerie's: a driver turned by a motor, a coupler
# carrying the finger's pad, a follower closing the four-bar through a site-form connect; the links'
# capsules cannot collide (contype/conaffinity 0 in the top default), the pads (class "pad") can.
# The palm's pad stands at STOP. The links lie in the x-y plane (hinges about +z), gravity along −z.
# Stiff loops and RK4 at 2 ms, so that the model as written meets the default tolerances.
FINGER = """<mujoco model="pads">
  <compiler angle="degree"/>
  <option timestep="0.002" integrator="RK4" gravity="0 0 -9.81"/>
  <default>
    <equality solref="0.004 1" solimp="0.9999 0.9999 0.001 0.5 2"/>
    <joint type="hinge" axis="0 0 1" damping="0.01"/>
    <geom type="capsule" size="0.004" density="2700" contype="0" conaffinity="0"/>
    <default class="pad">
      <geom type="box" size="0.006 0.002 0.01" contype="1" conaffinity="1"/>
    </default>
  </default>
  <worldbody>
    <body name="palm">
      <geom class="pad" name="palm_pad" pos="STOP"/>
    </body>
    <body name="driver">
      <joint name="drive"/>
      <geom fromto="0 0 0 0.05 0 0"/>
      <body name="coupler" pos="0.05 0 0" euler="0 0 90">
        <joint name="knuckle"/>
        <geom fromto="0 0 0 0.1 0 0"/>
        <geom class="pad" name="finger_pad" pos="0.05 0.01 0"/>
        <site name="cB" pos="0.1 0 0"/>
      </body>
    </body>
    <body name="follower" pos="0.15 0 0" euler="0 0 135">
      <joint name="follow"/>
      <geom fromto="0 0 0 0.1414213562373095 0 0"/>
      <site name="rB" pos="0.1414213562373095 0 0"/>
    </body>
  </worldbody>
  <equality>
    <connect name="finger_loop" site1="cB" site2="rB"/>
  </equality>
  <actuator>
    <motor name="fingers_actuator" joint="drive" gear="1" ctrlrange="-1 1"/>
  </actuator>
  <keyframe><key name="squeeze" qpos="0 0 0" ctrl="0.05"/></keyframe>
</mujoco>"""
# The finger's pad starts centred at (0.04, 0.05) and closes along +y, to about y = 0.069 at
# t = 0.3 s: a palm pad at y = 0.1 is never reached, one at y = 0.075 is (its lower face at 0.073,
# reached near t = 0.24 s), one at (0.04, 0.055) overlaps it at the start.
FAR, IN_THE_WAY, OVERLAPPING = "0.046 0.1 0", "0.046 0.075 0", "0.04 0.055 0"
HORIZON = 0.3


def _finger(tmp_path: Path, stop: str, collidable: bool = True) -> Path:
    text = FINGER.replace('pos="STOP"', f'pos="{stop}"')
    if not collidable:
        text = text.replace('contype="1" conaffinity="1"', 'contype="0" conaffinity="0"')
    path = tmp_path / ("pads.xml" if collidable else "no_contacts.xml")
    path.write_text(text)
    return path


def test_collidable_pads_that_never_touch_are_accepted_and_check_as_without_contacts(tmp_path):
    """The pads can collide but stay 0.03 m apart: the import accepts the model (planted: the old
    refusal of collidable geoms raises), and the check passes with the same figures, to the last
    digit, as the same model with the pads made non-collidable (no contact force ever acts, so the
    runs are the same arithmetic)."""
    imported = import_mjcf(_finger(tmp_path, FAR), keyframe="squeeze", horizon=HORIZON)
    assert not any("contact" in w or "collide" in w for w in imported.warnings), imported.warnings
    check = check_model(imported)
    assert check.contact is None
    assert check.passed, check.as_written
    plain = check_model(import_mjcf(_finger(tmp_path, FAR, collidable=False), keyframe="squeeze", horizon=HORIZON))
    assert plain.passed
    ran, without = check.as_written.comparison.other.trajectory, plain.as_written.comparison.other.trajectory
    assert np.array_equal(ran.q, without.q) and np.array_equal(ran.qdot, without.qdot)


def _contact_line(out: str) -> tuple[float, float]:
    """(time, distance) of the as-written run's contact in ``loopcheck check``'s output."""
    found = re.search(r"as written: +failed: geom 'palm_pad' and geom 'finger_pad' touch \(distance (\S+) m, "
                      r"margin 0 m\) at t = (\S+) s", out)
    assert found, out
    return float(found.group(2)), float(found.group(1))


def test_a_pair_that_touches_during_the_run_fails_the_check_naming_both_geoms_the_time_and_the_distance(
        tmp_path, capsys):
    """The palm's pad stands in the finger pad's way: `loopcheck check` exits 1, naming both pads,
    the time and the distance (planted: no contact test in the run, the check passes or fails on
    its figures alone without naming them). The time is the first step at which MuJoCo itself,
    stepping the file unchanged, reports a contact (the same step, so the same time to the printed
    6 digits); the distance is a penetration of at most one step's travel of the pad (under 2e-4 m:
    the pad moves under 0.07 m/s, 2 ms a step)."""
    path = _finger(tmp_path, IN_THE_WAY)
    code = main(["check", str(path), "--keyframe", "squeeze", "--horizon", str(HORIZON)])
    out = capsys.readouterr().out
    assert code == 1, out
    t, distance = _contact_line(out)
    assert "the difference comes from: a contact" in out
    assert "cheapest options" not in out  # no search: no options can meet the tolerances
    # the oracle: MuJoCo stepping the file as written, the first step with a contact
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    step = 0
    while True:
        mujoco.mj_forward(model, data)
        if data.ncon:
            break
        mujoco.mj_step(model, data)
        step += 1
        assert step * model.opt.timestep <= HORIZON, "MuJoCo found no contact"
    assert t == pytest.approx(step * model.opt.timestep, abs=1e-9)
    assert 0.2 < t < HORIZON
    assert -2e-4 < distance < 0.0


def test_the_run_stops_at_the_first_contact(tmp_path):
    """run_model raises CONTACT at the contact's time, before the horizon (planted: no check in
    the loop, the run reaches the horizon); the check fails on it and searches no options
    (planted: the search runs, every one of its runs touching)."""
    imported = import_mjcf(_finger(tmp_path, IN_THE_WAY), keyframe="squeeze", horizon=HORIZON)
    check = check_model(imported)
    assert not check.passed and check.contact is check.as_written.failure
    assert len(check.tried) == 3  # the as-written run and the two trials: no search for options
    with pytest.raises(NumericalFailure) as caught:
        run_model(imported)
    assert caught.value.reason is FailureReason.CONTACT
    assert 0.2 < caught.value.time < HORIZON
    assert "geom 'palm_pad' and geom 'finger_pad' touch" in str(caught.value)


def test_pads_touching_at_the_start_are_refused(tmp_path, capsys):
    """The pads overlap at the keyframe: one line naming both and the distance, exit 2, nothing on
    stdout (planted: no check at the start, the run fails instead with exit 1)."""
    path = _finger(tmp_path, OVERLAPPING)
    code = main(["check", str(path), "--keyframe", "squeeze", "--horizon", str(HORIZON)])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, lines
    # the finger pad's face at x = 0.04 − 0.002 + ... : the boxes overlap by 3 mm along y
    assert "geom 'palm_pad' and geom 'finger_pad' touch (distance -0.003 m, margin 0 m) at the start" in lines[0]


def test_the_contact_test_is_bounded_for_many_geoms(tmp_path):
    """5 000 collidable spheres on the palm, beside the pads: the import's contact test is MuJoCo's
    own collision (its broad phase), not a Python loop over the 12.5 million pairs (the old one took
    187 s on 20 000 geoms). Bound: the import within 3 s, over 10 times what it takes (0.25 s:
    MuJoCo's parse and the values' checks; the contact test itself under 1 ms), and under what a
    Python loop merely visiting the pairs takes (planted: 6 s)."""
    spheres = "".join(f'<geom type="sphere" size="0.001" pos="{-0.1 - 0.003 * (i % 100):.4f} '
                      f'{-0.1 - 0.003 * (i // 100):.4f} 0" contype="1" conaffinity="1"/>' for i in range(5000))
    path = _finger(tmp_path, FAR)
    path.write_text(path.read_text().replace('<geom class="pad" name="palm_pad"', spheres + '<geom class="pad" '
                                                                                           'name="palm_pad"'))
    start = time.perf_counter()
    imported = import_mjcf(path, keyframe="squeeze", horizon=HORIZON)
    assert time.perf_counter() - start < 3.0
    assert imported.model.ngeom == 5005


def test_a_refused_import_names_unnamed_geoms_by_their_bodies(tmp_path):
    """Unnamed overlapping pads are named as element_label names them (`geom #2 (on palm)`)."""
    path = _finger(tmp_path, OVERLAPPING)
    path.write_text(path.read_text().replace(' name="palm_pad"', "").replace(' name="finger_pad"', ""))
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path, keyframe="squeeze")
    assert "geom #1 (on palm) and geom #4 (on coupler) touch" in str(caught.value), caught.value



def test_a_contact_pair_counts_within_its_margin(tmp_path):
    """The pads non-collidable, an explicit `<pair>` of them with margin 0.03 m: the pads come
    within about 0.025 m, never touching; the pair's rows become active at a positive distance below
    the margin: the run fails on them (planted: counting only distances below 0)."""
    path = _finger(tmp_path, FAR, collidable=False)
    path.write_text(path.read_text().replace(
        "<equality>", '<contact><pair geom1="palm_pad" geom2="finger_pad" margin="0.03"/></contact><equality>', 1))
    check = check_model(import_mjcf(path, keyframe="squeeze", horizon=HORIZON))
    message = str(check.contact)
    assert check.contact is not None and check.contact.reason is FailureReason.CONTACT and not check.passed, message
    found = re.search(r"touch \(distance (\S+) m, margin 0.03 m\) at t = (\S+) s", message)
    assert found, message
    assert 0.0 < float(found.group(1)) <= 0.03  # printed to 3 digits
    assert 0.0 < float(found.group(2)) < HORIZON


def test_a_contact_pairs_rows_in_its_gap_are_not_contacts(tmp_path):
    """The same pair with margin 0.01 m and gap 0.02 m: MuJoCo lists rows for it from about 0.03 m
    apart, but while they lie in the gap its solver does not act on them (exclude 1, no constraint
    row), and the pads never come within 0.01 m: no contact, the check passes (planted: counting
    every row of data.contact fails it)."""
    path = _finger(tmp_path, FAR, collidable=False)
    path.write_text(path.read_text().replace(
        "<equality>", '<contact><pair geom1="palm_pad" geom2="finger_pad" margin="0.01" gap="0.02"/></contact>'
                      "<equality>", 1))
    imported = import_mjcf(path, keyframe="squeeze", horizon=HORIZON)
    check = check_model(imported)
    assert check.contact is None and check.passed, check.contact
