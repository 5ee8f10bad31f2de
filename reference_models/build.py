"""Build the MuJoCo model of a scene with ``mujoco.MjSpec``.

The four-bar is a tree of bodies closed by an equality constraint: crank and coupler hang
from O1, the rocker from O3, all hinges about z, and an ``<equality><connect>`` joins the
coupler and the rocker at B (``body1``/``body2``/``anchor``, as published closed-loop models
do). Every chain hangs from one fixed body ``base`` under ``<worldbody>`` (readers such as
Pinocchio's keep only the first body tree there), which also holds the ground points.

Pose. The model is authored in the scene's assembled configuration (the four-bar's closed
form at q0 on the scene's branch): each body's ``pos``/``quat`` (a rotation about z) put the
links where the assembly puts them, every hinge has ``ref`` 0, so ``qpos = 0`` is the
assembled pose and qpos counts the joint angles from it. MuJoCo's default state, the
``home`` keyframe (with the scene's q̇0 as joint rates) and any reader that starts from the
zero configuration therefore see the loop closed, and the connect's anchor on the rocker,
which MuJoCo computes at ``qpos0``, is B. :func:`joint_positions` and :func:`loop_angles`
convert between qpos and the loop angles (q, φ1, φ2).

Only the effects the scene declares are built: a damper is a spatial tendon with
``damping``, a spring a tendon with ``stiffness`` and ``springlength``, the torque a motor on
the crank hinge, gravity the scene's vector (else zero). There are no geoms, contacts are
disabled, and no joint has damping, armature, stiffness or friction loss.

Mass properties. A link given by its inertia about a fixed pivot becomes a body whose
centre of mass is the pivot (a 1 kg point there: it neither moves nor adds kinetic
energy) with I_zz equal to the pivot inertia. A link given by mass, centroidal inertia
and centre of mass maps onto MuJoCo's ``mass``, ``ipos`` and I_zz. The out-of-plane
moments I_xx = I_yy are set equal to I_zz: every hinge turns about z, so they never
enter the joint-space mass matrix, and the choice satisfies MuJoCo's triangle
inequality on principal moments.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco
import numpy as np

from reduced.scene import BODY_NAMES, MUJOCO_INTEGRATORS, BodyInertia, Scene

# Joint order in qpos/qvel: crank angle q, coupler relative angle φ1 − q, rocker angle φ2 + π,
# each counted from its value in the assembled pose at q0 (qpos = 0 is that pose).
JOINTS = ("crank_hinge", "coupler_hinge", "rocker_hinge")
# MuJoCo's enum for each integrator name (the names are listed once, in reduced.scene).
INTEGRATOR_ENUM = {name: getattr(mujoco.mjtIntegrator, f"mjINT_{name.upper()}") for name in MUJOCO_INTEGRATORS}
BASE_BODY = "base"  # the fixed body every chain hangs from
HOME_KEY = "home"  # keyframe with the scene's initial state
PIVOT_POINT_MASS = 1.0  # kg, at a fixed pivot: no kinetic or potential energy
LOOP_EQUALITY = "loop_closure_B"  # name of the connect equality that closes the loop


@dataclass(frozen=True)
class ConstraintSettings:
    """Softness of the loop-closure equality constraint (MuJoCo ``solref``/``solimp``)."""

    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]


@dataclass(frozen=True)
class TreeBody:
    """One moving body of the spanning tree, placed in its parent's frame at the assembled pose.

    Parameters
    ----------
    name : body name (a key of ``scene.bodies``).
    parent : parent body name (``BASE_BODY`` or another tree body).
    joint : name of the hinge (about z) that joins it to its parent.
    pos : (x, y) of the hinge in the parent's frame, m.
    angle : rotation about z of the body's frame relative to its parent's at the assembled
        pose, rad (the body's ``quat``; the hinge's qpos counts from it).
    """

    name: str
    parent: str
    joint: str
    pos: tuple[float, float]
    angle: float

    def __post_init__(self) -> None:
        if not all(np.isfinite([*self.pos, self.angle])):
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


def _set_inertial(body: mujoco.MjsBody, inertia: BodyInertia, pivoted: bool) -> None:
    body.explicitinertial = True
    if inertia.has_mass_distribution:
        body.mass = inertia.mass
        body.ipos = [inertia.com[0], inertia.com[1], 0.0]
        izz = inertia.centroidal_inertia
    elif pivoted:
        body.mass = PIVOT_POINT_MASS
        body.ipos = [0.0, 0.0, 0.0]
        izz = inertia.pivot_inertia
    else:  # the scene validator guarantees a free link has mass, com and inertia
        raise ValueError("a link without a fixed pivot needs mass, com and inertia")
    body.inertia = [izz, izz, izz]


def build_spec(scene: Scene, *, constraint: ConstraintSettings, integrator: str = "rk4",
               timestep: float = 1e-3, iterations: int = 100, tolerance: float = 1e-10,
               refsafe: bool = True, diagexact: bool = False) -> mujoco.MjSpec:
    """An ``MjSpec`` of the scene's four-bar with the given solver options."""
    g = scene.linkage
    spec = mujoco.MjSpec()
    spec.modelname = scene.name
    opt = spec.option
    opt.timestep = timestep
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
    bodies = {BASE_BODY: base}
    pivoted = {"crank": True, "coupler": False, "rocker": True}
    for link in spanning_tree(scene):
        body = bodies[link.parent].add_body(name=link.name, pos=[*link.pos, 0.0], quat=link.quat)
        body.add_joint(name=link.joint, type=mujoco.mjtJoint.mjJNT_HINGE, axis=z)
        _set_inertial(body, scene.bodies[link.name], pivoted=pivoted[link.name])
        bodies[link.name] = body
    bodies["crank"].add_site(name="A_crank", pos=[g.c1, 0.0, 0.0])
    # B on each side of the cut joint: read-outs of the loop closure (sensors below).
    bodies["coupler"].add_site(name="B_coupler", pos=[g.c2, 0.0, 0.0])
    bodies["rocker"].add_site(name="B_rocker", pos=[g.c3, 0.0, 0.0])

    # The cut joint B: anchor in the coupler's frame; MuJoCo finds the rocker's anchor at
    # qpos0, the assembled pose, where it is B.
    loop = spec.add_equality(name=LOOP_EQUALITY, type=mujoco.mjtEq.mjEQ_CONNECT,
                             objtype=mujoco.mjtObj.mjOBJ_BODY, name1="coupler", name2="rocker")
    loop.data[0:3] = [g.c2, 0.0, 0.0]
    loop.solref = list(constraint.solref)
    loop.solimp = list(constraint.solimp)

    dampers = []
    for i, d in enumerate(scene.dampers):
        name = f"damper{i}"
        _line_tendon(spec, bodies[d.body], name, d.ground_point, d.body_point).damping = [d.coefficient, 0.0, 0.0]
        dampers.append(name)
    for i, s in enumerate(scene.springs):
        tendon = _line_tendon(spec, bodies[s.body], f"spring{i}", s.ground_point, s.body_point)
        tendon.stiffness = [s.stiffness, 0.0, 0.0]
        tendon.springlength = [s.rest_length, s.rest_length]

    if scene.torque is not None:
        motor = spec.add_actuator(name="crank_motor", target=JOINTS[0],
                                  trntype=mujoco.mjtTrn.mjTRN_JOINT)
        motor.set_to_motor()
        motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        # The torque MuJoCo applied in each step, read at the step's start (the control holds
        # over the step).
        spec.add_sensor(name="crank_motor_force", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname="crank_motor")

    # Read-outs (no forces): constraint violation, crank acceleration, energy, damper rates.
    spec.add_sensor(name="B_coupler_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname="B_coupler")
    spec.add_sensor(name="B_rocker_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname="B_rocker")
    spec.add_sensor(name="crank_angacc", type=mujoco.mjtSensor.mjSENS_FRAMEANGACC,
                    objtype=mujoco.mjtObj.mjOBJ_BODY, objname="crank")
    # Centre-of-mass position and velocity and angular velocity of every link, for the energy
    # audit (MuJoCo's e_kinetic sensor reads the energy of the previous evaluation).
    for name in BODY_NAMES:
        for kind, sensor in (("com_pos", mujoco.mjtSensor.mjSENS_FRAMEPOS),
                             ("com_vel", mujoco.mjtSensor.mjSENS_FRAMELINVEL),
                             ("ang_vel", mujoco.mjtSensor.mjSENS_FRAMEANGVEL)):
            spec.add_sensor(name=f"{name}_{kind}", type=sensor, objtype=mujoco.mjtObj.mjOBJ_BODY, objname=name)
    for i in range(len(scene.springs)):
        spec.add_sensor(name=f"spring{i}_length", type=mujoco.mjtSensor.mjSENS_TENDONPOS,
                        objtype=mujoco.mjtObj.mjOBJ_TENDON, objname=f"spring{i}")
    for name in dampers:
        spec.add_sensor(name=f"{name}_rate", type=mujoco.mjtSensor.mjSENS_TENDONVEL,
                        objtype=mujoco.mjtObj.mjOBJ_TENDON, objname=name)

    # The scene's initial state; the control is the torque the run applies in its first step
    # (sampled at the step's midpoint, as ``run.control_sequence`` does).
    qpos0, qvel0 = initial_qpos_qvel(scene)
    ctrl0 = [] if scene.torque is None else [float(scene.torque.sample(np.array([0.5 * timestep]))[0])]
    spec.add_key(name=HOME_KEY, time=0.0, qpos=list(qpos0), qvel=list(qvel0), ctrl=ctrl0)
    return spec


def _line_tendon(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str,
                 ground_point: tuple[float, float], body_point: tuple[float, float]):
    spec.body(BASE_BODY).add_site(name=f"{name}_ground", pos=[*ground_point, 0.0])
    body.add_site(name=f"{name}_body", pos=[*body_point, 0.0])
    tendon = spec.add_tendon(name=name)
    tendon.wrap_site(f"{name}_ground")
    tendon.wrap_site(f"{name}_body")
    return tendon


def _number(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def mjcf_from_spec(spec: mujoco.MjSpec) -> str:
    """``spec.to_xml()`` with every number this builder sets written to full precision.

    MuJoCo 4.0.1's writer prints 6 significant digits, which would put the bodies of the
    assembled pose ~1e-6 m off and open the loop by that much when the file is loaded.
    Each number is rewritten as the shortest text that reads back to the same double
    (``repr``, without a trailing ".0"); attributes the writer left out (at their defaults) stay out.
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
        inertial = element.find("inertial")
        put(inertial, "pos", body.ipos)
        put(inertial, "mass", body.mass)
        put(inertial, "diaginertia", body.inertia)
    for element in root.iter("site"):
        if element.get("name") is not None:
            put(element, "pos", spec.site(element.get("name")).pos)
    for element in root.iter("spatial"):
        tendon = spec.tendon(element.get("name"))
        put(element, "damping", tendon.damping[0])
        put(element, "stiffness", tendon.stiffness[0])
        put(element, "springlength", tendon.springlength[0])
    for element in root.iter("connect"):
        equality = spec.equality(element.get("name"))
        put(element, "anchor", equality.data[0:3])
        put(element, "solref", equality.solref)
        put(element, "solimp", equality.solimp)
    for element in root.iter("key"):
        key = spec.key(element.get("name"))
        for attribute in ("qpos", "qvel", "ctrl"):
            put(element, attribute, getattr(key, attribute))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def compile_model(spec: mujoco.MjSpec) -> ModelHandles:
    """Compile the spec and index its sensors."""
    model = spec.compile()
    slices = {}
    for i in range(model.nsensor):
        adr, dim = model.sensor_adr[i], model.sensor_dim[i]
        slices[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i)] = slice(adr, adr + dim)
    dampers = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(model.ntendon)
                    if model.tendon_damping[i] > 0)
    return ModelHandles(model=model, spec=spec, sensor_slices=slices, damper_tendons=dampers)


def assembled_angles(scene: Scene) -> np.ndarray:
    """Loop angles (q, φ1, φ2) of the scene's assembly at q0 (rad): the model's authored pose."""
    from reduced.linkage import FourBar

    return FourBar(scene.linkage).assemble(scene.q0)


def spanning_tree(scene: Scene) -> tuple[TreeBody, ...]:
    """The moving bodies, parents first, placed at the assembled pose.

    Body frames: crank at O1 turned by q, coupler at A turned by φ1, rocker at O3 turned by
    φ2 + π (its x axis from O3 towards B), so the hinges' qpos at the pose are all zero.
    """
    g = scene.linkage
    angles = _hinge_angles(assembled_angles(scene))
    return (TreeBody("crank", BASE_BODY, JOINTS[0], (0.0, 0.0), angles[0]),
            TreeBody("coupler", "crank", JOINTS[1], (g.c1, 0.0), angles[1]),
            TreeBody("rocker", BASE_BODY, JOINTS[2], (g.c4, 0.0), angles[2]))


def initial_qpos_qvel(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and velocities consistent with the loop at the scene's (q0, q̇0).

    The positions are zero (the model is authored at the assembled pose). The joint rates
    are K ẋ_i in the best-conditioned coordinate x_i, so a start at the input link's dead
    centre (where q̇0 must be 0) is assembled too.
    """
    from reduced.linkage import FourBar

    linkage = FourBar(scene.linkage)
    x = assembled_angles(scene)
    kin = linkage.coefficients_at(x, int(np.argmax(linkage.conditioning(x))))
    rate = scene.qdot0 / kin.K[0] if scene.qdot0 != 0.0 else 0.0
    xdot = kin.K * rate
    return joint_positions(x, x), joint_rates(xdot)


def _hinge_angles(x: np.ndarray) -> np.ndarray:
    """Each hinge's angle from its parent's frame (crank q, coupler φ1 − q, rocker φ2 + π), shape (..., 3)."""
    x = np.asarray(x, dtype=float)
    return np.stack([x[..., 0], x[..., 1] - x[..., 0], x[..., 2] + np.pi], axis=-1)


def joint_positions(x: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """MuJoCo qpos (crank, coupler relative, rocker; rad) at loop angles ``x`` = (q, φ1, φ2)
    of a model authored at the loop angles ``pose`` (:func:`assembled_angles`)."""
    return _hinge_angles(x) - _hinge_angles(pose)


def joint_rates(xdot: np.ndarray) -> np.ndarray:
    """MuJoCo qvel (rad/s) from the loop rates (q̇, φ̇1, φ̇2)."""
    xdot = np.asarray(xdot, dtype=float)
    return np.stack([xdot[..., 0], xdot[..., 1] - xdot[..., 0], xdot[..., 2]], axis=-1)


def loop_angles(qpos: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Loop angles (q, φ1, φ2), shape (n, 3), from MuJoCo qpos rows, shape (n, 3), of a model
    authored at the loop angles ``pose``."""
    hinge = np.atleast_2d(qpos) + _hinge_angles(pose)
    return np.column_stack([hinge[:, 0], hinge[:, 0] + hinge[:, 1], hinge[:, 2] - np.pi])


def loop_rates(qvel: np.ndarray) -> np.ndarray:
    """Loop rates (q̇, φ̇1, φ̇2), shape (n, 3), from MuJoCo qvel rows, shape (n, 3)."""
    qvel = np.atleast_2d(qvel)
    return np.column_stack([qvel[:, 0], qvel[:, 0] + qvel[:, 1], qvel[:, 2]])


__all__ = ["BASE_BODY", "BODY_NAMES", "ConstraintSettings", "HOME_KEY", "JOINTS", "LOOP_EQUALITY", "ModelHandles",
           "TreeBody", "assembled_angles", "build_spec", "compile_model", "initial_qpos_qvel", "joint_positions",
           "joint_rates", "loop_angles", "loop_rates", "mjcf_from_spec", "spanning_tree"]
