"""The reduced engine on a linkage of several degrees of freedom: Eksergian's equation in k
independent joint coordinates, with coordinate partitioning (issue 40).

    𝔍(q) q̈ + c(q, q̇) = Q(t, q, q̇),   q = R x (k of the joints' own coordinates)

The arithmetic is compiled (:class:`loopcheck.reduced.kernels.several.Several`, whose docstring
states the formulation: c by one extra solve with the actual rates, the conditioning of a set of
joints and the best set by pivoted QR). This module drives it: scipy's ``solve_ivp`` (DOP853, or
Radau) on y = (q, q̇, W, E) (W the work of the timed forces and actuators, E the dampers'
dissipation, integrated alongside for the energy audit), restarted at every load edge; a terminal
event on the chart's ``stop_margin`` switches the coordinates:

    switch when  c(current set) < HYSTERESIS · c(best set)

(c(best set): the kernel's pivoted-QR choice) at the event's root, to the best-conditioned of every
set of k joints (:func:`best_set`), with q, q̇ re-expressed from x, ẋ there (q' = R' x,
q̇' = R' ẋ); every switch is logged (:class:`loopcheck.reduced.charts.Switch`, the sets named by
their joints, "O1, O5"). A configuration where even the best set's conditioning is below
:data:`loopcheck.kinematics.SINGULAR_CONDITIONING` stops the run (NumericalFailure "singular"); an
integration that fails otherwise names its time and the conditionings there. The inputs are the
first set, kept at the start unless another is better by more than the hysteresis (then a switch
at t = 0 is logged).

Samples: the solver's steps, each cut into at least SAMPLES_PER_STEP parts no longer than the
sample interval (as the one-DOF scipy runs); at each, x, ẋ, ẍ from the chart, every input's
q = r·x, q̇ = r·ẋ, q̈ = r·ẍ (its joint row r), and the audit's T = ½ q̇ᵀ𝔍q̇, V, W, E.
``JointTrajectory.coordinate`` is −1 (a chart is a set of joints, not one coordinate: the switches
say which).

A joint range ends the run where the joint reaches a bound (NumericalFailure "range-reached", as the
one-DOF engine: a terminal event on the nearest bound's distance). Not yet supported with several
DOF (refused in one line before any work, :func:`check_scene`): joint friction, a forcerange clamp
on a state-dependent actuator force, point forces over q, a load on the first input alone
(``[torque]``), redundant loops; RKN4.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass

import numpy as np

from loopcheck import kinematics as loops
from loopcheck.errors import NumericalFailure
from loopcheck.mechanism import PrismaticJoint
from loopcheck.results import EnergyAudit
from loopcheck.scene import Scene, SceneError
from loopcheck.trajectory import JointTrajectory, Trajectory

from .charts import Switch
from .dynamics import build_arrays, clamped_actuators, piece_edges, ranged_joints
from .integrators import SAMPLES_PER_STEP, sample_parts
from .kernels import several as kernel
from .settings import ReducedSettings

HYSTERESIS = kernel.HYSTERESIS
MAX_SWITCHES = 10_000
# a switch chooses among every set of k joints up to this many sets (best_set)
MAX_CANDIDATES = 500
SCIPY_METHODS = {"dop853": "DOP853", "scipy-dop853": "DOP853", "radau": "Radau"}


def check_scene(scene: Scene, settings: ReducedSettings | None = None) -> None:
    """Refuse, in one line, what the several-DOF engine does not run yet (module docstring).

    Raises
    ------
    SceneError
        Naming the element; ValueError naming the method (RKN4).
    """
    mech = scene.mechanism
    where = f"scene '{scene.name}' ({scene.dof} degrees of freedom)"
    if mech.joint_frictions:
        raise SceneError(f"{where}: joint friction ({', '.join(e.name for e in mech.joint_frictions)}) is not "
                         "supported by the reduced engine with several inputs yet")
    clamped = clamped_actuators(mech)
    if clamped:
        raise SceneError(f"{where}: actuator {', '.join(repr(a.name) for a in clamped)} clamps a force that depends "
                         "on the state (forcerange with bias b1 or b2): not supported by the reduced engine with "
                         "several inputs yet")
    if mech.point_forces:
        raise SceneError(f"{where}: point forces over q are not supported with several inputs")
    if scene.load is not None:
        raise SceneError(f"{where}: a load on the input ([torque]/[force]) is not supported with several inputs: "
                         "use [[actuators]] on the joints")
    system = loops.compile_linkage(mech.linkage)
    rows = system.m + len(system.coupling_rows)  # the loops', the linear rows, the couplings
    if rows != system.n - scene.dof:
        raise SceneError(f"{where}: {rows} closure equations over {system.n} coordinates (a redundantly closed "
                         "loop): not supported by the reduced engine with several inputs yet")
    if settings is not None and settings.method not in SCIPY_METHODS:
        raise ValueError(f"the reduced engine's method {settings.method} does not run a scene of several degrees "
                         f"of freedom yet ({where}): use method dop853 or radau")


class SeveralModel:
    """A scene of several DOF as the compiled chart's arrays: the system, the inputs' joints."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.system = loops.compile_linkage(scene.mechanism.linkage)
        self.arrays = build_arrays(scene, self.system)
        self.k = scene.dof
        self.joint_names = self.system.joint_names
        self.inputs = np.array([self.joint_names.index(j) for j in scene.inputs], dtype=np.int64)
        self.input_rows = self.system.input_rows
        self.piece_edges = piece_edges(scene)
        self.angle_columns = np.array([name.endswith(".angle") for name in self.system.coordinate_names])
        self.ranged = ranged_joints(scene.mechanism.linkage)
        self.range_rows = np.array([self.system.joint_row(j.name) for j in self.ranged]).reshape(-1, self.system.n)
        self.range_bounds = np.array([j.range for j in self.ranged], dtype=float).reshape(-1, 2)

    def range_margins(self, x: np.ndarray) -> np.ndarray:
        """(ranged joints, 2): each ranged joint's u − lo and hi − u at x."""
        u = self.range_rows @ x
        return np.stack([u - self.range_bounds[:, 0], self.range_bounds[:, 1] - u], axis=1)

    def new_chart(self) -> kernel.Several:
        return kernel.Several(self.arrays.F, self.arrays.I, self.system.joint_rows, self.k,
                              loops.SINGULAR_CONDITIONING)

    def set_name(self, joints) -> str:
        return ", ".join(self.joint_names[int(j)] for j in joints)

    def piece(self, start: float, end: float) -> int:
        """The model's load piece holding [start, end] (its index)."""
        edges = self.piece_edges
        return int(min(max(np.searchsorted(edges, 0.5 * (start + end), side="right") - 1, 0), len(edges) - 2))


def start_chart(model: SeveralModel, joints, x: np.ndarray) -> kernel.Several:
    """A chart of ``joints`` started at the assembled x (NumericalFailure where they cannot drive it)."""
    chart = model.new_chart()
    if not chart.start(np.array(x, dtype=float), np.array(joints, dtype=np.int64)):
        raise NumericalFailure("singular", f"the joints {model.set_name(joints)} cannot drive the linkage at "
                               f"x = {np.round(x, 12).tolist()}")
    return chart


class _Record:
    """The samples of a run, appended chart by chart."""

    def __init__(self):
        self.t, self.x, self.xdot, self.xdd, self.V, self.T, self.W, self.E, self.sets = ([] for _ in range(9))


def _sample(model, chart, sol, start, end, load, sample_interval, record, joints_index):
    """The samples of one integrated piece: the solver's steps cut as the one-DOF runs cut them
    (:func:`loopcheck.reduced.integrators.dense_samples`), the chart walked again from the piece's
    start (:meth:`rewind`) and evaluated at each, in order."""
    k = model.k
    t0, t1 = sol.t[:-1], sol.t[1:]
    parts = sample_parts(t1 - t0, sample_interval, SAMPLES_PER_STEP)
    step = np.repeat(np.arange(len(t0)), parts - 1)
    j = np.arange(len(step)) - np.repeat(np.cumsum(parts - 1) - (parts - 1), parts - 1) + 1
    inner = t0[step] + (t1 - t0)[step] * (j / parts[step])
    times = np.union1d(sol.t, inner)
    times = times[(times >= start) & (times <= end)]
    states = sol.sol(times)
    states[:, np.searchsorted(times, sol.t)] = sol.y
    chart.rewind()
    obs = np.zeros((len(times), chart.observation_size()))
    a = np.zeros(k)
    kinetic = np.zeros(len(times))
    for r in range(len(times)):
        q = np.ascontiguousarray(states[:k, r])
        v = np.ascontiguousarray(states[k:2 * k, r])
        if chart.acceleration(load, float(times[r]), q, v, a) != 0:
            raise NumericalFailure("singular", f"the chart of {model.set_name(chart.current)} could not close the "
                                   f"loops at t = {times[r]:.6g} s", float(times[r]))
        chart.observe(obs, r)
        kinetic[r] = chart.kinetic(v)
    n = model.system.n
    record.t.append(times)
    record.x.append(obs[:, :n])
    record.xdot.append(obs[:, n:2 * n])
    record.xdd.append(obs[:, 2 * n:3 * n])
    record.V.append(obs[:, 3 * n])
    record.T.append(kinetic)
    record.W.append(states[2 * k])
    record.E.append(states[2 * k + 1])
    record.sets.append(np.full(len(times), joints_index))


def integrate(model: SeveralModel, settings: ReducedSettings):
    """The run from t = 0 to the horizon (module docstring): (record, switches, steps, evaluations,
    the initial 𝔍, the sets of joints charted in turn)."""
    from scipy.integrate import solve_ivp

    scene = model.scene
    k = model.k
    method = SCIPY_METHODS[settings.method]
    rtol = settings.rtol
    x = np.array(scene.x0, dtype=float)
    q0 = np.array(scene.initial_q(), dtype=float)
    if not np.allclose(model.input_rows @ x, q0, rtol=0.0, atol=1e-9):
        x = loops.assemble_inputs(model.system, q0, x)
    joints = model.inputs
    v0 = np.array(scene.initial_qdot(), dtype=float)
    chart = _first_chart(model, x)
    c_inputs = chart.conditioning_of(joints)
    best, c_best = best_set(model, chart)
    if max(c_inputs, c_best) < loops.SINGULAR_CONDITIONING:
        name = model.set_name(joints if c_inputs >= c_best else best)
        raise NumericalFailure("singular", f"no set of joints can drive the linkage at t = 0 s: the best ({name}) "
                               f"has conditioning {max(c_inputs, c_best):.3g}, below {loops.SINGULAR_CONDITIONING:g} "
                               "(a singular configuration of the mechanism)", 0.0)
    if c_inputs < loops.SINGULAR_CONDITIONING:
        raise NumericalFailure("singular", f"the inputs {model.set_name(joints)} cannot drive the linkage at t = 0 s "
                               f"(conditioning {c_inputs:.3g}), where their rates are given", 0.0)
    if tuple(int(j) for j in chart.current) != tuple(int(j) for j in joints):
        chart = start_chart(model, joints, x)
    switches = []
    y = np.concatenate([q0, v0, [0.0, 0.0]])
    if not chart.stop_margin(0.0, q0, v0) > 0.0:  # another set is clearly better at the start: logged at t = 0
        y, chart, joints = _switch(model, chart, 0.0, y, switches)
    J0 = np.array(chart.Jm)
    record = _Record()
    edges = [b for b in scene.load_edges if 0.0 < b < scene.horizon] + [scene.horizon]
    t, n_steps, n_eval, sets = 0.0, 0, 0, [tuple(int(j) for j in joints)]
    a = np.zeros(k)
    while t < scene.horizon:
        end = next(e for e in edges if e > t)
        load = model.piece(t, end)
        chart.mark()

        def fun(tt, yy, chart=chart, load=load):
            q = np.ascontiguousarray(yy[:k])
            v = np.ascontiguousarray(yy[k:2 * k])
            if chart.acceleration(load, tt, q, v, a) != 0:
                return np.full(2 * k + 2, np.nan)
            return np.concatenate([v, a, [chart.power(load, v), chart.dissipation(v)]])

        def event(tt, yy, chart=chart):
            return chart.stop_margin(tt, np.ascontiguousarray(yy[:k]), np.ascontiguousarray(yy[k:2 * k]))
        event.terminal, event.direction = True, -1
        events = [event]
        if len(model.ranged):
            def in_range(tt, yy, chart=chart):
                """> 0 while every ranged joint is inside its range: the nearest bound's distance."""
                if not chart.evaluate(np.ascontiguousarray(yy[:k])):
                    return math.nan
                return float(np.min(model.range_margins(np.asarray(chart.lastx))))
            in_range.terminal, in_range.direction = True, -1
            events.append(in_range)
        with np.errstate(invalid="ignore", over="ignore"):
            sol = solve_ivp(fun, (t, end), y, method=method, rtol=rtol, atol=rtol, dense_output=True,
                            events=events)
        if not sol.success:
            raise _failure(model, chart, sol, method, t, end, joints)
        n_steps += len(sol.t) - 1
        n_eval += sol.nfev
        stop = float(sol.t[-1])
        _sample(model, chart, sol, t, stop, load, settings.sample_interval, record, len(sets) - 1)
        y = sol.y[:, -1].copy()
        if sol.status == 1 and len(sol.t_events) > 1 and len(sol.t_events[1]):
            raise _range_reached(model, np.asarray(chart.lastx) if chart.evaluate(np.ascontiguousarray(y[:k]))
                                 else None, stop)
        if sol.status == 1:
            if len(switches) >= MAX_SWITCHES:
                raise NumericalFailure("singular", f"more than {MAX_SWITCHES} coordinate switches", stop)
            y, chart, joints = _switch(model, chart, stop, y, switches)
            sets.append(tuple(int(j) for j in joints))
        t = stop
    return record, switches, n_steps, n_eval, J0, sets


def _range_reached(model: SeveralModel, x, t: float) -> NumericalFailure:
    """The run's end where a joint reached a bound of its range (as the one-DOF engine ends it:
    :func:`loopcheck.reduced.charts.compiled_failure`)."""
    margins = model.range_margins(x) if x is not None else np.zeros((len(model.ranged), 2))
    r, side = np.unravel_index(int(np.argmin(margins)), margins.shape)
    joint = model.ranged[int(r)]
    unit = "m" if isinstance(joint, PrismaticJoint) else "rad"
    lo, hi = joint.range
    failure = NumericalFailure(
        "range-reached", f"joint {joint.name!r} reached the {'upper' if side else 'lower'} bound "
        f"{joint.range[int(side)]:.6g} {unit} of its range [{lo:.6g}, {hi:.6g}] {unit} at t = {t:.9g} s: the exact "
        "solution stops there (MuJoCo's joint limit would act from then on)", t)
    failure.joint = joint.name
    return failure


def _failure(model: SeveralModel, chart, sol, method: str, start: float, end: float, joints) -> NumericalFailure:
    """The failure of an integration that did not reach its piece's end: "singular" where the best set
    of joints at its last state is below SINGULAR_CONDITIONING (the configuration is a singular one
    of the mechanism, or the next one is), else the solver's own (step-size), each with its time and
    the conditioning there."""
    t = float(sol.t[-1])
    k = model.k
    y = sol.y[:, -1]
    chart.rewind()
    margin = chart.stop_margin(t, np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k]))
    if margin != margin:
        where = "where the loops could not be closed"
    else:
        best, c_best = best_set(model, chart)
        c_best = max(c_best, float(chart.c_current))
        where = (f"where the coordinates {model.set_name(joints)} have conditioning {chart.c_current:.3g} and the "
                 f"best set {c_best:.3g}")
        if c_best < loops.SINGULAR_CONDITIONING:
            return NumericalFailure("singular", f"no set of joints can drive the linkage at t = {t:.9g} s, {where}, "
                                    f"below {loops.SINGULAR_CONDITIONING:g}: a singular configuration of the mechanism",
                                    t)
    return NumericalFailure("step-size", f"{method} failed in [{start:.6g}, {end:.6g}] s at t = {t:.9g} s in the "
                            f"coordinates {model.set_name(joints)}, {where}: {sol.message}", t)


def _first_chart(model: SeveralModel, x: np.ndarray):
    """A chart at x: the inputs', else the first set of joints whose [Φ_x; R] is not singular there
    (the conditionings at x are read from it)."""
    nj, k = len(model.joint_names), model.k
    sets = [tuple(int(j) for j in model.inputs)]
    if math.comb(nj, k) <= MAX_CANDIDATES:
        sets += [c for c in itertools.combinations(range(nj), k) if c != sets[0]]
    for joints in sets:
        try:
            return start_chart(model, joints, x)
        except NumericalFailure:
            continue
    raise NumericalFailure("singular", "no set of joints can drive the linkage at t = 0 s: [Φ_x; R] is singular at "
                           "the scene's configuration for every set tried (a singular configuration of the mechanism)",
                           0.0)


def best_set(model: SeveralModel, chart) -> tuple[tuple[int, ...], float]:
    """The best-conditioned set of k joints at the chart's configuration and its conditioning: the
    pivoted QR's choice (the kernel's), or a better one among every set of k joints when there are
    at most MAX_CANDIDATES of them, else among the sets one joint away from the current one. (At
    the event's root the QR's choice may still be the current set: the margin is discontinuous
    where the QR's choice changes, and the root can fall on either side.)"""
    current = tuple(int(j) for j in chart.current)
    candidates = {tuple(int(j) for j in chart.best)}
    nj, k = len(model.joint_names), model.k
    if math.comb(nj, k) <= MAX_CANDIDATES:
        candidates.update(itertools.combinations(range(nj), k))
    else:
        for i in range(k):
            for j in range(nj):
                if j not in current:
                    candidates.add(tuple(sorted(current[:i] + (j,) + current[i + 1:])))
    scored = sorted(((chart.conditioning_of(c), c) for c in candidates if c != current), reverse=True)
    return scored[0][1], float(scored[0][0])


def _switch(model: SeveralModel, chart, t: float, y: np.ndarray, switches: list):
    """At time t and state y in the chart's coordinates: the best set's chart there, y in its
    coordinates, the switch logged."""
    k = model.k
    q = np.ascontiguousarray(y[:k])
    v = np.ascontiguousarray(y[k:2 * k])
    a = np.zeros(k)
    chart.stop_margin(t, q, v)
    best, c_new = best_set(model, chart)
    c_old = float(chart.c_current)
    if c_new < loops.SINGULAR_CONDITIONING:
        raise NumericalFailure("singular", f"no set of joints can drive the linkage at t = {t:.9g} s: the best set "
                               f"({model.set_name(best)}) has conditioning {c_new:.3g}, below "
                               f"{loops.SINGULAR_CONDITIONING:g} (a singular configuration of the mechanism)", t)
    if not c_new > c_old:
        raise NumericalFailure("singular", f"no better-conditioned set of joints at t = {t:.9g} s", t)
    chart.acceleration(0, t, q, v, a)  # ẋ = K q̇ at q
    x, xdot = np.array(chart.lastx), np.array(chart.xdot)
    new = start_chart(model, best, x)
    R = np.asarray(new.R)
    switches.append(Switch(t, model.set_name(chart.current), model.set_name(best), c_old, c_new))
    return np.concatenate([R @ x, R @ xdot, y[2 * k:]]), new, np.array(best, dtype=np.int64)


@dataclass(frozen=True)
class SeveralRun:
    """A run of several DOF, before the engine's energy gate (:func:`loopcheck.reduced.engine.simulate`).

    inputs: each input's trajectory and peak, in the scene's inputs order; joints: every joint
    coordinate; audit: the energy balance at the samples; switches: the coordinate switches;
    kinetic_scale: ½ max diag 𝔍 at the start (J per (rad/s)²), the energy scale's floor.
    """

    inputs: tuple
    joints: JointTrajectory
    audit: EnergyAudit
    switches: tuple
    wall_s: float
    n_steps: int
    n_evaluations: int
    kinetic_scale: float
    solver: str


def run_several(scene: Scene, settings: ReducedSettings = ReducedSettings()) -> SeveralRun:
    """The reduced engine's run of a scene of several DOF (module docstring): every input's
    trajectory and peak, every joint coordinate, the energy audit, the switches."""
    check_scene(scene, settings)
    model = SeveralModel(scene)
    begin = time.perf_counter()
    record, switches, n_steps, n_eval, J0, sets = integrate(model, settings)
    wall = time.perf_counter() - begin
    t = np.concatenate(record.t)
    x = np.concatenate(record.x)
    xdot = np.concatenate(record.xdot)
    xdd = np.concatenate(record.xdd)
    x[:, model.angle_columns] = np.unwrap(x[:, model.angle_columns], axis=0)
    trajectories = [Trajectory(t, x @ r, xdot @ r, xdd @ r) for r in model.input_rows]
    joints = JointTrajectory(model.system.coordinate_names, t, x, xdot, np.full(len(t), -1),
                             loops.assembly_modes(model.system, x).reshape(len(t), -1))
    audit = EnergyAudit(t=t, kinetic=np.concatenate(record.T), potential=np.concatenate(record.V),
                        torque_work=np.concatenate(record.W), damper_dissipation=np.concatenate(record.E))
    return SeveralRun(tuple((tr, tr.peak_rate()) for tr in trajectories), joints, audit, tuple(switches), wall,
                      n_steps, n_eval, 0.5 * float(np.max(np.abs(np.diag(J0)))),
                      f"scipy {SCIPY_METHODS[settings.method]}")
