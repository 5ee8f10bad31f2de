"""Hand-written robots with a planar four-bar inside (issue 38), and the same four-bar written alone.

The four-bar is written once (:data:`FOUR_BAR`, in its own frame: the plane z = 0, ground pivots at
(0, 0) and (0.045, 0)); a robot hangs it under a chain of joints whose keyframe puts the loop's
base at the orientation ``[e1 e2 n]`` (n the loop's plane normal, e1 world x projected on the plane,
e2 = n × e1), so that the loop's 2-D description is the one written alone, whose gravity is the
robot's, in that basis. A toe pad on its own joint (``pad_j``, at 0.3 rad in the keyframe) hangs
from the rocker: mass, welded there (the loop alone writes it at that angle).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

PAD_ANGLE = 0.3
G = np.array([0.0, 0.0, -9.81])

FOUR_BAR = """
      <body name="{p}crank">
        <joint name="{p}crank_j" axis="0 0 1" damping="1e-4"/>
        <geom type="capsule" fromto="0 0 0 0 0.02 0" size="0.003" mass="0.01" contype="0" conaffinity="0"/>
        <body name="{p}coupler" pos="0 0.02 0">
          <joint name="{p}coupler_j" axis="0 0 1"/>
          <geom type="capsule" fromto="0 0 0 0.04 0.01 0" size="0.003" mass="0.02" contype="0" conaffinity="0"/>
        </body>
      </body>
      <body name="{p}rocker" pos="0.045 0 0">
        <joint name="{p}rocker_j" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 -0.005 0.03 0" size="0.003" mass="0.015" contype="0" conaffinity="0"/>
        <body name="{p}pad" pos="0.01 -0.005 0" {pad_quat}>
          {pad_joint}
          <geom type="box" pos="0.01 0.004 0" size="0.008 0.003 0.004" mass="0.008" contype="0" conaffinity="0"/>
        </body>
      </body>"""


def _closure(p: str, name: str | None) -> str:
    named = f'name="{name}" ' if name else ""
    return f'<connect {named}body1="{p}coupler" body2="{p}rocker" anchor="0.04 0.01 0"/>'


def plane_basis(n) -> np.ndarray:
    """[e1 e2 n] as columns: e1 is world x projected on the plane normal to n (as the import takes it)."""
    n = np.asarray(n, dtype=float) / np.linalg.norm(n)
    x = np.array([1.0, 0.0, 0.0])
    e1 = x - (x @ n) * n
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(n, e1), n])


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, R.flatten())
    return q


def _words(v) -> str:
    return " ".join(repr(float(x)) for x in v)


def _robot(chain: str, closing: str, extras: str, actuators: str, key_qpos, key_ctrl, base_parent: str,
           normal, base_quat="1 0 0 0", prefix: str = "", closure_name: str | None = None) -> str:
    pad_joint = f'<joint name="{prefix}pad_j" axis="0 0 1"/>'
    loop = FOUR_BAR.format(p=prefix, pad_quat="", pad_joint=pad_joint)
    return f"""<mujoco model="robot">
  <option timestep="0.001" integrator="RK4"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
{extras}
{chain.format(base=f'<body name="{prefix}base" quat="{base_quat}"><geom type="sphere" size="0.005" mass="0.1" contype="0" conaffinity="0"/>{loop}</body>')}
  </worldbody>
  <equality>{_closure(prefix, closure_name)}</equality>
  <actuator>{actuators}</actuator>
  <keyframe><key name="{closing}" qpos="{_words(key_qpos)}" ctrl="{_words(key_ctrl)}"/></keyframe>
</mujoco>"""


def _solve_base_quat(xml_of, key_qpos, base: str, normal) -> str:
    """The loop base's quat in its parent such that, at the keyframe, its frame is [e1 e2 n]."""
    m = mujoco.MjModel.from_xml_string(xml_of("1 0 0 0"))
    d = mujoco.MjData(m)
    d.qpos[:] = key_qpos
    mujoco.mj_kinematics(m, d)
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, base)
    parent = int(m.body_parentid[b])
    R_parent = d.xmat[parent].reshape(3, 3)
    return _words(_quat(R_parent.T @ plane_basis(normal)))


LEG_NORMAL = (0.3, -0.5, 0.8)  # at an angle to every world axis
LEG_CHAIN = """
    <body name="pelvis" pos="0 0 1">
      <freejoint name="root"/>
      <geom type="box" size="0.1 0.1 0.05" mass="5"/>
      <body name="thigh" pos="0 0 -0.1">
        <joint name="hip" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="2"/>
        <body name="shin" pos="0 0 -0.3" euler="0.2 0 0.1">
          <joint name="knee" axis="1 0 0"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.025" mass="1"/>
          <body name="ankle" pos="0 0 -0.3">
            {base}
          </body>
        </body>
      </body>
    </body>"""
LEG_KEY = [0.1, -0.2, 0.05, 0.9801, 0.0998, 0.0, 0.1494, 0.4, -0.7, 0.0, 0.0, 0.0, PAD_ANGLE]
LEG_KEY_CTRL = [3.0, -2.0, 0.004]
LEG_ACTUATORS = ('<motor name="hip_motor" joint="hip"/><motor name="knee_motor" joint="knee"/>'
                 '<motor name="foot_motor" joint="crank_j"/>')


def floating_leg() -> str:
    """(a) A floating-base leg (freejoint pelvis, hip, knee) whose foot four-bar lies in a plane at an
    angle to every world axis; keyframe 'stance'; the loop closed by connect 'foot_loop'."""
    def xml(quat):
        return _robot(LEG_CHAIN, "stance", "", LEG_ACTUATORS, LEG_KEY, LEG_KEY_CTRL, "ankle", LEG_NORMAL, quat,
                      closure_name="foot_loop")
    return xml(_solve_base_quat(xml, LEG_KEY, "base", LEG_NORMAL))


ARM_NORMAL = (-0.4, 0.7, 0.55)
ARM_CHAIN = """
    <body name="link0" pos="0 0 0.5">
      <geom type="cylinder" size="0.05 0.05" mass="3"/>
      <body name="upper" pos="0 0 0.1">
        <joint name="shoulder" axis="0 0 1"/>
        <geom name="upper_bumper" type="sphere" pos="0.1 0 0" size="0.04" mass="1.5"/>
        <body name="fore" pos="0.25 0 0">
          <joint name="elbow" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.03" mass="1"/>
          <body name="wrist" pos="0.25 0 0">
            <joint name="wrist_roll" axis="1 0 0"/>
            <geom type="box" size="0.02 0.02 0.02" mass="0.3"/>
            {base}
          </body>
        </body>
      </body>
    </body>"""
ARM_EXTRAS = '    <body name="table" pos="2 2 0.2"><geom name="table_top" type="box" size="0.3 0.3 0.02"/></body>'
ARM_KEY = [0.5, -0.3, 0.8, 0.0, 0.0, 0.0, PAD_ANGLE]
ARM_KEY_CTRL = [0.2, 0.005]
ARM_ACTUATORS = ('<position name="elbow_servo" joint="elbow" kp="50"/>'
                 '<motor name="finger_motor" joint="f_crank_j"/>')


def finger_arm() -> str:
    """(b) An arm (shoulder z, elbow y, wrist x) holding a finger four-bar (bodies prefixed ``f_``),
    closed by an unnamed connect; a servo on the elbow (dropped), the finger's own motor (kept),
    collidable geoms elsewhere (the upper arm's bumper, a table) that never touch; keyframe 'grip'."""
    def xml(quat):
        return _robot(ARM_CHAIN, "grip", ARM_EXTRAS, ARM_ACTUATORS, ARM_KEY, ARM_KEY_CTRL, "wrist", ARM_NORMAL, quat,
                      prefix="f_")
    return xml(_solve_base_quat(xml, ARM_KEY, "f_base", ARM_NORMAL))


def loop_alone(normal, ctrl: float, prefix: str = "", closure_name: str | None = None) -> str:
    """The same four-bar written alone in its own plane (z = 0): the base's ground, the pad at its
    keyframe angle, gravity the robot's in the plane's basis, the loop motor's control."""
    g = plane_basis(normal).T @ G
    half = PAD_ANGLE / 2
    loop = FOUR_BAR.format(p=prefix, pad_quat=f'quat="{math.cos(half)!r} 0 0 {math.sin(half)!r}"', pad_joint="")
    return f"""<mujoco model="alone">
  <option timestep="0.001" integrator="RK4" gravity="{_words(g)}"/>
  <worldbody>{loop}
  </worldbody>
  <equality>{_closure(prefix, closure_name)}</equality>
  <actuator><motor name="motor" joint="{prefix}crank_j"/></actuator>
  <keyframe><key name="alone" qpos="0 0 0" ctrl="{ctrl!r}"/></keyframe>
</mujoco>"""
