"""Generalized coordinate partitioning (Wehage & Haug) for Eksergian's equation.

The equation 𝔍 ẍ_i + ζ ẋ_i² + dV/dx_i = Q_i holds with any joint angle x_i as the
coordinate. At the input link's dead centre (coupler and rocker collinear) the input
angle q cannot serve: K = dφ/dq → ∞. The driver integrates in the coordinate whose
dependent loop Jacobian is best conditioned (:meth:`LoopLinkage.conditioning`) and switches,
with hysteresis, when the current one falls below ``HYSTERESIS`` times the best:

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

from .dynamics import Coefficients, MechanismModel
from .errors import NumericalFailure
from .integrators import Solution
from .linkage import Kinematics
from .trajectory import Trajectory

HYSTERESIS = 0.5  # switch when the current coordinate is less than half as well conditioned
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
class JointTrajectory:
    """Every joint angle along a run.

    t (n,) s; x (n, m) rad; xdot (n, m) rad/s; coordinate (n,) index of the independent
    angle used at each sample; branch (n,) the assembly branch (±1) at each sample.
    """

    names: tuple[str, ...]
    t: np.ndarray
    x: np.ndarray
    xdot: np.ndarray
    coordinate: np.ndarray
    branch: np.ndarray


class Chart:
    """Eksergian's equation in one independent coordinate, with its dependent-angle cache."""

    def __init__(self, model: MechanismModel, independent: int, start: Kinematics):
        self.model = model
        self.linkage = model.linkage
        self.independent = independent
        self.name = self.linkage.coordinate_names[independent]
        self.branch = self.linkage.branch_of(start.x)
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
        else:
            last = self._last
            delta = value - last.x[self.independent]
            guess = last.x + last.K * delta + 0.5 * last.L * delta * delta
            kin = self.linkage.solve(guess, self.independent, value, self.sign)
            self._last = kin
        self._memo = (value, kin)
        return kin

    def coefficients(self, value: float) -> Coefficients:
        return self.model.coefficients_from(self.kinematics(value))

    def rhs_on_piece(self, start: float, end: float):
        """ẍ_i = f(t, x_i, ẋ_i) on one smooth piece of the load history."""
        torque = self.model.torque_on_piece(start, end)

        def f(t: float, value: float, rate: float) -> float:
            return self.coefficients(value).acceleration(torque(t), rate)

        return f

    def switch_margin(self, t: float, value: float, rate: float) -> float:
        """> 0 while this coordinate is good enough; ≤ 0 when another is clearly better."""
        c = self.linkage.conditioning(self.kinematics(value).x)
        return c[self.independent] - HYSTERESIS * float(np.max(c))


def best_coordinate(model: MechanismModel, x: np.ndarray, current: int | None = None) -> int:
    """The best-conditioned coordinate, keeping ``current`` (or the input angle) unless
    another is better by more than the hysteresis factor."""
    c = model.linkage.conditioning(x)
    keep = 0 if current is None else current
    if c[keep] >= HYSTERESIS * np.max(c):
        return keep
    return int(np.argmax(c))


@dataclass(frozen=True)
class PartitionedSolution:
    """The charts and per-chart solutions of one run, and what they add up to."""

    segments: tuple[tuple[Chart, Solution], ...]
    switches: tuple[Switch, ...]
    trajectory: Trajectory  # the input link q, q̇, q̈
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
    if scene.qdot0 != 0.0 and abs(kin.K[0]) < 1e-12:
        raise NumericalFailure("singular", f"the input link is at a dead centre at q0 = {scene.q0} rad, "
                               "where its speed must be zero")
    rate = scene.qdot0 / kin.K[0] if scene.qdot0 != 0.0 else 0.0
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
    input_traj, joints = _assemble_outputs(segments)
    first = segments[0][1]
    return PartitionedSolution(
        segments=tuple(segments), switches=tuple(switches), trajectory=input_traj, joints=joints,
        n_steps=sum(s.n_steps for _, s in segments), n_evaluations=sum(s.n_evaluations for _, s in segments),
        method=first.method, settings=first.settings)


def _assemble_outputs(segments) -> tuple[Trajectory, JointTrajectory]:
    """The input link's trajectory and all joint angles, from every chart's samples.

    q = x[0], q̇ = K_0 ẋ_i, q̈ = L_0 ẋ_i² + K_0 ẍ_i (K, L w.r.t. the chart's coordinate).
    """
    ts, qs, vs, accs, xs, xdots, coords = [], [], [], [], [], [], []
    for chart, solution in segments:
        chart.reset()
        tr = solution.trajectory
        for t, value, rate, accel in zip(tr.t, tr.q, tr.qdot, tr.qddot):
            kin = chart.kinematics(float(value))
            ts.append(t)
            qs.append(kin.x[0])
            vs.append(kin.K[0] * rate)
            accs.append(kin.L[0] * rate * rate + kin.K[0] * accel)
            xs.append(kin.x)
            xdots.append(kin.K * rate)
            coords.append(chart.independent)
    linkage = segments[0][0].linkage
    x = np.unwrap(np.array(xs), axis=0)  # continuous angles (no 2π jumps)
    joints = JointTrajectory(linkage.coordinate_names, np.array(ts), x, np.array(xdots), np.array(coords),
                             linkage.branches(x))
    return Trajectory(np.array(ts), x[:, 0], np.array(vs), np.array(accs)), joints
