"""Generalized coordinate partitioning (Wehage & Haug) for Eksergian's equation.

The equation 𝔍 ẍ_i + ζ ẋ_i² + dV/dx_i = Q_i holds with any joint coordinate x_i as the
coordinate: a body's angle or a slider's displacement. At the input's dead centre (of a
crank, or of a slider driving a slider-crank) the input q cannot serve: K = dx/dq → ∞. The
driver integrates in the coordinate whose dependent loop Jacobian is best conditioned
(:meth:`LoopLinkage.conditioning`, over all joint coordinates) and switches, with
hysteresis, when the current one falls below ``HYSTERESIS`` times the best:

    switch when  c_i(x) < HYSTERESIS · max_j c_j(x);   ẋ_j = K_j ẋ_i  (K w.r.t. x_i).

Inside a chart the sign of det J_dep cannot change (the chart ends before its own
singularity), so it names the chart's assembly branch: the dependent angles are solved on
that branch (in closed form for the four-bar; by Newton's method from a predictor
x + K Δx_i + ½ L Δx_i², checked against the sign, for other linkages). The branch of the
input angle's closed form changes at each limit position and is tracked by this. The
integrators see only a scalar equation and a stop condition.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import loops
from .dynamics import Coefficients, MechanismModel
from .errors import NumericalFailure
from .integrators import Solution
from .linkage import Kinematics
from .trajectory import Trajectory

HYSTERESIS = 0.5  # switch when the current coordinate is less than half as well conditioned
MAX_SWITCHES = 10_000
# General path: a Newton correction larger than this fraction of the predicted motion |K Δ|
# means the jump was too long for the quadratic predictor (its error is O(Δ³)); the jump is
# then halved, at most MAX_HALVINGS times (each halving doubles the depth of the walk).
PREDICTOR_TRUST = 0.25
MAX_HALVINGS = 30
# A correction this small (rad or m) is always trusted: Newton's polish alone moves x by
# ~1e-16, and two assemblies are never this close except at a singular position.
TRUSTED_CORRECTION = 1e-9


@dataclass(frozen=True)
class Switch:
    """A change of independent coordinate at time t (s)."""

    time: float
    old: str
    new: str
    conditioning_old: float
    conditioning_new: float


@dataclass(frozen=True)
class JointTrajectory:
    """Every joint coordinate along a run, in the coordinates of :class:`reduced.loops.LoopSystem`.

    names (m,) its coordinate names; t (n,) s; x (n, m) rad or m (angles unwrapped);
    xdot (n, m) rad/s or m/s; coordinate (n,) index of the independent coordinate used at
    each sample (−1 for an engine without charts, MuJoCo); mode (n, loops) int, the
    assembly mode (:func:`reduced.loops.assembly_modes`) at each sample.
    """

    names: tuple[str, ...]
    t: np.ndarray
    x: np.ndarray
    xdot: np.ndarray
    coordinate: np.ndarray
    mode: np.ndarray


class Chart:
    """Eksergian's equation in one independent coordinate, with its dependent-angle cache."""

    def __init__(self, model: MechanismModel, independent: int, start: Kinematics):
        self.model = model
        self.linkage = model.linkage
        self.independent = independent
        self.name = self.linkage.coordinate_names[independent]
        self.branch = self.linkage.branch_of(start.x) if self.linkage.has_closed_form else 0
        self.sign = self.linkage.chart_sign(start.x, independent)
        self._start = start
        self._last = start
        # The input angle with a closed form keeps the branch it starts on inside a chart.
        self._closed_form = independent == 0 and self.linkage.has_closed_form
        # The stop check after a step asks again for the kinematics that the step's last
        # evaluation has just computed: keep that one.
        self._memo: tuple[float, Kinematics] | None = None

    def reset(self) -> None:
        self._last = self._start
        self._memo = None

    def kinematics(self, value: float) -> Kinematics:
        """Joint angles, K and L with x_i = value, continuous with the last call."""
        if self._memo is not None and self._memo[0] == value:
            return self._memo[1]
        if self._closed_form:
            kin = self.linkage.kinematics(value, self.branch)
        elif self.linkage.has_closed_form:  # the four-bar's dyad closed form (the guess picks the turn)
            last = self._last
            delta = value - last.x[self.independent]
            guess = last.x + last.K * delta + 0.5 * last.L * delta * delta
            kin = self.linkage.solve(guess, self.independent, value, self.sign)
            self._last = kin
        else:
            kin = self._continue(self._last, value, MAX_HALVINGS)
            self._last = kin
        self._memo = (value, kin)
        return kin

    def _continue(self, last: Kinematics, value: float, halvings: int) -> Kinematics:
        """Newton from the predictor x + K Δ + ½ L Δ² of ``last``; a jump whose Newton
        correction exceeds ``PREDICTOR_TRUST`` × the predicted motion |K Δ| (or that fails)
        is taken in two halves. Along a chart the configuration is a function of x_i
        (implicit function theorem, the branch fixed by the chart's sign), so walking back
        to an earlier value, as the dense output of an adaptive run does, finds the same
        configuration, in the same turn."""
        i = self.independent
        delta = value - last.x[i]
        guess = last.x + last.K * delta + 0.5 * last.L * delta * delta
        try:
            kin = self.linkage.solve(guess, i, value, self.sign)
            ok = float(np.max(np.abs(kin.x - guess))) <= PREDICTOR_TRUST * float(np.max(np.abs(last.K * delta))) + TRUSTED_CORRECTION
        except NumericalFailure:
            if halvings <= 0:
                raise
            ok, kin = False, None
        if ok or halvings <= 0:
            return kin
        middle = self._continue(last, last.x[i] + 0.5 * delta, halvings - 1)
        return self._continue(middle, value, halvings - 1)

    def coefficients(self, value: float) -> Coefficients:
        return self.model.coefficients_from(self.kinematics(value))

    def rhs_on_piece(self, start: float, end: float):
        """ẍ_i = f(t, x_i, ẋ_i) on one smooth piece of the load history."""
        load = self.model.load_on_piece(start, end)

        def f(t: float, value: float, rate: float) -> float:
            return self.coefficients(value).acceleration(load(t), rate)

        return f

    def switch_margin(self, t: float, value: float, rate: float) -> float:
        """> 0 while this coordinate is good enough; ≤ 0 when another is clearly better."""
        c = self.linkage.conditioning(self.kinematics(value).x)
        return c[self.independent] - HYSTERESIS * float(np.max(c))


def best_coordinate(model: MechanismModel, x: np.ndarray, current: int | None = None) -> int:
    """The best-conditioned coordinate, keeping ``current`` (or the input joint's coordinate,
    when q is one) unless another is better by more than the hysteresis factor."""
    c = model.linkage.conditioning(x)
    keep = model.linkage.input_coordinate if current is None else current
    if keep is not None and c[keep] >= HYSTERESIS * np.max(c):
        return keep
    return int(np.argmax(c))


@dataclass(frozen=True)
class PartitionedSolution:
    """The charts and per-chart solutions of one run, and what they add up to."""

    segments: tuple[tuple[Chart, Solution], ...]
    switches: tuple[Switch, ...]
    trajectory: Trajectory  # the input q, q̇, q̈
    joints: JointTrajectory
    n_steps: int
    n_evaluations: int
    method: str
    settings: dict = field(default_factory=dict)


def integrate_partitioned(model: MechanismModel, integrate_chart) -> PartitionedSolution:
    """Integrate the scene from t = 0 to its horizon, switching coordinates as needed.

    ``integrate_chart(rhs_on_piece, t_span, x0, v0, stop)`` runs one integrator in one chart
    and returns a :class:`Solution` (``stopped`` when ``stop`` fired).
    """
    scene, linkage = model.scene, model.linkage
    x0 = linkage.assemble(scene.q0)
    i = best_coordinate(model, x0)
    kin = linkage.coefficients_at(x0, i)
    input_rate = linkage.input_rate(kin.K)
    if scene.qdot0 != 0.0 and abs(input_rate) < 1e-12:
        raise NumericalFailure("singular", f"the input joint '{scene.mechanism.linkage.input_joint}' is at a "
                               f"dead centre at q0 = {scene.q0} {scene.input_unit}, where its speed must be zero")
    rate = scene.qdot0 / input_rate if scene.qdot0 != 0.0 else 0.0
    t = 0.0
    segments, switches = [], []
    while True:
        chart = Chart(model, i, kin)
        solution = integrate_chart(chart.rhs_on_piece, (t, scene.horizon), float(kin.x[i]), rate,
                                   chart.switch_margin)
        segments.append((chart, solution))
        if not solution.stopped or solution.trajectory.t[-1] >= scene.horizon:
            break
        if len(switches) >= MAX_SWITCHES:
            raise NumericalFailure("singular", f"more than {MAX_SWITCHES} coordinate switches", t)
        end = solution.trajectory
        t, value, rate_old = float(end.t[-1]), float(end.q[-1]), float(end.qdot[-1])
        old = chart.kinematics(value)
        c = linkage.conditioning(old.x)
        j = int(np.argmax(c))  # the stop condition fired: another coordinate is clearly better
        if j == i:
            raise NumericalFailure("singular", f"no better-conditioned coordinate at t = {t:.6g} s", t)
        kin = linkage.coefficients_at(old.x, j)
        rate = rate_old * old.K[j]  # ẋ_j = K_j ẋ_i, K w.r.t. the old coordinate
        switches.append(Switch(t, chart.name, linkage.coordinate_names[j], float(c[i]), float(c[j])))
        i = j
    input_traj, joints = _assemble_outputs(model, segments)
    first = segments[0][1]
    return PartitionedSolution(
        segments=tuple(segments), switches=tuple(switches), trajectory=input_traj, joints=joints,
        n_steps=sum(s.n_steps for _, s in segments), n_evaluations=sum(s.n_evaluations for _, s in segments),
        method=first.method, settings=first.settings)


def _assemble_outputs(model: MechanismModel, segments) -> tuple[Trajectory, JointTrajectory]:
    """The input's trajectory and all joint coordinates, from every chart's samples.

    q = drive·x, q̇ = (drive·K) ẋ_i, q̈ = (drive·L) ẋ_i² + (drive·K) ẍ_i (K, L w.r.t. the
    chart's coordinate x_i).
    """
    ts, vs, accs, xs, xdots, coords = [], [], [], [], [], []
    linkage = model.linkage
    for chart, solution in segments:
        chart.reset()
        tr = solution.trajectory
        for t, value, rate, accel in zip(tr.t, tr.q, tr.qdot, tr.qddot):
            kin = chart.kinematics(float(value))
            k_q = linkage.input_rate(kin.K)
            ts.append(t)
            vs.append(k_q * rate)
            accs.append(linkage.input_curvature(kin.L) * rate * rate + k_q * accel)
            xs.append(kin.x)
            xdots.append(kin.K * rate)
            coords.append(chart.independent)
    x = np.array(xs)
    angles = linkage.angle_columns()
    x[:, angles] = np.unwrap(x[:, angles], axis=0)  # continuous angles (no 2π jumps)
    general = linkage.to_general(x)
    q = general @ model.system.drive
    # Rates need no conversion: the closed form's coordinates differ from the general ones by
    # a constant (φ2 + π).
    joints = JointTrajectory(model.system.coordinate_names, np.array(ts), general,
                             np.array(xdots), np.array(coords),
                             loops.assembly_modes(model.system, general).reshape(len(ts), -1))
    return Trajectory(np.array(ts), q, np.array(vs), np.array(accs)), joints
