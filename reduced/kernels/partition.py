"""Coordinate partitioning in compiled code: a whole run of charts, switching at dead centres.

A run integrates one chart until its stop margin falls to ≤ 0 (another coordinate is better
conditioned by more than the hysteresis), then continues in the best-conditioned coordinate j
from the same configuration, with ẋ_j = K_j ẋ_i (K with respect to the old coordinate x_i).
:mod:`reduced.partition` documents the method; this module only strings the charts together,
with either integrator: :func:`run_rkn4` (fixed step) or :func:`run_dop853` (adaptive).

Both return (status, info, t, value, rate, accel, segment, coordinate, starts, switches,
n_steps, n_evaluations, observed, energy): the samples of each chart's coordinate, the segment (chart
number) of each sample, each segment's coordinate and start configuration (segments, 3, n), each
switch as (time, old, new, c_old, c_new), and the chart's fields, x, K and L at every sample
(:func:`.physics.observe`), and the work done and the energy dissipated since each chart's start
at every sample (samples, 2) (J, integrated alongside the state: :func:`.physics.power`).
info[0] is the time of a failure, info[1] its value.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import adaptive, physics
from .fixed_step import FAILED, NONFINITE, OK, rkn4_chart

# statuses beyond the integrators' own (OK 0, STEP_SIZE 1, NONFINITE 2, SPEED 3, UNSTABLE 4,
# FAILED 5)
NO_BETTER, TOO_MANY_SWITCHES, SINGULAR_START = 6, 7, 8


@njit(cache=True, error_model="numpy")
def _concatenate(parts, total):
    out = np.empty(total)
    k = 0
    for p in parts:
        for j in range(p.shape[0]):
            out[k + j] = p[j]
        k += p.shape[0]
    return out


@njit(cache=True, error_model="numpy")
def _concatenate_rows(parts, total, width):
    out = np.empty((total, width))
    k = 0
    for p in parts:
        for j in range(p.shape[0]):
            for c in range(width):
                out[k + j, c] = p[j, c]
        k += p.shape[0]
    return out


@njit(cache=True, error_model="numpy")
def switch(model, chart, value, rate, info):
    """Move ``chart`` (stopped at x_i = value, rate ẋ_i) to the best-conditioned coordinate.

    Returns (status, new rate); info[1:5] = (old, new, c_old, c_new) on success."""
    if not physics.evaluate(model, chart, value):
        return FAILED, rate
    views = physics._views(model[1], chart[1])
    fields, kin = views[4], views[3]
    i = chart[0][physics.INDEPENDENT]
    j = int(fields[physics.BEST])
    c_old, c_new = fields[physics.CONDITIONING], fields[physics.BEST_CONDITIONING]
    if j == i:
        return NO_BETTER, rate
    k_j = kin[1, j]
    x = kin[0].copy()
    if not physics.start_chart(model, chart, x, j):
        return FAILED, rate
    info[1], info[2], info[3], info[4] = i, j, c_old, c_new
    return OK, rate * k_j


@njit(cache=True, error_model="numpy")
def _pieces_from(edges, loads, t):
    """The load pieces of [t, edges[-1]]: edges (p+1,) starting at t and their loads (p,)."""
    first = 0
    while first < loads.shape[0] - 1 and edges[first + 1] <= t:
        first += 1
    p = loads.shape[0] - first
    out_edges = np.empty(p + 1)
    out_loads = np.empty(p)
    out_edges[0] = t
    for k in range(p):
        out_loads[k] = loads[first + k]
        out_edges[k + 1] = edges[first + k + 1]
    return out_edges, out_loads


@njit(cache=True, error_model="numpy")
def _dop853_chart(model, chart, edges, loads, t, value, rate, rtol, sample_interval, per_step, speed_limit,
                  max_evaluations, retry_caps, info):
    """One chart by DOP853 from t; a chart that meets a singular position (a trial stage past
    the reach of its coordinate, before the switch event fires) is integrated again from its
    start with the step capped to each fraction of its span in ``retry_caps`` in turn."""
    piece_edges, piece_loads = _pieces_from(edges, loads, t)
    span = edges[-1] - t
    for attempt in range(retry_caps.shape[0] + 1):
        cap = math.inf if attempt == 0 else retry_caps[attempt - 1] * span
        if attempt > 0:
            physics.reset(model, chart)
        (status, ts, qs, vs, accs, steps, evals, sample_evals, stopped, t_reached, fail_time,
         fail_value, observed, energy) = adaptive.dop853_run(model, chart, piece_edges, piece_loads, value, rate, rtol, rtol,
                                           sample_interval, per_step, speed_limit, max_evaluations, cap, True)
        walk_failed = status == NONFINITE and chart[0][physics.STATUS] != physics.OK  # SINGULAR or WORK_SPENT
        singular = walk_failed and chart[0][physics.STATUS] == physics.SINGULAR
        if not singular:
            break
    if status != OK:
        info[0], info[1] = fail_time, fail_value
        if walk_failed:
            status = FAILED
    return status, stopped, ts, qs, vs, accs, observed, energy, steps, evals  # as scipy counts: not the samples


@njit(cache=True, error_model="numpy")
def _run(model, chart, edges, loads, x0, independent, rate0, adaptive_method, step, rtol, sample_interval,
         per_step, speed_limit, stability, max_evaluations, retry_caps, max_switches):
    n = model[1][physics.N]
    info = np.zeros(8)
    t_parts, q_parts, v_parts, a_parts, seg_parts = [np.empty(0)], [np.empty(0)], [np.empty(0)], [np.empty(0)], \
        [np.empty(0)]
    width = physics.observation_size(model)
    o_parts = [np.empty((0, width))]
    e_parts = [np.empty((0, 2))]
    coordinates = [independent]
    starts = [np.empty((3, n))]
    switches = [np.zeros(5)]
    if not physics.start_chart(model, chart, x0, independent):
        return (SINGULAR_START, info, np.empty(0), np.empty(0), np.empty(0), np.empty(0),
                np.zeros(0, np.int64), np.zeros(0, np.int64), np.empty((0, 3, n)), np.empty((0, 5)), 0, 0,
                np.empty((0, width)), np.empty((0, 2)))
    starts[0] = physics._views(model[1], chart[1])[1].copy()
    t, value, rate = edges[0], x0[independent], rate0
    total = 0
    n_steps, n_eval = 0, 0
    status = OK
    while True:
        if adaptive_method:
            status, stopped, ts, qs, vs, accs, observed, energy, steps, evals = _dop853_chart(
                model, chart, edges, loads, t, value, rate, rtol, sample_interval, per_step, speed_limit,
                max_evaluations - n_eval, retry_caps, info)
        else:
            status, stopped, ts, qs, vs, accs, observed, energy, steps, evals = rkn4_chart(
                model, chart, edges, loads, t, value, rate, step, speed_limit, stability, True, info)
        n_steps += steps
        n_eval += evals
        t_parts.append(ts)
        q_parts.append(qs)
        v_parts.append(vs)
        a_parts.append(accs)
        o_parts.append(observed)
        e_parts.append(energy)
        seg_parts.append(np.full(ts.shape[0], float(len(coordinates) - 1)))
        total += ts.shape[0]
        if status != OK or not stopped or ts[-1] >= edges[-1]:
            break
        if len(switches) > max_switches:
            status = TOO_MANY_SWITCHES
            info[0] = ts[-1]
            break
        t, value = ts[-1], qs[-1]
        status, rate = switch(model, chart, value, vs[-1], info)
        if status != OK:
            info[0] = t
            break
        info[0] = t
        switches.append(info[:5].copy())
        start = physics._views(model[1], chart[1])[1]
        coordinates.append(chart[0][physics.INDEPENDENT])
        starts.append(start.copy())
        value = start[0, chart[0][physics.INDEPENDENT]]
    out_starts = np.empty((len(starts), 3, n))
    for s in range(len(starts)):
        physics._copy(starts[s], out_starts[s])
    out_switches = np.empty((len(switches) - 1, 5))
    for s in range(1, len(switches)):
        physics._copy(switches[s], out_switches[s - 1])
    return (status, info, _concatenate(t_parts, total), _concatenate(q_parts, total),
            _concatenate(v_parts, total), _concatenate(a_parts, total),
            _concatenate(seg_parts, total).astype(np.int64), np.array(coordinates, dtype=np.int64), out_starts,
            out_switches, n_steps, n_eval, _concatenate_rows(o_parts, total, width),
            _concatenate_rows(e_parts, total, 2))


def run_rkn4(model, chart, edges, loads, x0, independent, rate0, step, speed_limit, stability, max_switches):
    """RKN4 at the largest step ``step`` (s) over [edges[0], edges[-1]] from the assembled x0
    with ẋ_independent = rate0, switching charts as needed."""
    return _run(model, chart, edges, loads, x0, independent, rate0, False, step, 0.0, 0.0, 0, speed_limit,
                stability, 0, np.empty(0), max_switches)


def run_dop853(model, chart, edges, loads, x0, independent, rate0, rtol, sample_interval, per_step,
               speed_limit, max_evaluations, retry_caps, max_switches):
    """DOP853 at rtol = atol ``rtol`` (scipy's algorithm, :mod:`.adaptive`), sampled no coarser
    than ``sample_interval`` (s), each step in at least ``per_step`` parts; ``max_evaluations`` of q̈
    in all; charts that meet a singular position retried with the step capped to the fractions
    ``retry_caps`` (k,) of their span."""
    return _run(model, chart, edges, loads, x0, independent, rate0, True, 0.0, rtol, sample_interval, per_step,
                speed_limit, False, max_evaluations, retry_caps, max_switches)
