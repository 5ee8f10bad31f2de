"""Build the MuJoCo model of a scene with ``mujoco.MjSpec``.

The four-bar is an open chain closed by an equality constraint: crank and coupler hang
from O1, the rocker from O3, all hinges about z, and an ``<equality><connect>`` joins a
site at B on the coupler to a site at B on the rocker. Only the effects the scene
declares are built: a damper is a spatial tendon with ``damping``, a spring a tendon
with ``stiffness`` and ``springlength``, the torque a motor on the crank hinge, gravity
the scene's vector (else zero). There are no geoms, contacts are disabled, and no joint
has damping, armature, stiffness or friction loss.

Mass properties. A link given by its inertia about a fixed pivot becomes a body whose
centre of mass is the pivot (a 1 kg point there: it neither moves nor adds kinetic
energy) with I_zz equal to the pivot inertia. A link given by mass, centroidal inertia
and centre of mass maps onto MuJoCo's ``mass``, ``ipos`` and I_zz. The out-of-plane
moments I_xx = I_yy are set equal to I_zz: every hinge turns about z, so they never
enter the joint-space mass matrix, and the choice satisfies MuJoCo's triangle
inequality on principal moments.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from reduced.scene import BODY_NAMES, BodyInertia, Scene

# Joint order in qpos/qvel: crank angle q, coupler relative angle φ1 − q, rocker angle φ2 + π.
JOINTS = ("crank_hinge", "coupler_hinge", "rocker_hinge")
PIVOT_POINT_MASS = 1.0  # kg, at a fixed pivot: no kinetic or potential energy
LOOP_EQUALITY = "loop_closure_B"  # name of the connect equality that closes the loop


@dataclass(frozen=True)
class ConstraintSettings:
    """Softness of the loop-closure equality constraint (MuJoCo ``solref``/``solimp``)."""

    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]


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
    opt.integrator = {"euler": mujoco.mjtIntegrator.mjINT_EULER,
                      "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                      "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                      "rk4": mujoco.mjtIntegrator.mjINT_RK4}[integrator]
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
    crank = spec.worldbody.add_body(name="crank", pos=[0.0, 0.0, 0.0])
    crank.add_joint(name=JOINTS[0], type=mujoco.mjtJoint.mjJNT_HINGE, axis=z)
    _set_inertial(crank, scene.bodies["crank"], pivoted=True)
    crank.add_site(name="A_crank", pos=[g.c1, 0.0, 0.0])

    coupler = crank.add_body(name="coupler", pos=[g.c1, 0.0, 0.0])
    coupler.add_joint(name=JOINTS[1], type=mujoco.mjtJoint.mjJNT_HINGE, axis=z)
    _set_inertial(coupler, scene.bodies["coupler"], pivoted=False)
    coupler.add_site(name="B_coupler", pos=[g.c2, 0.0, 0.0])

    rocker = spec.worldbody.add_body(name="rocker", pos=[g.c4, 0.0, 0.0])
    rocker.add_joint(name=JOINTS[2], type=mujoco.mjtJoint.mjJNT_HINGE, axis=z)
    _set_inertial(rocker, scene.bodies["rocker"], pivoted=True)
    rocker.add_site(name="B_rocker", pos=[g.c3, 0.0, 0.0])
    bodies = {"crank": crank, "coupler": coupler, "rocker": rocker}

    loop = spec.add_equality(name=LOOP_EQUALITY, type=mujoco.mjtEq.mjEQ_CONNECT,
                             objtype=mujoco.mjtObj.mjOBJ_SITE, name1="B_coupler", name2="B_rocker")
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
    return spec


def _line_tendon(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str,
                 ground_point: tuple[float, float], body_point: tuple[float, float]):
    spec.worldbody.add_site(name=f"{name}_ground", pos=[*ground_point, 0.0])
    body.add_site(name=f"{name}_body", pos=[*body_point, 0.0])
    tendon = spec.add_tendon(name=name)
    tendon.wrap_site(f"{name}_ground")
    tendon.wrap_site(f"{name}_body")
    return tendon


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


def initial_qpos_qvel(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and velocities consistent with the loop at the scene's (q0, q̇0).

    The joint rates are K ẋ_i in the best-conditioned coordinate x_i, so a start at the
    input link's dead centre (where q̇0 must be 0) is assembled too.
    """
    from reduced.linkage import FourBar

    linkage = FourBar(scene.linkage)
    x = linkage.assemble(scene.q0)
    kin = linkage.coefficients_at(x, int(np.argmax(linkage.conditioning(x))))
    rate = scene.qdot0 / kin.K[0] if scene.qdot0 != 0.0 else 0.0
    xdot = kin.K * rate
    return joint_positions(x), np.array([xdot[0], xdot[1] - xdot[0], xdot[2]])


def joint_positions(x: np.ndarray) -> np.ndarray:
    """MuJoCo qpos (crank, coupler relative, rocker) from the loop angles (q, φ1, φ2)."""
    return np.array([x[0], x[1] - x[0], x[2] + np.pi])


def loop_angles(qpos: np.ndarray) -> np.ndarray:
    """Loop angles (q, φ1, φ2), shape (n, 3), from MuJoCo qpos rows, shape (n, 3)."""
    qpos = np.atleast_2d(qpos)
    return np.column_stack([qpos[:, 0], qpos[:, 0] + qpos[:, 1], qpos[:, 2] - np.pi])


__all__ = ["BODY_NAMES", "ConstraintSettings", "JOINTS", "LOOP_EQUALITY", "ModelHandles", "build_spec",
           "compile_model", "initial_qpos_qvel"]
