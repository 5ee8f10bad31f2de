"""Run a scene's MuJoCo model and return an :class:`EngineResult`.

The step loop runs in C (``mujoco.rollout``); Python only builds the control sequence before
and reads sensors and states after. A scene with point forces is stepped by a Python loop of
``mj_step`` instead, with the forces applied through ``mjcb_control`` at every integrator stage
(:func:`point_force_callback`). Every run is gated on its own diagnostics: the initial state
against MuJoCo's own residuals of every loop constraint (position and velocity), MuJoCo's
warnings (bad qacc and the like, which make ``mj_step`` reset the state), a non-finite state, a
trajectory that stops short of the horizon, the largest loop-closure violation (over the cut
joints, the gap between the joint's two sites), and an energy audit from MuJoCo's own body
velocities and positions (sensors read inside the run). Without an explicit timestep the step
is chosen from the scene and confirmed by step halving (:func:`simulate_mujoco`).

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
from xval.results import ConstraintViolation, EnergyAudit, EngineResult
from xval import kinematics as loops
from xval.loads import TabulatedForce
from xval.mechanism import PrismaticJoint
from xval.scene import Scene
from xval.trajectory import Trajectory

from .settings import MujocoSettings
from .build import (INPUT_MOTOR, INTEGRATOR_ENUM, ConstraintSettings, ModelHandles, build_spec, check_joint_order,
                    compile_model, coordinate_map, initial_qpos_qvel, mjcf_from_spec, set_timestep,
                    sensor_name, site_name)

_log = logging.getLogger("xval.mujoco")  # progress of the automatic step search

# Automatic timestep: the first candidate is the largest step ≤ TIMESTEP_CEILING (and ≤ 1/100
# of the horizon, and not below TIMESTEP_FLOOR) that puts every load edge on the step grid; a
# run at h and one at h/2 must differ by at most HALVING_FRACTION of the tolerances. The first
# failing check halves h; after two, the search jumps to the halving of the first step that the
# fitted order predicts (with the margin STEP_MARGIN), and it stops only when a check would take
# it past MAX_SEARCH_STEPS steps in all (a Stephenson six-bar near its toggle needs 7.8e-6 s, a
# check of 96 000 steps).
TIMESTEP_CEILING = 1e-3  # s
TIMESTEP_FLOOR = 1e-5  # s: the first candidate's
MIN_AUTO_STEPS = 100
HALVING_FRACTION = 0.25
STEP_MARGIN = 0.85
MIN_ORDER = 0.5
MAX_SEARCH_STEPS = 5_000_000
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

    An automatic timestep builds at the first candidate of :func:`grid_timestep` (the step
    halving happens only in a run; :func:`mjcf_text` exports the step a run chooses).
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


def grid_timestep(scene: Scene, ceiling: float = TIMESTEP_CEILING) -> float:
    """The largest step h ≤ min(ceiling, horizon/MIN_AUTO_STEPS) that puts every load edge
    inside the horizon on the step grid (edge/h integral to 1e-9), in s.

    Raises ValueError naming ``simulation.horizon`` when that bound is below TIMESTEP_FLOOR.
    Without such a step down to TIMESTEP_FLOOR (edges with no common divisor there), the bound
    itself is returned and the edges stay off the grid (the run warns and the halving check
    judges the consequence).
    """
    h_max = min(ceiling, scene.horizon / MIN_AUTO_STEPS)
    if h_max < TIMESTEP_FLOOR:
        raise ValueError(f"simulation.horizon {scene.horizon:g} s is too short for an automatic MuJoCo timestep "
                         f"({MIN_AUTO_STEPS} steps of at least {TIMESTEP_FLOOR:g} s): lengthen it or set "
                         "[mujoco] timestep (--timestep)")
    edges = [e for e in scene.load_edges if 0.0 < e < scene.horizon]
    if not edges:
        return h_max
    first = edges[0]
    for n in range(math.ceil(first / h_max - 1e-9), math.floor(first / TIMESTEP_FLOOR) + 1):
        h = first / n
        if h <= h_max * (1 + 1e-12) and all(abs(e / h - round(e / h)) <= 1e-9 for e in edges):
            return h
    return h_max


def control_sequence(scene: Scene, timestep: float, n_steps: int) -> tuple[np.ndarray, list[str]]:
    """Motor control for each step, shape (n_steps, nu): T at the step's midpoint t_k + h/2,
    so a load edge inside a step is applied at the nearest step boundary.

    Returns the controls and one warning per load edge that falls inside a step.
    """
    notes = []
    for edge in scene.load_edges:  # the input's and the timed forces' (timed_values)
        k = edge / timestep
        if 0.0 < edge < scene.horizon and abs(k - round(k)) > 1e-6:
            notes.append(f"load edge at t = {edge:g} s is not a multiple of the timestep {timestep:g} s: "
                         f"the jump is applied at t = {round(k) * timestep:g} s, up to "
                         f"{0.5 * timestep:g} s late or early")
    if scene.load is None:
        return np.zeros((n_steps, 0)), notes
    starts = np.arange(n_steps) * timestep
    return scene.load.sample(starts + 0.5 * timestep)[:, None], notes


def timed_values(scene: Scene, timestep: float, n_steps: int) -> np.ndarray:
    """Each timed force's value over each step (n_steps, timed forces), N: F(t) at the step's
    midpoint, as :func:`control_sequence` samples the input load (an edge on the step grid is
    applied exactly there)."""
    mid = np.arange(n_steps) * timestep + 0.5 * timestep
    return np.array([f.profile.sample(mid) for f in scene.mechanism.timed_forces], dtype=float).reshape(-1, n_steps).T


def _n_steps(scene: Scene, h: float) -> int:
    return int(math.ceil(scene.horizon / h - 1e-9))


def _check_work(scene: Scene, h: float, model: mujoco.MjModel | None = None) -> int:
    """Refuse a run of less than one step, or of more steps or memory than the limits.

    Returns the number of steps.
    """
    flag = "[mujoco] timestep (--timestep)"
    if not h <= scene.horizon:
        raise ValueError(f"MuJoCo timestep {h:g} s is longer than simulation.horizon {scene.horizon:g} s: "
                         f"set {flag} at most the horizon")
    n = _n_steps(scene, h)
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

    With an explicit ``settings.timestep`` the run uses it as given. With ``timestep=None``
    (the default) the step is chosen from the scene: the first candidate puts every load edge
    on the step grid (:func:`grid_timestep`); runs at h and h/2 are compared on h's grid and h
    is accepted when max |Δq|, max |Δω| and |Δ peak| are at most HALVING_FRACTION of the
    scene's q_atol, omega_atol and peak tolerance (for RK4 the difference estimates the
    coarser run's error, and the finer run is returned), else h is halved, or, after two
    checks, cut to the halving the observed order predicts (:func:`_predicted_step`), while the
    search's steps stay within MAX_SEARCH_STEPS; each failed check is logged on the
    ``xval.mujoco`` logger (INFO) as progress. ``result.settings`` have the step used;
    ``result.details`` (:class:`MujocoDetails`) say whether it was chosen, the halving evidence
    (per check the coarse step and the differences against their limits) and the runs, steps
    and rollout wall time the choice took. With ``handles`` (e.g. from an exported MJCF file)
    an automatic timestep is the model's own, and every other option must match the model.

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
    """The automatic step search of :func:`simulate_mujoco` (its docstring says the rule)."""
    tol = scene.tolerances
    h0 = grid_timestep(scene)
    evidence: list[dict] = []
    first = build_model(scene, replace(settings, timestep=h0))
    shape = first.model  # for the memory estimate
    _check_work(scene, h0, shape)
    layout = _Layout.of(scene, shape)  # the same for every timestep's model
    data = mujoco.MjData(shape)  # and so is the MjData, reset for each run
    runs: list[EngineResult | NumericalFailure] = []

    def attempt(h: float) -> EngineResult | NumericalFailure:
        step_settings = replace(settings, timestep=h)
        handles = first if h == h0 else _at_timestep(first, scene, step_settings)
        runs.append(_attempt(scene, step_settings, handles, layout, data))
        return runs[-1]

    h = h0
    coarse = attempt(h)
    while True:
        if not _within_limits(scene, h / 2, shape) or _search_steps(runs) + _n_steps(scene, h / 2) > MAX_SEARCH_STEPS:
            raise _search_failure(scene, coarse, evidence, runs, h, None)
        fine = attempt(h / 2)
        record = _check(scene, tol, h, coarse, fine)
        _confirm_after_failure(evidence, record)
        evidence.append(record)
        if record["accepted"]:
            done = [r for r in runs if isinstance(r, EngineResult)]
            cost = SearchCost(len(runs), sum(r.n_steps for r in done), sum(r.wall_s for r in done))
            return replace(fine, details=replace(fine.details, timestep_automatic=True,
                                                 timestep_checks=tuple(evidence), search_cost=cost))
        wanted = _predicted_step(evidence)
        # the next check's coarse step: the largest halving of h0 at or below the prediction
        # (load edges stay on the grid), and at least one halving finer than this check's
        halvings = max(round(math.log2(h0 / h)) + 1,
                       math.ceil(math.log2(h0 / wanted) - 1e-9) if wanted is not None else 0)
        step = h0 / 2 ** halvings
        needed = _n_steps(scene, step) * (3 if step < h / 2 else 2)  # a new coarse run too, or the fine one reused
        if (not _within_limits(scene, step / 2, shape)
                or _search_steps(runs) + needed > MAX_SEARCH_STEPS):
            raise _search_failure(scene, coarse if step == h / 2 else fine, evidence, runs, h, wanted)
        _log.info("MuJoCo timestep %.4g s against %.4g s: %s; %s", h, h / 2, _describe(record),
                  f"next check at {step:.4g} s ({_n_steps(scene, step / 2):,} steps)"
                  + (f", from the fitted order {record['order']:.2g}" if record.get("order") else ""))
        coarse, h = (fine, h / 2) if step == h / 2 else (attempt(step), step)


def _check(scene: Scene, tol, h: float, coarse, fine) -> dict:
    """The record of one check: runs at h and h/2 compared against HALVING_FRACTION of the
    tolerances (or the failure of either run)."""
    record = {"timestep": h, "unit": scene.input_unit}
    if isinstance(coarse, NumericalFailure) or isinstance(fine, NumericalFailure):
        failed = coarse if isinstance(coarse, NumericalFailure) else fine
        record.update(failure=f"{failed.reason.value}: {failed}", accepted=False)
        return record
    dq, dw, dpeak = _halving_difference(coarse, fine)
    limits = [HALVING_FRACTION * tol.q_atol, HALVING_FRACTION * tol.omega_atol,
              HALVING_FRACTION * tol.peak_bound(abs(fine.peak.omega))]
    record.update(max_dq=dq, max_domega=dw, dpeak=dpeak, limits=limits,
                  accepted=all(d <= lim for d, lim in zip((dq, dw, dpeak), limits)))
    return record


def _confirm_after_failure(evidence: list[dict], record: dict) -> None:
    """A check that meets its limits right after a check whose run failed (loop drift, energy
    imbalance, instability) is not accepted alone: its coarse step is at the edge of where
    MuJoCo's run works, where the differences of one halving need not fall as the step does
    (measured on a fast crank: 1.25e-4 s against 6.25e-5 s differ by < 0.125 rad/s while each
    is 1.6 rad/s off the converged run, and 6.25e-5 s against 3.125e-5 s by 1.2 rad/s). Such a
    record is marked ``unconfirmed`` and the search halves once more: the next check, measured
    after a measured one, is accepted on its own limits."""
    if record.get("accepted") and evidence and "failure" in evidence[-1]:
        record.update(accepted=False, unconfirmed=True)


def _predicted_step(evidence: list[dict]) -> float | None:
    """The coarse step (s) at which the differences would meet their limits, from the last two
    checks: each difference falls as h^p with the order p fitted between them (the loop's
    softness follows the step, so p is not RK4's 4: measured 1.9–4 on the six-bars). None
    before two measured checks, or when no difference falls (p < MIN_ORDER): then the search
    halves. The prediction is taken with the margin STEP_MARGIN."""
    measured = [r for r in evidence if "max_dq" in r]
    if len(measured) < 2 or measured[-1] is not evidence[-1]:
        return None
    prev, last = measured[-2], measured[-1]
    keys = ("max_dq", "max_domega", "dpeak")
    steps, orders = [], []
    for k, key in enumerate(keys):
        d1, d2, limit = prev[key], last[key], last["limits"][k]
        if d2 <= limit:
            continue
        if not (d1 > 0.0 and d2 > 0.0 and d1 > d2):
            return None
        p = math.log(d1 / d2) / math.log(prev["timestep"] / last["timestep"])
        if p < MIN_ORDER:
            return None
        orders.append(p)
        steps.append(last["timestep"] * (limit / d2) ** (1.0 / p))
    if not steps:
        return None
    last["order"] = min(orders)
    return STEP_MARGIN * min(steps)


def _search_steps(runs) -> int:
    """Steps the search has taken so far (a failed run counts its whole grid)."""
    return sum(r.n_steps if isinstance(r, EngineResult) else 0 for r in runs)


def _search_failure(scene: Scene, coarse, evidence: list[dict], runs, h: float,
                    wanted: float | None) -> NumericalFailure:
    """Why the automatic search stops at coarse step h: the step the tolerances need (when
    fitted) and its cost against the work limits."""
    if isinstance(coarse, NumericalFailure) and not evidence:
        return NumericalFailure(coarse.reason, f"{coarse} (at the first automatic MuJoCo timestep {h:g} s)",
                                coarse.time)
    last = evidence[-1] if evidence else {"timestep": h}
    done = [r for r in runs if isinstance(r, EngineResult) and r.n_steps]
    rate = sum(r.wall_s for r in done) / sum(r.n_steps for r in done) if done else None
    if wanted is not None:
        n = _n_steps(scene, wanted / 2)
        cost = f", about {n * 3 / 2 * rate:.2g} s here" if rate else ""
        need = (f"the tolerances need a step of about {wanted:.2g} s (order {last.get('order', 0):.2g} fitted "
                f"from the last two checks): a check of {n * 3 // 2:,} steps{cost}, beyond the search's "
                f"work limit of {MAX_SEARCH_STEPS:,} steps")
    else:
        need = f"a finer check would exceed the search's work limit of {MAX_SEARCH_STEPS:,} steps"
    return NumericalFailure(FailureReason.INACCURATE,
                            f"no automatic MuJoCo timestep meets the tolerances: {need} (last check, "
                            f"h = {last['timestep']:g} s against h/2: {_describe(last)}); set [mujoco] timestep "
                            "(--timestep) or loosen [tolerances] (--q-atol, --omega-atol, --peak-rtol)")


def _describe(record: dict) -> str:
    if "failure" in record:
        return record["failure"]
    if "max_dq" not in record:
        return "not run"
    unit = record.get("unit", "rad")  # the input coordinate's: rad or m
    return (f"max |Δq| {record['max_dq']:.3g} {unit}, max |Δω| {record['max_domega']:.3g} {unit}/s, "
            f"|Δ peak| {record['dpeak']:.3g} {unit}/s against limits {', '.join(f'{v:.3g}' for v in record['limits'])}"
            + (", within them but after a failed coarser run: to be confirmed at h/2" if record.get("unconfirmed") else ""))


def _attempt(scene: Scene, settings: MujocoSettings, handles: ModelHandles, layout: "_Layout",
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


def _halving_difference(coarse: EngineResult, fine: EngineResult) -> tuple[float, float, float]:
    """max |Δq|, max |Δω| on the coarse grid (every second fine state) and |Δ peak ω|."""
    qc, wc = coarse.details.grid_q, coarse.details.grid_qdot
    qf, wf = fine.details.grid_q[::2], fine.details.grid_qdot[::2]
    n = min(len(qc), len(qf))
    return (float(np.max(np.abs(qc[:n] - qf[:n]))), float(np.max(np.abs(wc[:n] - wf[:n]))),
            abs(coarse.peak.omega - fine.peak.omega))


def _run(scene: Scene, settings: MujocoSettings, handles: ModelHandles,
         layout: _Layout | None = None, data: mujoco.MjData | None = None) -> EngineResult:
    """One run at the settings' explicit timestep, gated on its diagnostics.

    Without point forces the step loop is ``mujoco.rollout`` (in C); with them it is a Python
    loop of ``mj_step`` with :func:`point_force_callback` installed as ``mjcb_control``.
    ``layout``: the scene's :class:`_Layout` if the caller has it (made here otherwise).
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
        layout = _Layout.of(scene, model)

    timed = timed_values(scene, h, n_steps)
    with _point_forces_installed(scene, model, layout) as callback:
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
            violation = np.maximum(violation, np.sqrt(_squares_by_row(gap)))
        qddot = _input_acceleration(model, data, handles, layout, states, sensors, ctrl, spec, timed, callback)
        trajectory = _with_edge_samples(model, data, times, q, qdot, qddot, states, ctrl, handles, layout, spec,
                                        timed, callback)
    max_violation = float(np.max(violation))
    if not math.isfinite(max_violation) or max_violation > settings.max_constraint_violation:
        k = int(np.argmax(np.nan_to_num(violation, nan=np.inf)))
        raise NumericalFailure(FailureReason.CONSTRAINT_DRIFT, f"loop-closure violation {violation[k]:.3g} m at "
                               f"t = {times[k]:.6g} s exceeds {settings.max_constraint_violation:g} m",
                               float(times[k]))

    audit = _energy_audit(scene, model, handles, layout, times, states, sensors, ctrl, q, timed)
    residual = np.abs(audit.residual)
    # A run in which almost nothing moves is judged against at least ½ 𝔍0 (1 unit/s)², never
    # against an energy scale made of round-off (the reduced engine uses the same floor).
    scale = max(audit.scale, 0.5 * initial["unit_rate_inertia"])
    if not audit.max_abs_residual <= settings.max_energy_residual * scale:
        k = int(np.argmax(np.nan_to_num(residual, nan=np.inf)))
        raise NumericalFailure(FailureReason.ENERGY_IMBALANCE,
                               f"MuJoCo's energy balance is off by {residual[k]:.3g} J at t = {times[k]:.6g} s, "
                               f"{residual[k] / scale:.3g} of the energy scale {scale:.6g} J, above "
                               f"max_energy_residual {settings.max_energy_residual:g}", float(times[k]))
    key = sensor_name(INPUT_MOTOR, "force")
    motor = sensors[:, sl[key]][:, 0] if key in sl else np.zeros(len(times))
    details = MujocoDetails(grid_q=q, grid_qdot=qdot.copy(), input_load=motor, initial_residuals=initial,
                            edge_warnings=tuple(edge_notes), mujoco_version=mujoco.__version__,
                            point_forces="mjcb_control (qfrc_applied, every RK stage)"
                            if scene.mechanism.point_forces or scene.mechanism.timed_forces else None)
    return EngineResult(
        engine="mujoco", trajectory=trajectory, joints=_joint_trajectory(layout, times, x, xdot),
        peak=trajectory.peak_angular_velocity(), audit=audit, wall_s=wall, n_steps=n_steps,
        n_evaluations=n_steps * (4 if settings.integrator == "rk4" else 1), settings=settings,
        effects=tuple(scene.effects), constraint_violation=ConstraintViolation(times, violation), details=details)


@dataclass(frozen=True)
class SearchCost:
    """What the automatic timestep's choice took: its runs, their steps and rollout time (s)."""

    runs: int
    steps: int
    wall_s: float


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
    timestep_checks : that search's checks, in order: per check the coarse step and the
        differences against their limits, or the failure (``_check``'s records).
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
    timestep_checks: tuple[Mapping[str, Any], ...] = ()
    search_cost: SearchCost | None = None

    def as_dict(self) -> dict:
        return {"mujoco_version": self.mujoco_version, "timestep_automatic": self.timestep_automatic,
                "timestep_check": list(self.timestep_checks),
                "automatic_timestep_cost": None if self.search_cost is None else asdict(self.search_cost),
                "edge_warnings": list(self.edge_warnings), "point_forces": self.point_forces,
                "initial_residuals": dict(self.initial_residuals)}


@dataclass(frozen=True)
class _Layout:
    """How MuJoCo's qpos/qvel map to the scene's coordinates (:func:`build.coordinate_map`),
    and the rest of what a run takes from the scene alone (made once for all the runs of a
    scene's model, whatever their timestep).

    x0 (n,), T (n, nq): x = x0 + T qpos; drive (n,): q = drive·x; input_dof: the input
    joint's dof; input_hinge: whether it is a hinge (else a slide); qpos0, qvel0: the initial
    state (:func:`build.initial_qpos_qvel`); size: the mechanism's size (m,
    :func:`_mechanism_size`).
    """

    system: loops.LoopSystem
    x0: np.ndarray
    T: np.ndarray
    input_dof: int
    input_hinge: bool
    input_body: str
    input_parent: str
    qpos0: np.ndarray
    qvel0: np.ndarray
    size: float

    @staticmethod
    def of(scene: Scene, model: mujoco.MjModel) -> "_Layout":
        linkage = scene.mechanism.linkage
        system = loops.compile_linkage(linkage)
        x0, T = coordinate_map(scene)
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, linkage.input_joint)
        edge = next(e for e in linkage.tree if e.joint == linkage.input_joint)
        return _Layout(system, x0, T, int(model.jnt_dofadr[joint]),
                       not isinstance(linkage.joint_map[linkage.input_joint], PrismaticJoint), edge.body, edge.parent,
                       *initial_qpos_qvel(scene), _mechanism_size(scene))

    def x(self, qpos: np.ndarray) -> np.ndarray:
        return self.x0 + np.atleast_2d(qpos) @ self.T.T

    def xdot(self, qvel: np.ndarray) -> np.ndarray:
        return np.atleast_2d(qvel) @ self.T.T

    @property
    def input_row(self) -> np.ndarray:
        """(nq,) the input coordinate's rate from qvel: q̇ = input_row·qvel."""
        return self.system.drive @ self.T


def point_force_callback(scene: Scene, model: mujoco.MjModel, layout: "_Layout"):
    """The ``mjcb_control`` callback that applies the scene's point forces, or None without any.

    How: MuJoCo calls ``mjcb_control`` in every ``mj_forward`` after the position and velocity
    stages, before actuation and acceleration, so also in each of RK4's four stages at that
    stage's state. The callback sets ``qfrc_applied`` = Σ J_pᵀ F(q) u (J_p the site's
    translational Jacobian ``mj_jacSite``, u the force's fixed ground direction, q the input
    coordinate from that stage's qpos): the force is exactly F(q(t)) at every stage, so RK4
    keeps its order. Scenes with point forces are stepped by a Python loop of ``mj_step``
    (:func:`_step_loop`) rather than ``mujoco.rollout``: single-threaded rollout does call a
    Python ``mjcb_control`` (measured with MuJoCo 4.0.1: 1600 calls in 400 RK4 steps, states
    identical to the loop's) but the documented callback contract does not cover its threads, and
    the callback (~65 µs, mostly the spline) dominates either way.
    """
    def site_of(force, what):
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name(force.body, force.point))
        if site < 0:
            raise ValueError(f"the model has no site {site_name(force.body, force.point)!r} for {what} {force.name!r}")
        return site, np.array([math.cos(force.direction), math.sin(force.direction), 0.0])

    forces = [(TabulatedForce(pf.coordinate, pf.values, pf.period), *site_of(pf, "point force"))
              for pf in scene.mechanism.point_forces]
    timed = [site_of(tf, "timed force") for tf in scene.mechanism.timed_forces]
    if not forces and not timed:
        return None
    q0 = float(layout.system.drive @ layout.x0)
    row = layout.input_row
    jac = np.zeros((3, model.nv))
    step_values = np.zeros(len(timed))  # the timed forces' values over the current step

    def callback(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        q = q0 + float(row @ d.qpos)
        total = np.zeros(m.nv)
        for force, site, u in forces:
            mujoco.mj_jacSite(m, d, jac, None, site)
            total += float(force(q)) * (u @ jac)
        for value, (site, u) in zip(step_values, timed):
            mujoco.mj_jacSite(m, d, jac, None, site)
            total += float(value) * (u @ jac)
        d.qfrc_applied[:] = total

    callback.step_values = step_values  # set by the step loop before each step (timed_values)
    return callback


@contextlib.contextmanager
def _point_forces_installed(scene: Scene, model: mujoco.MjModel, layout: "_Layout"):
    """Install :func:`point_force_callback` for the block; yields it (None without point forces)."""
    callback = point_force_callback(scene, model, layout)
    if callback is None:
        yield None
        return
    previous = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(callback)
    try:
        yield callback
    finally:
        mujoco.set_mjcb_control(previous)


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


def _mechanism_size(scene: Scene) -> float:
    """The largest distance between two named points at x0 (m): the mechanism's size."""
    system = loops.compile_linkage(scene.mechanism.linkage)
    p = loops.positions(system.points, np.asarray(scene.x0, dtype=float))
    return float(np.max(np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)))


def check_initial_state(scene: Scene, model: mujoco.MjModel, data: mujoco.MjData,
                        layout: "_Layout | None" = None) -> dict:
    """MuJoCo's own loop residuals at the state in ``data``; NumericalFailure if above round-off.

    After mj_forward, the equality rows of ``efc_pos`` are the gaps of every connect (m) and
    of ``efc_vel`` = J q̇ their rates (m/s); the position residual also counts how far each
    connect's anchor on body2 (MuJoCo's, computed at qpos0) is from the cut joint's point_b. Bounds: INITIAL_RESIDUAL_REL × the mechanism's size
    (the largest distance between two of its points at x0), and × the largest point speed
    scale (size × largest hinge rate, or largest slide rate). ``layout``: the scene's
    :class:`_Layout` if the caller has it (made here otherwise).
    """
    if layout is None:
        layout = _Layout.of(scene, model)
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


def _joint_trajectory(layout: _Layout, times, x, xdot) -> JointTrajectory:
    """MuJoCo's general coordinates and rates (from its qpos and qvel: :meth:`_Layout.x`,
    :meth:`_Layout.xdot`), with the assembly mode of each sample."""
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


def _squares_by_row(v: np.ndarray) -> np.ndarray:
    """Σ_j v[:, j]² of each row of v (samples, 3), the columns added in order: the same sums as
    ``np.sum(v * v, axis=1)`` (and ``np.linalg.norm(v, axis=1)²``), without numpy's slow
    reduction along a short row."""
    total = v[:, 0] * v[:, 0]
    for j in range(1, v.shape[1]):
        total = total + v[:, j] * v[:, j]
    return total


def _cumulative_trapezoid(power: np.ndarray, dt: np.ndarray) -> np.ndarray:
    return np.concatenate([np.zeros(1), np.cumsum(0.5 * (power[:-1] + power[1:]) * dt)])


def _energy_audit(scene, model, handles, layout, times, states, sensors, ctrl, q, timed) -> EnergyAudit:
    """The energy balance from MuJoCo's own quantities at every stored state.

    Kinetic Σ ½ m |v_G|² + ½ I_zz ω_z² over every moving body and potential −Σ m g·r_G +
    Σ ½ k (l − l0)² over every spring tendon, from the body and tendon sensors with the model's
    masses, inertias, stiffnesses (kinetic energy agrees with ½ q̇ᵀM q̇); the work of the motor
    ∫ u q̇_input dt (the input joint's rate; the control is constant within each step) plus the
    work of the point forces ∫ Σ F(q) u·v_p dt and of the timed forces ∫ Σ F(t) u·v_p dt (F held
    over each step, ``timed`` (steps, forces); in ``torque_work``: the work of the external
    loads), and the damper dissipation ∫ Σ b l̇² dt, by the trapezoid rule.
    """
    sl = handles.sensor_slices
    n = len(times)
    kinetic, potential = np.zeros(n), np.zeros(n)
    gravity = model.opt.gravity
    for name in scene.mechanism.linkage.moving:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        mass, izz = model.body_mass[body], model.body_inertia[body, 2]
        v, w = sensors[:, sl[sensor_name(name, "com_vel")]], sensors[:, sl[sensor_name(name, "ang_vel")]]
        kinetic += 0.5 * mass * _squares_by_row(v) + 0.5 * izz * w[:, 2] ** 2
        potential -= mass * sensors[:, sl[sensor_name(name, "com_pos")]] @ gravity
    for tendon in range(model.ntendon):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, tendon)
        if sensor_name(name, "length") in sl:
            stretch = sensors[:, sl[sensor_name(name, "length")]][:, 0] - model.tendon_lengthspring[tendon, 0]
            potential += 0.5 * model.tendon_stiffness[tendon] * stretch * stretch
    dt = np.diff(times)
    zero = np.zeros(1)
    if model.nu:
        rate = states[:, 1 + model.nq + layout.input_dof]
        power_dt = ctrl[:, 0] * 0.5 * (rate[:-1] + rate[1:]) * dt
        load_work = np.concatenate([zero, np.cumsum(power_dt)])
    else:
        load_work = np.zeros(n)
    if scene.mechanism.point_forces:
        power = np.zeros(n)
        for pf in scene.mechanism.point_forces:
            u = np.array([math.cos(pf.direction), math.sin(pf.direction), 0.0])
            force = TabulatedForce(pf.coordinate, pf.values, pf.period)
            power += np.asarray(force(q), dtype=float) * (sensors[:, sl[sensor_name(pf.name, "vel")]] @ u)
        load_work = load_work + _cumulative_trapezoid(power, dt)
    for k, tf in enumerate(scene.mechanism.timed_forces):  # F constant over each step (timed_values)
        u = np.array([math.cos(tf.direction), math.sin(tf.direction), 0.0])
        along = sensors[:, sl[sensor_name(tf.name, "vel")]] @ u
        load_work = load_work + np.concatenate([zero, np.cumsum(timed[:, k] * 0.5 * (along[:-1] + along[1:]) * dt)])
    rate = np.zeros(n)
    for name in handles.damper_tendons:
        b = model.tendon_damping[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, name)]
        ldot = sensors[:, sl[sensor_name(name, "rate")]][:, 0]
        rate += b * ldot * ldot
    dissipation = np.concatenate([zero, np.cumsum(0.5 * (rate[:-1] + rate[1:]) * dt)])
    return EnergyAudit(t=times, kinetic=kinetic, potential=potential, torque_work=load_work,
                       damper_dissipation=dissipation)


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
