"""What a MuJoCo-family run's stored states say, by MuJoCo C's own functions: the initial
state's loop residuals (:func:`check_initial_state`), the sensors at a state (:func:`sensors_at`),
the loop gap, q̈ of the input, the trajectory with a sample on each side of a load edge, the
general coordinates, and the energy audit (:func:`record_run`, over :mod:`.energy`).

MuJoCo C steps in its own rollout and reads its sensors as it goes; MJX and MJWarp hand over
their states alone, and the sensors are computed here at each state (``sensors=None``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from loopcheck import kinematics as loops
from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.results import ConstraintViolation, EnergyAudit
from loopcheck.scene import Scene
from loopcheck.trajectory import JointTrajectory, Trajectory

from .build import INPUT_MOTOR, ModelHandles, sensor_name
from .energy import energy_audit, squares_by_row
from .layout import InputJoint, Layout

# Initial state: MuJoCo's loop residuals after mj_forward at the assembled (qpos, qvel), relative
# to the mechanism's size (m) and to its point-speed scale (m/s) (check_initial_state). The
# assembly leaves ~1e-16 relative (measured on the seed, two slider-cranks and a Watt II six-bar:
# ≤ 2.2e-16 m and ≤ 4.4e-16 m/s, sizes 0.4–2 m), so 1e-12 is round-off with 1000x margin.
INITIAL_RESIDUAL_REL = 1e-12
STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS  # the states' layout: time, qpos, qvel, act, ...


def samples_refine_extrema(model: mujoco.MjModel) -> bool:
    """Whether a run of ``model`` gives samples that support an extremum located between them
    (:class:`loopcheck.trajectory.Trajectory`'s ``refined_extrema``): RK4's, fourth order, do; Euler's,
    implicit's and implicitfast's, first order, do not (their peak is the extreme sample)."""
    return int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4)


@dataclass(frozen=True)
class RunRecord:
    """A run's stored states read by MuJoCo C.

    times : s, the states' times; q, qdot : the input coordinate and its rate there (rad or m);
    x, xdot : the scene's general coordinates and rates; trajectory : q, q̇, q̈ with a sample on
    each side of every load edge; joints : the general coordinates with their assembly modes;
    constraint_violation : the largest loop gap at each state (m); audit : the energy balance;
    input_load : N·m or N, the input motor's force at each state (zero without one); notes : a
    line per joint or tendon limit that acted, and when it first did; other_inputs : with several
    inputs, each input after the first: its q and q̇ at the states and its trajectory (as q, qdot
    and trajectory are the first's).
    """

    times: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    trajectory: Trajectory
    joints: JointTrajectory
    constraint_violation: ConstraintViolation
    audit: EnergyAudit
    input_load: np.ndarray
    notes: tuple[str, ...] = ()  # each MuJoCo limit that acted (constraint_flows)
    other_inputs: tuple[tuple[np.ndarray, np.ndarray, Trajectory], ...] = ()

    def gate(self, max_constraint_violation: float, max_energy_residual: float, initial: dict, engine: str) -> None:
        """NumericalFailure when the loop gap or the energy residual is beyond its bound (the
        messages name ``engine`` and the setting)."""
        self.constraint_violation.gate(max_constraint_violation, engine, "max_constraint_violation")
        self.audit.gate(max_energy_residual, 0.5 * initial["unit_rate_inertia"], engine, "max_energy_residual")


def record_run(scene: Scene, handles: ModelHandles, layout: Layout, data: mujoco.MjData, states: np.ndarray,
               sensors: np.ndarray | None, ctrl: np.ndarray, timed: np.ndarray, callback=None, *,
               h: float, engine: str = "MuJoCo") -> RunRecord:
    """Read a run's ``states`` (rows of ``STATE``, the first the initial one, one per step)
    with MuJoCo C.

    ``sensors``: the sensor rows MuJoCo computed at the start of each step (the last row, at the
    end state, is computed here), or None to compute every row here at its state (with that
    step's control ``ctrl`` and timed forces' values ``timed``, handed to ``callback``).

    Raises
    ------
    NumericalFailure
        INCOMPLETE: the states stop short of the horizon by more than half a step ``h``.
    """
    model = handles.model
    times = states[:, 0]
    check_complete(scene, times, h, engine)
    qpos = states[:, 1:1 + model.nq]
    qvel = states[:, 1 + model.nq:1 + model.nq + model.nv]
    x, xdot = layout.x(qpos), layout.xdot(qvel)  # qpos counts from the assembled pose
    q, qdot = x @ layout.system.drive, xdot @ layout.system.drive
    if sensors is None:
        sensors = np.empty((len(states), model.nsensordata))
        for k in range(len(states) - 1):
            if timed.shape[1]:
                callback.step_values[:] = timed[k]
            sensors[k] = sensors_at(model, data, states[k], ctrl[k] if model.nu else None, STATE)
    if timed.shape[1]:
        callback.step_values[:] = timed[-1]
    sensors[-1] = sensors_at(model, data, states[-1], ctrl[-1] if model.nu else None, STATE)

    sl = handles.sensor_slices
    violation = np.zeros(len(times))
    for name in scene.mechanism.linkage.cut_joints:
        gap = sensors[:, sl[sensor_name(name, "a_pos")]] - sensors[:, sl[sensor_name(name, "b_pos")]]
        violation = np.maximum(violation, np.sqrt(squares_by_row(gap)))
    qddot = input_acceleration(model, data, handles, layout, states, sensors, ctrl, STATE, timed, callback)
    trajectory = with_edge_samples(model, data, times, q, qdot, qddot, states, ctrl, handles, layout, STATE,
                                   timed, callback)
    others = []
    for joint in layout.inputs[1:]:  # several inputs: each one's own, as the first's
        row = layout.system.joint_row(joint.name)
        qi, qdoti = x @ row, xdot @ row
        qddoti = input_acceleration(model, data, handles, layout, states, sensors, ctrl, STATE, timed, callback,
                                    joint)
        others.append((qi, qdoti, with_edge_samples(model, data, times, qi, qdoti, qddoti, states, ctrl, handles,
                                                    layout, STATE, timed, callback, joint)))
    audit = energy_audit(scene, model, handles, layout, times, states, sensors, ctrl, q, timed)
    friction, notes = constraint_flows(model, data, states, ctrl, timed, callback)
    if friction is not None:
        audit = dataclasses.replace(audit, damper_dissipation=audit.damper_dissipation + friction)
    key = sensor_name(INPUT_MOTOR, "force")
    motor = sensors[:, sl[key]][:, 0] if key in sl else np.zeros(len(times))
    return RunRecord(times=times, q=q, qdot=qdot, trajectory=trajectory,
                     joints=joint_trajectory(layout, times, x, xdot),
                     constraint_violation=ConstraintViolation(times, violation), audit=audit, input_load=motor,
                     notes=notes, other_inputs=tuple(others))


def input_acceleration(model, data, handles, layout, states, sensors, ctrl, spec, timed, callback,
                       joint: InputJoint | None = None) -> np.ndarray:
    """q̈ of an input (``joint``, default the first) at every stored state (rad/s² or m/s²).

    A hinge input: the z angular acceleration of its child body minus its parent's (sensors
    read at each step's start). A slide input: row·qacc from ``mj_forward`` at each state
    with that step's control and timed forces' values (``timed``, handed to ``callback``).
    """
    joint = layout.inputs[0] if joint is None else joint
    if joint.hinge:
        return hinge_acceleration(handles.sensor_slices, layout, sensors, joint)
    out = np.empty(len(states))
    for k, state in enumerate(states):
        mujoco.mj_setState(model, data, state, spec)
        if model.nu:
            data.ctrl[:] = ctrl[min(k, len(ctrl) - 1)]
        if timed.shape[1]:
            callback.step_values[:] = timed[min(k, len(timed) - 1)]
        mujoco.mj_forward(model, data)
        out[k] = joint.row @ data.qacc
    return out


def hinge_acceleration(sl, layout, sensors, joint: InputJoint | None = None) -> np.ndarray:
    """A hinge input's (``joint``, default the first) q̈ from the angular-acceleration sensors."""
    joint = layout.inputs[0] if joint is None else joint
    sensors = np.atleast_2d(sensors)
    acc = sensors[:, sl[sensor_name(joint.body, "angacc")]][:, 2]
    if sensor_name(joint.parent, "angacc") in sl:
        acc = acc - sensors[:, sl[sensor_name(joint.parent, "angacc")]][:, 2]
    return acc


def check_initial_state(scene: Scene, model: mujoco.MjModel, data: mujoco.MjData,
                        layout: "Layout | None" = None) -> dict:
    """MuJoCo's own loop residuals at the state in ``data``; NumericalFailure if above round-off.

    After mj_forward, the equality rows of ``efc_pos`` are the gaps of every connect (m) and
    of ``efc_vel`` = J q̇ their rates (m/s); the position residual also counts how far each
    connect's anchor on body2 (MuJoCo's, computed at qpos0) is from the cut joint's point_b. Bounds: INITIAL_RESIDUAL_REL × the mechanism's size
    (the largest distance between two of its points at x0), and × the largest point speed
    scale (size × largest hinge rate, or largest slide rate). ``layout``: the scene's
    :class:`Layout` if the caller has it (made here otherwise).
    """
    if layout is None:
        layout = Layout.of(scene, model)
    mujoco.mj_forward(model, data)
    rows = np.flatnonzero(data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    position = float(np.linalg.norm(data.efc_pos[rows])) if len(rows) else 0.0
    # MuJoCo derives each connect's anchor on body2 from the authored pose (at qpos0), so a pose
    # that does not close a loop shows there, not in efc_pos: it must be the joint's point_b.
    linkage = scene.mechanism.linkage
    for name in linkage.cut_joints:
        eq = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, name)
        jt = linkage.joint_map[name]
        point_b = np.array([*linkage.body_map[jt.body_b].points[jt.point_b], 0.0])
        position = max(position, float(np.linalg.norm(model.eq_data[eq, 3:6] - point_b)) if eq >= 0 else math.inf)
    velocity = float(np.linalg.norm(data.efc_vel[rows])) if len(rows) else 0.0
    length = layout.size
    hinge = model.jnt_type[model.dof_jntid] == mujoco.mjtJoint.mjJNT_HINGE
    qvel = np.abs(data.qvel)
    speed = max(length * float(np.max(qvel[hinge], initial=0.0)), float(np.max(qvel[~hinge], initial=0.0)))
    limits = (INITIAL_RESIDUAL_REL * length, INITIAL_RESIDUAL_REL * speed)
    expected = 3 * len(scene.mechanism.linkage.cut_joints) + len(scene.mechanism.linkage.couplings)
    if len(rows) != expected or not position <= limits[0] or not velocity <= limits[1]:
        raise NumericalFailure(FailureReason.INITIAL_STATE,
                               f"MuJoCo's loop residuals at the initial state are {position:.3g} m (position, "
                               f"limit {limits[0]:.3g} m) and {velocity:.3g} m/s (velocity, limit {limits[1]:.3g} m/s) "
                               f"over {len(rows)} equality rows ({expected} expected): the assembled (q0, q̇0) "
                               "does not close the loops", 0.0)
    return {"position": position, "velocity": velocity, "limits": limits,
            "unit_rate_inertia": unit_rate_inertia(model, data, rows, layout.input_row) if len(layout.inputs) <= 1
            else inputs_unit_rate_inertia(model, data, rows, np.array([j.row for j in layout.inputs]))}


def unit_rate_inertia(model: mujoco.MjModel, data: mujoco.MjData, rows: np.ndarray,
                       input_row: np.ndarray) -> float:
    """uᵀ M u (kg·m² or kg) for the joint rates u that keep every loop closed with the input
    joint at unit rate (1 rad/s or 1 m/s).

    u spans the null space of all equality rows of MuJoCo's constraint Jacobian J (at the state
    in ``data``), scaled so input_row·u = 1; at a dead centre of the input (input_row·u ≈ 0)
    so that its largest component is 1. This is 𝔍(q0) of Eksergian's equation, from MuJoCo's
    quantities.
    """
    if len(rows):
        jacobian = np.zeros((data.nefc, model.nv))
        if mujoco.mj_isSparse(model):
            mujoco.mju_sparse2dense(jacobian, data.efc_J, data.efc_J_rownnz, data.efc_J_rowadr,
                                    data.efc_J_colind)
        else:
            jacobian[:] = data.efc_J.reshape(data.nefc, model.nv)
        u = np.linalg.svd(jacobian[rows])[2][-1]  # right singular vector of the smallest singular value
    else:
        u = input_row.copy()
    rate = float(input_row @ u)
    u = u / rate if abs(rate) > 1e-6 * np.max(np.abs(u)) else u / np.max(np.abs(u))
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    return float(u @ mass @ u)


def inputs_unit_rate_inertia(model: mujoco.MjModel, data: mujoco.MjData, rows: np.ndarray,
                             input_rows: np.ndarray) -> float:
    """With several inputs (``input_rows`` (k, nv): each input's rate from qvel), the smallest of
    :func:`unit_rate_inertia`'s uᵀ M u over the inputs, each at unit rate with the others held
    (the smallest diagonal term of the k×k 𝔍(q0)): u = N (R N)⁻¹ eᵢ, N (nv, k) the null space
    of MuJoCo's equality rows. The energy gate's floor ½ 𝔍 (1 unit/s)² so judges a run in which
    almost nothing moves against the lightest input."""
    jacobian = np.zeros((data.nefc, model.nv))
    if mujoco.mj_isSparse(model):
        mujoco.mju_sparse2dense(jacobian, data.efc_J, data.efc_J_rownnz, data.efc_J_rowadr, data.efc_J_colind)
    else:
        jacobian[:] = data.efc_J.reshape(data.nefc, model.nv)
    k = input_rows.shape[0]
    null = np.linalg.svd(jacobian[rows])[2][-k:].T if len(rows) else np.eye(model.nv)[:, :k]
    u = null @ np.linalg.pinv(input_rows @ null)  # (nv, k): column i moves input i alone at unit rate
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    return float(np.min(np.einsum("ik,ij,jk->k", u, mass, u)))


def check_complete(scene: Scene, times: np.ndarray, h: float, engine: str = "MuJoCo") -> None:
    """INCOMPLETE unless the trajectory reaches the horizon within half a step."""
    if not times[-1] >= scene.horizon - 0.5 * h:
        raise NumericalFailure(FailureReason.INCOMPLETE,
                               f"{engine}'s trajectory ends at t = {times[-1]:.6g} s, short of simulation.horizon "
                               f"{scene.horizon:g} s (timestep {h:g} s)", float(times[-1]))


def joint_trajectory(layout: Layout, times, x, xdot) -> JointTrajectory:
    """MuJoCo's general coordinates and rates (from its qpos and qvel: :meth:`Layout.x`,
    :meth:`Layout.xdot`), with the assembly mode of each sample."""
    mode = loops.assembly_modes(layout.system, x)
    return JointTrajectory(layout.system.coordinate_names, times, x, xdot,
                           np.full(len(times), -1), mode)


_FRICTION_ROWS = (int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF), int(mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON))
_LIMIT_ROWS = {int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT): mujoco.mjtObj.mjOBJ_JOINT,
               int(mujoco.mjtConstraint.mjCNSTR_LIMIT_TENDON): mujoco.mjtObj.mjOBJ_TENDON}


def has_events(model: mujoco.MjModel) -> bool:
    """Whether the model has dry friction (``frictionloss`` on a dof or a tendon) or limits."""
    return bool(np.any(model.dof_frictionloss > 0.0) or np.any(model.tendon_frictionloss > 0.0)
                or np.any(model.jnt_limited) or np.any(model.tendon_limited))


_EVENT_ROWS = _FRICTION_ROWS + tuple(_LIMIT_ROWS)


def friction_power(data: mujoco.MjData) -> float:
    """The power MuJoCo's dry friction and limits take out of the motion at the state last
    forwarded (W): −Σ efc_force · efc_vel over the friction rows (mjCNSTR_FRICTION_DOF,
    mjCNSTR_FRICTION_TENDON: the row's force on its velocity J q̇; the friction opposes the
    motion, so it is ≥ 0 to the solver's softness) and the limit rows (mjCNSTR_LIMIT_JOINT,
    mjCNSTR_LIMIT_TENDON: a soft limit's spring and damper, whose work the audit books with the
    dissipation; zero until a limit acts)."""
    n = data.nefc
    rows = np.isin(data.efc_type[:n], _EVENT_ROWS)
    return -float(data.efc_force[:n][rows] @ data.efc_vel[:n][rows])


def active_limits(model: mujoco.MjModel, data: mujoco.MjData) -> list[str]:
    """The joints and tendons whose limit row is active (a nonzero force) at the state last
    forwarded, as MuJoCo names them ("joint 'spin'", "tendon 'O_range'")."""
    out = []
    for i in range(data.nefc):
        obj = _LIMIT_ROWS.get(int(data.efc_type[i]))
        if obj is not None and data.efc_force[i] != 0.0:
            name = mujoco.mj_id2name(model, obj, int(data.efc_id[i])) or f"#{int(data.efc_id[i])}"
            out.append(f"{'joint' if obj == mujoco.mjtObj.mjOBJ_JOINT else 'tendon'} '{name}'")
    return out


def limit_note(element: str, t: float) -> str:
    """The note of a MuJoCo limit that acted (first at t, s)."""
    return (f"{element}: MuJoCo's limit acted from t = {t:.6g} s (the exact reference ends where the joint "
            "reaches its range)")


def constraint_flows(model, data, states, ctrl, timed, callback) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """What the friction and limit rows did over the stored states, read at each (``mj_forward``
    with that step's control and timed forces): the energy they took out of the motion since the
    first state (J, by the trapezoid rule of :func:`friction_power`; None without either), and a
    note per limit that acted (:func:`limit_note`)."""
    if not has_events(model):
        return None, ()
    rate = np.zeros(len(states))
    first: dict[str, float] = {}
    for k, state in enumerate(states):
        if timed.shape[1]:
            callback.step_values[:] = timed[min(k, len(timed) - 1)]
        sensors_at(model, data, state, ctrl[min(k, len(ctrl) - 1)] if model.nu else None, STATE)
        rate[k] = friction_power(data)
        for element in active_limits(model, data):
            first.setdefault(element, float(state[0]))
    notes = tuple(limit_note(e, t) for e, t in first.items())
    dt = np.diff(states[:, 0])
    return np.concatenate([np.zeros(1), np.cumsum(0.5 * (rate[:-1] + rate[1:]) * dt)]), notes


def sensors_at(model, data, state, ctrl_row, spec) -> np.ndarray:
    mujoco.mj_setState(model, data, state, spec)
    if ctrl_row is not None:
        data.ctrl[:] = ctrl_row
    mujoco.mj_forward(model, data)
    return data.sensordata.copy()


def with_edge_samples(model, data, times, q, qdot, qddot, states, ctrl, handles, layout, spec,
                       timed, callback, joint: InputJoint | None = None) -> Trajectory:
    """Insert, at each step where the control or a timed force jumps, a sample with q̈ (of the
    input ``joint``, default the first) from before the jump."""
    joint = layout.inputs[0] if joint is None else joint
    jumped = np.zeros(max(len(states) - 2, 0), dtype=bool)
    if model.nu:
        jumped |= np.any(np.diff(ctrl, axis=0) != 0.0, axis=1)
    if timed.shape[1]:
        jumped |= np.any(np.diff(timed, axis=0) != 0.0, axis=1)
    refined = samples_refine_extrema(model)
    if not np.any(jumped):
        return Trajectory(times.copy(), q.copy(), qdot.copy(), qddot.copy(), refined)
    jumps = np.flatnonzero(jumped) + 1
    before = []
    for k in jumps:
        if timed.shape[1]:
            callback.step_values[:] = timed[k - 1]
        if joint.hinge:
            before.append(hinge_acceleration(handles.sensor_slices, layout,
                                              sensors_at(model, data, states[k], ctrl[k - 1], spec), joint)[0])
        else:
            sensors_at(model, data, states[k], ctrl[k - 1], spec)
            before.append(float(joint.row @ data.qacc))
    return Trajectory(np.insert(times, jumps, times[jumps]), np.insert(q, jumps, q[jumps]),
                      np.insert(qdot, jumps, qdot[jumps]), np.insert(qddot, jumps, before), refined)


