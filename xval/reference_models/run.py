"""Run a scene's MuJoCo model and return an :class:`EngineResult`.

The step loop runs in C (``mujoco.rollout``); Python only builds the control sequence before and
reads sensors and states after. A scene with point forces is stepped by a Python loop of ``mj_step``
instead, with the forces applied through ``mjcb_control`` at every integrator stage
(:func:`xval.reference_models.loads.point_force_callback`). Every run is gated on its own
diagnostics: the initial state against MuJoCo's own residuals of every loop constraint (position and
velocity), MuJoCo's warnings (bad qacc and the like, which make ``mj_step`` reset the state), a
non-finite state, a trajectory that stops short of the horizon, the largest loop-closure violation
(over the cut joints, the gap between the joint's two sites), and an energy audit from MuJoCo's own
body velocities and positions (sensors read inside the run). Without an explicit timestep the step
is chosen from the scene and confirmed by step halving (:func:`simulate_mujoco`;
:mod:`xval.reference_models.timestep`).

MuJoCo's qpos/qvel map linearly onto the scene's general coordinates (x = x0 + T·qpos,
:func:`xval.reference_models.build.coordinate_map`); the trajectory is the input coordinate
q = drive·x (rad or m, ``scene.input_unit``) and its rates.
"""


from __future__ import annotations

import contextlib
import logging
import math
import time
import warnings
from dataclasses import asdict, dataclass, replace
from typing import Any, Mapping

import mujoco
import numpy as np
from mujoco import rollout

from xval.errors import FailureReason, NumericalFailure
from xval.trajectory import JointTrajectory
from xval.results import ConstraintViolation, EngineResult
from xval import kinematics as loops
from xval.scene import Scene
from xval.trajectory import Trajectory

from .settings import MujocoSettings
from .build import (INPUT_MOTOR, INTEGRATOR_ENUM, ConstraintSettings, ModelHandles, build_spec, check_joint_order,
                    compile_model, mjcf_from_spec, set_timestep, sensor_name)
from .energy import energy_audit, squares_by_row
from .layout import Layout
from .loads import control_sequence, point_forces_installed, timed_values
from .timestep import SearchCost, TimestepCheck, grid_timestep, search_timestep, step_count

_log = logging.getLogger("xval.mujoco")  # each run (the step search logs its progress there too)


# Work refused up front: the rollout keeps every state and sensor row (~60 float64 per step
# here, held about three times over while the result is assembled).
MAX_STEPS = 20_000_000
MAX_MEMORY_BYTES = 2 * 1024 ** 3
_COPIES = 3
# Initial state: MuJoCo's loop residuals after mj_forward at the assembled (qpos, qvel), relative
# to the mechanism's size (m) and to its point-speed scale (m/s) (check_initial_state). The
# assembly leaves ~1e-16 relative (measured on the seed, two slider-cranks and a Watt II six-bar:
# ≤ 2.2e-16 m and ≤ 4.4e-16 m/s, sizes 0.4–2 m), so 1e-12 is round-off with 1000x margin.
INITIAL_RESIDUAL_REL = 1e-12


class OffGridEdgeWarning(UserWarning):
    """A load edge does not fall on a MuJoCo step boundary."""


# MuJoCo prints its warnings and appends them to MUJOCO_LOG.TXT in the working directory.
# During a run we keep the latest text instead and turn warnings into failures through
# data.warning; the process's handler is restored afterwards.
_last_mujoco_warning: list[str] = []


def _keep_warning(message: str) -> None:
    _last_mujoco_warning[:] = [message.strip()]


@contextlib.contextmanager
def _warnings_kept():
    previous = mujoco.get_mju_user_warning()
    _last_mujoco_warning.clear()
    mujoco.set_mju_user_warning(_keep_warning)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def build_model(scene: Scene, settings: MujocoSettings = MujocoSettings()) -> ModelHandles:
    """Compile the scene's model with the settings' solver options.

    An automatic timestep builds at the first candidate of
    :func:`xval.reference_models.timestep.grid_timestep` (the step halving happens only in a run;
    :func:`mjcf_text` exports the step a run chooses).
    """
    if settings.timestep is None:
        settings = replace(settings, timestep=grid_timestep(scene))
    spec = build_spec(scene, constraint=ConstraintSettings(settings.effective_solref, settings.solimp),
                      integrator=settings.integrator, timestep=settings.timestep,
                      iterations=settings.iterations, tolerance=settings.tolerance,
                      refsafe=settings.refsafe, diagexact=settings.diagexact)
    return compile_model(spec)


def _at_timestep(handles: ModelHandles, scene: Scene, settings: MujocoSettings) -> ModelHandles:
    """The model :func:`build_model` makes of the scene and settings, from one it made of them at
    another timestep: its spec copied, set to ``settings.timestep`` (:func:`build.set_timestep`)
    and compiled, without building the spec again (nor indexing its sensors and dampers again:
    the same as ``handles``')."""
    spec = handles.spec.copy()
    set_timestep(spec, scene, settings.timestep, settings.effective_solref)
    return replace(handles, model=spec.compile(), spec=spec)


def _check_work(scene: Scene, h: float, model: mujoco.MjModel | None = None) -> int:
    """Refuse a run of less than one step, or of more steps or memory than the limits.

    Returns the number of steps.
    """
    flag = "[mujoco] timestep (--timestep)"
    if not h <= scene.horizon:
        raise ValueError(f"MuJoCo timestep {h:g} s is longer than simulation.horizon {scene.horizon:g} s: "
                         f"set {flag} at most the horizon")
    n = step_count(scene, h)
    if n > MAX_STEPS:
        raise ValueError(f"MuJoCo run of {n:.3g} steps (simulation.horizon {scene.horizon:g} s / timestep {h:g} s) "
                         f"exceeds the limit of {MAX_STEPS:.3g} steps: raise {flag} or shorten simulation.horizon")
    if model is not None:
        width = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS) + model.nsensordata + model.nu
        need = _COPIES * 8 * width * (n + 1)
        if need > MAX_MEMORY_BYTES:
            raise ValueError(f"MuJoCo run of {n:.3g} steps (simulation.horizon {scene.horizon:g} s / timestep {h:g} s) "
                             f"needs about {need / 1024 ** 3:.3g} GiB, more than {MAX_MEMORY_BYTES / 1024 ** 3:g} GiB: "
                             f"raise {flag} or shorten simulation.horizon")
    return n


def _within_limits(scene: Scene, h: float, model: mujoco.MjModel) -> bool:
    try:
        _check_work(scene, h, model)
    except ValueError:
        return False
    return True


def _check_handles(scene: Scene, handles: ModelHandles, settings: MujocoSettings) -> None:
    """Refuse a compiled model whose joints, loops or options differ from the scene's and the
    settings' (ValueError naming both)."""
    m = handles.model
    check_joint_order(scene, m)
    loops_ = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_EQUALITY, i) for i in range(m.neq))
    if loops_ != scene.mechanism.linkage.cut_joints:
        raise ValueError(f"the model's loop equalities {loops_} are not the scene's cut joints "
                         f"{scene.mechanism.linkage.cut_joints}")
    pairs = [("timestep", float(m.opt.timestep), settings.timestep),
             ("integrator", int(m.opt.integrator), int(INTEGRATOR_ENUM[settings.integrator])),
             ("iterations", int(m.opt.iterations), settings.iterations),
             ("tolerance", float(m.opt.tolerance), settings.tolerance)]
    for eq in range(m.neq):
        pairs += [("solref", tuple(float(v) for v in m.eq_solref[eq]), tuple(settings.effective_solref)),
                  ("solimp", tuple(float(v) for v in m.eq_solimp[eq]), tuple(float(v) for v in settings.solimp))]
    pairs += [("refsafe", not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_REFSAFE, settings.refsafe),
              ("diagexact", bool(m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_DIAGEXACT), settings.diagexact)]
    for name, model_value, wanted in pairs:
        same = (np.allclose(model_value, wanted, rtol=1e-12, atol=0.0) if not isinstance(wanted, bool)
                else bool(model_value) == wanted)
        if not same:
            if name == "integrator":
                model_value = next(k for k, v in INTEGRATOR_ENUM.items() if int(v) == model_value)
                wanted = settings.integrator
            raise ValueError(f"the model's {name} {model_value} differs from the settings' {name} {wanted}: "
                             "run it with settings that match the model (or build it from these settings)")


def simulate_mujoco(scene: Scene, settings: MujocoSettings = MujocoSettings(),
                    handles: ModelHandles | None = None) -> EngineResult:
    """Roll the scene's MuJoCo model out to the horizon.

    With an explicit ``settings.timestep`` the run uses it as given. With ``timestep=None`` (the
    default) the step is chosen from the scene: the first candidate puts every load edge on the step
    grid (:func:`xval.reference_models.timestep.grid_timestep`); runs at h and h/2 are compared on
    h's grid and h is accepted when max |Δq|, max |Δω| and |Δ peak| are at most HALVING_FRACTION of
    the scene's q_atol, omega_atol and peak tolerance (for RK4 the difference estimates the coarser
    run's error, and the finer run is returned), else h is halved, or, after two checks, cut to the
    halving the observed order predicts (:func:`xval.reference_models.timestep._predicted_step`),
    while the search's steps stay within MAX_SEARCH_STEPS; each failed check is logged on the
    ``xval.mujoco`` logger (INFO) as progress. ``result.settings`` have the step used;
    ``result.details`` (:class:`MujocoDetails`) say whether it was chosen, the halving evidence (per
    check the coarse step and the differences against their limits) and the runs, steps and rollout
    wall time the choice took. With ``handles`` (e.g. from an exported MJCF file) an automatic
    timestep is the model's own, and every other option must match the model.

    Raises
    ------
    ValueError
        Handles whose options differ from the settings; a timestep longer than the horizon;
        a run beyond MAX_STEPS steps or MAX_MEMORY_BYTES of rollout memory.
    NumericalFailure
        INITIAL_STATE: MuJoCo's loop residuals at the start exceed round-off; UNSTABLE or
        NON_FINITE: MuJoCo warnings or a non-finite state; INCOMPLETE: the trajectory stops
        short of the horizon by more than half a step; CONSTRAINT_DRIFT: a loop-closure gap
        above ``settings.max_constraint_violation``; ENERGY_IMBALANCE: an energy residual
        above ``settings.max_energy_residual`` of the energy scale; INACCURATE: no automatic
        step within the search's work limit meets the tolerance (the message gives the step
        the fitted order predicts and its cost).
    """
    with _warnings_kept():
        if handles is not None:
            if settings.timestep is None:
                settings = replace(settings, timestep=float(handles.model.opt.timestep))
            _check_handles(scene, handles, settings)
            result = _run(scene, settings, handles)
        elif settings.timestep is not None:
            _check_work(scene, settings.timestep)
            result = _run(scene, settings, build_model(scene, settings))
        else:
            result = _automatic(scene, settings)
    _log.debug("MuJoCo %s at h = %.4g s on %s: %d steps, %.3g s", result.settings.integrator, result.settings.timestep,
               scene.name, result.n_steps, result.wall_s)
    return result


def _automatic(scene: Scene, settings: MujocoSettings) -> EngineResult:
    """The runs of the automatic step search of :func:`simulate_mujoco` (its docstring says the
    rule; :func:`xval.reference_models.timestep.search_timestep` chooses the steps): one model
    built at the first candidate, set to each other step, one layout and one MjData for all."""
    h0 = grid_timestep(scene)
    first = build_model(scene, replace(settings, timestep=h0))
    shape = first.model  # for the memory estimate
    _check_work(scene, h0, shape)
    layout = Layout.of(scene, shape)  # the same for every timestep's model
    data = mujoco.MjData(shape)  # and so is the MjData, reset for each run

    def attempt(h: float) -> EngineResult | NumericalFailure:
        step_settings = replace(settings, timestep=h)
        handles = first if h == h0 else _at_timestep(first, scene, step_settings)
        return _attempt(scene, step_settings, handles, layout, data)

    return search_timestep(scene, h0, attempt, lambda h: _within_limits(scene, h, shape))


def _attempt(scene: Scene, settings: MujocoSettings, handles: ModelHandles, layout: "Layout",
             data: mujoco.MjData) -> EngineResult | NumericalFailure:
    """One run of the model built at the settings' explicit step; a numerical failure is
    returned for the halving check."""
    _check_work(scene, settings.timestep, handles.model)
    try:
        return _run(scene, settings, handles, layout, data)
    except NumericalFailure as failure:
        if failure.reason == FailureReason.INITIAL_STATE:
            raise
        return failure


def _run(scene: Scene, settings: MujocoSettings, handles: ModelHandles,
         layout: Layout | None = None, data: mujoco.MjData | None = None) -> EngineResult:
    """One run at the settings' explicit timestep, gated on its diagnostics.

    Without point forces the step loop is ``mujoco.rollout`` (in C); with them it is a Python
    loop of ``mj_step`` with :func:`~xval.reference_models.loads.point_force_callback` installed as ``mjcb_control``.
    ``layout``: the scene's :class:`Layout` if the caller has it (made here otherwise).
    ``data``: an MjData to reuse (reset here, as a new one starts), made for a model of the
    same sizes, as the automatic timestep's models are (they differ only in values:
    :func:`_at_timestep`); else a new one.
    """
    model = handles.model
    if data is None:
        data = mujoco.MjData(model)
    else:
        mujoco.mj_resetData(model, data)
    check_joint_order(scene, model)
    h = settings.timestep
    n_steps = _check_work(scene, h, model)
    ctrl, edge_notes = control_sequence(scene, h, n_steps)
    for note in edge_notes:
        warnings.warn(note, OffGridEdgeWarning, stacklevel=3)
    if layout is None:
        layout = Layout.of(scene, model)

    timed = timed_values(scene, h, n_steps)
    with point_forces_installed(scene, model, layout) as callback:
        data.qpos[:], data.qvel[:] = layout.qpos0, layout.qvel0
        initial = check_initial_state(scene, model, data, layout)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state0 = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, state0, spec)

        # The run writes in place: state k + 1 is after step k + 1 (state 0 is the initial one);
        # sensors k were computed at the start of step k + 1 (the last row, at the end, below).
        states = np.empty((n_steps + 1, state0.size))
        sensors = np.empty((n_steps + 1, model.nsensordata))
        states[0] = state0
        start = time.perf_counter()
        if callback is not None:
            _step_loop(model, data, state0, ctrl, n_steps, spec, states[1:], sensors[:-1], timed, callback)
        else:
            rollout.rollout(model, data, state0[None, :], ctrl[None, :, :] if model.nu else None, nstep=n_steps,
                            state=states[None, 1:], sensordata=sensors[None, :-1])
        wall = time.perf_counter() - start

        _check_warnings(data, states[1:], h)
        times = states[:, 0]
        _check_complete(scene, times, h)
        qpos = states[:, 1:1 + model.nq]
        qvel = states[:, 1 + model.nq:1 + model.nq + model.nv]
        x, xdot = layout.x(qpos), layout.xdot(qvel)  # qpos counts from the assembled pose
        q, qdot = x @ layout.system.drive, xdot @ layout.system.drive
        sensors[-1] = _sensors_at(model, data, states[-1], ctrl[-1] if model.nu else None, spec)

        sl = handles.sensor_slices
        violation = np.zeros(len(times))
        for name in scene.mechanism.linkage.cut_joints:
            gap = sensors[:, sl[sensor_name(name, "a_pos")]] - sensors[:, sl[sensor_name(name, "b_pos")]]
            violation = np.maximum(violation, np.sqrt(squares_by_row(gap)))
        qddot = _input_acceleration(model, data, handles, layout, states, sensors, ctrl, spec, timed, callback)
        trajectory = _with_edge_samples(model, data, times, q, qdot, qddot, states, ctrl, handles, layout, spec,
                                        timed, callback)
    constraint_violation = ConstraintViolation(times, violation)
    constraint_violation.gate(settings.max_constraint_violation, "MuJoCo", "max_constraint_violation")

    audit = energy_audit(scene, model, handles, layout, times, states, sensors, ctrl, q, timed)
    audit.gate(settings.max_energy_residual, 0.5 * initial["unit_rate_inertia"], "MuJoCo", "max_energy_residual")
    key = sensor_name(INPUT_MOTOR, "force")
    motor = sensors[:, sl[key]][:, 0] if key in sl else np.zeros(len(times))
    details = MujocoDetails(grid_q=q, grid_qdot=qdot.copy(), input_load=motor, initial_residuals=initial,
                            edge_warnings=tuple(edge_notes), mujoco_version=mujoco.__version__,
                            point_forces="mjcb_control (qfrc_applied, every RK stage)"
                            if scene.mechanism.point_forces or scene.mechanism.timed_forces else None)
    return EngineResult(
        engine="mujoco", trajectory=trajectory, joints=_joint_trajectory(layout, times, x, xdot),
        peak=trajectory.peak_rate(), audit=audit, wall_s=wall, n_steps=n_steps,
        n_evaluations=n_steps * (4 if settings.integrator == "rk4" else 1), settings=settings,
        effects=tuple(scene.effects), constraint_violation=constraint_violation, details=details)


@dataclass(frozen=True)
class MujocoDetails:
    """The MuJoCo engine's own record of a run (:attr:`EngineResult.details`).

    grid_q, grid_qdot : q and q̇ at every step of the grid (the trajectory adds the load edges
        between steps); the automatic step search compares runs on them.
    input_load : N·m or N, the input motor's force at each step.
    initial_residuals : MuJoCo's loop residuals at the start (:func:`check_initial_state`).
    edge_warnings : one note per load edge off the step grid.
    mujoco_version : the MuJoCo that ran.
    point_forces : how point forces were applied; None without them.
    timestep_automatic : the step was chosen by the automatic search.
    timestep_checks : that search's checks, in order (:class:`~xval.reference_models.timestep.MeasuredCheck`:
        the coarse step and the differences against their limits; or
        :class:`~xval.reference_models.timestep.FailedCheck`), each with its outcome.
    search_cost : what the search took; None for a fixed timestep.
    """

    grid_q: np.ndarray
    grid_qdot: np.ndarray
    input_load: np.ndarray
    initial_residuals: Mapping[str, Any]
    edge_warnings: tuple[str, ...]
    mujoco_version: str
    point_forces: str | None = None
    timestep_automatic: bool = False
    timestep_checks: tuple[TimestepCheck, ...] = ()
    search_cost: SearchCost | None = None

    def as_dict(self) -> dict:
        return {"mujoco_version": self.mujoco_version, "timestep_automatic": self.timestep_automatic,
                "timestep_check": [c.as_dict() for c in self.timestep_checks],
                "automatic_timestep_cost": None if self.search_cost is None else asdict(self.search_cost),
                "edge_warnings": list(self.edge_warnings), "point_forces": self.point_forces,
                "initial_residuals": dict(self.initial_residuals)}


def _step_loop(model, data, state0, ctrl, n_steps, spec, states, sensors, timed=None, callback=None) -> None:
    """``rollout``'s states and sensordata, written into ``states`` and ``sensors`` (n_steps
    rows each), from a Python loop of ``mj_step`` (for callbacks); ``timed`` (n_steps, k) the
    timed forces' values, handed to ``callback`` before each step."""
    mujoco.mj_setState(model, data, state0, spec)
    for k in range(n_steps):
        if model.nu:
            data.ctrl[:] = ctrl[k]
        if timed is not None and timed.shape[1]:
            callback.step_values[:] = timed[k]
        mujoco.mj_step(model, data)
        mujoco.mj_getState(model, data, states[k], spec)
        sensors[k] = data.sensordata


def _input_acceleration(model, data, handles, layout, states, sensors, ctrl, spec, timed, callback) -> np.ndarray:
    """q̈ at every stored state (rad/s² or m/s²).

    A hinge input: the z angular acceleration of its child body minus its parent's (sensors
    read at each step's start). A slide input: drive·T·qacc from ``mj_forward`` at each state
    with that step's control and timed forces' values (``timed``, handed to ``callback``).
    """
    if layout.input_hinge:
        return _hinge_acceleration(handles.sensor_slices, layout, sensors)
    out = np.empty(len(states))
    for k, state in enumerate(states):
        mujoco.mj_setState(model, data, state, spec)
        if model.nu:
            data.ctrl[:] = ctrl[min(k, len(ctrl) - 1)]
        if timed.shape[1]:
            callback.step_values[:] = timed[min(k, len(timed) - 1)]
        mujoco.mj_forward(model, data)
        out[k] = layout.input_row @ data.qacc
    return out


def _hinge_acceleration(sl, layout, sensors) -> np.ndarray:
    sensors = np.atleast_2d(sensors)
    acc = sensors[:, sl[sensor_name(layout.input_body, "angacc")]][:, 2]
    if sensor_name(layout.input_parent, "angacc") in sl:
        acc = acc - sensors[:, sl[sensor_name(layout.input_parent, "angacc")]][:, 2]
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
    expected = 3 * len(scene.mechanism.linkage.cut_joints)
    if len(rows) != expected or not position <= limits[0] or not velocity <= limits[1]:
        raise NumericalFailure(FailureReason.INITIAL_STATE,
                               f"MuJoCo's loop residuals at the initial state are {position:.3g} m (position, "
                               f"limit {limits[0]:.3g} m) and {velocity:.3g} m/s (velocity, limit {limits[1]:.3g} m/s) "
                               f"over {len(rows)} equality rows ({expected} expected): the assembled (q0, q̇0) "
                               "does not close the loops", 0.0)
    return {"position": position, "velocity": velocity, "limits": limits,
            "unit_rate_inertia": _unit_rate_inertia(model, data, rows, layout.input_row)}


def _unit_rate_inertia(model: mujoco.MjModel, data: mujoco.MjData, rows: np.ndarray,
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


def _check_complete(scene: Scene, times: np.ndarray, h: float) -> None:
    """INCOMPLETE unless the trajectory reaches the horizon within half a step."""
    if not times[-1] >= scene.horizon - 0.5 * h:
        raise NumericalFailure(FailureReason.INCOMPLETE,
                               f"MuJoCo's trajectory ends at t = {times[-1]:.6g} s, short of simulation.horizon "
                               f"{scene.horizon:g} s (timestep {h:g} s)", float(times[-1]))


def _joint_trajectory(layout: Layout, times, x, xdot) -> JointTrajectory:
    """MuJoCo's general coordinates and rates (from its qpos and qvel: :meth:`Layout.x`,
    :meth:`Layout.xdot`), with the assembly mode of each sample."""
    mode = loops.assembly_modes(layout.system, x)
    return JointTrajectory(layout.system.coordinate_names, times, x, xdot,
                           np.full(len(times), -1), mode)


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


def _with_edge_samples(model, data, times, q, qdot, qddot, states, ctrl, handles, layout, spec,
                       timed, callback) -> Trajectory:
    """Insert, at each step where the control or a timed force jumps, a sample with q̈ from
    before the jump."""
    jumped = np.zeros(max(len(states) - 2, 0), dtype=bool)
    if model.nu:
        jumped |= np.any(np.diff(ctrl, axis=0) != 0.0, axis=1)
    if timed.shape[1]:
        jumped |= np.any(np.diff(timed, axis=0) != 0.0, axis=1)
    if not np.any(jumped):
        return Trajectory(times.copy(), q.copy(), qdot.copy(), qddot.copy())
    jumps = np.flatnonzero(jumped) + 1
    before = []
    for k in jumps:
        if timed.shape[1]:
            callback.step_values[:] = timed[k - 1]
        if layout.input_hinge:
            before.append(_hinge_acceleration(handles.sensor_slices, layout,
                                              _sensors_at(model, data, states[k], ctrl[k - 1], spec))[0])
        else:
            _sensors_at(model, data, states[k], ctrl[k - 1], spec)
            before.append(float(layout.input_row @ data.qacc))
    return Trajectory(np.insert(times, jumps, times[jumps]), np.insert(q, jumps, q[jumps]),
                      np.insert(qdot, jumps, qdot[jumps]), np.insert(qddot, jumps, before))


def mjcf_text(scene: Scene, settings: MujocoSettings = MujocoSettings()) -> str:
    """The scene's model as human-readable MJCF text that MuJoCo loads on its own.

    An automatic timestep is resolved by a run first (:func:`simulate_mujoco`), so the text
    reproduces the default run. Writing it to a file is the caller's (``xval export-mjcf``
    writes it through the one output writer, ``xval.compare.output``).
    """
    if settings.timestep is None:  # the step a run would choose, so the file reproduces it
        settings = replace(settings, timestep=simulate_mujoco(scene, settings).settings.timestep)
    return mjcf_from_spec(build_model(scene, settings).spec)


def handles_from_mjcf(path) -> ModelHandles:
    """Compile an exported MJCF file (e.g. to re-run it with :func:`simulate_mujoco`)."""
    return compile_model(mujoco.MjSpec.from_file(str(path)))
