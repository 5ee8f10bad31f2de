"""The minimal reproduction of MJX's defect (docs/engines.md, "MJX and the connect constraint"):
a plate pinned to the world by one ``connect`` 0.5 m from its centre of mass, spinning at
ω = 10 rad/s, no load, no gravity. At the initial state the pin's error and its rate are zero,
so the constraint's reference acceleration is −J̇·q̇ alone: the anchor's centripetal
acceleration, −ω²r = −50 m/s² along x (closed form). MuJoCo C computes it (mj_Jdotv in
mj_referenceConstraint); MJX 3.17.0 leaves the term out and gets 0.

One forward pass (jit of mjx.forward: a few seconds to compile, not a scan).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax", reason="the mjx engine's extra is not installed (pip install -e '.[mjx]' in loopcheck's checkout)")
pytest.importorskip("mujoco.mjx", reason="MJX is not installed (pip install --no-deps mujoco-mjx: docs/engines.md)")

import jax  # noqa: E402
import mujoco  # noqa: E402
from mujoco import mjx  # noqa: E402

OMEGA, R = 10.0, 0.5  # rad/s, m
SPINNER = f"""
<mujoco model="spinner">
  <option timestep="0.0005" integrator="RK4" gravity="0 0 0"><flag contact="disable"/></option>
  <worldbody>
    <body name="plate" pos="{R} 0 0">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="rz" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
    </body>
  </worldbody>
  <equality>
    <connect name="pin" body1="plate" body2="world" anchor="-{R} 0 0" solref="0.001 1"
             solimp="0.9999 0.9999 0.001 0.5 2"/>
  </equality>
  <keyframe><key name="spin" qvel="0 {OMEGA * R} {OMEGA}"/></keyframe>
</mujoco>
"""
EXACT = np.array([-OMEGA ** 2 * R, 0.0, 0.0])  # m/s²: −J̇·q̇ of the pin's rows (x, y, z)


@pytest.fixture(scope="module")
def forward():
    m = mujoco.MjModel.from_xml_string(SPINNER)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    with jax.enable_x64(True):
        dx = jax.jit(mjx.forward)(mjx.put_model(m), mjx.put_data(m, d))
        mjx_aref = np.asarray(dx._impl.efc_aref, dtype=float)
        mjx_jacobian = np.asarray(dx._impl.efc_J, dtype=float)
    return d, mjx_aref, mjx_jacobian


def test_the_pin_is_closed_and_still_at_the_start(forward):
    """The setup the reproduction needs: zero error and zero rate (so aref is −J̇·q̇ alone)."""
    d = forward[0]
    assert np.max(np.abs(d.efc_pos)) < 1e-15 and np.max(np.abs(d.efc_vel)) < 1e-13


def test_mujoco_c_reference_acceleration_is_the_closed_form(forward):
    """C's aref is −ω²r along x to round-off (1e-12 m/s² of 50)."""
    assert np.allclose(forward[0].efc_aref, EXACT, rtol=0.0, atol=1e-12)


def test_mjx_constraint_jacobian_is_mujocos(forward):
    """The rows are the same (so the difference below is aref's alone)."""
    d, _, jacobian = forward
    assert np.allclose(jacobian.reshape(d.efc_J.size), d.efc_J, rtol=0.0, atol=1e-15)


@pytest.mark.xfail(strict=True, raises=AssertionError, reason="MJX 3.17.0 omits J̇·q̇ from the connect constraint's reference "
                                       "acceleration (its aref is 0 here): docs/engines.md")
def test_mjx_reference_acceleration_is_the_closed_form(forward):
    assert np.allclose(forward[1], EXACT, rtol=0.0, atol=1e-9)
