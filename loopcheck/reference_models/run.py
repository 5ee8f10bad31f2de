"""Run a scene's MuJoCo model and return an :class:`EngineResult`.

The step loop runs in C (``mujoco.rollout``); Python only builds the control sequence before and
reads sensors and states after. A scene with point forces is stepped by a Python loop of ``mj_step``
instead, with the forces applied through ``mjcb_control`` at every integrator stage
(:func:`loopcheck.mujoco_model.loads.point_force_callback`). Every run is gated on its own
diagnostics: the initial state against MuJoCo's own residuals of every loop constraint (position and
velocity), MuJoCo's warnings (bad qacc and the like, which make ``mj_step`` reset the state), a
non-finite state, a trajectory that stops short of the horizon, the largest loop-closure violation
(over the cut joints, the gap between the joint's two sites), and an energy audit from MuJoCo's own
body velocities and positions (sensors read inside the run). Without an explicit timestep the step
is chosen from the scene and confirmed by step halving (:func:`simulate_mujoco`;
:mod:`loopcheck.reference_models.timestep`).

MuJoCo's qpos/qvel map linearly onto the scene's general coordinates (x = x0 + T·qpos,
:func:`loopcheck.mujoco_model.build.coordinate_map`); the trajectory is the input coordinate
q = drive·x (rad or m, ``scene.input_unit``) and its rates; with several inputs, each input after
the first is recorded the same way (``EngineResult.other_inputs``).
"""


from __future__ import annotations

import logging
import time
import warnings
from dataclasses import asdict, dataclass, replace
from typing import Any, Mapping

import mujoco
import numpy as np
from mujoco import rollout

from loopcheck.errors import FailureReason, NumericalFailure, with_partial
from loopcheck.mujoco_model.build import (INTEGRATOR_ENUM, ConstraintSettings, ModelHandles, build_spec, check_joint_order,
                                     compile_model, mjcf_from_spec, set_timestep)
from loopcheck.mujoco_model.layout import Layout
from loopcheck.mujoco_model.loads import control_sequence, point_forces_installed, timed_values
from loopcheck.mujoco_model.record import check_initial_state, record_run
from loopcheck.mujoco_model.steps import grid_timestep, step_count
from loopcheck.mujoco_model.warning_handler import bad_state, compile_spec, mujoco_warnings, singular_mass_matrix

from loopcheck.results import EngineResult
from loopcheck.scene import Scene

from .settings import MujocoSettings
from .timestep import SearchCost, TimestepCheck, search_timestep

_log = logging.getLogger("loopcheck.mujoco")  # each run (the step search logs its progress there too)


# Work refused up front: the rollout keeps every state and sensor row (~60 float64 per step
# here, held about three times over while the result is assembled).
MAX_STEPS = 20_000_000
MAX_MEMORY_BYTES = 2 * 1024 ** 3
_COPIES = 3


class OffGridEdgeWarning(UserWarning):
    """A load edge does not fall on a MuJoCo step boundary."""


def build_model(scene: Scene, settings: MujocoSettings = MujocoSettings()) -> ModelHandles:
    """Compile the scene's model with the settings' solver options.

    An automatic timestep builds at the first candidate of
    :func:`loopcheck.reference_models.timestep.grid_timestep` (the step halving happens only in a run;
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
    return replace(handles, model=compile_spec(spec), spec=spec)


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
    linkage = scene.mechanism.linkage
    if loops_ != linkage.cut_joints + tuple(c.name for c in linkage.couplings):
        raise ValueError(f"the model's loop equalities {loops_} are not the scene's cut joints "
                         f"{linkage.cut_joints} and couplings {tuple(c.name for c in linkage.couplings)}")
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
    grid (:func:`loopcheck.reference_models.timestep.grid_timestep`); runs at h and h/2 are compared on
    h's grid and h is accepted when max |Δq|, max |Δω| and |Δ peak| are at most HALVING_FRACTION of
    the scene's q_atol, omega_atol and peak tolerance (for RK4 the difference estimates the coarser
    run's error, and the finer run is returned), else h is halved, or, after two checks, cut to the
    halving the observed order predicts (:func:`loopcheck.reference_models.timestep._predicted_step`),
    while the search's steps stay within MAX_SEARCH_STEPS; each failed check is logged on the
    ``loopcheck.mujoco`` logger (INFO) as progress. ``result.settings`` have the step used;
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
    with mujoco_warnings() as said:
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
    said.report(f"MuJoCo on {scene.name}")
    _log.debug("MuJoCo %s at h = %.4g s on %s: %d steps, %.3g s", result.settings.integrator, result.settings.timestep,
               scene.name, result.n_steps, result.wall_s)
    return result


def _automatic(scene: Scene, settings: MujocoSettings) -> EngineResult:
    """The runs of the automatic step search of :func:`simulate_mujoco` (its docstring says the
    rule; :func:`loopcheck.reference_models.timestep.search_timestep` chooses the steps): one model
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
    loop of ``mj_step`` with :func:`~loopcheck.mujoco_model.loads.point_force_callback` installed as ``mjcb_control``.
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
            _rollout(model, data, state0, ctrl, n_steps, states, sensors)
        wall = time.perf_counter() - start

        _check_warnings(data, states, settings)
        record = record_run(scene, handles, layout, data, states, sensors, ctrl, timed, callback, h=h)
    q, qdot = record.q, record.qdot
    details = MujocoDetails(grid_q=q, grid_qdot=qdot.copy(), input_load=record.input_load, initial_residuals=initial,
                            edge_warnings=tuple(edge_notes), mujoco_version=mujoco.__version__,
                            point_forces="mjcb_control (qfrc_applied, every RK stage)"
                            if scene.mechanism.point_forces or scene.mechanism.timed_forces else None,
                            other_grid=tuple((qi, qdoti.copy()) for qi, qdoti, _ in record.other_inputs))
    result = EngineResult(
        engine="mujoco", trajectory=record.trajectory, joints=record.joints,
        peak=record.trajectory.peak_rate(), audit=record.audit, wall_s=wall, n_steps=n_steps,
        n_evaluations=n_steps * (4 if settings.integrator == "rk4" else 1), settings=settings,
        effects=tuple(scene.effects), constraint_violation=record.constraint_violation, details=details,
        caveats=record.notes,
        other_inputs=tuple((trajectory, trajectory.peak_rate()) for _, _, trajectory in record.other_inputs))
    # a failed gate carries the run (NumericalFailure.partial): shown up to the failure's time
    return with_partial(lambda: record.gate(settings.max_constraint_violation, settings.max_energy_residual,
                                            initial, "MuJoCo"), result)


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
    timestep_checks : that search's checks, in order (:class:`~loopcheck.reference_models.timestep.MeasuredCheck`:
        the coarse step and the differences against their limits; or
        :class:`~loopcheck.reference_models.timestep.FailedCheck`), each with its outcome.
    search_cost : what the search took; None for a fixed timestep.
    other_grid : with several inputs, each input after the first: its q and q̇ at every step of
        the grid (as grid_q and grid_qdot are the first's); empty with one input.
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
    other_grid: tuple[tuple[np.ndarray, np.ndarray], ...] = ()

    def as_dict(self) -> dict:
        return {"mujoco_version": self.mujoco_version, "timestep_automatic": self.timestep_automatic,
                "timestep_check": [c.as_dict() for c in self.timestep_checks],
                "automatic_timestep_cost": None if self.search_cost is None else asdict(self.search_cost),
                "edge_warnings": list(self.edge_warnings), "point_forces": self.point_forces,
                "initial_residuals": dict(self.initial_residuals)}


ROLLOUT_CHUNK = 2000  # steps per call of mujoco.rollout: a run stops within this many steps of MuJoCo's first reset


def _rollout(model, data, state0, ctrl, n_steps, states, sensors) -> None:
    """``mujoco.rollout`` over ``n_steps`` in chunks of ROLLOUT_CHUNK steps, writing ``states[1:]``
    and ``sensors[:-1]``; it stops after the chunk in which MuJoCo reset the state (bad qpos, qvel
    or qacc), leaving the rest of ``states`` NaN for :func:`_check_warnings`."""
    states[1:] = np.nan
    start, initial = 0, state0
    while start < n_steps:
        stop = min(start + ROLLOUT_CHUNK, n_steps)
        rollout.rollout(model, data, initial[None, :], ctrl[None, start:stop, :] if model.nu else None,
                        nstep=stop - start, state=states[None, 1 + start:1 + stop],
                        sensordata=sensors[None, start:stop])
        if bad_state(data) is not None:
            return
        start, initial = stop, states[stop]


def _step_loop(model, data, state0, ctrl, n_steps, spec, states, sensors, timed=None, callback=None) -> None:
    """``rollout``'s states and sensordata, written into ``states`` and ``sensors`` (n_steps
    rows each), from a Python loop of ``mj_step`` (for callbacks); ``timed`` (n_steps, k) the
    timed forces' values, handed to ``callback`` before each step. It stops at MuJoCo's first
    reset of the state (the rest of ``states`` NaN)."""
    mujoco.mj_setState(model, data, state0, spec)
    states[:] = np.nan
    for k in range(n_steps):
        if model.nu:
            data.ctrl[:] = ctrl[k]
        if timed is not None and timed.shape[1]:
            callback.step_values[:] = timed[k]
        mujoco.mj_step(model, data)
        mujoco.mj_getState(model, data, states[k], spec)
        sensors[k] = data.sensordata
        if bad_state(data) is not None:
            return


def _check_warnings(data: mujoco.MjData, states: np.ndarray, settings: MujocoSettings) -> None:
    """Fail a run in which MuJoCo reset the state (bad qpos, qvel or qacc: the warning's text and
    the time of the last state before the reset), or whose state is not finite, or whose time
    went backwards."""
    options = f"{settings.integrator}, timestep {settings.timestep:g} s"
    bad = bad_state(data)
    if bad is not None:
        t = states[:, 0]
        back = np.flatnonzero(~(np.diff(t) > 0.0))  # a reset sets the time to 0; NaN after the stop
        time_ = float(t[back[0]]) if len(back) else None
        raise NumericalFailure(FailureReason.UNSTABLE, bad.message(time_, options), time_)
    singular = singular_mass_matrix(data, options)
    if singular is not None:
        raise NumericalFailure(FailureReason.UNSTABLE, singular)
    if not np.all(np.isfinite(states)):
        raise NumericalFailure("non-finite", "MuJoCo's state became NaN or infinite")
    # A reset (warning swallowed elsewhere) shows as time going backwards.
    if np.any(np.diff(states[:, 0]) <= 0.0):
        raise NumericalFailure("unstable", "MuJoCo's time went backwards: the state was reset")


def mjcf_text(scene: Scene, settings: MujocoSettings = MujocoSettings()) -> str:
    """The scene's model as human-readable MJCF text that MuJoCo loads on its own.

    An automatic timestep is resolved by a run first (:func:`simulate_mujoco`), so the text
    reproduces the default run. Writing it to a file is the caller's (``loopcheck export-mjcf``
    writes it through the one output writer, ``loopcheck.compare.output``).
    """
    if settings.timestep is None:  # the step a run would choose, so the file reproduces it
        settings = replace(settings, timestep=simulate_mujoco(scene, settings).settings.timestep)
    return mjcf_from_spec(build_model(scene, settings).spec)


def handles_from_mjcf(path) -> ModelHandles:
    """Compile an exported MJCF file (e.g. to re-run it with :func:`simulate_mujoco`)."""
    with mujoco_warnings() as said:
        handles = compile_model(mujoco.MjSpec.from_file(str(path)))
    said.report(f"MuJoCo loading {path}")
    return handles
