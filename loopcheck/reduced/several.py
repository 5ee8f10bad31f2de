"""The reduced engine on a linkage of several degrees of freedom: Eksergian's equation in k
independent joint coordinates, with coordinate partitioning (issue 40).

    𝔍(q) q̈ + c(q, q̇) = Q(t, q, q̇),   q = R x (k of the joints' own coordinates)

The arithmetic is compiled (:class:`loopcheck.reduced.kernels.several.Several`, whose docstring
states the formulation: c by one extra solve with the actual rates, the conditioning of a set of
joints and the best set by pivoted QR). The chart is a
:class:`~loopcheck.reduced.kernels.vector_problem.VectorRightHandSide`, so the methods of the one-DOF
engine (:data:`loopcheck.reduced.settings.METHODS`) mean the same here:

- ``dop853`` (the default): the compiled DOP853 in n coordinates
  (:func:`~loopcheck.reduced.kernels.vector_adaptive.vector_dop853_run`: scipy's algorithm step for
  step, restarted at every load edge with the one-DOF rule), the chart called from compiled code;
- ``rkn4``: the compiled RKN4 (:func:`~loopcheck.reduced.kernels.vector_fixed_step.vector_rkn_chart`)
  at the settings' step, with its stability check; the engine estimates its error by step doubling
  (:func:`loopcheck.reduced.engine.simulate_several`);
- ``scipy-dop853``: scipy's ``solve_ivp`` DOP853 on the same compiled chart, its error estimate on
  (q, q̇) alone and the same first steps and restarts as the compiled one (an independent check of
  the compiled integrator: they agree to round-off, tests/reduced/test_several_dof.py);
- ``radau``: scipy's Radau on y = (q, q̇, W, E).

Each integrates W (the work of the timed forces and actuators) and E (the dampers' dissipation)
alongside the state for the energy audit (outside the error estimate, but for Radau's). The
chart's stop event (its ``stop_margin``: a terminal event located at its root by DOP853, after the
step by RKN4) is the coordinate switch,

    switch when  c(current set) < HYSTERESIS · c(best set)

(c(best set): the kernel's pivoted-QR choice), or a ranged joint reaching a bound. At a switch the run
goes on from the event in the best-conditioned of every set of k joints (:func:`best_set`), with
q, q̇ re-expressed from x, ẋ there (q' = R' x, q̇' = R' ẋ); every switch is logged
(:class:`loopcheck.reduced.charts.Switch`, the sets named by their joints, "O1, O5"). A configuration
where even the best set's conditioning is below :data:`loopcheck.kinematics.SINGULAR_CONDITIONING`
stops the run (NumericalFailure "singular"); an integration that fails otherwise names its time and
the conditionings there. The inputs are the first set, kept at the start unless another is better
by more than the hysteresis (then a switch at t = 0 is logged).

Samples: the adaptive methods' steps, each cut into at least SAMPLES_PER_STEP parts no longer than
the sample interval (as the one-DOF runs); RKN4's steps. At each, x, ẋ, ẍ, V and T = ½ q̇ᵀ𝔍q̇ from
the chart, every input's q = r·x, q̇ = r·ẋ, q̈ = r·ẍ (its joint row r), W and E.
``JointTrajectory.coordinate`` is −1 (a chart is a set of joints, not one coordinate: the switches
say which).

A joint range ends the run where the joint reaches a bound (NumericalFailure "range-reached", as the
one-DOF engine: the nearest bound's distance in the chart's stop event, located at its root by
either integrator).

A redundantly closed loop (more constraint rows than n − k, consistent): the chart runs on the n − k
independent rows at the assembled start (:meth:`SeveralModel.select_rows`), and every sample's
dropped rows are checked closed to DROPPED_TOL (:func:`check_dropped`: a failure names the time
where the selection lost rank).

A forcerange clamp on a force that depends on the state (an actuator with bias b1 or b2): each such
actuator has a clamp mode (the one-DOF engine's: free, at hi, at lo), its margin in the chart's
stop event (:meth:`kernel.Several.clamp_margin`, CLAMP_HYSTERESIS) and checked at each load piece's
start (``stop_at_start``; scipy's legs set the modes at each piece's start); at such a stop the
modes are set anew by value (:func:`_clamp_stop`) and the run goes on in the same coordinates.

Joint friction (Coulomb, f on a joint's own coordinate u; static = kinetic). Each friction has a
mode: slipping in the direction s = ±1 (its force −f s K_u on q, f |u̇| among the dissipation,
its margin s u̇ in the chart's stop event), or stuck (s = 0: its coordinate held by one more row
of the chart's KKT system, :meth:`kernel.Several._stuck_solve`, λ its holding force; its margin
f − |λ| in the stop event, a load edge that steps |λ| past f a stop at the piece's start). At each
such stop the modes are decided together (:func:`_set_frictions`: the moving ones slip their
way, a stuck one at |λ| = f slips with s = −sign λ, those at rest take the first consistent set
of modes, fewest slipping first), the stuck joints' rates projected to 0 (:func:`_hold`), each
change logged (:class:`loopcheck.reduced.charts.FrictionEvent` with its joint); where no set is
consistent the run stops (NumericalFailure "singular" naming the joints and the time). A
statically indeterminate hold (more stuck joints than their rows' rank: two frictions on one DOF,
three on the five-bar) is a hold like any other: the chart's q̈ is unique, its holding forces the
max-margin share and its margin the linear programme's max_μ min_e f_e − |λ_p,e + N_e μ|
(:meth:`kernel.Several._indeterminate`, :meth:`kernel.Several._max_margin`); a stuck set is
consistent where that margin is positive. A coordinate switch carries the clamps' and the
frictions' modes to the new chart.

Not yet supported with several DOF (refused in one line before any work, :func:`check_scene`):
point forces over q, a load on the first input alone (``[torque]``).
"""

from __future__ import annotations

import functools
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

from .charts import FrictionEvent, Switch
from .dynamics import build_arrays, clamped_actuators, piece_edges, ranged_joints
from .integrators import MAX_EVALUATIONS, RESTART_STEPS, SAMPLES_PER_STEP, SPEED_LIMIT, budget_spent, sample_parts
from .kernels import output, vector_adaptive, vector_fixed_step
from .kernels import several as kernel
from .kernels.fixed_step import RKN4
from .kernels.vector_output import VectorSamples
from .settings import ReducedSettings

HYSTERESIS = kernel.HYSTERESIS
MAX_SWITCHES = 10_000
# a switch chooses among every set of k joints up to this many sets (best_set)
MAX_CANDIDATES = 500
# the methods (loopcheck.reduced.settings.METHODS): compiled, or scipy's solve_ivp on the compiled chart
COMPILED = ("dop853", "rkn4")
SCIPY_METHODS = {"scipy-dop853": "DOP853", "radau": "Radau"}


def check_scene(scene: Scene) -> None:
    """Refuse, in one line, what the several-DOF engine does not run yet (module docstring).

    Raises
    ------
    SceneError
        Naming the element.
    """
    mech = scene.mechanism
    where = f"scene '{scene.name}' ({scene.dof} degrees of freedom)"
    if mech.point_forces:
        raise SceneError(f"{where}: point forces over q are not supported with several inputs")
    if scene.load is not None:
        raise SceneError(f"{where}: a load on the input ([torque]/[force]) is not supported with several inputs: "
                         "use [[actuators]] on the joints")


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
        self.clamped = clamped_actuators(scene.mechanism)
        frictions = list(dict.fromkeys(e.joint for e in scene.mechanism.joint_frictions))  # build_arrays' order
        self.friction_joints = tuple(frictions)
        self.friction_rows = np.array([self.system.joint_row(j) for j in frictions]).reshape(-1, self.system.n)
        self.select = None  # a redundant loop's independent rows (select_rows), else every row
        self.dropped = np.zeros(0, dtype=np.int64)

    def select_rows(self, x: np.ndarray) -> None:
        """At the assembled start x: where the constraint rows are more than n − k (a redundantly
        closed loop), the n − k independent ones (:func:`loopcheck.kinematics.independent_rows`,
        as :meth:`loopcheck.kinematics.LoopSystem.with_independent_rows` chooses them for one
        input) for the chart, the others kept to be checked along the run (:func:`check_dropped`).
        Raises SceneError where the rank is not n − k (not k degrees of freedom)."""
        n, k = self.system.n, self.k
        J = loops.all_constraints(self.system, x)[1]
        if J.shape[0] == n - k:
            return
        rows = loops.independent_rows(J)
        if len(rows) != n - k:
            raise SceneError(f"scene '{self.scene.name}': the loop equations have rank {len(rows)} of {J.shape[0]} "
                             f"rows over {n} coordinates at the start: {n - len(rows)} degrees of freedom, not the "
                             f"{k} inputs")
        self.select = np.array(rows, dtype=np.int64)
        self.dropped = np.array([r for r in range(J.shape[0]) if r not in rows], dtype=np.int64)

    def range_margins(self, x: np.ndarray) -> np.ndarray:
        """(ranged joints, 2): each ranged joint's u − lo and hi − u at x."""
        u = self.range_rows @ x
        return np.stack([u - self.range_bounds[:, 0], self.range_bounds[:, 1] - u], axis=1)

    def new_chart(self) -> kernel.Several:
        return kernel.Several(self.arrays.F, self.arrays.I, self.system.joint_rows, self.k,
                              loops.SINGULAR_CONDITIONING, self.select)

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
    """The samples of a run, appended chart by chart: t, x, ẋ, ẍ, V, T, and the work done and the
    energy dissipated since t = 0 (W, E), and each sample's index into the sets charted (sets)."""

    def __init__(self):
        self.t, self.x, self.xdot, self.xdd, self.V, self.T, self.W, self.E, self.sets = ([] for _ in range(9))

    def append(self, n: int, t, observed, work, dissipated, set_index: int) -> None:
        """One chart's samples: ``observed`` (m, 3n + 2) the chart's :meth:`observe` rows (x, ẋ, ẍ,
        V, T), ``work`` and ``dissipated`` (m,) since t = 0."""
        self.t.append(np.asarray(t))
        self.x.append(observed[:, :n])
        self.xdot.append(observed[:, n:2 * n])
        self.xdd.append(observed[:, 2 * n:3 * n])
        self.V.append(observed[:, 3 * n])
        self.T.append(observed[:, 3 * n + 1])
        self.W.append(np.asarray(work))
        self.E.append(np.asarray(dissipated))
        self.sets.append(np.full(len(t), set_index))


@dataclass
class _Leg:
    """How one chart's integration ended: the time and state reached (q, q̇ in its coordinates,
    the work done and the energy dissipated since t = 0), whether its stop event ended it, and
    what it cost."""

    t: float
    y: np.ndarray  # (2k + 2,): q, q̇, W, E
    stopped: bool
    n_steps: int
    n_evaluations: int


def _sample(model, chart, sol, start, end, load, sample_interval, record, joints_index, base):
    """The samples of one piece integrated by scipy: the solver's steps cut as the compiled
    DOP853 cuts them (:func:`loopcheck.reduced.integrators.dense_samples`), the chart walked again
    from the piece's start (:meth:`rewind`) and evaluated at each, in order; ``base`` the work done
    and the energy dissipated before the chart's start (its own integrated from 0, as the compiled
    runs integrate them)."""
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
    for r in range(len(times)):
        q = np.ascontiguousarray(states[:k, r])
        v = np.ascontiguousarray(states[k:2 * k, r])
        if chart.acceleration(load, float(times[r]), q, v, a) != 0:
            raise NumericalFailure("singular", f"the chart of {model.set_name(chart.current)} could not close the "
                                   f"loops at t = {times[r]:.6g} s", float(times[r]))
        chart.observe(obs, r)
    record.append(model.system.n, times, obs, base[0] + states[2 * k], base[1] + states[2 * k + 1], joints_index)


@functools.cache
def _state_error_dop853():
    """scipy's DOP853 on y = (q, q̇, W, E) with its error estimate on (q, q̇) alone (the first
    ``state_size`` components): the energy flows ride along, integrated with the state's weights
    and given its dense output, and take no part in the steps, as in the compiled DOP853
    (:mod:`loopcheck.reduced.kernels.vector_adaptive`). (A class made at first use: scipy is
    imported only by the runs that use it.)"""
    from scipy.integrate import DOP853

    class StateErrorDOP853(DOP853):
        def __init__(self, fun, t0, y0, t_bound, *, state_size: int, **options):
            self.state_size = state_size
            super().__init__(fun, t0, y0, t_bound, **options)

        def _estimate_error_norm(self, K, h, scale):
            m = self.state_size
            return super()._estimate_error_norm(K[:, :m], h, scale[:m])

    return StateErrorDOP853


def _norm(x: np.ndarray) -> float:
    """The 2-norm summed plainly from the first component (the compiled DOP853's order)."""
    acc = x[0] * x[0]
    for i in range(1, len(x)):
        acc = acc + x[i] * x[i]
    return math.sqrt(acc)


def _first_step(fun, t0: float, y0: np.ndarray, end: float, m: int, rtol: float, atol: float, cap: float):
    """scipy's select_initial_step (common.py, order 7) on the first m components of y (q, q̇), its
    norms summed as the compiled DOP853's ``_initial_step`` sums them, at most ``cap`` when > 0 (a
    restart at a load edge: the largest of the previous piece's last RESTART_STEPS steps). Returns
    (h, the function to hand solve_ivp: ``fun`` but for its first call at (t0, y0), which returns f0
    as computed here, before the probe moved the chart on)."""
    f0 = fun(t0, y0)
    pending = [(t0, np.array(y0, dtype=float), f0)]

    def primed(t, y):
        if pending and t == pending[0][0] and np.array_equal(y, pending[0][1]):
            return pending.pop()[2].copy()
        return fun(t, y)

    interval = abs(end - t0)
    scale = atol + np.abs(y0[:m]) * rtol
    d0 = _norm(y0[:m] / scale) / math.sqrt(m)
    d1 = _norm(f0[:m] / scale) / math.sqrt(m)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, interval)
    f1 = fun(t0 + h0, y0 + h0 * f0)
    d2 = _norm((f1[:m] - f0[:m]) / scale) / math.sqrt(m) / h0
    h1 = max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    h = min(100 * h0, h1, interval)
    return (min(h, cap) if cap > 0.0 else h), primed


def _leg_scipy(model: SeveralModel, chart, t: float, y: np.ndarray, settings: ReducedSettings, record: _Record,
               set_index: int, joints, budget: int) -> _Leg:
    """One chart from t, integrated by scipy's solve_ivp (DOP853: :func:`_state_error_dop853` and the
    compiled DOP853's restart rule; Radau on all of y) piece by piece to the horizon or to the chart's
    stop event (a switch, a range's bound); at most ``budget`` evaluations of q̈ (the run's failure,
    :func:`loopcheck.reduced.integrators.budget_spent`, beyond them)."""
    from scipy.integrate import solve_ivp

    k = model.k
    scene = model.scene
    name = SCIPY_METHODS[settings.method]
    rtol = settings.rtol
    edges = [b for b in scene.load_edges if t < b < scene.horizon] + [scene.horizon]
    a = np.zeros(k)
    n_steps = n_eval = 0
    cap = 0.0
    base = y[2 * k:].copy()  # W and E at the chart's start: its own from 0 (the compiled runs' sums)
    y = np.concatenate([y[:2 * k], [0.0, 0.0]])
    left = [budget]
    while True:
        end = edges[0]
        load = model.piece(t, end)
        if len(model.clamped):  # each piece's start sets the clamp modes by value (a control step past a bound)
            _set_clamps(model, chart, t, y)
        if len(model.friction_joints) and 0.0 in np.asarray(chart.slip) and _breaking(model, chart, t, y):
            # a load edge that breaks a stuck joint loose: a stop at the piece's start (the compiled runs'
            # stop_at_start), its modes set by the run
            return _Leg(t, np.concatenate([y[:2 * k], base + y[2 * k:]]), True, n_steps, n_eval)
        chart.mark()

        def fun(tt, yy, chart=chart, load=load):
            left[0] -= 1
            if left[0] < 0:
                raise budget_spent(f"scipy {name}", MAX_EVALUATIONS, float(tt), 0.0, scene.horizon)
            q = np.ascontiguousarray(yy[:k])
            v = np.ascontiguousarray(yy[k:2 * k])
            if chart.acceleration(load, tt, q, v, a) != 0:
                return np.full(2 * k + 2, np.nan)
            return np.concatenate([v, a, [chart.power(load, v), chart.dissipation(v)]])

        def event(tt, yy, chart=chart):
            return chart.stop_margin(tt, np.ascontiguousarray(yy[:k]), np.ascontiguousarray(yy[k:2 * k]))
        event.terminal, event.direction = True, -1
        if name == "DOP853":
            first, fun = _first_step(fun, t, y, end, 2 * k, rtol, rtol, cap)
            method, options = _state_error_dop853(), {"state_size": 2 * k, "first_step": first}
            n_eval += 1  # the probe's evaluation (the first, f0, solve_ivp counts)
        else:
            method, options = name, {}
        with np.errstate(invalid="ignore", over="ignore"):
            sol = solve_ivp(fun, (t, end), y, method=method, rtol=rtol, atol=rtol, dense_output=True,
                            events=[event], **options)
        if not sol.success:
            raise _failure(model, chart, sol, f"scipy {name}", t, end, joints)
        n_steps += len(sol.t) - 1
        n_eval += sol.nfev
        stop = float(sol.t[-1])
        _sample(model, chart, sol, t, stop, load, settings.sample_interval, record, set_index, base)
        y = sol.y[:, -1].copy()
        reached = np.concatenate([y[:2 * k], base + y[2 * k:]])
        if sol.status == 1:
            return _Leg(stop, reached, True, n_steps, n_eval)
        t = stop
        edges.pop(0)
        if not edges:
            return _Leg(t, reached, False, n_steps, n_eval)
        cap = float(np.max(np.diff(sol.t)[-RESTART_STEPS:]))


def _leg_compiled(model: SeveralModel, chart, t: float, y: np.ndarray, settings: ReducedSettings, record: _Record,
                  set_index: int, joints, step: float | None, budget: int, workspace) -> _Leg:
    """One chart from t, integrated in the compiled core without Python (the chart is a
    :class:`~loopcheck.reduced.kernels.vector_problem.VectorRightHandSide`): DOP853
    (:func:`~loopcheck.reduced.kernels.vector_adaptive.vector_dop853_run`, scipy's algorithm step for
    step) or RKN4 at ``step`` with its stability check
    (:func:`~loopcheck.reduced.kernels.vector_fixed_step.vector_rkn_chart`), over the load pieces to
    the horizon or to the chart's stop event (a switch, a range's bound)."""
    k = model.k
    edges = model.piece_edges
    out = VectorSamples(k, chart.observation_size())
    q0, v0 = np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k])
    if step is None:
        first = int(np.searchsorted(edges, t, side="right")) - 1
        here = np.ascontiguousarray(np.concatenate([[t], edges[first + 1:]]))
        loads = np.arange(first, len(edges) - 1, dtype=np.intp)
        outcome = vector_adaptive.vector_dop853_run(
            chart, here, loads, q0, v0, settings.rtol, settings.rtol, settings.sample_interval, SAMPLES_PER_STEP,
            SPEED_LIMIT, budget, math.inf, True, out, workspace)
        method = "DOP853"
    else:
        outcome = vector_fixed_step.vector_rkn_chart(chart, RKN4, edges, np.arange(len(edges) - 1, dtype=np.intp),
                                                     t, q0, v0, float(step), SPEED_LIMIT, True, True, out)
        method = "RKN4"
    times, _, _, _, observed, energy = out.arrays()
    if len(times):
        record.append(model.system.n, times, observed, y[2 * k] + energy[:, 0], y[2 * k + 1] + energy[:, 1],
                      set_index)
    if outcome.status != output.OK:
        raise _compiled_failure(model, chart, outcome, method, joints, step, budget)
    _, q, v, _, _, _ = out.arrays()
    end = np.concatenate([q[-1], v[-1], [y[2 * k] + energy[-1, 0], y[2 * k + 1] + energy[-1, 1]]])
    return _Leg(float(outcome.t_reached), end, bool(outcome.stopped), int(outcome.n_steps),
                int(outcome.n_evaluations))


def integrate(model: SeveralModel, settings: ReducedSettings, step: float | None = None):
    """The run from t = 0 to the horizon (module docstring): (record, switches, steps, evaluations,
    the initial 𝔍, the sets of joints charted in turn). ``step`` overrides RKN4's step (the error
    estimate's run at twice the step)."""
    scene = model.scene
    k = model.k
    x = np.array(scene.x0, dtype=float)
    q0 = np.array(scene.initial_q(), dtype=float)
    if not np.allclose(model.input_rows @ x, q0, rtol=0.0, atol=1e-9):
        x = loops.assemble_inputs(model.system, q0, x)
    model.select_rows(x)
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
    _set_clamps(model, chart, 0.0, y)
    events = []
    if len(model.friction_joints):
        y = _set_frictions(model, chart, 0.0, y, events)
    if not chart.stop_margin(0.0, q0, v0) > 0.0:  # another set is clearly better at the start: logged at t = 0
        _check_range(model, chart, 0.0, y)
        y, chart, joints = _switch(model, chart, 0.0, y, switches)
    J0 = np.array(chart.Jm)
    record = _Record()
    t, n_steps, n_eval, sets = 0.0, 0, 0, [tuple(int(j) for j in joints)]
    still = 0  # legs in a row that stopped where they started
    compiled = settings.method in COMPILED
    fixed = (settings.step if step is None else step) if settings.method == "rkn4" else None
    workspace = vector_adaptive.VectorSteps(k) if settings.method == "dop853" else None
    while t < scene.horizon:
        if compiled:
            leg = _leg_compiled(model, chart, t, y, settings, record, len(sets) - 1, joints, fixed,
                                MAX_EVALUATIONS - n_eval, workspace)
        else:
            leg = _leg_scipy(model, chart, t, y, settings, record, len(sets) - 1, joints, MAX_EVALUATIONS - n_eval)
        n_steps += leg.n_steps
        n_eval += leg.n_evaluations
        still = still + 1 if leg.stopped and leg.t == t else 0
        if still > MAX_STILL_STOPS:
            raise NumericalFailure("singular", f"the run stopped {still} times at t = {t:.9g} s without advancing: "
                                   "events coincide there (a joint's friction or a switch decided anew, and another "
                                   "event's margin crossing at once), which the reduced engine of several inputs does "
                                   "not resolve", t)
        t, y = leg.t, leg.y
        if not leg.stopped:
            break
        _check_range(model, chart, t, y)
        if _clamp_stop(model, chart, t, y):
            continue
        friction, y = _slip_stop(model, chart, t, y, events)
        if friction:
            continue
        if len(switches) >= MAX_SWITCHES:
            raise NumericalFailure("singular", f"more than {MAX_SWITCHES} coordinate switches", t)
        y, chart, joints = _switch(model, chart, t, y, switches)
        sets.append(tuple(int(j) for j in joints))
    return record, switches, n_steps, n_eval, J0, sets, tuple(events)


# legs in a row that may stop where they started (an event handled, the next found at the same
# time: possible where events coincide) before the run is stopped as going nowhere: the several-
# input test scenes take none (tests/reduced/test_several_stick.py pass with 0)
MAX_STILL_STOPS = 16


# a redundant loop's dropped rows: |Φ_r| at most this (m or rad) at every sample (check_dropped):
# consistent rows stay at the closure's round-off (NEWTON_TOL 1e-12, ~1e-15 measured)
DROPPED_TOL = 1e-9


def check_dropped(model: SeveralModel, t: np.ndarray, x: np.ndarray) -> None:
    """A redundant loop's rows the chart did not run on (:meth:`SeveralModel.select_rows`) at
    every sample x (samples, n): NumericalFailure "singular" at the first time one exceeds
    DROPPED_TOL (the selected rows no longer imply it: the selection lost rank there, a
    bifurcation of the redundant linkage), with the row, its value and the rank there."""
    if not len(model.dropped):
        return
    for i in range(len(t)):
        phi, J = loops.all_constraints(model.system, x[i])
        gap = np.abs(phi[model.dropped])
        if np.max(gap) > DROPPED_TOL:
            r = int(model.dropped[int(np.argmax(gap))])
            rank = len(loops.independent_rows(J[model.select]))
            raise NumericalFailure(
                "singular", f"the redundant loop's constraint row {r}, dropped at the start as dependent, opened to "
                f"{np.max(gap):.3g} (> {DROPPED_TOL:g}) at t = {t[i]:.9g} s: the {len(model.select)} rows the chart "
                f"runs on have rank {rank} there and no longer imply it (the selection lost rank)", float(t[i]))


def _set_clamps(model: SeveralModel, chart, t: float, y: np.ndarray) -> int:
    """Each clamped actuator's mode set by its force at (t, y) on t's load piece
    (:meth:`kernel.Several.set_clamps`): the count changed."""
    k = model.k
    changed = chart.set_clamps(model.piece(t, t), np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k]))
    if changed < 0:
        raise NumericalFailure("singular", f"the chart of {model.set_name(chart.current)} could not close the loops "
                               f"at t = {t:.9g} s", t)
    return changed


def _clamp_stop(model: SeveralModel, chart, t: float, y: np.ndarray) -> bool:
    """At a stop of the chart's event: True where it was a clamped actuator's force leaving its
    mode (its margin the least of the event's three), the modes then set anew at (t, y): the run
    goes on in the same chart. False where it was a switch."""
    if not len(model.clamped):
        return False
    k = model.k
    switch = chart.stop_margin(t, np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k]))
    clamp = chart.clamp_margin(np.ascontiguousarray(y[k:2 * k]))
    if switch != switch or clamp > chart.c_current - HYSTERESIS * chart.c_best:
        return False
    if _set_clamps(model, chart, t, y) == 0:
        raise NumericalFailure("singular", f"an actuator's forcerange clamp stopped the run at t = {t:.9g} s without "
                               "changing its mode", t)
    return True


# a joint friction's rate |u̇| at most this (rad/s or m/s) at a stop is at rest there (_set_frictions)
REST_RATE = 1e-9
# a stuck joint's holding force |λ| within this fraction of its friction f at a stop breaks loose
# there (the stop's root is located to round-off: |λ| − f ~ 1e-13 f measured)
BREAK_TOL = 1e-9
# at most this many frictions at rest decided together (3^n combinations of modes tried)
MAX_AT_REST = 8


def _friction_state(model: SeveralModel, chart, t: float, q: np.ndarray, v: np.ndarray):
    """The acceleration at (t, q, v) on t's load piece with the chart's friction modes: each
    friction's u̇, ü and holding force λ (0 where it slips; a statically indeterminate hold's
    max-margin λ, :meth:`kernel.Several.slip_margin`), or None where the acceleration fails (a
    singular hold)."""
    a = np.zeros(model.k)
    if chart.acceleration(model.piece(t, t), t, q, v, a) != 0:
        return None
    if chart.slip_margin(v) != chart.slip_margin(v):  # (the max-margin λ of an indeterminate hold)
        return None
    rows = model.friction_rows
    return rows @ np.asarray(chart.xdot), rows @ np.asarray(chart.xdd), np.array(chart.lam)[:len(rows)]


def _set_frictions(model: SeveralModel, chart, t: float, y: np.ndarray, events: list) -> np.ndarray:
    """Set every joint friction's mode at (t, y) (module docstring): one moving (|u̇| > REST_RATE)
    slips its way; a stuck one whose |λ| reaches f (:func:`_at_capacity`) slips against its holding
    force (s = −sign λ: the friction keeps pushing with f as the joint moves the way the rest of
    the linkage pushes it); the others at rest (|u̇| ≤ REST_RATE, or stuck) take the first
    consistent set of modes, fewest slipping first: each stuck with |λ| < f, each slipping from
    rest with s ü > 0. Each change is logged in ``events`` (:class:`FrictionEvent`, with its
    joint). The stuck joints' rates are then projected to 0 (q̇ ← q̇ − 𝔍⁻¹Rᵀ(R𝔍⁻¹Rᵀ)⁻¹R q̇, the
    smallest kinetic energy change: a plastic hold; its loss, ~(u̇ ≤ REST_RATE)², among the
    dissipation). Returns y so set. Raises NumericalFailure ("singular", naming the joints and
    the time) where no set of modes is consistent."""
    k, nf = model.k, len(model.friction_joints)
    q, v = np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k])
    before = np.array(chart.slip)[:nf]
    state = _friction_state(model, chart, t, q, v)
    if state is None:
        raise NumericalFailure("singular", f"the chart of {model.set_name(chart.current)} could not evaluate the "
                               f"acceleration at t = {t:.9g} s", t)
    rate, _, lam = state
    forced = _at_capacity(chart, lam)
    rest = []
    for e in range(nf):
        if e in forced:
            chart.set_slip(e, -1.0 if lam[e] > 0 else 1.0)
        elif before[e] != 0.0 and abs(rate[e]) > REST_RATE:
            chart.set_slip(e, 1.0 if rate[e] > 0 else -1.0)
        elif before[e] == 0.0 or abs(rate[e]) <= REST_RATE:
            rest.append(e)
    if len(rest) > MAX_AT_REST:
        raise NumericalFailure("singular", f"{len(rest)} joint frictions at rest together at t = {t:.9g} s: at most "
                               f"{MAX_AT_REST} are decided together", t)
    # the candidates: fewest slipping first; a slip from rest its previous way first
    combos = sorted(itertools.product(*[(0.0, before[e] or 1.0, -(before[e] or 1.0)) for e in rest]),
                    key=lambda c: sum(m != 0.0 for m in c))
    for combo in combos:
        for e, mode in zip(rest, combo):
            chart.set_slip(e, mode)
        state = _friction_state(model, chart, t, q, v)
        if state is None:
            continue
        _, acc, lam = state
        if all((abs(lam[e]) < chart.friction_capacity(e)) if mode == 0.0 else (mode * acc[e] > 0.0)
               for e, mode in zip(rest, combo)):
            break
    else:
        names = ", ".join(repr(model.friction_joints[e]) for e in rest)
        raise NumericalFailure("singular", f"joint friction on {names} at rest at t = {t:.9g} s: no consistent set "
                               "of stick and slip modes (each stuck within its friction by some admissible share "
                               "of the holding forces, each slipping the way it accelerates)", t)
    after = np.array(chart.slip)[:nf]
    stuck = [e for e in range(nf) if after[e] == 0.0]
    if stuck:
        y = _hold(model, chart, t, y, stuck)
        v = np.ascontiguousarray(y[k:2 * k])
    for e in range(nf):
        if after[e] != before[e] and (t > 0.0 or after[e] == 0.0):
            events.append(FrictionEvent(float(t), "stick" if after[e] == 0.0 else "slip", int(after[e]),
                                        model.friction_joints[e]))
    return y


def _hold(model: SeveralModel, chart, t: float, y: np.ndarray, stuck) -> np.ndarray:
    """y with q̇ projected onto u̇_e = 0 for the stuck frictions (𝔍-weighted, :func:`_set_frictions`),
    the kinetic energy it takes added to the dissipation E."""
    k = model.k
    q, v = np.ascontiguousarray(y[:k]), np.array(y[k:2 * k])
    if not chart.evaluate(q):
        raise NumericalFailure("singular", f"the chart of {model.set_name(chart.current)} could not close the loops "
                               f"at t = {t:.9g} s", t)
    J = np.array(chart.Jm)
    R = model.friction_rows[stuck] @ np.asarray(chart.K).T  # (s, k): u̇_S = R q̇
    JiRt = np.linalg.solve(J, R.T)
    G = R @ JiRt
    if np.linalg.matrix_rank(R) == len(stuck):
        w = v - JiRt @ np.linalg.solve(G, R @ v)
    else:  # dependent rows (an indeterminate hold): any solution of G y = R q̇ gives the same J⁻¹Rᵀy
        w = v - JiRt @ np.linalg.lstsq(G, R @ v, rcond=None)[0]
    y = y.copy()
    y[k:2 * k] = w
    y[2 * k + 1] += 0.5 * (v @ J @ v - w @ J @ w)
    return y


def _slip_stop(model: SeveralModel, chart, t: float, y: np.ndarray, events: list):
    """At a stop of the chart's event: (True, y) where it was a joint friction's (its margin the
    least of the event's: a slipping joint's s u̇ reaching 0, or a stuck joint's f − |λ|), the
    modes then set anew (:func:`_set_frictions`, the stuck ones reaching f made to slip): the
    run goes on in the same coordinates from the y returned. (False, y) where it was a switch."""
    if not len(model.friction_joints):
        return False, y
    k = model.k
    v = np.ascontiguousarray(y[k:2 * k])
    switch = chart.stop_margin(t, np.ascontiguousarray(y[:k]), v)  # (the holding forces at y, where stuck)
    if switch != switch or chart.slip_margin(v) > chart.c_current - HYSTERESIS * chart.c_best:
        return False, y
    return True, _set_frictions(model, chart, t, y, events)


def _breaking(model: SeveralModel, chart, t: float, y: np.ndarray) -> tuple:
    """The stuck frictions whose holding force at (t, y) reaches their friction (to BREAK_TOL)."""
    k = model.k
    state = _friction_state(model, chart, t, np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k]))
    return () if state is None else _at_capacity(chart, state[2])


def _at_capacity(chart, lam: np.ndarray) -> tuple:
    """The stuck frictions whose holding forces ``lam`` (one per friction) reach their friction
    (to BREAK_TOL)."""
    return tuple(e for e in range(len(lam))
                 if chart.slip[e] == 0.0 and abs(lam[e]) >= (1.0 - BREAK_TOL) * chart.friction_capacity(e))


def _check_range(model: SeveralModel, chart, t: float, y: np.ndarray) -> None:
    """At a stop of the chart's event: raise the run's end (:func:`_range_reached`) where it was a
    ranged joint's bound (its margin the nearer of the two), else return (a switch)."""
    if not len(model.ranged):
        return
    k = model.k
    switch = chart.stop_margin(t, np.ascontiguousarray(y[:k]), np.ascontiguousarray(y[k:2 * k]))
    bound = chart.range_margin()
    if switch != switch or bound <= chart.c_current - HYSTERESIS * chart.c_best:
        raise _range_reached(model, np.asarray(chart.lastx) if switch == switch else None, t)


def _compiled_failure(model: SeveralModel, chart, outcome, method: str, joints, step: float | None,
                      budget: int) -> NumericalFailure:
    """The failure a compiled run reports (``outcome``, :class:`loopcheck.reduced.kernels.output.Outcome`),
    each with its time: a configuration the chart could not close ("singular", with the
    conditionings at the last one it closed), q̈ or the state not finite, a speed beyond the limit,
    RKN4's step outside its stability region, DOP853's step collapsed or its budget spent."""
    t = float(outcome.fail_time) if outcome.fail_time == outcome.fail_time else 0.0
    status = outcome.status
    if status == output.SPEED:
        name = model.joint_names[int(chart.current[int(outcome.detail[0])])]
        return NumericalFailure("unstable", f"the rate of joint {name} ({abs(outcome.fail_value):.3g}) exceeds "
                                f"{SPEED_LIMIT:.3g} at t = {t:.6g} s: the integration is unstable"
                                + (" at this step" if step is not None else ""), t)
    if status == output.UNSTABLE:
        re, im, amplification, limit = outcome.detail
        return NumericalFailure(
            "unstable", f"the step h = {step:.3g} s is outside RKN4's stability region at t = {t:.6g} s "
            f"(h·λ = {re:.3g}{im:+.3g}j, |R| = {amplification:.6g} > {limit:.6g}): the problem is "
            "too stiff for this explicit step; use a smaller step (`--step`, `[reduced] step`) or "
            "the implicit Radau method", t)
    if status == output.STEP_SIZE:
        if outcome.n_evaluations >= budget:
            return budget_spent(method, MAX_EVALUATIONS, t, 0.0, model.scene.horizon)
        return NumericalFailure(
            "step-size", f"DOP853's step fell below the spacing of the floating-point numbers at t = {t:.6g} s in "
            f"the coordinates {model.set_name(joints)}: it has collapsed (an extreme speed, damper or inertia "
            "in the scene?)", t)
    if not chart.valid:  # the walk failed: the chart's last configuration is the last it closed
        chart.best_joints()
        best, c_best = best_set(model, chart)
        c_now = chart.conditioning_of(chart.current)
        c_best = max(c_best, c_now)
        where = f"where the coordinates {model.set_name(joints)} have conditioning {c_now:.3g} and the best set " \
                f"{c_best:.3g}"
        if c_best < loops.SINGULAR_CONDITIONING:
            return NumericalFailure("singular", f"no set of joints can drive the linkage at t = {t:.9g} s, {where}, "
                                    f"below {loops.SINGULAR_CONDITIONING:g}: a singular configuration of the "
                                    "mechanism", t)
        return NumericalFailure("singular", f"{method} could not close the loops in the coordinates "
                                f"{model.set_name(joints)} at t = {t:.9g} s, {where}", t)
    return NumericalFailure("non-finite", f"the acceleration or the state became NaN or infinite at t = {t:.6g} s "
                            f"in the coordinates {model.set_name(joints)}", t)


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
    np.asarray(new.clampm)[:] = np.asarray(chart.clampm)  # the clamps' modes and the frictions' slips go on
    np.asarray(new.slip)[:] = np.asarray(chart.slip)
    R = np.asarray(new.R)
    switches.append(Switch(t, model.set_name(chart.current), model.set_name(best), c_old, c_new))
    return np.concatenate([R @ x, R @ xdot, y[2 * k:]]), new, np.array(best, dtype=np.int64)


@dataclass(frozen=True)
class SeveralRun:
    """A run of several DOF, before the engine's energy gate (:func:`loopcheck.reduced.engine.simulate`).

    inputs: each input's trajectory and peak, in the scene's inputs order; joints: every joint
    coordinate; audit: the energy balance at the samples; switches: the coordinate switches;
    kinetic_scale: ½ max diag 𝔍 at the start (J per (rad/s)²), the energy scale's floor;
    friction_events: each change of a joint friction's mode (stick, slip and its way), in time order.
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
    friction_events: tuple = ()


SOLVER_NAMES = {"dop853": "DOP853", "rkn4": RKN4.name, "scipy-dop853": "scipy DOP853", "radau": "scipy Radau"}


def run_several(scene: Scene, settings: ReducedSettings = ReducedSettings(), step: float | None = None) -> SeveralRun:
    """The reduced engine's run of a scene of several DOF (module docstring): every input's
    trajectory and peak, every joint coordinate, the energy audit, the switches (``step``: RKN4's
    step instead of the settings', for its error estimate)."""
    check_scene(scene)
    model = SeveralModel(scene)
    begin = time.perf_counter()
    record, switches, n_steps, n_eval, J0, sets, events = integrate(model, settings, step)
    wall = time.perf_counter() - begin
    t = np.concatenate(record.t)
    x = np.concatenate(record.x)
    check_dropped(model, t, x)
    xdot = np.concatenate(record.xdot)
    xdd = np.concatenate(record.xdd)
    x[:, model.angle_columns] = loops.unwrap_angles(x[:, model.angle_columns])
    trajectories = [Trajectory(t, x @ r, xdot @ r, xdd @ r) for r in model.input_rows]
    joints = JointTrajectory(model.system.coordinate_names, t, x, xdot, np.full(len(t), -1),
                             loops.assembly_modes(model.system, x).reshape(len(t), -1))
    audit = EnergyAudit(t=t, kinetic=np.concatenate(record.T), potential=np.concatenate(record.V),
                        torque_work=np.concatenate(record.W), damper_dissipation=np.concatenate(record.E))
    return SeveralRun(tuple((tr, tr.peak_rate()) for tr in trajectories), joints, audit, tuple(switches), wall,
                      n_steps, n_eval, 0.5 * float(np.max(np.abs(np.diag(J0)))), SOLVER_NAMES[settings.method],
                      events)
