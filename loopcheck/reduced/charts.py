"""Generalized coordinate partitioning (Wehage & Haug) for Eksergian's equation.

The equation 𝔍 ẍ_i + ζ ẋ_i² + dV/dx_i = Q_i holds with any joint coordinate x_i as the
coordinate: a body's angle or a slider's displacement. At the input's dead centre (of a
crank, or of a slider driving a slider-crank) the input q cannot serve: K = dx/dq → ∞. The
driver integrates in the coordinate whose dependent loop Jacobian is best conditioned
(c_j = |det Φ_dep| / Π ‖columns of Φ_dep‖ over all joint coordinates) and switches, with
hysteresis, when the current one falls below ``HYSTERESIS`` times the best:

    switch when  c_i(x) < HYSTERESIS · max_j c_j(x);   ẋ_j = K_j ẋ_i  (K w.r.t. x_i).

Inside a chart the sign of det [Φ_x; e_i] cannot change (the chart ends before its own
singularity), so it names the chart's assembly branch: the dependent coordinates are found
by Newton's method from the predictor x + K Δx_i + ½ L Δx_i² of the chart's last
configuration, checked against the sign, a jump too long for the predictor taken in halves
(:mod:`loopcheck.reduced.kernels.physics`). The compiled runs string the charts together in the compiled
core (:mod:`loopcheck.reduced.kernels.partition`); :func:`integrate_partitioned` does it in Python for
the integrators that take a Python function (scipy's).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from loopcheck import kinematics as loops
from .dynamics import Coefficients, Kinematics, MechanismModel, coefficients_from, ranged_joints
from loopcheck.errors import NumericalFailure
from loopcheck.mechanism import PrismaticJoint
from .integrators import MAX_EVALUATIONS, SAMPLES_PER_STEP, SPEED_LIMIT, Solution, budget_spent
from .kernels import output, physics
from .kernels import partition as compiled
from .kernels.fixed_step import RKN4
from .kernels.output import Samples
from loopcheck.trajectory import JointTrajectory, Trajectory

HYSTERESIS = physics.HYSTERESIS  # switch when the current coordinate is less than half as well conditioned
MAX_SWITCHES = 10_000


@dataclass(frozen=True)
class Switch:
    """A change of independent coordinate at time t (s)."""

    time: float
    old: str
    new: str
    conditioning_old: float
    conditioning_new: float


@dataclass(frozen=True)
class FrictionEvent:
    """A change of the joint friction's mode at time t (s): "stick", or "slip" with the sign of
    the chart coordinate's rate (+1 or −1) in ``direction`` (0 for a stick). ``joint``: with
    several inputs, the joint whose friction changed (the sign then its own coordinate's rate);
    None with one input (every friction sticks and slips with the one coordinate)."""

    time: float
    mode: str
    direction: int = 0
    joint: str | None = None

    def __post_init__(self):
        if self.mode not in ("stick", "slip") or self.direction not in ((0,) if self.mode == "stick" else (1, -1)):
            raise ValueError(f"FrictionEvent: mode 'stick' with direction 0 or 'slip' with ±1, not {self.mode!r}, "
                             f"{self.direction!r}")


@dataclass(frozen=True)
class ClampEvent:
    """A change of an actuator's forcerange clamp at time t (s), its force from then on: "free"
    (between its bounds), "upper" or "lower" (held at that bound)."""

    time: float
    actuator: str
    mode: str

    def __post_init__(self):
        if self.mode not in CLAMP_MODES.values():
            raise ValueError(f"ClampEvent: mode {self.mode!r}, one of {sorted(CLAMP_MODES.values())}")


# the kernel's clamp modes (physics.CLAMP_FREE, …) by name
CLAMP_MODES = {physics.CLAMP_FREE: "free", physics.CLAMP_HI: "upper", physics.CLAMP_LO: "lower"}


class Chart:
    """Eksergian's equation in one independent coordinate: a Python view of a compiled chart
    (:class:`loopcheck.reduced.kernels.physics.Chart`) that starts at an assembled configuration x."""

    def __init__(self, model: MechanismModel, independent: int, x: np.ndarray, *, started: bool = False):
        """``started``: the chart of a compiled run, started there already: its compiled state is
        made when first used (a sweep's summary run uses none), not here."""
        self.model = model
        self.independent = independent
        self.name = model.coordinate_names[independent]
        self._x = np.array(x, dtype=float)  # a C-contiguous copy, as the kernel takes
        if not started:
            self.state  # noqa: B018 - made now: a start that fails is refused here

    @functools.cached_property
    def state(self) -> physics.Chart:
        """The compiled chart, started at x."""
        state = self.model.new_chart()
        if not state.start(self._x, self.independent):
            raise NumericalFailure("singular", f"{self.name} cannot drive the linkage at its start "
                                              f"({self.name} = {self._x[self.independent]:.15g})")
        return state

    @functools.cached_property
    def _views(self) -> dict:
        return self.state.arrays()

    @property
    def start(self) -> Kinematics:
        x, K, L = self._views["start"]
        return Kinematics(x.copy(), K.copy(), L.copy())

    def reset(self) -> None:
        """Walk again from the chart's start."""
        self.state.reset()

    def _evaluate(self, value: float) -> None:
        if not self.state.evaluate(float(value)):
            if self.state.S[physics.STATUS] == physics.WORK_SPENT:
                raise walk_work_spent(self.name, f"to {self.name} = {value:.15g}", None)
            raise NumericalFailure("singular", f"Newton's method did not close the loops with {self.name} = "
                                   f"{value:.15g} held on the chart's branch: the position is singular or "
                                   f"unreachable")

    def kinematics(self, value: float) -> Kinematics:
        """Joint coordinates, K and L with x_i = value, continuous with the last call."""
        self._evaluate(value)
        x, K, L = self._views["kin"]
        return Kinematics(x.copy(), K.copy(), L.copy())

    def coefficients(self, value: float) -> Coefficients:
        self._evaluate(value)
        return coefficients_from(self._views["fields"], self._views["kin"])

    def walk(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """From the chart's start, the coefficient fields (m, field_count) and kinematics
        (m, 3, n) at each of ``values`` in turn (compiled)."""
        values = np.array(values, dtype=float)  # a C-contiguous float64 copy, as the kernel takes
        fields = np.empty((len(values), physics.field_count(self.model.arrays)))
        kin = np.empty((len(values), 3, len(self.model.coordinate_names)))
        done = self.state.walk(values, fields, kin)
        if done < len(values) and self.state.S[physics.STATUS] == physics.WORK_SPENT:
            raise walk_work_spent(self.name, f"to {self.name} = {values[done]:.15g}", None)
        if done < len(values):
            raise NumericalFailure("singular", f"the chart of {self.name} cannot be followed to "
                                   f"{self.name} = {values[done]:.15g}")
        return fields, kin

    def rhs_on_piece(self, start: float, end: float):
        """ẍ_i = f(t, x_i, ẋ_i) on one smooth piece of the load history (a Python function)."""
        load = int(piece_load(self.model, start, end))
        state = self.state
        state.mark()

        def f(t: float, value: float, rate: float) -> float:
            a = state.acceleration(load, t, value, rate)
            if a != a and state.S[physics.STATUS] != physics.OK:  # SINGULAR or WORK_SPENT
                self._evaluate(value)  # raises with the reason
            return a

        f.rewind = state.rewind  # as the compiled DOP853 does
        return f

    def switch_margin(self, t: float, value: float, rate: float) -> float:
        """> 0 while this coordinate is good enough; ≤ 0 when another is clearly better."""
        self._evaluate(value)
        return self.state.stop_margin(t, value, rate)

    def conditioning(self, value: float) -> tuple[float, float, int]:
        """(c_i, max_j c_j, argmax_j) at x_i = value."""
        self._evaluate(value)
        f = self._views["fields"]
        return float(f[physics.CONDITIONING]), float(f[physics.BEST_CONDITIONING]), int(f[physics.BEST])


def conditioning(model: MechanismModel, x: np.ndarray) -> np.ndarray:
    """For each coordinate as the independent one, |det Φ_dep| / Π ‖columns of Φ_dep‖ (n,):
    0 where it cannot drive the linkage, 1 with the other columns orthogonal."""
    return loops.conditioning(model.system, x)


def best_coordinate(model: MechanismModel, x: np.ndarray, current: int | None = None) -> int:
    """The best-conditioned coordinate, keeping ``current`` (or the input joint's coordinate,
    when q is one) unless another is better by more than the hysteresis factor."""
    c = conditioning(model, x)
    keep = model.input_coordinate if current is None else current
    if keep is not None and c[keep] >= HYSTERESIS * np.max(c):
        return keep
    return int(np.argmax(c))


@dataclass(frozen=True)
class PartitionedSolution:
    """The charts and per-chart solutions of one run, and what they add up to."""

    segments: tuple[tuple[Chart, Solution], ...]
    switches: tuple[Switch, ...]
    trajectory: Trajectory  # the input q, q̇, q̈
    joints: JointTrajectory | None  # None for a summary run (integrate_dop853's ``summary``)
    n_steps: int
    n_evaluations: int
    # per segment, the coefficient fields (m, N_FIELDS) at its samples: recorded by the compiled
    # runs, walked to for the others (the outputs and the energy audit both use them)
    sample_fields: tuple[np.ndarray, ...]
    # per segment, the work done and the energy dissipated since the chart's start (m, 2), J,
    # integrated alongside the state by the compiled runs; None for scipy's (the energy audit
    # then integrates the power over the samples' interpolant)
    sample_energy: tuple[np.ndarray, ...] | None
    start_inertia: float  # 𝔍 (kg·m² or kg) at the scene's start configuration (:class:`Start`)
    method: str
    settings: dict = field(default_factory=dict)
    friction_events: tuple[FrictionEvent, ...] = ()  # the compiled runs' (each stick and slip)
    clamp_events: tuple[ClampEvent, ...] = ()        # the compiled runs' (each change of a forcerange clamp)


class Start(NamedTuple):
    """Where a run starts (:func:`_start`): the assembled x0 (n,), the coordinate i to start in, its
    rate ẋ_i for the scene's q̇0, 𝔍 there (kg·m² or kg: the energy scale's floor,
    :func:`loopcheck.reduced.engine.energy_scale`) and the compiled chart that found them (a compiled
    run starts it again and goes on with it: a chart fewer to make)."""

    x: np.ndarray
    coordinate: int
    rate: float
    inertia: float
    chart: physics.Chart


def _start(model: MechanismModel) -> Start:
    """Where the scene's run starts (:class:`Start`)."""
    scene = model.scene
    x0 = model.assemble(scene.q0)
    i = best_coordinate(model, x0)
    chart = Chart(model, i, x0)
    coefficients = chart.coefficients(float(x0[i]))
    if scene.qdot0 != 0.0 and loops.driving_conditioning(model.system, x0) < loops.SINGULAR_CONDITIONING:
        raise NumericalFailure("singular", f"the input joint '{scene.mechanism.linkage.input_joint}' is at a "
                               f"dead centre at q0 = {scene.q0} {scene.input_unit}, where its speed must be zero")
    rate = scene.qdot0 / coefficients.input_rate if scene.qdot0 != 0.0 else 0.0
    return Start(x0, i, rate, coefficients.generalized_inertia, chart.state)


def integrate_partitioned(model: MechanismModel, integrate_chart) -> PartitionedSolution:
    """Integrate the scene from t = 0 to its horizon, switching coordinates as needed, with
    an integrator that takes Python functions (scipy's).

    ``integrate_chart(rhs_on_piece, t_span, x0, v0, stop)`` runs one integrator in one chart
    and returns a :class:`Solution` (``stopped`` when ``stop`` fired).
    """
    scene = model.scene
    start = _start(model)
    x, i, rate = start.x, start.coordinate, start.rate
    t = 0.0
    segments, switches = [], []
    while True:
        chart = Chart(model, i, x)
        solution = integrate_chart(chart.rhs_on_piece, (t, scene.horizon), float(x[i]), rate,
                                   chart.switch_margin)
        segments.append((chart, solution))
        if not solution.stopped or solution.trajectory.t[-1] >= scene.horizon:
            break
        if len(switches) >= MAX_SWITCHES:
            raise NumericalFailure("singular", f"more than {MAX_SWITCHES} coordinate switches", t)
        end = solution.trajectory
        t, value, rate_old = float(end.t[-1]), float(end.q[-1]), float(end.qdot[-1])
        c_i, c_j, j = chart.conditioning(value)  # the stop condition fired: another is clearly better
        if j == i:
            raise NumericalFailure("singular", f"no better-conditioned coordinate at t = {t:.6g} s", t)
        old = chart.kinematics(value)
        rate = rate_old * old.K[j]  # ẋ_j = K_j ẋ_i, K w.r.t. the old coordinate
        switches.append(Switch(t, chart.name, model.coordinate_names[j], c_i, c_j))
        x, i = old.x, j
    return _solution(model, segments, switches, start.inertia)


def piece_load(model: MechanismModel, start: float, end: float) -> int:
    """The kernels' ``load`` on one smooth piece [start, end] of the load history: the index of
    the model's load piece holding it (:func:`loopcheck.reduced.dynamics.piece_values` holds the loads
    there, constant on it)."""
    edges = model.piece_edges
    return int(min(max(np.searchsorted(edges, 0.5 * (start + end), side="right") - 1, 0), len(edges) - 2))


def load_pieces(model: MechanismModel, t0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Edges (p+1,) of the smooth pieces of [t0, horizon] and each one's ``load``, its index
    among the model's load pieces (p,)."""
    horizon = model.scene.horizon
    edges = np.array([t0, *[b for b in model.load_edges if t0 < b < horizon], horizon])  # sorted, unique
    loads = np.array([piece_load(model, a, b) for a, b in zip(edges[:-1], edges[1:])], dtype=np.intp)
    return edges, loads


def walk_work_spent(name: str, where: str, t: float | None, rkn4: bool = False) -> NumericalFailure:
    """The failure of a chart of coordinate ``name`` whose walk (``where``: to a value, or at a
    time) needed more than :data:`~loopcheck.reduced.kernels.physics.MAX_WALK_CLOSURES` loop closures
    (``rkn4``: in a fixed-step run, whose step is the setting; else an adaptive one's rtol)."""
    shorter = "a smaller step (`--step`, `[reduced] step`)" if rkn4 else "a tighter rtol (`--rtol`, `[reduced] rtol`)"
    return NumericalFailure(
        "singular", f"the chart of {name} could not follow the linkage {where}: the walk needed more than "
        f"{physics.MAX_WALK_CLOSURES} closures of the loops (Newton's method on the loop equations converging "
        f"slowly or not at all: a position near a singular one, or loop equations that disagree with their "
        f"Jacobian); {shorter} shortens the jumps between the positions it must close", t)


def compiled_failure(model: MechanismModel, outcome, chart, step: float | None = None) -> NumericalFailure:
    """The :class:`NumericalFailure` for how a compiled run ended (``outcome``,
    :class:`loopcheck.reduced.kernels.output.Outcome`; ``step``: an RKN run's step, None for DOP853)."""
    t = float(outcome.fail_time) if outcome.fail_time == outcome.fail_time else 0.0
    unit = model.scene.input_unit
    status = outcome.status
    if status == output.NONFINITE:
        return NumericalFailure("non-finite", f"the state became NaN or infinite at t = {t:.6g} s", t)
    if status == output.SPEED:
        return NumericalFailure("unstable", f"|q̇| = {abs(outcome.fail_value):.3g} {unit}/s exceeds "
                                f"{SPEED_LIMIT:.3g} {unit}/s at t = {t:.6g} s: the integration is unstable at this step", t)
    if status == output.UNSTABLE:
        re, im, amplification, limit = outcome.detail
        return NumericalFailure(
            "unstable", f"the step h = {step:.3g} s is outside RKN4's stability region at t = {t:.6g} s "
            f"(h·λ = {re:.3g}{im:+.3g}j, |R| = {amplification:.6g} > {limit:.6g}): the problem is "
            "too stiff for this explicit step; use a smaller step (`--step`, `[reduced] step`) or "
            "the implicit Radau method", t)
    if status == output.STEP_SIZE:
        if outcome.n_evaluations >= MAX_EVALUATIONS:
            return budget_spent("DOP853", MAX_EVALUATIONS, t, 0.0, model.scene.horizon)
        return NumericalFailure(
            "step-size", f"DOP853's step fell below the spacing of the floating-point numbers at t = {t:.6g} s: "
            "it has collapsed (an extreme speed, damper or inertia in the scene?)", t)
    if status == output.FAILED:
        if chart.S[physics.STATUS] == physics.WORK_SPENT:
            name = model.coordinate_names[chart.S[physics.INDEPENDENT]]
            return walk_work_spent(name, f"at t = {t:.6g} s", t, rkn4=step is not None)
        if chart.S[physics.STATUS] == physics.SINGULAR:
            name = model.coordinate_names[chart.S[physics.INDEPENDENT]]
            return NumericalFailure("singular", f"Newton's method did not close the loops in the chart of {name} "
                                    f"at t = {t:.6g} s: the position is singular or unreachable", t)
        return NumericalFailure("non-finite", f"the acceleration became NaN or infinite at t = {t:.6g} s", t)
    if status == output.NO_BETTER:
        return NumericalFailure("singular", f"no better-conditioned coordinate at t = {t:.6g} s", t)
    if status == output.TOO_MANY_SWITCHES:
        return NumericalFailure("singular", f"more than {MAX_SWITCHES} coordinate switches, changes of the joint "
                                "friction between stick and slip or of an actuator's forcerange clamp", t)
    if status == output.RANGE_REACHED:
        r, side, u, bound = outcome.detail
        joint = ranged_joints(model.scene.mechanism.linkage)[int(r)]
        unit = "m" if isinstance(joint, PrismaticJoint) else "rad"
        lo, hi = joint.range
        failure = NumericalFailure(
            "range-reached", f"joint {joint.name!r} reached the {'upper' if side else 'lower'} bound {bound:.6g} {unit} "
            f"of its range [{lo:.6g}, {hi:.6g}] {unit} at t = {t:.9g} s: the exact solution stops there (MuJoCo's "
            "joint limit would act from then on)", t)
        failure.joint = joint.name  # the scene joint (an import says where its range came from)
        return failure
    return NumericalFailure("singular", "the run cannot start: its coordinate cannot drive the linkage", t)


def _run_compiled(model: MechanismModel, kernel, *settings, step: float | None = None,
                  **options) -> tuple[compiled.PartitionedRun, Start]:
    """A whole compiled run (``kernel``: :func:`loopcheck.reduced.kernels.partition.run_rkn` or
    ``run_dop853``, with its ``settings`` after the start and its keyword ``options``) from the
    scene's start over its load pieces; the run and its start, or the failure it reports raised."""
    start = _start(model)
    edges, loads = load_pieces(model)
    chart = start.chart
    run = kernel(chart, edges, loads, start.x, start.coordinate, start.rate, *settings,
                 Samples(chart.observation_size()), **options)
    if run.outcome.status != output.OK:
        raise compiled_failure(model, run.outcome, chart, step)
    return run, start


def integrate_rkn4(model: MechanismModel, step: float, check_stability: bool = True) -> PartitionedSolution:
    """The compiled RKN4 run of the scene at the largest step ``step`` (s), all charts."""
    run, start = _run_compiled(model, compiled.run_rkn, RKN4, float(step), SPEED_LIMIT, check_stability,
                               MAX_SWITCHES, step=step)
    return compiled_solution(model, run, start, RKN4.name, {"method": "rkn4", "step": step})


def integrate_dop853(model: MechanismModel, rtol: float, sample_interval: float,
                     retry_caps: tuple[float, ...], summary: bool = False) -> PartitionedSolution:
    """The compiled DOP853 run of the scene at rtol = atol = ``rtol``, all charts; samples no
    further apart than ``sample_interval`` (s); a chart that meets a singular position is run
    again with the step capped to each fraction ``retry_caps`` of its span.

    ``summary``: samples only at the solver's steps, and as above only in the steps beside each
    local maximum of the input's |q̇| over the steps (:func:`loopcheck.reduced.kernels.adaptive.dop853_run`'s
    ``peak_column``): a full run's steps, peak and energy flows to round-off, for a run whose
    trajectory is not kept (a sweep's row)."""
    run, start = _run_compiled(model, compiled.run_dop853, float(rtol), float(sample_interval), SAMPLES_PER_STEP,
                               SPEED_LIMIT, MAX_EVALUATIONS, tuple(float(c) for c in retry_caps), MAX_SWITCHES,
                               peak_column=physics.INPUT_RATE if summary else -1)
    return compiled_solution(model, run, start, "DOP853", {"method": "dop853", "rtol": rtol, "atol": rtol},
                             joints=not summary)


def _solution(model: MechanismModel, segments, switches, start_inertia: float, observed=None, energy=None,
              friction_events: tuple[FrictionEvent, ...] = (),
              clamp_events: tuple[ClampEvent, ...] = (), joints: bool = True) -> PartitionedSolution:
    """``observed``: per segment, what the compiled run recorded at its samples
    (:meth:`loopcheck.reduced.kernels.physics.Chart.observe`), or None to walk each chart to its samples;
    ``energy``: per segment, the energy flows the compiled run integrated (or None); ``joints``:
    whether to assemble the joints' trajectory (not for a summary run, whose row keeps none)."""
    n = len(model.coordinate_names)
    if observed is None:
        observed = [None] * len(segments)
    nf = physics.field_count(model.arrays)
    recorded = [(o[:, :nf], o[:, nf:].reshape(-1, 3, n)) if o is not None else
                chart.walk(solution.trajectory.q) for (chart, solution), o in zip(segments, observed)]
    input_traj, joint_traj = _assemble_outputs(model, segments, recorded, joints)
    first = segments[0][1]
    return PartitionedSolution(
        segments=tuple(segments), switches=tuple(switches), trajectory=input_traj, joints=joint_traj,
        n_steps=sum(s.n_steps for _, s in segments), n_evaluations=sum(s.n_evaluations for _, s in segments),
        sample_fields=tuple(f for f, _ in recorded), sample_energy=None if energy is None else tuple(energy),
        method=first.method, settings=first.settings, start_inertia=start_inertia, friction_events=friction_events,
        clamp_events=clamp_events)


def compiled_solution(model: MechanismModel, run: compiled.PartitionedRun, start: Start, method: str,
                      settings: dict, joints: bool = True) -> PartitionedSolution:
    """A :class:`PartitionedSolution` from a compiled partitioned run from ``start`` (``joints``:
    with the joints' trajectory, :func:`_solution`)."""
    t, value, rate, accel, observed, energy = run.samples.arrays()
    cuts = run.segment_starts[1:]
    bounds = [0, *(int(c) for c in cuts), len(t)]
    segments = []
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):  # (views of the samples' fresh copies)
        chart = Chart(model, int(run.coordinates[k]), run.starts[k][0], started=True)
        traj = Trajectory(t[a:b], value[a:b], rate[a:b], accel[a:b])
        stopped = k + 1 < len(run.coordinates)
        first = k == 0  # the run's counts go with its first segment
        segments.append((chart, Solution(traj, method, run.outcome.n_steps if first else 0,
                                         run.outcome.n_evaluations if first else 0, settings, stopped=stopped)))
    names = model.coordinate_names
    switches = [Switch(float(r[0]), names[int(r[1])], names[int(r[2])], float(r[3]), float(r[4]))
                for r in run.switches]
    events = tuple(FrictionEvent(float(t), "stick", 0) if mode == physics.STICK else FrictionEvent(float(t), "slip", int(mode))
                   for t, mode in run.events)
    actuators = model.scene.mechanism.actuators
    clamps = tuple(ClampEvent(float(t), actuators[int(a)].name, CLAMP_MODES[int(mode)]) for t, a, mode in run.clamps)
    return _solution(model, segments, switches, start.inertia, np.split(observed, cuts), np.split(energy, cuts),
                     events, clamps, joints)


def _assemble_outputs(model: MechanismModel, segments, recorded,
                      joints: bool = True) -> tuple[Trajectory, JointTrajectory | None]:
    """The input's trajectory and, with ``joints``, all joint coordinates (else None), from every
    chart's samples and the fields (m, N_FIELDS) and kinematics (m, 3, n) at them (``recorded``,
    per segment).

    q = drive·x, q̇ = (drive·K) ẋ_i, q̈ = (drive·L) ẋ_i² + (drive·K) ẍ_i (K, L w.r.t. the
    chart's coordinate x_i).
    """
    ts, vs, accs, xs, xdots, coords = [], [], [], [], [], []
    for (chart, solution), (fields, kin) in zip(segments, recorded):
        tr = solution.trajectory
        k_q, l_q = fields[:, physics.INPUT_RATE], fields[:, physics.INPUT_CURVATURE]
        ts.append(tr.t)
        vs.append(k_q * tr.qdot)
        accs.append(l_q * tr.qdot ** 2 + k_q * tr.qddot)
        xs.append(kin[:, 0, :])
        if joints:
            xdots.append(kin[:, 1, :] * tr.qdot[:, None])
            coords.append(np.full(len(tr.t), chart.independent))
    x = np.concatenate(xs)
    angles = model.angle_columns
    x[:, angles] = loops.unwrap_angles(x[:, angles])  # continuous angles (no 2π jumps)
    t = np.concatenate(ts)
    joint_traj = JointTrajectory(model.coordinate_names, t, x, np.concatenate(xdots), np.concatenate(coords),
                                 loops.assembly_modes(model.system, x).reshape(len(t), -1)) if joints else None
    return Trajectory(t, x @ model.system.drive, np.concatenate(vs), np.concatenate(accs)), joint_traj
