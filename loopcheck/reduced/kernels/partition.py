# cython: wraparound=True
# (the chart switching indexes Python arrays from their end; it has no hot loop)
"""Coordinate partitioning and events: a whole run of charts, switching at dead centres.

A run integrates one chart until its stop margin falls to ≤ 0 (another coordinate is better
conditioned by more than the hysteresis), then continues in the best-conditioned coordinate j
from the same configuration, with ẋ_j = K_j ẋ_i (K with respect to the old coordinate x_i), and a slipping friction's sign
that of ẋ_j.
:mod:`loopcheck.reduced.charts` documents the method; this module only strings the charts together,
with either integrator: :func:`run_rkn` (fixed step, :mod:`.fixed_step`) or :func:`run_dop853`
(adaptive, :mod:`.adaptive`). Each chart's samples are appended to one :class:`.output.Samples`,
so the run's samples come out in one piece; :class:`PartitionedRun` says where each chart's begin.

A chart's stop margin is the least of its events' (:meth:`.physics.Chart.stop_margin`): after a
stop the run asks the chart which fired (:meth:`~.physics.Chart.fired`) and acts on it. A chart
switch, as above. The joint friction: at q̇ = 0 while slipping, or at a load edge while
sticking, the friction sticks if every other generalized force there, Q_rest (q̇ = 0), is
within its capacity C = Σ f |K_u| (|Q_rest| ≤ C), else slips in the sign of Q_rest; the chart
starts again there with q̇ = 0 (a new segment in the same coordinate). A friction's kink (its
K_u = row·K changing sign while it slips: its force −s f |K_u| has a kink there): the chart starts
again there (a new segment), so that no step straddles it. A joint's range: the
run ends there with RANGE_REACHED (detail: the range's index, its side 0 lower or 1 upper, the
joint's coordinate and the bound). An actuator's forcerange clamp on a force that depends on the
state: where its unclamped force crosses a bound (by the clamp's hysteresis), each clamp's mode is
set again from the state (:meth:`~.physics.Chart.set_clamps`: free between the bounds, else held at
the bound it passed) and the chart starts again there, at the same rate (q̈ is continuous there, its
derivative is not: the integrators never step across the kink).

The switching happens a handful of times a run (none on most scenes): this is the one kernel
module whose work is not in a hot loop, compiled with the others but typed only where it is free.
"""

from typing import NamedTuple

import cython
import numpy as np

from . import adaptive, fixed_step, physics
from .output import FAILED, NO_BETTER, NONFINITE, OK, RANGE_REACHED, SINGULAR_START, TOO_MANY_SWITCHES

if cython.compiled:
    from cython.cimports.loopcheck.reduced.kernels.output import Outcome, Samples
else:
    from .output import Outcome, Samples


class PartitionedRun(NamedTuple):
    """A whole run: how it ended, and its samples (in ``samples``, appended chart after chart)."""

    outcome: Outcome               # status, counts (over every chart), fail_time, fail_value, detail
    samples: Samples               # t, the chart's coordinate and its rate and acceleration, observed, energy
    segment_starts: np.ndarray     # (segments,) the index of each chart's first sample
    coordinates: np.ndarray        # (segments,) each chart's coordinate
    starts: np.ndarray             # (segments, 3, n) each chart's start configuration (x, K, L)
    switches: np.ndarray           # (switches, 5) each chart switch: time, old, new, c_old, c_new
    events: np.ndarray             # (friction events, 2) each change of the friction's mode: time, new mode
    clamps: np.ndarray = np.empty((0, 3))  # (clamp events, 3) each change of a clamp's mode: time, actuator, new mode


def switch(chart, value: cython.double, rate: cython.double):
    """Move ``chart`` (stopped at x_i = value, rate ẋ_i) to the best-conditioned coordinate.

    Returns (status, new rate, (old, new, c_old, c_new))."""
    if not chart.evaluate(value):
        return FAILED, rate, None
    views = chart.arrays()
    fields, kin = views["fields"], views["kin"]
    i = int(chart.S[physics.INDEPENDENT])
    j = int(fields[physics.BEST])
    c_old, c_new = float(fields[physics.CONDITIONING]), float(fields[physics.BEST_CONDITIONING])
    if j == i:
        return NO_BETTER, rate, None
    k_j = float(kin[1, j])
    if not chart.start(kin[0].copy(), j):
        return FAILED, rate, None
    return OK, rate * k_j, (i, j, c_old, c_new)


def _pieces_from(edges, loads, t: cython.double):
    """The load pieces of [t, edges[-1]]: edges (p+1,) starting at t and their loads (p,)."""
    first: cython.Py_ssize_t = 0
    while first < loads.shape[0] - 1 and edges[first + 1] <= t:
        first += 1
    out_edges = np.array(edges[first:], dtype=np.float64)
    out_edges[0] = t
    return out_edges, np.array(loads[first:], dtype=np.intp)


def _dop853_chart(chart, steps, edges, loads, t: cython.double, value: cython.double, rate: cython.double,
                  rtol: cython.double, sample_interval: cython.double, per_step: cython.Py_ssize_t,
                  speed_limit: cython.double, max_evaluations: cython.Py_ssize_t, retry_caps, out: Samples,
                  peak_column: cython.Py_ssize_t = -1):
    """One chart by DOP853 from t; a chart that meets a singular position (a trial stage past
    the reach of its coordinate, before the switch event fires) is integrated again from its
    start with the step capped to each fraction of its span in ``retry_caps`` in turn (the
    failed attempt's samples dropped)."""
    piece_edges, piece_loads = _pieces_from(edges, loads, t)
    span = edges[-1] - t
    first = out.n
    for attempt in range(len(retry_caps) + 1):
        cap = np.inf if attempt == 0 else retry_caps[attempt - 1] * span
        if attempt > 0:
            chart.reset()
            out.n = first
        outcome = adaptive.dop853_run(chart, piece_edges, piece_loads, value, rate, rtol, rtol, sample_interval,
                                      per_step, speed_limit, max_evaluations, cap, True, out, steps, peak_column)
        walk_failed = outcome.status == NONFINITE and chart.S[physics.STATUS] != physics.OK  # SINGULAR, WORK_SPENT
        if not (walk_failed and chart.S[physics.STATUS] == physics.SINGULAR):
            break
    if walk_failed:
        outcome.status = FAILED
    return outcome


def _friction_mode(chart, edges, loads, t: cython.double, value: cython.double, rate: cython.double):
    """The friction's mode at (t, value, rate): slipping in the sign of a nonzero rate, else
    sticking if the loads of the piece from t leave Q_rest within the capacity, else slipping in
    the sign of Q_rest. NaN where the configuration fails."""
    if rate > 0.0:
        return 1.0
    if rate < 0.0:
        return -1.0
    load = int(_pieces_from(edges, loads, t)[1][0])
    rest = chart.rest_force(load, value)
    if rest != rest:
        return rest
    capacity = float(chart.arrays()["fields"][physics.FRICTION_CAPACITY])
    if abs(rest) <= capacity:
        return float(physics.STICK)
    return 1.0 if rest > 0.0 else -1.0


def _run(chart, edges, loads, x0, independent: cython.Py_ssize_t, rate0: cython.double, integrate_chart,
         max_switches: cython.Py_ssize_t, out: Samples) -> PartitionedRun:
    """The charts from the start: ``integrate_chart(t, value, rate, spent)`` runs the current chart
    from t (``spent``: the evaluations of q̈ the run has used so far) and returns its :class:`Outcome`.
    ``max_switches`` bounds the chart switches and the friction's changes of mode, each."""
    n = int(chart.n)
    total = Outcome()
    segment_starts, coordinates, starts, switches, events = [out.n], [independent], [], [], []
    friction = bool(chart.model.I[physics.N_FRICTION])
    clamped = bool(chart.model.I[physics.N_CLAMPED])
    clamps = []
    if not chart.start(np.ascontiguousarray(x0, dtype=np.float64), independent):
        total.status = SINGULAR_START
        return PartitionedRun(total, out, np.zeros(0, np.intp), np.zeros(0, np.intp), np.empty((0, 3, n)),
                              np.empty((0, 5)), np.empty((0, 2)))
    starts.append(chart.arrays()["start"].copy())
    t, value, rate = float(edges[0]), float(x0[independent]), rate0
    if clamped and chart.set_clamps(int(_pieces_from(edges, loads, t)[1][0]), value, rate) < 0:
        total.status = SINGULAR_START
        return PartitionedRun(total, out, np.zeros(0, np.intp), np.zeros(0, np.intp), np.empty((0, 3, n)),
                              np.empty((0, 5)), np.empty((0, 2)))
    if friction:
        mode = _friction_mode(chart, edges, loads, t, value, rate)
        if mode != mode:
            total.status = SINGULAR_START
            return PartitionedRun(total, out, np.zeros(0, np.intp), np.zeros(0, np.intp), np.empty((0, 3, n)),
                                  np.empty((0, 5)), np.empty((0, 2)))
        chart.set_friction(mode)
        chart.set_kinks(-1)
    kinks = physics.RANGE_EVENT + 2 * int(chart.model.I[physics.N_RANGES])  # the first kink's event
    while True:
        outcome = integrate_chart(t, value, rate, total.n_evaluations)
        total.n_steps += outcome.n_steps
        total.n_evaluations += outcome.n_evaluations
        total.n_sample_evaluations += outcome.n_sample_evaluations
        total.status, total.stopped = outcome.status, outcome.stopped
        total.fail_time, total.fail_value, total.detail = outcome.fail_time, outcome.fail_value, outcome.detail
        last = out.n - 1
        if outcome.status != OK or not outcome.stopped or last < 0:
            break
        t, value, rate = out.t[last], out.q[last], out.v[last]
        event = chart.fired(t, value, rate)
        if event < 0:
            total.status, total.fail_time = FAILED, t
            break
        actuator = chart.clamp_event(event)
        if physics.RANGE_EVENT <= event < kinks:  # the run ends here, even at its last instant
            r, side = divmod(event - physics.RANGE_EVENT, 2)
            row = chart.model.F[chart.model.I[physics.RANGE_ROWS] + r * n:][:n]
            bound = chart.model.F[chart.model.I[physics.RANGE_BOUNDS] + 2 * r + side]
            u = float(row @ chart.arrays()["kin"][0])
            total.status, total.fail_time = RANGE_REACHED, t
            total.detail = np.array([r, side, u, bound], dtype=np.float64)
            break
        if t >= edges[-1]:
            break
        total.stopped = False
        if event >= kinks and actuator < 0:  # a friction's K_u changed sign: the chart again from here, that kink's sign flipped
            if not chart.start(chart.arrays()["kin"][0].copy(), int(chart.S[physics.INDEPENDENT])):
                total.status, total.fail_time = FAILED, t
                break
            chart.set_kinks(event - kinks)
        if actuator >= 0:  # a clamp's kink: each clamp's mode set from the state (no jump in q̈)
            if len(clamps) + 1 > max_switches:
                total.status, total.fail_time = TOO_MANY_SWITCHES, t
                break
            before = chart.arrays()["clamp"].copy()
            load = int(_pieces_from(edges, loads, t)[1][0])
            if chart.set_clamps(load, value, rate) < 0 or not chart.start(chart.arrays()["kin"][0].copy(),
                                                                          int(chart.S[physics.INDEPENDENT])):
                total.status, total.fail_time = FAILED, t
                break
            after = chart.arrays()["clamp"]
            changed = np.flatnonzero(after != before)
            clamps += [(t, int(a), float(after[a])) for a in changed] or [(t, actuator, float(after[actuator]))]
        if event >= kinks:
            segment_starts.append(out.n)
            coordinates.append(int(chart.S[physics.INDEPENDENT]))
            starts.append(chart.arrays()["start"].copy())
            value = starts[-1][0, coordinates[-1]]
            continue
        if event == physics.FRICTION_EVENT:
            if len(events) + 1 > max_switches:
                total.status, total.fail_time = TOO_MANY_SWITCHES, t
                break
            mode = _friction_mode(chart, edges, loads, t, value, 0.0)
            if mode != mode or not chart.start(chart.arrays()["kin"][0].copy(), int(chart.S[physics.INDEPENDENT])):
                total.status, total.fail_time = FAILED, t
                break
            chart.set_friction(mode)
            chart.set_kinks(-1)
            rate = 0.0
            events.append((t, mode))
            segment_starts.append(out.n)
            coordinates.append(int(chart.S[physics.INDEPENDENT]))
            starts.append(chart.arrays()["start"].copy())
            value = starts[-1][0, coordinates[-1]]
            continue
        if len(switches) + 1 > max_switches:
            total.status, total.fail_time = TOO_MANY_SWITCHES, t
            break
        status, rate, switched = switch(chart, value, rate)
        if status != OK:
            total.status, total.fail_time = status, t
            break
        switches.append((t, *switched))
        mode = chart.arrays()["fields"][physics.FRICTION_MODE]
        if friction and (mode == 1.0 or mode == -1.0):  # the slip's sign is ẋ_j's now: ẋ_j = K_j ẋ_i
            chart.set_friction(mode if (rate > 0.0) == (mode > 0.0) or rate == 0.0 else -mode)
        if friction:
            chart.set_kinks(-1)  # K w.r.t. the new coordinate
        segment_starts.append(out.n)
        coordinates.append(switched[1])
        starts.append(chart.arrays()["start"].copy())
        value = starts[-1][0, switched[1]]
    total.t_reached = out.t[out.n - 1] if out.n else edges[0]
    return PartitionedRun(total, out, np.array(segment_starts, dtype=np.intp), np.array(coordinates, dtype=np.intp),
                          np.array(starts).reshape(-1, 3, n), np.array(switches, dtype=np.float64).reshape(-1, 5),
                          np.array(events, dtype=np.float64).reshape(-1, 2),
                          np.array(clamps, dtype=np.float64).reshape(-1, 3))


def run_rkn(chart, edges, loads, x0, independent: cython.Py_ssize_t, rate0: cython.double, tableau,
            step: cython.double, speed_limit: cython.double, stability: cython.bint,
            max_switches: cython.Py_ssize_t, out: Samples) -> PartitionedRun:
    """An RKN method (``tableau``, :mod:`.fixed_step`) at the largest step ``step`` (s) over
    [edges[0], edges[-1]] (load piece ``loads[k]`` on [edges[k], edges[k+1]]) from the assembled
    x0 with ẋ_independent = rate0, switching charts as needed; samples appended to ``out``."""
    def integrate_chart(t, value, rate, spent):
        return fixed_step.rkn_chart(chart, tableau, edges, loads, t, value, rate, step, speed_limit, stability,
                                    True, out)

    return _run(chart, edges, loads, x0, independent, rate0, integrate_chart, max_switches, out)


def run_dop853(chart, edges, loads, x0, independent: cython.Py_ssize_t, rate0: cython.double,
               rtol: cython.double, sample_interval: cython.double, per_step: cython.Py_ssize_t,
               speed_limit: cython.double, max_evaluations: cython.Py_ssize_t, retry_caps,
               max_switches: cython.Py_ssize_t, out: Samples, steps=None,
               peak_column: cython.Py_ssize_t = -1) -> PartitionedRun:
    """DOP853 at rtol = atol ``rtol`` (scipy's algorithm, :mod:`.adaptive`), sampled no coarser
    than ``sample_interval`` (s), each step in at least ``per_step`` parts; ``max_evaluations`` of q̈
    in all; charts that meet a singular position retried with the step capped to the fractions
    ``retry_caps`` of their span; ``steps`` (:class:`.adaptive.Steps`), the step storage (may be reused), taken
    when given; ``peak_column`` ≥ 0: a summary run (:func:`.adaptive.dop853_run`), sampled only where
    the peak of that observed column times q̇ can lie."""
    steps = adaptive.Steps() if steps is None else steps

    def integrate_chart(t, value, rate, spent):
        return _dop853_chart(chart, steps, edges, loads, t, value, rate, rtol, sample_interval, per_step,
                             speed_limit, max_evaluations - spent, retry_caps, out, peak_column)

    return _run(chart, edges, loads, x0, independent, rate0, integrate_chart, max_switches, out)
