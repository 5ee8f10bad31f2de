"""The adaptive reference through scipy (``solve_ivp``, DOP853 by default) for q̈ = f(t, q, q̇),
the cross-check of the compiled kernels; it knows nothing about linkages. The fixed-step RKN
methods (RKN4, its tableau, the printed variant) live in :mod:`.kernels.fixed_step` only: one
implementation, compiled.

:func:`solve_adaptive` takes ``rhs_on_piece(start, end) -> f``, a factory that returns the
acceleration function valid on one smooth piece of the load history, and the ``breakpoints``
where the loads jump. Every breakpoint is a step boundary, and every stage of a step
evaluates the piece that contains the step (seed-notes erratum 5, README).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from loopcheck.errors import NumericalFailure
# The compiled kernel holds the restart rule both paths follow
from .kernels.adaptive import RESTART_STEPS
from loopcheck.trajectory import Trajectory

# the error estimators' orders, as select_initial_step takes them (scipy's RK and Radau classes)
ESTIMATOR_ORDER = {"DOP853": 7, "RK45": 4, "RK23": 2, "Radau": 3}


def _rms(x0: float, x1: float) -> float:
    """scipy's RMS norm of a 2-vector, summed as the compiled kernel does (not by the BLAS)."""
    return math.sqrt(x0 * x0 + x1 * x1) / math.sqrt(2.0)


def restart(fun, t0: float, y0: np.ndarray, t_bound: float, max_step: float, order: int, rtol: float,
            atol: float, previous_times: np.ndarray):
    """A piece after a load edge: its first step (s) and the function to hand solve_ivp.

    The step is select_initial_step's (scipy's common.py: ``fun`` at (t0, y0) and at one probe),
    at most the largest of the previous piece's last RESTART_STEPS steps (``previous_times``: its
    step times). The function is ``fun`` but for its first call at (t0, y0), solve_ivp's own
    evaluation of f0, which returns the f0 already computed: the probe has moved the chart on
    since, and Newton from there would close it in other last bits.

    Returns (first_step, fun for solve_ivp)."""
    f0 = fun(t0, y0)
    pending = [(t0, np.array(y0, dtype=float), f0)]

    def primed(t, state):
        if pending and t == pending[0][0] and np.array_equal(state, pending[0][1]):
            return pending.pop()[2].copy()
        return fun(t, state)

    interval = abs(t_bound - t0)
    s0, s1 = atol + abs(y0[0]) * rtol, atol + abs(y0[1]) * rtol
    d0 = _rms(y0[0] / s0, y0[1] / s1)
    d1 = _rms(f0[0] / s0, f0[1] / s1)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, interval)
    f1 = fun(t0 + h0, y0 + h0 * f0)
    d2 = _rms((f1[0] - f0[0]) / s0, (f1[1] - f0[1]) / s1) / h0
    h1 = max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / (order + 1))
    h = min(100 * h0, h1, interval, max_step)
    steps = np.diff(previous_times)[-RESTART_STEPS:]
    return (float(min(h, np.max(steps))) if steps.size else float(h)), primed


Acceleration = Callable[[float, float, float], float]
# rhs_on_piece(start, end) -> f on that piece. An f that keeps state between calls (a linkage
# chart continues from its last configuration) may carry f.rewind(): back to its state when it
# was made, called before the piece's samples are evaluated, in order from the piece's start.
PieceFactory = Callable[[float, float], Acceleration]
StopCondition = Callable[[float, float, float], float]  # stop where it crosses from > 0 to ≤ 0

# The adaptive solver's work is bounded: the most expensive shipped scene (45 s of
# long_conservative) needs 3e5 evaluations. 1e6 bounds a run's time and memory (about 1 s of
# evaluations in compiled code, 10–20 s through scipy; and its samples, 4 per step). A run
# spends it when its step collapses (an extreme speed, damper or inertia) or when it is simply
# long and fast at a tight rtol (DOP853 at rtol 1e-12 takes ~300 evaluations per radian of a
# fast crank: 1e6 is ~3 300 rad): budget_spent says which to change.
MAX_EVALUATIONS = 1_000_000
# |q̇| (rad/s or m/s) beyond which a run is declared unstable rather than returned.
SPEED_LIMIT = 1e6


def budget_spent(method: str, budget: int, t: float, t0: float, t_end: float) -> NumericalFailure:
    """The failure of an adaptive run that spent its ``budget`` of evaluations at t (s) of its
    span [t0, t_end], with the rate it was spending it at and what to change."""
    pace = (f", at ~{budget / (t - t0):.2g} per simulated second, so the whole span would need "
            f"~{budget / (t - t0) * (t_end - t0):.2g}") if t > t0 else " without advancing"
    return NumericalFailure(
        "step-size", f"{method} spent its budget of {budget} evaluations of the equation (a bound on a run's "
        f"time and memory) by t = {t:.6g} s of [{t0:.6g}, {t_end:.6g}] s{pace}: loosen rtol (`--rtol`, "
        "`[reduced] rtol`) or shorten `simulation.horizon`; a budget spent within moments means the step "
        "collapsed (an extreme speed, damper or inertia in the scene?)", float(t))


@dataclass(frozen=True)
class Solution:
    """A finished run: the trajectory and what it cost."""

    trajectory: Trajectory
    method: str
    n_steps: int
    n_evaluations: int
    settings: dict = field(default_factory=dict)
    stopped: bool = False  # ended early because the stop condition fired


def pieces(t0: float, tf: float, breakpoints: tuple[float, ...]) -> list[tuple[float, float]]:
    """Split [t0, tf] at the breakpoints strictly inside it."""
    cuts = sorted({b for b in breakpoints if t0 < b < tf})
    edges = [t0, *cuts, tf]
    return list(zip(edges[:-1], edges[1:]))


def _check_state(t: float, q: float, v: float, speed_limit: float, *, initial: bool = False) -> None:
    """NumericalFailure for a non-finite state or a speed beyond ``speed_limit`` (rad/s)."""
    if not (math.isfinite(q) and math.isfinite(v)):
        what = f"the initial state is NaN or infinite (q = {q}, q̇ = {v})" if initial else \
            f"the state became NaN or infinite at t = {t:.6g} s"
        raise NumericalFailure("non-finite", what, t)
    if abs(v) > speed_limit:
        what = (f"the initial speed |q̇| = {abs(v):.3g} rad/s exceeds the integrators' limit of "
                f"{speed_limit:.3g} rad/s: no step can resolve it") if initial else \
            (f"|q̇| = {abs(v):.3g} rad/s exceeds {speed_limit:.3g} rad/s at t = {t:.6g} s: "
             "the integration is unstable at this step")
        raise NumericalFailure("unstable", what, t)


def _hermite(t0, t1, y0, y1, a0, a1, times):
    """q and q̇ of the quintic Hermite interpolant through (q, q̇, q̈) at t0 and t1 (arrays)."""
    h = t1 - t0
    s = (times - t0) / h
    c0, c1, c2 = y0[0], h * y0[1], 0.5 * h * h * a0
    r0 = y1[0] - c0 - c1 - c2
    r1 = h * y1[1] - c1 - 2.0 * c2
    r2 = h * h * a1 - 2.0 * c2
    c3 = 10.0 * r0 - 4.0 * r1 + 0.5 * r2
    c4 = -15.0 * r0 + 7.0 * r1 - r2
    c5 = 6.0 * r0 - 3.0 * r1 + 0.5 * r2
    q = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
    v = (c1 + s * (2 * c2 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)))) / h
    return q, v


# Samples per accepted step of the adaptive solver. Quintic Hermite interpolation on
# spacing δ errs by O(δ⁵) in q̇; the solver's steps are short where the motion is fast, so
# a fixed fraction of each step puts the samples where they are needed; a step longer than
# per_step × sample_interval is cut finer, into ⌈h / sample_interval⌉ parts (sample_parts).
# Measured on the crossed-branch seed scene (DOP853, rtol 1e-12, 1 ms sample_interval), peak
# ω against 64 parts per step: off by 2.1e-7 rad/s with 1 part (the steps and the 1 ms
# cuts), 8.7e-9 with 2, 6.1e-11 with 4, 8.9e-10 with 8, 6.0e-10 with 16: from 4 on the
# difference is noise of the dense output (two references, samples 20 µs apart from steps
# cut into at least 4 or at least 64 parts, differ by 7e-10), not the interpolant's error.
# (Until 2026-11 the cuts were the union of 4 per step and a 1 ms grid: 1.5x the samples on
# the seed, the same bound on the spacing; between samples the interpolant's largest error in
# q̇ on the seed, against samples 20 µs apart of the same dense output, was 1.4e-8 rad/s then
# and is 1.1e-8 now, in q 1.7e-12 and 1.2e-12 rad.)
SAMPLES_PER_STEP = 4


def sample_parts(h: np.ndarray, sample_interval: float, per_step: int) -> np.ndarray:
    """The equal parts each step of length h (s) is cut into for sampling:
    max(per_step, ⌈h / sample_interval⌉), so that samples are no further apart than
    ``sample_interval`` nor than h / per_step (int array, the shape of h)."""
    return np.maximum(per_step, np.ceil(h / sample_interval)).astype(np.int64)


def dense_samples(sol, f, start: float, end: float, sample_interval: float,
                  per_step: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample times, states (2, n) and q̈ on [start, end] from a solver's dense output.

    The times are the solver's steps, each cut into :func:`sample_parts` equal parts (no
    further apart than ``sample_interval`` (s) nor than a ``per_step``-th of the step). The
    states at the solver's steps are its own (not interpolated); q̈ = f at every sample, in
    order, after ``f.rewind()`` where f has one (:data:`PieceFactory`).
    """
    per_step = SAMPLES_PER_STEP if per_step is None else per_step
    t0, t1 = sol.t[:-1], sol.t[1:]
    parts = sample_parts(t1 - t0, sample_interval, per_step)
    step = np.repeat(np.arange(len(t0)), parts - 1)
    k = np.arange(len(step)) - np.repeat(np.cumsum(parts - 1) - (parts - 1), parts - 1) + 1
    inner = t0[step] + (t1 - t0)[step] * (k / parts[step])  # t_j + h_j (k / p_j), k = 1 … p_j − 1
    times = np.union1d(sol.t, inner)
    times = times[(times >= start) & (times <= end)]
    states = sol.sol(times)
    at_step = np.searchsorted(times, sol.t)
    states[:, at_step] = sol.y
    getattr(f, "rewind", lambda: None)()
    acc = np.array([f(t, qq, vv) for t, qq, vv in zip(times.tolist(), states[0].tolist(), states[1].tolist())])
    return times, states, acc


def solve_adaptive(rhs_on_piece: PieceFactory, t_span: tuple[float, float], q0: float, qdot0: float,
                   *, rtol: float = 1e-12, atol: float | None = None, method: str = "DOP853",
                   breakpoints: tuple[float, ...] = (), sample_interval: float = 1e-3,
                   speed_limit: float = 1e6, stop: StopCondition | None = None,
                   max_evaluations: int = MAX_EVALUATIONS, max_step: float = math.inf) -> Solution:
    """Integrate with scipy's ``solve_ivp``, restarted at every breakpoint.

    The trajectory holds every accepted step, each cut by points of the solver's own dense
    output into at least ``SAMPLES_PER_STEP`` equal parts no longer than ``sample_interval``
    (s) (:func:`dense_samples`), so that the quintic Hermite interpolant between
    samples is not the limit of the trajectory's accuracy.

    Parameters
    ----------
    rtol, atol : float
        Tolerances handed to ``solve_ivp``; ``atol`` defaults to ``rtol`` (q in rad, q̇ in rad/s).
    method : str
        Any ``solve_ivp`` method; DOP853 by default, Radau for stiff problems.
    stop : callable, optional
        g(t, q, q̇); a terminal event: the run ends where g crosses zero downwards.
    max_evaluations : int
        Evaluations of f (all pieces) after which the step is declared collapsed.

    Raises
    ------
    NumericalFailure
        When the solver fails or exceeds ``max_evaluations`` (STEP_SIZE), the state or f
        becomes non-finite, or the state runs away.
    """
    from scipy.integrate import solve_ivp  # scipy only for this cross-check path (import ~0.5 s)

    atol = rtol if atol is None else atol
    _check_state(t_span[0], q0, qdot0, speed_limit, initial=True)
    ts, qs, vs, accs = [], [], [], []
    y = np.array([q0, qdot0], dtype=float)
    n_steps = n_eval = 0
    budget = [max_evaluations]
    previous_steps = np.empty(0)  # step times of the piece before (none before the first)
    for start, end in pieces(*t_span, breakpoints):
        f = rhs_on_piece(start, end)

        def first_order(t, state, f=f):
            budget[0] -= 1
            if budget[0] < 0:
                raise budget_spent(method, max_evaluations, float(t), *t_span)
            accel = f(t, state[0], state[1])
            if not math.isfinite(accel):
                raise NumericalFailure("non-finite", f"the acceleration became NaN or infinite at "
                                       f"t = {t:.6g} s (q = {state[0]:.6g} rad, q̇ = {state[1]:.6g} rad/s)",
                                       float(t))
            return np.array([state[1], accel])

        events = None
        if stop is not None:
            def event(t, state):
                return stop(t, state[0], state[1])
            event.terminal, event.direction = True, -1
            events = [event]
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                fun, first_step = first_order, None
                if previous_steps.size and method in ESTIMATOR_ORDER and end > start:
                    first_step, fun = restart(first_order, start, y, end, max_step, ESTIMATOR_ORDER[method],
                                              rtol, atol, previous_steps)
                    n_eval += 1  # the probe; f0 is in solve_ivp's nfev
                sol = solve_ivp(fun, (start, end), y, method=method, rtol=rtol, atol=atol,
                                dense_output=True, events=events, max_step=max_step, first_step=first_step)
        except NumericalFailure:
            raise
        except (ArithmeticError, ValueError) as exc:
            raise NumericalFailure("singular", f"{method} failed in [{start:.6g}, {end:.6g}] s: {exc}",
                                   start) from None
        if not sol.success:
            raise NumericalFailure("step-size", f"{method} failed in [{start:.6g}, {end:.6g}] s: "
                                   f"{sol.message}", float(sol.t[-1]))
        n_steps += len(sol.t) - 1
        n_eval += sol.nfev
        end = float(sol.t[-1])  # earlier than the piece's end if the stop event fired
        times, states, acc = dense_samples(sol, f, start, end, sample_interval)
        if not (np.all(np.isfinite(states)) and np.all(np.isfinite(acc))):
            bad = int(np.argmin(np.all(np.isfinite(states), axis=0) & np.isfinite(acc)))
            raise NumericalFailure("non-finite", f"the state became NaN or infinite at t = {times[bad]:.6g} s",
                                   float(times[bad]))
        fast = np.flatnonzero(np.abs(states[1]) > speed_limit)
        if fast.size:
            _check_state(float(times[fast[0]]), float(states[0, fast[0]]), float(states[1, fast[0]]),
                         speed_limit)
        ts.append(times), qs.append(states[0]), vs.append(states[1]), accs.append(acc)
        y = sol.y[:, -1]
        if sol.status == 1:  # the stop event ended the run
            break
        previous_steps = sol.t
    traj = Trajectory(np.concatenate(ts), np.concatenate(qs), np.concatenate(vs), np.concatenate(accs))
    return Solution(traj, method, n_steps, n_eval,
                    {"method": method.lower(), "rtol": rtol, "atol": atol}, stopped=sol.status == 1)
