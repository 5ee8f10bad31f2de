"""What MuJoCo's ports (MJX, MJWarp) share around their step loops: the scene's model built as
the MuJoCo engine builds it, with the same options (:func:`prepare`), and their stored states read
back by MuJoCo C into an :class:`~loopcheck.results.EngineResult` (:func:`finish`).

A port only steps: it takes the compiled model without the energy flag (MJX refuses
``mjENBL_ENERGY``; the ports compute no energy), the initial qpos/qvel and the control of each
step, and returns qpos and qvel after every step. Everything else, the initial state's check, the
sensors, the loop gap, q̈, the energy audit, is MuJoCo C's at those states
(:mod:`loopcheck.mujoco_model.record`), so the three MuJoCo-family engines are audited alike.
"""

from __future__ import annotations

import contextlib
import warnings
from dataclasses import dataclass, replace
from typing import Any

import mujoco
import numpy as np

from loopcheck.errors import FailureReason, NumericalFailure, with_partial
from loopcheck.results import EngineResult
from loopcheck.scene import Scene

from .build import ConstraintSettings, ModelHandles, build_spec, check_joint_order, compile_model, release
from .layout import Layout
from .loads import control_sequence
from .options import ModelOptions
from .record import STATE, check_initial_state, record_run
from .steps import grid_timestep, step_count
from .warning_handler import compile_spec, mujoco_warnings

# A port keeps qpos and qvel of every step on the host: refuse up front what cannot fit.
MAX_STEPS = 5_000_000
MAX_STATE_BYTES = 2 * 1024 ** 3


class PortRefusal(ValueError):
    """A scene or setting a port cannot run, in one line naming what and why."""


@contextlib.contextmanager
def refusing_unimplemented(engine: str):
    """A port's NotImplementedError (what its ``put_model`` finds it does not implement in the
    model) as a :class:`PortRefusal` in one line naming it."""
    try:
        yield
    except NotImplementedError as exc:
        raise PortRefusal(f"{engine} does not implement {exc} (in the MuJoCo model of the scene)") from None


@dataclass(frozen=True)
class PortRun:
    """One scene's model, ready for a port to step.

    settings : the engine's settings with the timestep resolved.
    handles : the compiled model (MuJoCo C's, with the energy flag) and its sensor index.
    port_model : the same model with the energy flag cleared, for the port.
    layout : the map between qpos/qvel and the scene's coordinates.
    data : MuJoCo C's data at the initial state (qpos0, qvel0).
    initial : MuJoCo C's loop residuals at the initial state (:func:`check_initial_state`).
    ctrl : (n_steps, nu), the motor's control over each step.
    edge_notes : one note per load edge off the step grid.
    """

    scene: Scene
    settings: Any
    handles: ModelHandles
    port_model: mujoco.MjModel
    layout: Layout
    data: mujoco.MjData
    initial: dict
    ctrl: np.ndarray
    edge_notes: tuple[str, ...]

    @property
    def timestep(self) -> float:
        return float(self.settings.timestep)

    @property
    def n_steps(self) -> int:
        return len(self.ctrl)


def prepare(scene: Scene, settings: ModelOptions, engine: str, table: str) -> PortRun:
    """The scene's model for a port, built with ``settings`` (an engine's settings extending
    :class:`ModelOptions`; a timestep of None is the grid step, :func:`grid_timestep`).

    ``engine`` names the port in messages ("MJX"); ``table`` its scene table ("mjx").

    Raises
    ------
    PortRefusal
        A scene with point or timed forces (their loads are applied by a callback at every
        integrator stage, which the ports do not have); a timestep longer than the horizon; a
        run beyond MAX_STEPS steps or MAX_STATE_BYTES of stored states.
    NumericalFailure
        INITIAL_STATE: MuJoCo's loop residuals at the start exceed round-off.
    """
    mechanism = scene.mechanism
    forces = [f.name for f in (*mechanism.point_forces, *mechanism.timed_forces)]
    if forces:
        raise PortRefusal(f"{engine} does not run point or timed forces ({', '.join(forces)}): MuJoCo applies them "
                          "through mjcb_control at every integrator stage, which the port does not call")
    frictions = [e.name for e in mechanism.joint_frictions]
    if frictions:
        raise PortRefusal(f"{engine} does not run joint friction ({', '.join(frictions)}): the port's support of "
                          "MuJoCo's tendon frictionloss is not checked against the reduced reference")
    ranged = [j.name for j in mechanism.linkage.joints if j.range is not None]
    if ranged:
        raise PortRefusal(f"{engine} does not run joint ranges ({', '.join(ranged)}): the port's support of "
                          "MuJoCo's tendon limits is not checked against the reduced reference")
    key = f"[{table}] timestep (--timestep)"
    h = settings.timestep if settings.timestep is not None else grid_timestep(scene, key=key)
    if not h <= scene.horizon:
        raise PortRefusal(f"{engine} timestep {h:g} s is longer than simulation.horizon {scene.horizon:g} s: set {key} "
                          "at most the horizon")
    settings = replace(settings, timestep=h)
    n = step_count(scene, h)
    if n > MAX_STEPS:
        raise PortRefusal(f"{engine} run of {n:.3g} steps (simulation.horizon {scene.horizon:g} s / timestep {h:g} s) "
                          f"exceeds the limit of {MAX_STEPS:.3g} steps: raise {key} or shorten simulation.horizon")
    spec = build_spec(scene, constraint=ConstraintSettings(settings.effective_solref, settings.solimp),
                      integrator=settings.integrator, timestep=h, iterations=settings.iterations,
                      tolerance=settings.tolerance, refsafe=settings.refsafe, diagexact=settings.diagexact)
    handles = compile_model(spec)
    model = handles.model
    need = 8 * (model.nq + model.nv + 1) * (n + 1)
    if need > MAX_STATE_BYTES:
        raise PortRefusal(f"{engine} run of {n:.3g} steps needs about {need / 1024 ** 3:.3g} GiB of states, more than "
                          f"{MAX_STATE_BYTES / 1024 ** 3:g} GiB: raise {key} or shorten simulation.horizon")
    check_joint_order(scene, model)
    port_model = compile_spec(spec)
    port_model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    layout = Layout.of(scene, model)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = layout.qpos0, layout.qvel0
    with mujoco_warnings() as said:
        initial = check_initial_state(scene, model, data, layout)
    said.report(f"{engine} on {scene.name}")
    ctrl, notes = control_sequence(scene, h, n)
    return PortRun(scene=scene, settings=settings, handles=handles, port_model=port_model, layout=layout,
                   data=data, initial=initial, ctrl=ctrl, edge_notes=tuple(notes))


def known_defects(run: PortRun, version: str, checked: str, defect: str) -> tuple[str, ...]:
    """A port's known defect of the loop constraints (``defect``, one line) as the caveat of a
    run of a scene with loops, while the port's ``version`` is at most ``checked``, the newest
    release found to have it (a later one is not assumed to); else none."""
    if run.scene.mechanism.linkage.cut_joints and release(version) <= release(checked):
        return (defect,)
    return ()


def finish(run: PortRun, qpos: np.ndarray, qvel: np.ndarray, *, name: str, engine: str, wall_s: float,
           evaluations_per_step: int, details: Any, caveats: tuple[str, ...] = ()) -> EngineResult:
    """The EngineResult of a port's run: ``qpos``, ``qvel`` (n_steps, nq) and (n_steps, nv) after
    every step, read by MuJoCo C (:func:`record_run`) and gated on the loop gap and the energy
    balance. ``name``: the engine's registry name ("mjx"); ``engine``: its name in messages.

    Raises
    ------
    NumericalFailure
        NON_FINITE: a NaN or infinite state; CONSTRAINT_DRIFT, ENERGY_IMBALANCE: beyond the
        settings' bounds.
    """
    model, h = run.handles.model, run.timestep
    bad = ~(np.all(np.isfinite(qpos), axis=1) & np.all(np.isfinite(qvel), axis=1))
    if np.any(bad):
        k = int(np.argmax(bad))
        raise NumericalFailure(FailureReason.NON_FINITE, f"{engine}'s state became NaN or infinite at step {k + 1} "
                               f"(t = {(k + 1) * h:.6g} s)", (k + 1) * h)
    state0 = np.empty(mujoco.mj_stateSize(model, STATE))
    mujoco.mj_getState(model, run.data, state0, STATE)
    states = np.tile(state0, (len(qpos) + 1, 1))
    states[1:, 0] = h * np.arange(1, len(qpos) + 1)  # the step grid's times, as MuJoCo's rollout counts them
    states[1:, 1:1 + model.nq] = qpos
    states[1:, 1 + model.nq:1 + model.nq + model.nv] = qvel
    for note in run.edge_notes:
        warnings.warn(note, UserWarning, stacklevel=3)
    timed = np.zeros((len(qpos), 0))
    with mujoco_warnings() as said:
        record = record_run(run.scene, run.handles, run.layout, run.data, states, None, run.ctrl, timed, h=h,
                            engine=engine)
    said.report(f"{engine} on {run.scene.name}")
    s = run.settings
    result = EngineResult(engine=name, trajectory=record.trajectory, joints=record.joints,
                          peak=record.trajectory.peak_rate(), audit=record.audit, wall_s=wall_s, n_steps=len(qpos),
                          n_evaluations=len(qpos) * evaluations_per_step, settings=s,
                          effects=tuple(run.scene.effects), constraint_violation=record.constraint_violation,
                          details=details, caveats=caveats,
                          other_inputs=tuple((trajectory, trajectory.peak_rate())
                                             for *_, trajectory in record.other_inputs))
    # a failed gate carries the run and its known defects (NumericalFailure.partial)
    return with_partial(lambda: record.gate(s.max_constraint_violation, s.max_energy_residual, run.initial, engine),
                        result)


def stack_runs(runs: list[PortRun], engine: str) -> None:
    """PortRefusal unless ``runs`` (a batch) share one model structure and step count: a port
    batches values, not shapes."""
    first = runs[0]
    m0 = model_structure(first.port_model)
    for k, run in enumerate(runs[1:], start=1):
        if model_structure(run.port_model) != m0 or run.n_steps != first.n_steps:
            raise PortRefusal(f"{engine} batches variants of one model: scene {k} ({run.scene.name}) has another "
                              f"structure or step count than scene 0 ({first.scene.name})")


def model_structure(m: mujoco.MjModel) -> tuple:
    """What a port's compile depends on in a model (its sizes and integrator), not its values:
    the models of one batch share it (:func:`stack_runs`)."""
    return (m.nq, m.nv, m.nu, m.nbody, m.njnt, m.neq, m.ntendon, m.nwrap, m.nsite, m.ngeom, int(m.opt.integrator))


def prepared(scenes: list[Scene], make, each: bool) -> tuple[list, list[tuple[int, PortRun]]]:
    """A batch's runs made by ``make(scene)`` (:func:`prepare`), with their scenes' indices, and a
    list of outcomes by scene: with ``each``, a scene that ``make`` refuses has its exception there
    (the others still run); without, the first refusal is raised."""
    outcomes: list = [None] * len(scenes)
    runs: list[tuple[int, PortRun]] = []
    for k, scene in enumerate(scenes):
        try:
            runs.append((k, make(scene)))
        except Exception as exc:  # noqa: BLE001 - this variant's own outcome
            if not each:
                raise
            outcomes[k] = exc
    return outcomes, runs


def finished(make, each: bool):
    """``make()`` (a variant's :func:`finish`), or with ``each`` the exception it raises."""
    if not each:
        return make()
    try:
        return make()
    except Exception as exc:  # noqa: BLE001 - this variant's own outcome
        return exc


def states_limit(run: PortRun, itemsize: int, device_bytes: int | None) -> int:
    """The most variants of ``run``'s structure one batch holds: the host's
    :data:`MAX_STATE_BYTES` over a variant's states read back (float64, nq + nv per step), and on
    a device of ``device_bytes`` (None: the host is the device) half of it over a variant's
    states there (``itemsize`` bytes per number). At least 1."""
    m = run.port_model
    numbers = (m.nq + m.nv) * (run.n_steps + 1)
    limit = MAX_STATE_BYTES // (8 * numbers)
    if device_bytes:
        limit = min(limit, int(device_bytes) // 2 // (itemsize * numbers))
    return max(1, limit)
