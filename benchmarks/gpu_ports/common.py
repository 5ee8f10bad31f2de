"""What the GPU-port research scripts share (issue 28, docs/engines-gpu-research.md).

Like the scripts, it needs only ``mujoco`` (not loopcheck), so that they run in the ports' own
environments: the seed's exported model loaded as the ports take it, the seed's control, the
state at a time, and the minimal reproduction's spinning plate.
"""

from __future__ import annotations

import argparse

import numpy as np

# The minimal reproduction of MJX's missing J̇·q̇ (mjx_jdotv_repro.py): a planar plate (slides x, y
# and a hinge) pinned to the world 0.5 m from its centre of mass, spinning at 10 rad/s.
SPINNER = """
<mujoco model="spinner">
  <option timestep="0.0005" integrator="RK4" gravity="0 0 0">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="plate" pos="0.5 0 0">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="rz" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
    </body>
  </worldbody>
  <equality>
    <connect name="pin" body1="plate" body2="world" anchor="-0.5 0 0" solref="0.001 1" solimp="0.9999 0.9999 0.001 0.5 2"/>
  </equality>
  <keyframe>
    <key name="spin" qvel="0 5 10"/>
  </keyframe>
</mujoco>
"""


def load(path: str, integrator: str | None = None, timestep: float | None = None, iterations: int | None = None):
    """(model, data) of an exported MJCF as the ports take it: the energy flag cleared (MJX
    refuses ``mjENBL_ENERGY``), the options given changed, the data at keyframe 0."""
    import mujoco
    m = mujoco.MjModel.from_xml_path(path)
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    if integrator is not None:
        m.opt.integrator = {"rk4": mujoco.mjtIntegrator.mjINT_RK4,
                            "euler": mujoco.mjtIntegrator.mjINT_EULER,
                            "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}[integrator]
    if timestep is not None:
        m.opt.timestep = timestep
    if iterations is not None:
        m.opt.iterations = iterations
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    return m, d


def controls(m, n: int, value: float, duration: float) -> np.ndarray:
    """The seed's control of each of ``n`` steps, (n, nu): ``value`` while the step's midpoint is
    before ``duration`` s, 0 after."""
    mid = (np.arange(n) + 0.5) * m.opt.timestep
    return np.where(mid < duration, value, 0.0)[:, None] * np.ones((1, m.nu))


def state_arguments(description: str, argv=None) -> argparse.Namespace:
    """The forward-pass scripts' arguments: MODEL, --at (s), --ctrl."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("model")
    p.add_argument("--at", type=float, default=0.6)
    p.add_argument("--ctrl", type=float, default=250.0)
    return p.parse_args(argv)


def state_at(path: str, at: float, ctrl: float):
    """(model, data): MuJoCo C stepped from keyframe 0 to ``at`` s at the constant control
    ``ctrl``, then ``mj_forward`` there."""
    import mujoco
    m, d = load(path)
    d.ctrl[:] = ctrl
    for _ in range(round(at / m.opt.timestep)):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    return m, d
