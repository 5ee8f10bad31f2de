"""A slide joint whose child body's frame is turned in the plane is the same mechanism.

The scene format's prismatic joint keeps its child's frame parallel to its parent's; the
importer once took a slide child's 2-D frame from its own MuJoCo x axis, so a piston frame turned
90° (its slide axis, pin and centre of mass rewritten so that MuJoCo runs the same mechanism)
imported as another mechanism: Newton then turned the piston back by 1.57 rad and its pin with it.

Probe models (written here, in the style of hand-made MJCF: degrees, euler frames, site-form
connects, a keyframe): an offset slider-crank (crank 40 mm, rod 120 mm, the cylinder's axis 5 mm
below the main bearing) whose wrist pin sits 20 mm from the piston's origin and whose piston's
centre of mass is off its origin, in two structures: the rod on the crank (the loop closes at the
wrist pin), and the rod on the piston (the loop closes at the crank pin); and an inverted
slider-crank, whose block slides on a turning guide (the slide's parent moves). Oracles: the same
file with the slider's frame not turned, and MuJoCo running each file as written.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

import loopcheck
from loopcheck.reference_models.mjcf_import import import_mjcf

CRANK, ROD, OFFSET, THETA0, PIN = 0.04, 0.12, -0.005, math.radians(40.0), 0.02
HORIZON = 0.3


def _geometry():
    """The crank tip, the wrist pin (world, at the keyframe) and the rod's angle from crank tip to pin."""
    tip = (CRANK * math.cos(THETA0), CRANK * math.sin(THETA0))
    dy = OFFSET - tip[1]
    pin_x = tip[0] + math.sqrt(ROD * ROD - dy * dy)
    return tip, pin_x, math.atan2(dy, pin_x - tip[0])


def _piston(turned: bool, inner: str = "") -> str:
    """The piston body. Turned: its frame is turned +90° about z, so its x axis is the world's y and
    its y axis the world's −x; the slide axis (world +x), the wrist pin (world +20 mm along x) and
    the centre of mass (world (6, −4) mm) are written in that frame, so the mechanism is unchanged."""
    _, pin_x, _ = _geometry()
    if turned:
        frame, axis, com, pin = 'euler="0 0 90"', "0 -1 0", "-0.004 -0.006 0", f"0 {-PIN!r} 0"
    else:
        frame, axis, com, pin = "", "1 0 0", "0.006 -0.004 0", f"{PIN!r} 0 0"
    return f"""
    <body name="piston" pos="{pin_x - PIN!r} {OFFSET!r} 0" {frame}>
      <joint name="guide" type="slide" axis="{axis}" damping="1.5"/>
      <inertial pos="{com}" mass="0.2" diaginertia="4e-5 4e-5 6e-5"/>
      <site name="wrist" pos="{pin}"/>{inner.replace("PIN_POS", pin)}
    </body>"""


def _model(turned: bool, rod_on_piston: bool) -> str:
    tip, pin_x, rod_angle = _geometry()
    crank_site = f'<site name="crank_tip" pos="{CRANK!r} 0 0"/>'
    if rod_on_piston:  # the rod hangs from the wrist pin, pointing back to the crank tip
        back = math.degrees(rod_angle + math.pi) - (90.0 if turned else 0.0)
        rod = f"""
      <body name="rod" pos="PIN_POS" euler="0 0 {back!r}">
        <joint name="small_end" type="hinge" axis="0 0 1"/>
        <inertial pos="0.07 0 0" mass="0.1" diaginertia="1e-5 1.5e-4 1.5e-4"/>
        <site name="rod_end" pos="{ROD!r} 0 0"/>
      </body>"""
        crank_child, piston = crank_site, _piston(turned, rod)
        connect = '<connect name="crank_bearing" site1="crank_tip" site2="rod_end"/>'
    else:
        rel = math.degrees(rod_angle - THETA0)
        crank_child = f"""
      <body name="rod" pos="{CRANK!r} 0 0" euler="0 0 {rel!r}">
        <joint name="big_end" type="hinge" axis="0 0 1"/>
        <inertial pos="0.05 0 0" mass="0.1" diaginertia="1e-5 1.5e-4 1.5e-4"/>
        <site name="rod_end" pos="{ROD!r} 0 0"/>
      </body>"""
        piston = _piston(turned)
        connect = '<connect name="wrist_pin" site1="rod_end" site2="wrist"/>'
    return f"""<mujoco model="probe_turned_slide">
  <compiler angle="degree"/>
  <option timestep="0.0005" gravity="0 -9.81 0"/>
  <worldbody>
    <body name="crank" euler="0 0 {math.degrees(THETA0)!r}">
      <joint name="crank_pin" type="hinge" axis="0 0 1" damping="0.01"/>
      <inertial pos="0.012 0.002 0" mass="0.3" diaginertia="1e-4 1e-4 2e-4"/>{crank_child}
    </body>{piston}
  </worldbody>
  <equality>
    {connect}
  </equality>
  <actuator>
    <motor name="drive" joint="crank_pin" gear="1"/>
  </actuator>
  <keyframe>
    <key name="spin" qpos="0 0 0" ctrl="0.3"/>
  </keyframe>
</mujoco>
"""


def _inverted(turned: bool) -> str:
    """An inverted slider-crank: a block slides on a guide that turns about the origin, its pin
    20 mm along the guide from its origin joined to a crank (50 mm, about (0.1, 0), at 60°).
    Turned: the block's frame is turned +90° about z from the guide's, its slide axis (the guide's
    +x), pin and centre of mass (the guide's (−4, −3) mm) written in it."""
    pivot, crank, theta = 0.1, 0.05, math.radians(60.0)
    tip = (pivot + crank * math.cos(theta), crank * math.sin(theta))
    if turned:
        frame, axis, pin, com = 'euler="0 0 90"', "0 -1 0", f"0 {-PIN!r} 0", "-0.003 0.004 0"
    else:
        frame, axis, pin, com = "", "1 0 0", f"{PIN!r} 0 0", "-0.004 -0.003 0"
    return f"""<mujoco model="probe_turned_slide_on_a_guide">
  <compiler angle="degree"/>
  <option timestep="0.001" gravity="0 -9.81 0"/>
  <worldbody>
    <body name="guide" euler="0 0 {math.degrees(math.atan2(tip[1], tip[0]))!r}">
      <joint name="guide_pivot" type="hinge" axis="0 0 1"/>
      <inertial pos="0.05 0 0" mass="0.2" diaginertia="1e-4 4e-4 4e-4"/>
      <body name="block" pos="{math.hypot(*tip) - PIN!r} 0 0" {frame}>
        <joint name="track" type="slide" axis="{axis}" damping="0.5"/>
        <inertial pos="{com}" mass="0.1" diaginertia="2e-5 2e-5 3e-5"/>
        <site name="block_pin" pos="{pin}"/>
      </body>
    </body>
    <body name="crank" pos="{pivot!r} 0 0" euler="0 0 {math.degrees(theta)!r}">
      <joint name="crank_pin" type="hinge" axis="0 0 1"/>
      <inertial pos="0.02 0 0" mass="0.1" diaginertia="1e-5 1e-5 2e-5"/>
      <site name="crank_tip" pos="{crank!r} 0 0"/>
    </body>
  </worldbody>
  <equality><connect name="pin" site1="crank_tip" site2="block_pin"/></equality>
  <actuator><motor name="drive" joint="crank_pin"/></actuator>
  <keyframe><key name="spin" ctrl="0.01"/></keyframe>
</mujoco>
"""


def _write(tmp_path: Path, turned: bool, structure: str) -> Path:
    path = tmp_path / f"slider_{'turned' if turned else 'straight'}_{structure}.xml"
    path.write_text(_inverted(turned) if structure == "on_a_guide" else _model(turned, structure == "rod_on_piston"))
    return path


def _mujoco_run(path: Path, dt: float) -> tuple[np.ndarray, float]:
    """MuJoCo runs the file as written but for its step (RK4 at ``dt``, the loop stiffened to solref
    (2 dt, 1)) over the horizon: the final qpos and the largest |q̇| of the motor's joint."""
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.timestep, m.opt.integrator = dt, mujoco.mjtIntegrator.mjINT_RK4
    m.eq_solref[:] = (2 * dt, 1.0)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    dof = m.jnt_dofadr[m.actuator_trnid[0][0]]
    peak = abs(d.qvel[dof])
    for _ in range(int(round(HORIZON / dt))):
        mujoco.mj_step(m, d)
        peak = max(peak, abs(d.qvel[dof]))
    return d.qpos.copy(), peak


@pytest.mark.parametrize("structure", ["rod_on_crank", "rod_on_piston", "on_a_guide"])
def test_a_turned_slide_frame_is_the_same_mechanism(tmp_path, structure):
    """The turned and the straight piston import to the same scene (up to round-off), the same
    exact peak, and the peak MuJoCo converges on when it runs either file as written.

    Measured: MuJoCo's runs of the two files end with qpos equal to 1e-14; the reduced peak over
    0.3 s is the same for either file to 1e-13 (slider-crank 34.413098 rad/s, the guide 29.123423)
    and MuJoCo's (RK4 at 1e-4 s) is within 0.9e-6 (rod on crank), 1.7e-6 (rod on piston) and 5.1e-6
    (on a guide) of it. With the old frame rule (the slide child's own x axis) Newton moves the
    configuration by 1.57 rad (1.42 on the guide) and the turned file's peak is 33.611 rad/s, 2.3 %
    off (slider-cranks), 32.091 rad/s, 10 % off (on a guide).
    Tolerances: 1e-10 relative between the two scenes (they differ only by round-off in the points,
    ~1e-17 m, against DOP853's rtol 1e-12); 5e-5 relative against MuJoCo (its error at 1e-4 s,
    measured up to 5.1e-6, with 10x room; the planted bug is 400x beyond)."""
    straight, turned = (_write(tmp_path, t, structure) for t in (False, True))
    q_straight, _ = _mujoco_run(straight, 1e-4)
    q_turned, mujoco_peak = _mujoco_run(turned, 1e-4)
    # the probe is what it claims: MuJoCo runs the two files as one mechanism (the slide's qpos is
    # the same displacement, in the same direction, in both)
    np.testing.assert_allclose(q_turned, q_straight, rtol=0, atol=1e-12)

    a = import_mjcf(straight, keyframe="spin", horizon=HORIZON)
    b = import_mjcf(turned, keyframe="spin", horizon=HORIZON)
    peak_a = loopcheck.simulate(a.scene, loopcheck.ReducedSettings()).peak.omega
    peak_b = loopcheck.simulate(b.scene, loopcheck.ReducedSettings()).peak.omega
    assert abs(peak_a) == pytest.approx(mujoco_peak, rel=5e-5)
    assert peak_b == pytest.approx(peak_a, rel=1e-10)
    # and the scenes are one: Newton had nothing to move, the pin and the centre of mass are where
    # the straight file puts them
    assert a.polish < 1e-12 and b.polish < 1e-12, (a.polish, b.polish)
    body_a = {body.name: body for body in a.scene.mechanism.linkage.bodies}
    body_b = {body.name: body for body in b.scene.mechanism.linkage.bodies}
    slider, pin = ("block", "block_pin") if structure == "on_a_guide" else ("piston", "wrist")
    np.testing.assert_allclose(body_b[slider].points[pin], body_a[slider].points[pin], atol=1e-15)
    np.testing.assert_allclose(body_b[slider].com, body_a[slider].com, atol=1e-15)

