"""Build the MuJoCo model of any scene's planar linkage with ``mujoco.MjSpec``.

Tree. The linkage's spanning tree (:attr:`loopcheck.mechanism.Linkage.tree`, parents first)
becomes MuJoCo's body tree: every chain hangs from one fixed body ``base`` under
``<worldbody>`` (readers such as Pinocchio's keep only the first body tree there), which
holds the ground points as sites. Each moving body's MuJoCo frame IS the description's body
frame, so every named point is a site at its own coordinates (``"<body>.<point>"``) and the
inertial frame sits at the body's ``com``. A revolute tree joint is a hinge about z at the
child's joint point; a prismatic tree joint a slide along the joint's line (expressed in the
child's frame; the relative angle is 0). MuJoCo joints carry the description's joint names.

Loops. Each cut joint (:attr:`Linkage.cut_joints`, always revolute) is one ``connect``
equality named after the joint, with ``body1``/``body2`` its two bodies (``base`` for
ground) and ``anchor`` its point on body1, in body1's frame (as menagerie's Cassie and
Robotiq 2F-85 do); solref/solimp from the settings.

Couplings. Each joint coupling (:class:`loopcheck.mechanism.JointCoupling`) is one ``joint``
equality named after it, joint1 the coupled joint and joint2 the driver, both tree joints
(the scene takes them into the tree first): its ``polycoef`` is the coupling's polynomial
re-expanded exactly about MuJoCo's qpos0 (0: the authored pose) and in the hinges' own sign
(:func:`coupling_polycoef`); solref/solimp are the loops'.

Pose. The model is authored in the scene's assembled configuration ``scene.x0`` (the
coordinates of :class:`loopcheck.kinematics.LoopSystem`): each child is placed in its parent's
frame from the joint's two points and the relative angle at x0, every hinge and slide has
``ref`` 0, so ``qpos = 0`` is the assembly, MuJoCo's default state and every reader that
starts from the zero configuration see every loop closed, and MuJoCo's anchor on body2
(computed at qpos0) is the joint's point. x = x0 + T·qpos (:func:`coordinate_map`) maps
MuJoCo's qpos (and qvel) to the general coordinates: a body's angle is its x0 angle plus the
hinge qpos along its tree path, a slider's s is s0 plus its slide's qpos.

Effects. Only what the scene declares is built: a damper is a spatial tendon between its two
sites with ``damping``, a spring one with ``stiffness`` and ``springlength``, a damper or spring
on a joint a fixed tendon on the joint's coordinate (:func:`joint_tendons`), the input load
a motor on the input joint (always a tree joint, hinge or slide), each actuator a ``general`` actuator
(:func:`_add_actuators`), gravity the scene's vector
(else zero). There are no geoms, contacts are disabled, and no joint has damping, armature,
stiffness or friction loss (a joint inertia is a fixed tendon's ``armature``). Point forces (F(q) along a fixed ground direction at a body
point) are not a model element: :mod:`loopcheck.reference_models.run` applies them during a run through
``mjcb_control`` (see :func:`loopcheck.reference_models.loads.point_force_callback`), so an exported MJCF
of such a scene lacks them.

Mass properties. A body with mass maps onto MuJoCo's ``mass``, ``ipos`` = com and I_zz =
its centroidal inertia. A body of mass 0 (given by its inertia about a fixed pivot, its com
that pivot) becomes a 1 kg point at the pivot (it neither moves nor adds kinetic or potential
energy) with I_zz equal to the pivot inertia. The out-of-plane moments I_xx = I_yy are set
equal to I_zz: every hinge turns about z and every slide stays in the plane, so they never
enter the joint-space mass matrix, and the choice satisfies MuJoCo's triangle inequality.
"""

from __future__ import annotations

import dataclasses
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco
import numpy as np

from loopcheck import kinematics as loops
from loopcheck import tree_coordinates as tree
from loopcheck.tree_coordinates import joint_order
from loopcheck.mechanism import GROUND, PrismaticJoint
from loopcheck.loads import ConstantLoad, LoadProfile, PiecewiseConstantLoad, PulseLoad
from loopcheck.scene import Scene, Tolerances

from .options import INTEGRATORS as MUJOCO_INTEGRATORS
from .warning_handler import compile_spec

# The MuJoCo this engine needs: 4.0.0 has the sparse-Cholesky bug (docs/engines.md), and installing
# MJX or MJWarp with pip can put MuJoCo 3.17's library in the same folder as mujoco-core 4.0.1, or
# downgrade it, with no pip command noticing (docs/engines-gpu-research.md): the library that
# `import mujoco` loaded is checked, not the distribution pip lists.
MIN_MUJOCO = "4.0.1"


def release(text: str) -> tuple[int, ...]:
    """A version string's release numbers, e.g. (4, 0, 1) of "4.0.1" (at most three)."""
    return tuple(int(part) for part in re.findall(r"\d+", text)[:3])


def check_mujoco_version(version: str) -> None:
    """ImportError in one line unless ``version`` (MuJoCo's, e.g. ``mujoco.__version__``) is at
    least MIN_MUJOCO."""
    if release(version) < release(MIN_MUJOCO):
        raise ImportError(f"loopcheck's MuJoCo engine needs MuJoCo {MIN_MUJOCO} or newer, but `import mujoco` loads "
                          f"{version}: reinstall with pip install --force-reinstall 'mujoco-core>={MIN_MUJOCO}' (MJX "
                          "and MJWarp: install them with --no-deps, docs/engines.md)")


check_mujoco_version(mujoco.__version__)

# MuJoCo's enum for each integrator name (the names are listed once, in loopcheck.scene).
INTEGRATOR_ENUM = {name: getattr(mujoco.mjtIntegrator, f"mjINT_{name.upper()}") for name in MUJOCO_INTEGRATORS}
BASE_BODY = "base"  # the fixed body every chain hangs from (the description's ground)
HOME_KEY = "home"  # keyframe with the scene's initial state
# What a scene holds outside the model, written as MJCF <custom> numerics for import-mjcf to read back
CUSTOM_PREFIX = "loopcheck."
CUSTOM_HORIZON = "loopcheck.horizon"  # [s]
CUSTOM_CTRL = "loopcheck.ctrl"  # the input motor's control table [t0, v0, t1, v1, ...] (s, ctrl units; gear 1)
CUSTOM_ACTUATOR_CTRL = "loopcheck.ctrl."  # + an actuator's name: its control table [t0, v0, t1, v1, ...]
CUSTOM_TOLERANCES = "loopcheck.tolerances."  # + KEY, or + ENGINE.KEY: [value]
CUSTOM_INPUTS = "loopcheck.inputs"  # a <text>: the inputs' joints in order, "D,J" (several DOF only)
PIVOT_POINT_MASS = 1.0  # kg, at a fixed pivot: no kinetic or potential energy
INPUT_MOTOR = "input_motor"  # the actuator of the scene's load on the input joint
RESERVED_NAMES = (BASE_BODY, "world")  # MuJoCo names a description's body may not take


@dataclass(frozen=True)
class ConstraintSettings:
    """Softness of the loop-closure equality constraints (MuJoCo ``solref``/``solimp``)."""

    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]


@dataclass(frozen=True)
class TreeBody:
    """One moving body of the spanning tree, placed in its parent's frame at the assembled pose.

    Parameters
    ----------
    name : the description's body name.
    parent : parent body name (``BASE_BODY`` for ground, or another tree body).
    joint : the tree joint's name (a hinge about z or a slide).
    pos : (x, y) of the body's origin in the parent's frame, m.
    angle : rotation about z of the body's frame relative to its parent's at the assembled
        pose, rad (the body's ``quat``; a hinge's qpos counts from it; 0 for a slide).
    joint_pos : (x, y) of the joint in the body's own frame (its joint point), m.
    axis : (x, y) unit vector of a slide in the body's own frame; None for a hinge.
    """

    name: str
    parent: str
    joint: str
    pos: tuple[float, float]
    angle: float
    joint_pos: tuple[float, float]
    axis: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not all(np.isfinite([*self.pos, self.angle, *self.joint_pos])):
            raise ValueError(f"body {self.name!r}: pos and angle must be finite, got {self.pos!r}, {self.angle!r}")

    @property
    def quat(self) -> list[float]:
        """Unit quaternion (w, x, y, z) of the rotation by ``angle`` about z."""
        return [float(np.cos(0.5 * self.angle)), 0.0, 0.0, float(np.sin(0.5 * self.angle))]


@dataclass(frozen=True)
class ModelHandles:
    """The compiled model and the names the runner reads back."""

    model: mujoco.MjModel
    spec: mujoco.MjSpec
    sensor_slices: dict  # sensor name -> slice into sensordata
    damper_tendons: tuple[str, ...]


def _mujoco_body(name: str) -> str:
    return BASE_BODY if name == GROUND else name


def site_name(body: str, point: str) -> str:
    """The site of a description's point (``"<body>.<point>"``; ground points on ``base``)."""
    return f"{body}.{point}"


def sensor_name(owner: str, kind: str) -> str:
    """The name of a read-out sensor, ``"<owner>:<kind>"``: scene names cannot contain ':'
    (letters, digits, '_' and '-'), so no scene name makes two sensors' names equal (a point
    force ``piston_com`` and a body ``piston`` once both gave ``piston_com_vel``)."""
    return f"{owner}:{kind}"


def spanning_tree(scene: Scene) -> tuple[TreeBody, ...]:
    """The moving bodies in the linkage's tree order (parents first), placed at ``scene.x0``.

    A revolute tree joint: the child's origin in the parent's frame is the parent's joint
    point minus R(θ_child − θ_parent)·the child's joint point. A prismatic one: relative angle
    0, the child displaced by s0 along the joint's line (point_b = point_a + s0 e(direction_a)).
    """
    linkage = scene.mechanism.linkage
    bodies, joints = linkage.body_map, linkage.joint_map
    system = loops.compile_linkage(linkage)
    x0 = assembled_angles(scene)
    angle = {GROUND: 0.0, **{b: float(x0[i]) for i, b in enumerate(linkage.moving)}}
    out = []
    for edge in linkage.tree:
        jt = joints[edge.joint]
        child_is_b = jt.body_b == edge.body
        own = jt.point_b if child_is_b else jt.point_a
        other = jt.point_a if child_is_b else jt.point_b
        px, py = bodies[edge.parent].points[other]
        cx, cy = bodies[edge.body].points[own]
        if isinstance(jt, PrismaticJoint):
            s0 = float(x0[system.coordinate(f"{jt.name}.s")])
            sign = 1.0 if child_is_b else -1.0
            ex, ey = math.cos(jt.direction_a), math.sin(jt.direction_a)
            pos = (px + sign * s0 * ex - cx, py + sign * s0 * ey - cy)
            out.append(TreeBody(edge.body, _mujoco_body(edge.parent), jt.name, pos, 0.0, (cx, cy),
                                (sign * ex, sign * ey)))
        else:
            rel = angle[edge.body] - angle[edge.parent]
            c, s = math.cos(rel), math.sin(rel)
            pos = (px - (c * cx - s * cy), py - (s * cx + c * cy))
            out.append(TreeBody(edge.body, _mujoco_body(edge.parent), jt.name, pos, rel, (cx, cy)))
    return tuple(out)


def coordinate_map(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(x0, T) with x = x0 + T·qpos and ẋ = T·qvel: shapes (n,), (n, nq), x0 the authored pose
    (:func:`assembled_angles`), qpos in :func:`joint_order` (:func:`loopcheck.tree_coordinates.coordinate_map`)."""
    return assembled_angles(scene), tree.coordinate_map(scene.mechanism.linkage)[0]


def joint_rates_matrix(scene: Scene) -> np.ndarray:
    """P with qvel = P·ẋ (and qpos = P·(x − x0)), shape (nq, n): a hinge's relative rate
    θ̇_child − θ̇_parent, a slide's ṡ. P·T = I."""
    return tree.coordinate_map(scene.mechanism.linkage)[1]


def joint_positions(scene: Scene, x: np.ndarray) -> np.ndarray:
    """MuJoCo qpos at general coordinates ``x`` (shape (..., n)), shape (..., nq)."""
    P = joint_rates_matrix(scene)
    return (np.asarray(x, dtype=float) - assembled_angles(scene)) @ P.T


def joint_rates(scene: Scene, xdot: np.ndarray) -> np.ndarray:
    """MuJoCo qvel from the general rates ẋ (shape (..., n)), shape (..., nq)."""
    return np.asarray(xdot, dtype=float) @ joint_rates_matrix(scene).T


def loop_angles(scene: Scene, qpos: np.ndarray) -> np.ndarray:
    """General coordinates x, shape (samples, n), from MuJoCo qpos rows, shape (samples, nq)."""
    x0, T = coordinate_map(scene)
    return x0 + np.atleast_2d(qpos) @ T.T


def loop_rates(scene: Scene, qvel: np.ndarray) -> np.ndarray:
    """General rates ẋ, shape (samples, n), from MuJoCo qvel rows, shape (samples, nq)."""
    _, T = coordinate_map(scene)
    return np.atleast_2d(qvel) @ T.T


# A four-bar shorthand scene is authored at its closed-form assembly when that agrees with
# scene.x0 (Newton-polished from it) to this many rad: the two differ by round-off (4e-16 on
# the seed), which the stiff loop constraint and the step search carry to 3.9e-10 in q or q̇
# over the seed's run and 1.1e-6 on hard/fast_crank (measured with the pose at x0 instead); the
# closed form reproduces the earlier four-bar-only model's numbers exactly (docs/architecture.md).
CLOSED_FORM_POSE_RAD = 1e-12


def assembled_angles(scene: Scene) -> np.ndarray:
    """The model's authored pose in general coordinates, shape (n,): ``scene.x0``, or for a
    ``four_bar`` shorthand scene the four-bar's closed-form assembly at q0 (checked fast path:
    used only when it agrees with x0 to CLOSED_FORM_POSE_RAD)."""
    x0 = np.asarray(scene.x0, dtype=float)
    if scene.four_bar is None:
        return x0
    from loopcheck.four_bar import FourBar

    q, phi1, phi2 = FourBar(scene.four_bar).assemble(scene.q0)
    system = loops.compile_linkage(scene.mechanism.linkage)
    pose = x0.copy()
    for name, value in (("crank.angle", q), ("coupler.angle", phi1), ("rocker.angle", phi2 + np.pi)):
        pose[system.coordinate(name)] = value  # the rocker's frame points O3 → B
    return pose if np.max(np.abs(pose - x0)) <= CLOSED_FORM_POSE_RAD else x0


def initial_rates(scene: Scene) -> np.ndarray:
    """ẋ0 (general rates) consistent with the loops at (x0, q̇0), shape (n,)
    (:func:`loopcheck.tree_coordinates.initial_rates` at the authored pose; with several inputs,
    :func:`loopcheck.kinematics.input_rates` of every input's rate)."""
    if scene.dof > 1:  # every input at its rate: ẋ0 = K q̇0
        return loops.input_rates(loops.compile_linkage(scene.mechanism.linkage), assembled_angles(scene),
                                 scene.initial_qdot())
    return tree.initial_rates(scene.mechanism.linkage, assembled_angles(scene), scene.qdot0)


def initial_qpos_qvel(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions (zero: the model is authored at x0) and velocities at (q0, q̇0)."""
    P = joint_rates_matrix(scene)
    return np.zeros(P.shape[0]), P @ initial_rates(scene)


def _set_inertial(body: mujoco.MjsBody, mass: float, com: tuple[float, float], inertia: float) -> None:
    body.explicitinertial = True
    body.mass = mass if mass > 0.0 else PIVOT_POINT_MASS  # mass 0: com is the fixed pivot
    body.ipos = [com[0], com[1], 0.0]
    body.inertia = [inertia, inertia, inertia]


def build_spec(scene: Scene, *, constraint: ConstraintSettings, integrator: str = "rk4",
               timestep: float = 1e-3, iterations: int = 100, tolerance: float = 1e-10,
               refsafe: bool = True, diagexact: bool = False) -> mujoco.MjSpec:
    """An ``MjSpec`` of the scene's linkage with the given solver options."""
    mech = scene.mechanism
    linkage = mech.linkage
    described = linkage.body_map
    for name in linkage.moving:
        if name in RESERVED_NAMES:
            raise ValueError(f"body name {name!r} is reserved in the MuJoCo model: rename the body")
    for e in mech.joint_inertias:
        if e.joint in linkage.cut_joints:
            raise ValueError(f"joint inertia {e.name!r} is on joint {e.joint!r}, which closes a loop in the MuJoCo model "
                             "(the loops leave no spanning tree holding every inertia's joint): MuJoCo's tendon armature "
                             "keeps only the mass-matrix terms of one branch, so it would not be ½ I u̇²; move the "
                             "inertia to a joint of the tree or run the reduced engine alone")
    taken = {e.name for e in mech.elements + mech.joint_elements}
    for joint in linkage.joints:
        if joint.range is not None and range_tendon(joint.name) in taken:
            raise ValueError(f"element name {range_tendon(joint.name)!r} is the MuJoCo model's tendon of joint "
                             f"{joint.name!r}'s range: rename the element")
    spec = mujoco.MjSpec()
    spec.modelname = scene.name
    opt = spec.option
    opt.integrator = INTEGRATOR_ENUM[integrator]
    opt.iterations = iterations
    opt.tolerance = tolerance
    opt.gravity = [*(scene.gravity or (0.0, 0.0)), 0.0]
    opt.disableflags = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    if not refsafe:
        opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    # Energy is computed for the audit sensors only; it adds no force.
    opt.enableflags = int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    if diagexact:
        opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)

    z = [0.0, 0.0, 1.0]
    base = spec.worldbody.add_body(name=BASE_BODY)  # fixed: no joint
    bodies = {GROUND: base}
    for link in spanning_tree(scene):
        body = bodies[GROUND if link.parent == BASE_BODY else link.parent].add_body(
            name=link.name, pos=[*link.pos, 0.0], quat=link.quat)
        if link.axis is None:
            body.add_joint(name=link.joint, type=mujoco.mjtJoint.mjJNT_HINGE, axis=z,
                           pos=[*link.joint_pos, 0.0])
        else:
            body.add_joint(name=link.joint, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[*link.axis, 0.0],
                           pos=[*link.joint_pos, 0.0])
        b = described[link.name]
        _set_inertial(body, b.mass, b.com, b.inertia)
        body.gravcomp = b.gravcomp  # its weight scaled by 1 − gravcomp (MuJoCo's passive force)
        bodies[link.name] = body
    for name, body in bodies.items():
        if name in described:
            for point, (px, py) in described[name].points.items():
                body.add_site(name=site_name(name, point), pos=[px, py, 0.0])

    joints = linkage.joint_map
    for name in linkage.cut_joints:
        jt = joints[name]
        # The anchor is point_a in body1's frame; MuJoCo finds body2's anchor at qpos0, the
        # assembled pose, where it is point_b.
        loop = spec.add_equality(name=name, type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_BODY,
                                 name1=_mujoco_body(jt.body_a), name2=_mujoco_body(jt.body_b))
        loop.data[0:3] = [*described[jt.body_a].points[jt.point_a], 0.0]
        loop.solimp = list(constraint.solimp)
        # Read-outs of the loop closure: the joint's point on either side.
        for side, body, point in (("a", jt.body_a, jt.point_a), ("b", jt.body_b, jt.point_b)):
            spec.add_sensor(name=sensor_name(name, f"{side}_pos"), type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                            objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name(body, point))

    for c in linkage.couplings:
        joint1, joint2, polycoef = coupling_polycoef(scene, c)
        coupling = spec.add_equality(name=c.name, type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                                     name1=joint1, name2=joint2)
        coupling.data[0:5] = polycoef
        coupling.solimp = list(constraint.solimp)

    dampers = []
    for e in mech.elements:
        tendon = spec.add_tendon(name=e.name)
        tendon.wrap_site(site_name(e.body_a, e.point_a))
        tendon.wrap_site(site_name(e.body_b, e.point_b))
        if e.kind == "damper":
            tendon.damping = [e.coefficient, 0.0, 0.0]
            dampers.append(e.name)
        else:
            tendon.stiffness = [e.coefficient, 0.0, 0.0]
            tendon.springlength = [e.rest_length, e.rest_length]

    dampers += _add_joint_elements(spec, scene)

    tree_joint = {e.joint: e for e in linkage.tree}
    if scene.load is not None:
        motor = spec.add_actuator(name=INPUT_MOTOR, target=linkage.input_joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        motor.set_to_motor()
        motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        # The load MuJoCo applied in each step, read at the step's start (the control holds
        # over the step).
        spec.add_sensor(name=sensor_name(INPUT_MOTOR, "force"), type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=INPUT_MOTOR)

    _add_actuators(spec, scene)

    # Read-outs (no forces): the input's acceleration (a hinge's: the child's angular
    # acceleration minus the parent's; a slide's is read from qacc by the runner), energy,
    # damper rates, point-force velocities.
    # (every input's, with several: each body once)
    read = []
    for name in linkage.inputs:
        if not isinstance(joints[name], PrismaticJoint):
            read += [body for body in (tree_joint[name].body, tree_joint[name].parent)
                     if body != GROUND and body not in read]
    for body in read:
        spec.add_sensor(name=sensor_name(body, "angacc"), type=mujoco.mjtSensor.mjSENS_FRAMEANGACC,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname=body)
    # Centre-of-mass position and velocity and angular velocity of every body, for the energy
    # audit (MuJoCo's e_kinetic sensor reads the energy of the previous evaluation).
    for name in linkage.moving:
        for kind, sensor in (("com_pos", mujoco.mjtSensor.mjSENS_FRAMEPOS),
                             ("com_vel", mujoco.mjtSensor.mjSENS_FRAMELINVEL),
                             ("ang_vel", mujoco.mjtSensor.mjSENS_FRAMEANGVEL)):
            spec.add_sensor(name=sensor_name(name, kind), type=sensor, objtype=mujoco.mjtObj.mjOBJ_BODY, objname=name)
    for e in mech.springs + mech.joint_springs:  # every spring is a tendon: its length for the energy audit
        spec.add_sensor(name=sensor_name(e.name, "length"), type=mujoco.mjtSensor.mjSENS_TENDONPOS,
                        objtype=mujoco.mjtObj.mjOBJ_TENDON, objname=e.name)
    for name in dampers + [e.name for e in mech.joint_inertias]:  # dissipation, and an inertia's ½ I u̇²
        spec.add_sensor(name=sensor_name(name, "rate"), type=mujoco.mjtSensor.mjSENS_TENDONVEL,
                        objtype=mujoco.mjtObj.mjOBJ_TENDON, objname=name)
    for pf in mech.point_forces + mech.timed_forces:
        spec.add_sensor(name=sensor_name(pf.name, "vel"), type=mujoco.mjtSensor.mjSENS_FRAMELINVEL,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name(pf.body, pf.point))

    # Point forces are applied by the runner (mjcb_control), not by the model: say so in the file.
    for pf in mech.point_forces:
        spec.add_text(name=f"point_force {pf.name}",
                      data=f"F(q) N along {pf.direction!r} rad (ground frame) at site {site_name(pf.body, pf.point)}, "
                           "tabulated over the input coordinate: not a model element; loopcheck applies it through "
                           "mjcb_control (loopcheck.reference_models.loads.point_force_callback)")
    for tf in mech.timed_forces:
        spec.add_text(name=f"timed_force {tf.name}",
                      data=f"F(t) N along {tf.direction!r} rad (ground frame) at site {site_name(tf.body, tf.point)}, "
                           f"a {type(tf.profile).__name__} over time: not a model element; loopcheck applies it through "
                           "mjcb_control, held over each step at its midpoint value "
                           "(loopcheck.reference_models.loads.timed_values)")

    add_scene_customs(spec, scene)
    # The scene's initial state (the control follows the timestep: set_timestep).
    qpos0, qvel0 = initial_qpos_qvel(scene)
    spec.add_key(name=HOME_KEY, time=0.0, qpos=list(qpos0), qvel=list(qvel0))
    set_timestep(spec, scene, timestep, constraint.solref)
    return spec


def load_table(load: LoadProfile | None) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """The load as a table of (time s, value) pairs, each value held from its time on, zero before
    the first (``import-mjcf``'s ``--ctrl`` form): ((0,), (0,)) without a load; None for a kind of
    load a table cannot give."""
    if load is None:
        return (0.0,), (0.0,)
    if isinstance(load, ConstantLoad):
        return (0.0,), (float(load.amplitude),)
    if isinstance(load, PulseLoad):
        if load.duration == 0.0:
            return (0.0,), (0.0,)
        return (float(load.start), float(load.start + load.duration)), (float(load.amplitude), 0.0)
    if isinstance(load, PiecewiseConstantLoad):
        return tuple(map(float, load.times)), tuple(map(float, load.values))
    return None


def add_scene_customs(spec: mujoco.MjSpec, scene: Scene) -> None:
    """What the scene holds outside the model, as ``<custom>`` numerics (``loopcheck import-mjcf``
    reads them back; they do not act on the model): the horizon, every tolerance given (the
    scene's ``[tolerances]`` and each engine's own table's keys) and the input's load table, when
    it has a load (the motor's gear is 1, so its control is the load). With several inputs, their joints
    in order as a ``<custom>`` text (an input no actuator drives, such as a spring-held joint, is then
    read back as the same input, not chosen again by partitioning). A point or timed force is said in a
    text (:func:`build_spec`): MJCF cannot carry it."""
    spec.add_numeric(name=CUSTOM_HORIZON, data=[float(scene.horizon)])
    if len(scene.inputs) > 1:
        spec.add_text(name=CUSTOM_INPUTS, data=",".join(scene.inputs))
    for f in dataclasses.fields(Tolerances):
        value = getattr(scene.tolerances, f.name)
        if value is not None:
            spec.add_numeric(name=f"{CUSTOM_TOLERANCES}{f.name}", data=[float(value)])
    for engine, given in scene.engine_tolerances.items():
        for key, value in given.items():
            spec.add_numeric(name=f"{CUSTOM_TOLERANCES}{engine}.{key}", data=[float(value)])
    for a in scene.mechanism.actuators:
        if a.control is None:
            continue
        table = load_table(a.control)
        if table is None:
            raise ValueError(f"actuator {a.name!r}: its control, a {type(a.control).__name__}, is not a table of "
                             "(time, value) pairs: MJCF cannot carry it")
        spec.add_numeric(name=f"{CUSTOM_ACTUATOR_CTRL}{a.name}", data=[v for pair in zip(*table) for v in pair])
    if scene.load is None:  # no motor either
        return
    table = load_table(scene.load)
    if table is None:
        raise ValueError(f"the load, a {type(scene.load).__name__}, is not a table of (time, value) pairs: MJCF "
                         "cannot carry it")
    spec.add_numeric(name=CUSTOM_CTRL, data=[v for pair in zip(*table) for v in pair])


def joint_tendons(scene: Scene) -> dict[str, tuple[np.ndarray, float]]:
    """For each joint of a joint element, (coef, u0): the joint's own coordinate
    (:attr:`loopcheck.kinematics.LoopSystem.joint_rows`: relative angle θ_b − θ_a in rad, or
    displacement in m) as u = u0 + coef·qpos, coef (nq,) over :func:`joint_order`. The bodies
    turn about z only, so a body's angle is its authored angle plus the hinge angles on its tree
    path (:func:`coordinate_map`) and u is linear in qpos also for a cut joint: the coefficients
    are 0 or ±1, and a fixed tendon is u − u0."""
    elements = scene.mechanism.joint_elements
    ranged = [j.name for j in scene.mechanism.linkage.joints if j.range is not None]
    if not elements and not ranged:
        return {}
    system = loops.compile_linkage(scene.mechanism.linkage)
    x0, T = coordinate_map(scene)
    rows = {name: system.joint_row(name) for name in [e.joint for e in elements] + ranged}
    return {joint: (row @ T, float(row @ x0)) for joint, row in rows.items()}


def coupling_polycoef(scene: Scene, coupling) -> tuple[str, str, list[float]]:
    """(joint1, joint2, polycoef) of MuJoCo's ``equality/joint`` for a joint coupling: with u =
    u0 + σ qpos on each of its two tree joints (:func:`joint_tendons`' map, σ = ±1, qpos0 = 0),
    u_y − y_ref = p(u_x − x_ref) is qpos_y = P(qpos_x) with P(s) = σ_y (p(d + σ_x s) − e),
    d = u0_x − x_ref, e = u0_y − y_ref: P's coefficients are σ_y σ_x^k p⁽ᵏ⁾(d)/k! (a Taylor
    expansion, exact for a quartic), less σ_y e in a0. ValueError where a joint of it is not a
    tree joint (it closes a loop: no MuJoCo joint to couple)."""
    linkage = scene.mechanism.linkage
    tree_joints = {e.joint for e in linkage.tree}
    for name in (coupling.joint, coupling.driver):
        if name not in tree_joints:
            raise ValueError(f"coupling {coupling.name!r} couples joint {name!r}, which closes a loop in the MuJoCo "
                             "model (a connect equality, no MuJoCo joint): MuJoCo's equality/joint needs two tree "
                             "joints")
    order = joint_order(linkage)
    system = loops.compile_linkage(linkage)
    x0, T = coordinate_map(scene)
    ends = []
    for name in (coupling.joint, coupling.driver):
        row = system.joint_row(name)
        coef = row @ T
        k = order.index(name)
        sign = float(coef[k])
        assert abs(sign) == 1.0 and np.count_nonzero(coef) == 1, "a tree joint's coordinate is ± its own qpos"
        ends.append((sign, float(row @ x0)))
    (sy, u0y), (sx, u0x) = ends
    d, e = u0x - coupling.x_ref, u0y - coupling.y_ref
    a = coupling.coefficients
    out = []
    for k in range(len(a)):  # p⁽ᵏ⁾(d)/k! = Σ_{j≥k} C(j, k) a_j d^(j−k)
        taylor = sum(math.comb(j, k) * a[j] * d ** (j - k) for j in range(k, len(a)))
        out.append(sy * sx ** k * taylor)
    out[0] -= sy * e
    return coupling.joint, coupling.driver, out


def _add_joint_elements(spec: mujoco.MjSpec, scene: Scene) -> list[str]:
    """One fixed tendon per joint damper, spring or inertia (named after it) on the joint's
    coordinate (:func:`joint_tendons`): a damper's with ``damping`` c, a spring's with
    ``stiffness`` k and ``springlength`` u_rest − u0 (so ½ k (L − l0)² = ½ k (u − u_rest)²), an
    inertia's with ``armature`` I (MuJoCo adds I JᵀJ to the mass matrix: ½ I u̇²). A tendon, not
    the joint's own stiffness, damping and armature: it serves a cut joint too (closed by a
    connect equality, no MuJoCo joint), and two elements on one joint stay two. Where u_rest − u0 < 0 the tendon
    is written with the opposite sign (same force and energy), since MuJoCo reads a
    springlength of −1 as "the length at qpos0". A joint friction's tendon has ``frictionloss`` f
    (MuJoCo's dry friction on the tendon's length, u − u0: f on u). A joint's range is a tendon
    named ``<joint>_range`` with ``range`` [lo − u0, hi − u0] (limited), a cut joint's as a tree
    joint's. Returns the dampers' names."""
    order = joint_order(scene.mechanism.linkage)
    tendons = joint_tendons(scene)
    dampers = []
    for e in scene.mechanism.joint_elements:
        coef, u0 = tendons[e.joint]
        length = e.rest - u0 if e.kind == "spring" else 0.0
        sign = -1.0 if length < 0.0 else 1.0
        tendon = spec.add_tendon(name=e.name)
        for k in np.flatnonzero(coef):
            tendon.wrap_joint(order[k], sign * float(coef[k]))
        if e.kind == "damper":
            tendon.damping = [e.coefficient, 0.0, 0.0]
            dampers.append(e.name)
        elif e.kind == "inertia":
            tendon.armature = e.coefficient
        elif e.kind == "friction":
            tendon.frictionloss = e.coefficient
        else:
            tendon.stiffness = [e.coefficient, 0.0, 0.0]
            tendon.springlength = [sign * length, sign * length]
    for joint in scene.mechanism.linkage.joints:
        if joint.range is None:
            continue
        coef, u0 = tendons[joint.name]
        tendon = spec.add_tendon(name=range_tendon(joint.name))
        for k in np.flatnonzero(coef):
            tendon.wrap_joint(order[k], float(coef[k]))
        tendon.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        tendon.range = [joint.range[0] - u0, joint.range[1] - u0]
    return dampers


def actuator_tendons(scene: Scene) -> dict[str, tuple[np.ndarray, float]]:
    """For each actuator, (coef, l0): its transmission's length l = Σ c_j u_j as l = l0 + coef·qpos,
    coef (nq,) over :func:`joint_order` (as :func:`joint_tendons` gives a joint's coordinate)."""
    acts = scene.mechanism.actuators
    if not acts:
        return {}
    system = loops.compile_linkage(scene.mechanism.linkage)
    x0, T = coordinate_map(scene)
    out = {}
    for a in acts:
        row = sum(c * system.joint_row(j) for j, c in a.terms)
        out[a.name] = (row @ T, float(row @ x0))
    return out


def transmission_tendon(actuator: str) -> str:
    """The name of the fixed tendon an actuator acts on when its transmission is not a tree joint's
    qpos: ``"<actuator>:transmission"`` (no scene name holds ':')."""
    return f"{actuator}:transmission"


def _add_actuators(spec: mujoco.MjSpec, scene: Scene) -> None:
    """One ``general`` actuator per scene actuator (named after it), after the input motor: on its
    joint (a joint transmission) where that joint's coordinate is a tree joint's qpos, else on a fixed
    tendon l − l0 = coef·qpos (:func:`actuator_tendons`, named :func:`transmission_tendon`); gain
    fixed (gainprm[0] = gain), bias affine where nonzero, with b0 + b1·gear·l0 for b0 (MuJoCo's
    length counts from the assembled pose, the scene's from the joints' zero), gear, ctrlrange and
    forcerange with ctrllimited/forcelimited. Sensors of each actuator's length and velocity (the
    energy audit)."""
    acts = scene.mechanism.actuators
    if not acts:
        return
    if scene.load is not None and INPUT_MOTOR in {a.name for a in acts}:
        raise ValueError(f"actuator name {INPUT_MOTOR!r} is the input load's motor in the MuJoCo model: rename the actuator")
    order = joint_order(scene.mechanism.linkage)
    tendons = actuator_tendons(scene)
    for a in acts:
        coef, l0 = tendons[a.name]
        on_joint = (a.joint is not None and a.joint in order
                    and np.array_equal(coef, np.eye(len(order))[order.index(a.joint)]))
        if on_joint:
            act = spec.add_actuator(name=a.name, target=a.joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        else:
            tendon = spec.add_tendon(name=transmission_tendon(a.name))
            for k in np.flatnonzero(coef):
                tendon.wrap_joint(order[k], float(coef[k]))
            act = spec.add_actuator(name=a.name, target=transmission_tendon(a.name), trntype=mujoco.mjtTrn.mjTRN_TENDON)
        act.dyntype = mujoco.mjtDyn.mjDYN_NONE
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        gain = [0.0] * len(act.gainprm)
        gain[0] = a.gain
        act.gainprm = gain
        b0, b1, b2 = a.bias
        bias = [0.0] * len(act.biasprm)
        if a.state_dependent or b0 != 0.0:
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            bias[0:3] = [b0 + b1 * a.gear * l0, b1, b2]
        else:
            act.biastype = mujoco.mjtBias.mjBIAS_NONE
        act.biasprm = bias
        gear = [0.0] * 6
        gear[0] = a.gear
        act.gear = gear
        for attr, rng in (("ctrl", a.ctrlrange), ("force", a.forcerange)):
            setattr(act, f"{attr}limited", mujoco.mjtLimited.mjLIMITED_TRUE if rng is not None
                    else mujoco.mjtLimited.mjLIMITED_FALSE)
            if rng is not None:
                setattr(act, f"{attr}range", list(rng))
        for kind, sensor in (("length", mujoco.mjtSensor.mjSENS_ACTUATORPOS),
                             ("velocity", mujoco.mjtSensor.mjSENS_ACTUATORVEL)):
            spec.add_sensor(name=sensor_name(a.name, kind), type=sensor, objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
                            objname=a.name)


def actuator_controls(scene: Scene, times: np.ndarray) -> np.ndarray:
    """Every control at each time (len(times), nu): the input motor's load (when the scene has
    one), then each actuator's control (unclamped: MuJoCo clamps it to ctrlrange)."""
    columns = [scene.load.sample(times)] if scene.load is not None else []
    columns += [a.control.sample(times) if a.control is not None else np.zeros(len(times))
                for a in scene.mechanism.actuators]
    return np.column_stack(columns) if columns else np.zeros((len(times), 0))


def range_tendon(joint: str) -> str:
    """The name of the fixed tendon that holds joint ``joint``'s range in the MuJoCo model."""
    return f"{joint}_range"


def set_timestep(spec: mujoco.MjSpec, scene: Scene, timestep: float, solref: tuple[float, float]) -> None:
    """Set what follows the timestep in a spec made by :func:`build_spec` of ``scene``: the
    option's timestep, every loop's solref and the home key's control (the load the run applies
    in its first step, sampled at the step's midpoint as ``run.control_sequence`` does).

    A spec built at one step and set to another compiles to the model built at the other.
    """
    spec.option.timestep = timestep
    for name in scene.mechanism.linkage.cut_joints + tuple(c.name for c in scene.mechanism.linkage.couplings):
        spec.equality(name).solref = list(solref)
    spec.key(HOME_KEY).ctrl = [float(v) for v in actuator_controls(scene, np.array([0.5 * timestep]))[0]]


def _number(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def mjcf_from_spec(spec: mujoco.MjSpec) -> str:
    """``spec.to_xml()`` with every number this builder sets written to full precision.

    MuJoCo 4.0.1's writer prints 6 significant digits, which would put the bodies of the
    assembled pose ~1e-6 m off and open the loops by that much when the file is loaded.
    Each number is rewritten as the shortest text that reads back to the same double
    (``repr``, without a trailing ".0"); attributes the writer left out (at their defaults)
    stay out. Covers the option, bodies (pos, quat, inertial), joints (pos, axis, range, ref,
    springref, armature, frictionloss, damping, stiffness), sites, tendons (their coefficients,
    damping, stiffness, springlength, armature, frictionloss, range), actuators, connects, joint
    couplings, keyframes and custom numerics.
    """
    root = ET.fromstring(spec.to_xml())

    def put(element, attribute, values):
        if element is not None and attribute in element.attrib:
            element.set(attribute, " ".join(_number(v) for v in np.atleast_1d(values)))

    option = root.find("option")
    for attribute, value in (("timestep", spec.option.timestep), ("tolerance", spec.option.tolerance),
                             ("gravity", spec.option.gravity)):
        put(option, attribute, value)
    for element in root.iter("body"):
        body = spec.body(element.get("name"))
        put(element, "pos", body.pos)
        put(element, "quat", body.quat)
        put(element, "gravcomp", body.gravcomp)
        inertial = element.find("inertial")
        put(inertial, "pos", body.ipos)
        put(inertial, "mass", body.mass)
        put(inertial, "diaginertia", body.inertia)
    for element in root.iter("joint"):
        if element.get("joint1") is not None:  # a coupling (equality/joint)
            equality = spec.equality(element.get("name"))
            put(element, "polycoef", equality.data[0:5])
            put(element, "solref", equality.solref)
            put(element, "solimp", equality.solimp)
        elif element.get("name") is not None:
            joint = spec.joint(element.get("name"))
            for attribute in ("pos", "axis", "range", "ref", "springref", "armature", "frictionloss"):
                put(element, attribute, getattr(joint, attribute))
            put(element, "damping", joint.damping[0])
            put(element, "stiffness", joint.stiffness[0])
    for element in root.iter("site"):
        if element.get("name") is not None:
            put(element, "pos", spec.site(element.get("name")).pos)
    for element in [*root.iter("spatial"), *root.iter("fixed")]:
        tendon = spec.tendon(element.get("name"))
        put(element, "damping", tendon.damping[0])
        put(element, "stiffness", tendon.stiffness[0])
        put(element, "springlength", tendon.springlength[0])
        for attribute in ("armature", "frictionloss", "range"):
            put(element, attribute, getattr(tendon, attribute))
        if element.tag == "fixed":  # its joints' coefficients, in the order written
            for child, wrap in zip(element.findall("joint"), tendon.path):
                put(child, "coef", wrap.coef)
    for element in root.iter("general"):
        act = spec.actuator(element.get("name"))
        put(element, "gainprm", act.gainprm[0:1])
        put(element, "biasprm", act.biasprm[0:3])
        put(element, "gear", act.gear[0:1])
        put(element, "ctrlrange", act.ctrlrange)
        put(element, "forcerange", act.forcerange)
    for element in root.iter("connect"):
        equality = spec.equality(element.get("name"))
        put(element, "anchor", equality.data[0:3])
        put(element, "solref", equality.solref)
        put(element, "solimp", equality.solimp)
    for element in root.iter("numeric"):
        put(element, "data", spec.numeric(element.get("name")).data)
    for element in root.iter("key"):
        key = spec.key(element.get("name"))
        for attribute in ("qpos", "qvel", "ctrl"):
            put(element, attribute, getattr(key, attribute))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def compile_model(spec: mujoco.MjSpec) -> ModelHandles:
    """Compile the spec and index its sensors."""
    model = compile_spec(spec)
    slices = {}
    for i in range(model.nsensor):
        adr, dim = model.sensor_adr[i], model.sensor_dim[i]
        slices[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i)] = slice(adr, adr + dim)
    dampers = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(model.ntendon)
                    if model.tendon_damping[i] > 0)
    return ModelHandles(model=model, spec=spec, sensor_slices=slices, damper_tendons=dampers)


def check_joint_order(scene: Scene, model: mujoco.MjModel) -> None:
    """ValueError unless the model's joints are the scene's tree joints in :func:`joint_order`
    (one qpos and one qvel each), which :func:`coordinate_map` assumes."""
    names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt))
    wanted = joint_order(scene.mechanism.linkage)
    if names != wanted or model.nq != len(wanted) or model.nv != len(wanted):
        raise ValueError(f"the model's joints {names} are not the scene's tree joints {wanted} in order")


__all__ = ["BASE_BODY", "CUSTOM_CTRL", "CUSTOM_HORIZON", "CUSTOM_INPUTS", "CUSTOM_PREFIX", "CUSTOM_TOLERANCES", "ConstraintSettings",
           "HOME_KEY", "INPUT_MOTOR", "actuator_controls", "actuator_tendons", "transmission_tendon", "ModelHandles", "TreeBody", "add_scene_customs", "assembled_angles",
           "build_spec", "check_joint_order", "compile_model", "coupling_polycoef", "coordinate_map", "initial_qpos_qvel", "initial_rates",
           "joint_order", "joint_positions", "joint_rates", "joint_rates_matrix", "joint_tendons", "load_table",
           "loop_angles", "loop_rates", "mjcf_from_spec", "set_timestep", "site_name", "spanning_tree"]
