"""Run a scene's MuJoCo model with ``mujoco.rollout`` and return an :class:`EngineResult`.

The step loop runs in C (``rollout``); Python only builds the control sequence before and
reads sensors and states after. Diagnostics on every run: the largest loop-closure
violation |B_coupler − B_rocker|, MuJoCo's warnings (bad qacc and the like, which make
``mj_step`` reset the state), and an energy audit from MuJoCo's own body velocities and
positions (sensors read inside the rollout).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import asdict, dataclass

import mujoco
import numpy as np
from mujoco import rollout

from reduced.errors import NumericalFailure
from reduced.partition import JointTrajectory
from reduced.result import EnergyAudit, EngineResult
from reduced.scene import BODY_NAMES, Scene
from reduced.trajectory import Trajectory

from .build import (ConstraintSettings, ModelHandles, build_spec, compile_model, initial_qpos_qvel,
                    loop_angles)

INTEGRATORS = ("euler", "implicit", "implicitfast", "rk4")

# MuJoCo prints its warnings and appends them to MUJOCO_LOG.TXT in the working directory.
# We keep the latest text instead and turn warnings into failures through data.warning.
_last_mujoco_warning: list[str] = []


def _keep_warning(message: str) -> None:
    _last_mujoco_warning[:] = [message.strip()]


mujoco.set_mju_user_warning(_keep_warning)


class OffGridEdgeWarning(UserWarning):
    """A load edge does not fall on a MuJoCo step boundary."""


@dataclass(frozen=True)
class MujocoSettings:
    """Everything that changes MuJoCo's answer; recorded with every result.

    The defaults are chosen for accuracy (README, "MuJoCo defaults"): RK4 at 1e-3 s;
    a hard loop constraint, solimp (0.9999, 0.9999, 0.001, 0.5, 2) and solref with
    time constant 2·timestep (the smallest that ``refsafe`` allows) and critical damping;
    Newton solver tolerance 1e-12.
    """

    integrator: str = "rk4"
    timestep: float = 1e-3
    solref: tuple[float, float] | None = None  # None: (2·timestep, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.9999, 0.9999, 0.001, 0.5, 2.0)
    iterations: int = 100
    tolerance: float = 1e-12
    refsafe: bool = True
    diagexact: bool = False
    max_constraint_violation: float = 1e-3  # m; beyond it the run is reported as drifted

    def __post_init__(self) -> None:
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")
        if not self.timestep > 0.0:
            raise ValueError("timestep must be positive")

    @property
    def effective_solref(self) -> tuple[float, float]:
        return self.solref if self.solref is not None else (2.0 * self.timestep, 1.0)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["solref"] = list(self.effective_solref)
        d["solimp"] = list(self.solimp)
        d["mujoco_version"] = mujoco.__version__
        return d


def build_model(scene: Scene, settings: MujocoSettings = MujocoSettings()) -> ModelHandles:
    """Compile the scene's model with the settings' solver options."""
    spec = build_spec(scene, constraint=ConstraintSettings(settings.effective_solref, settings.solimp),
                      integrator=settings.integrator, timestep=settings.timestep,
                      iterations=settings.iterations, tolerance=settings.tolerance,
                      refsafe=settings.refsafe, diagexact=settings.diagexact)
    return compile_model(spec)


def control_sequence(scene: Scene, timestep: float, n_steps: int) -> tuple[np.ndarray, list[str]]:
    """Motor control for each step (the torque on the step's open interval), shape (n_steps, nu).

    Returns the controls and one warning per load edge that falls inside a step.
    """
    if scene.torque is None:
        return np.zeros((n_steps, 0)), []
    starts = np.arange(n_steps) * timestep
    ctrl = scene.torque.sample(starts + 0.5 * timestep)[:, None]
    notes = []
    for edge in scene.torque.edges:
        k = edge / timestep
        if 0.0 < edge < scene.horizon and abs(k - round(k)) > 1e-6:
            notes.append(f"load edge at t = {edge:g} s is not a multiple of the timestep {timestep:g} s: "
                         f"the jump is applied at t = {round(k) * timestep:g} s, up to "
                         f"{0.5 * timestep:g} s late or early")
    return ctrl, notes


def simulate_mujoco(scene: Scene, settings: MujocoSettings = MujocoSettings(),
                    handles: ModelHandles | None = None) -> EngineResult:
    """Roll the scene's MuJoCo model out to the horizon.

    Raises
    ------
    NumericalFailure
        On MuJoCo warnings (bad qacc etc.), a non-finite state, or a loop-constraint
        violation above ``settings.max_constraint_violation``.
    """
    handles = handles or build_model(scene, settings)
    model, data = handles.model, mujoco.MjData(handles.model)
    h = settings.timestep
    n_steps = int(math.ceil(scene.horizon / h - 1e-9))
    ctrl, edge_notes = control_sequence(scene, h, n_steps)
    for note in edge_notes:
        warnings.warn(note, OffGridEdgeWarning, stacklevel=2)

    qpos0, qvel0 = initial_qpos_qvel(scene)
    data.qpos[:], data.qvel[:] = qpos0, qvel0
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)

    start = time.perf_counter()
    states, sensordata = rollout.rollout(model, data, state0[None, :], ctrl[None, :, :] if model.nu else None,
                                         nstep=n_steps)
    wall = time.perf_counter() - start

    states, sensordata = states[0], sensordata[0]
    _check_warnings(data, states, h)
    # rollout's state k is after step k+1; sensordata k was computed at the start of step k+1.
    states = np.vstack([state0, states])
    times = states[:, 0]
    qpos = states[:, 1:1 + model.nq]
    qvel = states[:, 1 + model.nq:1 + model.nq + model.nv]
    final_sensors = _sensors_at(model, data, states[-1], ctrl[-1] if model.nu else None, spec)
    sensors = np.vstack([sensordata, final_sensors])

    sl = handles.sensor_slices
    gap = sensors[:, sl["B_coupler_pos"]] - sensors[:, sl["B_rocker_pos"]]
    violation = np.linalg.norm(gap, axis=1)
    qddot = sensors[:, sl["crank_angacc"]][:, 2]
    trajectory = _with_edge_samples(model, data, scene, times, qpos[:, 0], qvel[:, 0], qddot,
                                    states, ctrl, handles, spec)
    max_violation = float(np.max(violation))
    if not math.isfinite(max_violation) or max_violation > settings.max_constraint_violation:
        k = int(np.argmax(np.nan_to_num(violation, nan=np.inf)))
        raise NumericalFailure("constraint-drift", f"loop-closure violation {violation[k]:.3g} m at "
                               f"t = {times[k]:.6g} s exceeds {settings.max_constraint_violation:g} m",
                               float(times[k]))

    audit = _energy_audit(model, handles, times, states, sensors, ctrl)
    return EngineResult(
        engine="mujoco", trajectory=trajectory, peak=trajectory.peak_angular_velocity(), audit=audit,
        wall_s=wall, n_steps=n_steps, n_evaluations=n_steps * (4 if settings.integrator == "rk4" else 1),
        settings=settings.as_dict(),
        diagnostics={"max_constraint_violation": max_violation, "joints": _joint_trajectory(scene, times, qpos, qvel),
                     "constraint_violation": violation, "times": times,
                     "edge_warnings": edge_notes, "effects": list(scene.effects)})


def _joint_trajectory(scene: Scene, times, qpos, qvel) -> JointTrajectory:
    """MuJoCo's loop angles and rates, with the assembly branch of each sample."""
    from reduced.linkage import FourBar

    linkage = FourBar(scene.linkage)
    x = loop_angles(qpos)
    xdot = loop_angles(qvel) + np.array([0.0, 0.0, np.pi])  # rates: no offset on the rocker
    branch = linkage.branches(x)
    return JointTrajectory(linkage.coordinate_names, times, x, xdot, np.full(len(times), -1), branch)


def _check_warnings(data: mujoco.MjData, states: np.ndarray, h: float) -> None:
    names = {mujoco.mjtWarning.mjWARN_BADQACC: "bad qacc", mujoco.mjtWarning.mjWARN_BADQVEL: "bad qvel",
             mujoco.mjtWarning.mjWARN_BADQPOS: "bad qpos", mujoco.mjtWarning.mjWARN_INERTIA: "bad inertia"}
    for kind, label in names.items():
        w = data.warning[int(kind)]
        if w.number:
            text = f" ({_last_mujoco_warning[0]})" if _last_mujoco_warning else ""
            raise NumericalFailure("unstable", f"MuJoCo reported {label} {w.number} time(s){text}; "
                                   "mj_step reset the state: the simulation is unstable at these settings")
    if not np.all(np.isfinite(states)):
        raise NumericalFailure("non-finite", "MuJoCo's state became NaN or infinite")
    # A reset (warning swallowed elsewhere) shows as time going backwards.
    if np.any(np.diff(states[:, 0]) <= 0.0):
        raise NumericalFailure("unstable", "MuJoCo's time went backwards: the state was reset")


def _sensors_at(model, data, state, ctrl_row, spec) -> np.ndarray:
    mujoco.mj_setState(model, data, state, spec)
    if ctrl_row is not None:
        data.ctrl[:] = ctrl_row
    mujoco.mj_forward(model, data)
    return data.sensordata.copy()


def _with_edge_samples(model, data, scene, times, q, qdot, qddot, states, ctrl, handles, spec) -> Trajectory:
    """Insert, at each step where the control jumps, a sample with q̈ from before the jump."""
    t, qs, vs, accs = list(times), list(q), list(qdot), list(qddot)
    if model.nu:
        jumps = np.flatnonzero(np.any(np.diff(ctrl, axis=0) != 0.0, axis=1)) + 1
        acc_slice = handles.sensor_slices["crank_angacc"]
        for k in sorted(jumps, reverse=True):
            before = _sensors_at(model, data, states[k], ctrl[k - 1], spec)[acc_slice][2]
            t.insert(k, times[k]), qs.insert(k, q[k]), vs.insert(k, qdot[k]), accs.insert(k, before)
    return Trajectory(np.array(t), np.array(qs), np.array(vs), np.array(accs))


def _energy_audit(model, handles, times, states, sensors, ctrl) -> EnergyAudit:
    """The energy balance from MuJoCo's own quantities at every stored state.

    Kinetic Σ ½ m |v_G|² + ½ I_zz ω_z² and potential −Σ m g·r_G + Σ ½ k (l − l0)² from the
    body and tendon sensors with the model's masses, inertias, stiffnesses (kinetic energy
    agrees with ½ q̇ᵀM q̇); the work of the motor ∫ u q̇_crank dt and the damper dissipation
    ∫ Σ b l̇² dt by the trapezoid rule (the control is constant within each step).
    """
    sl = handles.sensor_slices
    n = len(times)
    kinetic, potential = np.zeros(n), np.zeros(n)
    gravity = model.opt.gravity
    for name in BODY_NAMES:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        mass, izz = model.body_mass[body], model.body_inertia[body, 2]
        v, w = sensors[:, sl[f"{name}_com_vel"]], sensors[:, sl[f"{name}_ang_vel"]]
        kinetic += 0.5 * mass * np.sum(v * v, axis=1) + 0.5 * izz * w[:, 2] ** 2
        potential -= mass * sensors[:, sl[f"{name}_com_pos"]] @ gravity
    for tendon in range(model.ntendon):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, tendon)
        if f"{name}_length" in sl:
            stretch = sensors[:, sl[f"{name}_length"]][:, 0] - model.tendon_lengthspring[tendon, 0]
            potential += 0.5 * model.tendon_stiffness[tendon] * stretch * stretch
    dt = np.diff(times)
    qvel_crank = states[:, 1 + model.nq]
    zero = np.zeros(1)
    if model.nu:
        power_dt = ctrl[:, 0] * 0.5 * (qvel_crank[:-1] + qvel_crank[1:]) * dt
        torque_work = np.concatenate([zero, np.cumsum(power_dt)])
    else:
        torque_work = np.zeros(n)
    rate = np.zeros(n)
    for name in handles.damper_tendons:
        b = model.tendon_damping[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, name)]
        ldot = sensors[:, sl[f"{name}_rate"]][:, 0]
        rate += b * ldot * ldot
    dissipation = np.concatenate([zero, np.cumsum(0.5 * (rate[:-1] + rate[1:]) * dt)])
    return EnergyAudit(t=times, kinetic=kinetic, potential=potential, torque_work=torque_work,
                       damper_dissipation=dissipation)


def export_mjcf(scene: Scene, path, settings: MujocoSettings = MujocoSettings()) -> str:
    """Write the scene's model as human-readable MJCF that MuJoCo loads on its own.

    The file is written to a temporary name and renamed, so a failure leaves nothing behind.
    Returns the XML text.
    """
    from pathlib import Path

    xml = build_model(scene, settings).spec.to_xml()
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(xml, encoding="utf-8")
    tmp.replace(path)
    return xml


def handles_from_mjcf(path) -> ModelHandles:
    """Compile an exported MJCF file (e.g. to re-run it with :func:`simulate_mujoco`)."""
    return compile_model(mujoco.MjSpec.from_file(str(path)))
