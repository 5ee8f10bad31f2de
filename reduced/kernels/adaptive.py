"""A compiled DOP853 driver for one scalar second-order ODE x'' = f(t, x, x').

:func:`dop853_run` does, in one call of compiled code, what ``reduced.integrators.solve_adaptive``
does with scipy: the load history is constant on pieces; on each piece it runs scipy's
``solve_ivp(method="DOP853", dense_output=True, events=[stop])`` algorithm step for step
(``scipy/integrate/_ivp/rk.py``: ``RungeKutta._step_impl``, ``DOP853._estimate_error_norm``,
``DOP853._dense_output_impl`` and ``Dop853DenseOutput``; ``select_initial_step`` in
``common.py``; the terminal event as in ``ivp.py`` with scipy's Brent root finder), restarting
at every piece edge, and samples the result with xval's rule (``dense_samples`` in
``reduced/integrators.py``). The coefficients are scipy's (``dop853_coefficients``), read at
import time into global arrays that numba freezes as constants.

The problem is opaque here: the kernel calls ``acceleration(problem, chart, load, t, q, v)`` and
``stop_margin(problem, chart, t, q, v)`` from :mod:`reduced.kernels.problem` and passes
``problem`` and ``chart`` through untouched.

Failures are status codes, never exceptions (:data:`OK`, :data:`STEP_SIZE`, :data:`NONFINITE`,
:data:`SPEED`).

Debugging: ``NUMBA_DISABLE_JIT=1`` runs the same code as plain Python (slow but steppable).
Caching: see :mod:`reduced.kernels` (the cache follows every source of the package).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from . import dop853_tableau as _coef

from ._options import NO_RUNTIME, RUNTIME
from .problem import acceleration, mark, observation_size, observe, power, rewind, stop_margin

# ---- status codes (module constants; the kernel returns one of them) -------------------------
OK = 0          #: the run reached the end of the last piece, or the stop event ended it
STEP_SIZE = 1   #: more than max_evaluations evaluations of f, or scipy's "required step size is
#                  less than spacing between numbers"; fail_time: where the solver was
NONFINITE = 2   #: f was NaN/inf at a stage (fail_time: that stage's time) or a sample's state or
#                  q̈ was not finite (fail_time: the sample's time); also a non-finite initial state
SPEED = 3       #: |q̇| > speed_limit at a sample (or initially); fail_time, fail_value: where, q̇
STATUS_NAMES = {OK: "ok", STEP_SIZE: "step-size", NONFINITE: "non-finite", SPEED: "unstable"}

# Restarts at load edges: a piece after an edge starts with scipy's select_initial_step (Hairer,
# Nørsett & Wanner II.4), but at most the largest of the previous piece's last RESTART_STEPS
# steps (its last is cut short by the edge): the edge changes the load, not the mechanism's time
# scale. On seed variants (damper 61–63 N·s/m, coupler 36.1–36.2 kg) the selection alone gave
# 8.0 ms after the pulse's end where the steps before were 1.3 ms; DOP853's error estimate
# accepted it and the run's energy balance missed by 1.1e-8 (the nominal seed: 1.3e-11; with
# the cap, at most 2.8e-11 over those variants). The selection stays the bound near a dead centre,
# where it is the smaller. The scipy path (reduced.integrators.restart) does the same.
RESTART_STEPS = 2

# ---- scipy's DOP853 constants ---------------------------------------------------------------
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
N_STAGES = _coef.N_STAGES                    # 12
N_STAGES_EXTENDED = _coef.N_STAGES_EXTENDED  # 16
INTERPOLATOR_POWER = _coef.INTERPOLATOR_POWER  # 7
ERROR_ESTIMATOR_ORDER = 7
ERROR_EXPONENT = -1 / (ERROR_ESTIMATOR_ORDER + 1)
EPS = float(np.finfo(float).eps)
SQRT_N = 2 ** 0.5  # x.size ** 0.5 in scipy's RMS norm, n = 2

A = np.ascontiguousarray(_coef.A, dtype=np.float64)          # (16, 16)
B = np.ascontiguousarray(_coef.B, dtype=np.float64)          # (12,)
C = np.ascontiguousarray(_coef.C, dtype=np.float64)          # (16,)
E3 = np.ascontiguousarray(_coef.E3, dtype=np.float64)        # (13,)
E5 = np.ascontiguousarray(_coef.E5, dtype=np.float64)        # (13,)
D = np.ascontiguousarray(_coef.D, dtype=np.float64)          # (4, 16)


class RunResult(NamedTuple):
    """What :func:`dop853_run` returns (a plain tuple from the kernel, named by :func:`run`)."""
    status: int            # OK, STEP_SIZE, NONFINITE or SPEED
    t: np.ndarray          # sample times (pieces concatenated; a piece's first time repeats the
    q: np.ndarray          # previous piece's last), states and q̈ at every sample
    v: np.ndarray
    a: np.ndarray
    n_steps: int           # accepted steps over all pieces (a step cut by the stop event counts)
    n_evaluations: int     # scipy's nfev summed over pieces (initial f, initial-step probe,
    #                        12 per attempted step, 3 per dense output)
    n_sample_evaluations: int  # evaluations of f at the samples (not in n_evaluations)
    stopped: bool          # the stop event ended the run
    t_reached: float       # the last time integrated (the event's root if stopped)
    fail_time: float       # where a failure happened (nan if OK)
    fail_value: float      # q̇ for SPEED, else nan
    observed: np.ndarray   # what the problem observed at each sample (m, observation_size)
    energy: np.ndarray     # the work done and the energy dissipated since the start (m, 2), J


# ---- helpers --------------------------------------------------------------------------------

@njit(cache=True, inline="always")
def _pymin(a, b):
    """Python's min(a, b): a unless b < a (NaN handling as in Python)."""
    return b if b < a else a


@njit(cache=True, inline="always")
def _pymax(a, b):
    """Python's max(a, b): a unless b > a."""
    return b if b > a else a


@njit(cache=True, inline="always")
def _npmax(a, b):
    """np.maximum(a, b) of two floats (NaN if either is)."""
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


@njit(cache=True, **NO_RUNTIME)
def _dense_eval(t, t_old, h, y_old0, y_old1, F, j, c=0):
    """Dop853DenseOutput._call_impl at t for step j, components c and c + 1 (F: (n_steps, 7, 4):
    q, q̇, then the energy flows), same operation order."""
    x = (t - t_old) / h
    y0 = 0.0
    y1 = 0.0
    for i in range(INTERPOLATOR_POWER):
        r = INTERPOLATOR_POWER - 1 - i
        y0 += F[j, r, c]
        y1 += F[j, r, c + 1]
        if i % 2 == 0:
            y0 *= x
            y1 *= x
        else:
            y0 *= 1 - x
            y1 *= 1 - x
    return y0 + y_old0, y1 + y_old1


@njit(cache=True, **NO_RUNTIME)
def _brentq_stop(problem, chart, xa, xb, t_old, h, y_old0, y_old1, F, j):
    """scipy.optimize.brentq (Zeros/brentq.c) of stop_margin on step j's dense output,
    xtol = rtol = 4 EPS, maxiter 100, as solve_ivp's solve_event_equation calls it."""
    xtol = 4 * EPS
    rtol = 4 * EPS
    xpre = xa
    xcur = xb
    xblk = 0.0
    fblk = 0.0
    spre = 0.0
    scur = 0.0
    q, v = _dense_eval(xpre, t_old, h, y_old0, y_old1, F, j)
    fpre = stop_margin(problem, chart, xpre, q, v)
    q, v = _dense_eval(xcur, t_old, h, y_old0, y_old1, F, j)
    fcur = stop_margin(problem, chart, xcur, q, v)
    if fpre == 0:
        return xpre
    if fcur == 0:
        return xcur
    for _ in range(100):
        if fpre != 0 and fcur != 0 and ((math.copysign(1.0, fpre) < 0) != (math.copysign(1.0, fcur) < 0)):
            xblk = xpre
            fblk = fpre
            spre = xcur - xpre
            scur = spre
        if abs(fblk) < abs(fcur):
            xpre = xcur
            xcur = xblk
            xblk = xpre
            fpre = fcur
            fcur = fblk
            fblk = fpre
        delta = (xtol + rtol * abs(xcur)) / 2
        sbis = (xblk - xcur) / 2
        if fcur == 0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2 * abs(stry) < min(abs(spre), 3 * abs(sbis) - delta):
                spre = scur
                scur = stry
            else:
                spre = sbis
                scur = sbis
        else:
            spre = sbis
            scur = sbis
        xpre = xcur
        fpre = fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        q, v = _dense_eval(xcur, t_old, h, y_old0, y_old1, F, j)
        fcur = stop_margin(problem, chart, xcur, q, v)
    return xcur  # scipy would raise (no convergence in 100 iterations); not reachable for a
    #              bracketed continuous g at these tolerances


@njit(cache=True, inline="always")
def _norm2(x0, x1):
    """np.linalg.norm((x0, x1)) summed plainly (numpy: sqrt(x.dot(x)), by the BLAS)."""
    return math.sqrt(x0 * x0 + x1 * x1)


@njit(cache=True, inline="always")
def _rms2(x0, x1):
    """scipy's norm of (x0, x1): np.linalg.norm(x) / x.size ** 0.5."""
    return _norm2(x0, x1) / SQRT_N


@njit(cache=True, **NO_RUNTIME)
def _dot_kt(K, a, s, out):
    """out = np.dot(K[:s].T, a[:s]) summed in one fixed order: columns in blocks of four,
    t += (p0 + p1), t += (p2 + p3), then the rest one by one; no FMA. It is OpenBLAS's dgemv_n on
    the Intel machine it was measured on (bit-equal to numpy on 2100 random cases), not on every
    CPU (on an AMD EPYC 1085 of 2000 cases differ in the last bit): OpenBLAS picks its kernels at
    run time. The order matters where runs are compared step for step (at tight tolerances the
    error estimate is mostly round-off, and another order moves the step sequence by ~1e-6
    relative at rtol 1e-12), so the tests that do run scipy in this order
    (tests/helpers.py, scipy_in_kernel_order)."""
    nb = s - s % 4
    for r in range(2):
        acc = 0.0
        i = 0
        while i < nb:
            acc = acc + (K[i, r] * a[i] + K[i + 1, r] * a[i + 1])
            acc = acc + (K[i + 2, r] * a[i + 2] + K[i + 3, r] * a[i + 3])
            i += 4
        while i < s:
            acc = acc + K[i, r] * a[i]
            i += 1
        out[r] = acc


@njit(cache=True, inline="always")
def _fun(problem, chart, load, t, q, v, K, P, row, work):
    """The first-order system (q̇, f) into K[row] and the energy flows' rates (P, D) there
    into P[row]; work = [nfev, max_evaluations].
    Returns a status: STEP_SIZE when the budget is spent (f not called), NONFINITE if f is."""
    if work[0] >= work[1]:
        return STEP_SIZE
    work[0] += 1
    acc = acceleration(problem, chart, load, t, q, v)
    K[row, 0] = v
    K[row, 1] = acc
    P[row, 0], P[row, 1] = power(problem, chart, load, v)
    if not math.isfinite(acc):
        return NONFINITE
    return OK


@njit(cache=True, inline="always")
def _grow1(a, n):
    b = np.empty(2 * a.shape[0])
    for i in range(n):  # explicit loops: a slice assignment costs seconds of compile time
        b[i] = a[i]
    return b


@njit(cache=True, inline="always")
def _grow_rows(a, n):
    b = np.empty((2 * a.shape[0], a.shape[1]))
    for i in range(n):
        for c in range(a.shape[1]):
            b[i, c] = a[i, c]
    return b


@njit(cache=True, inline="always")
def _grow_steps(sy, sF, n):
    sy2 = np.empty((2 * sy.shape[0], 4))
    sF2 = np.empty((2 * sF.shape[0], INTERPOLATOR_POWER, 4))
    for i in range(n):
        for c in range(4):
            sy2[i, c] = sy[i, c]
            for r in range(INTERPOLATOR_POWER):
                sF2[i, r, c] = sF[i, r, c]
    return sy2, sF2


@njit(cache=True, **NO_RUNTIME)
def _initial_step(problem, chart, load, t, end, y0, y1, rtol, atol, max_step, restart_cap, K, P, work):
    """RungeKutta.__init__: f0 = fun(t0, y0) into K[0], then select_initial_step (common.py),
    at most ``restart_cap`` when that is > 0 (a restart at a load edge: RESTART_STEPS).
    Returns (status, fail_time, h_abs)."""
    s = _fun(problem, chart, load, t, y0, y1, K, P, 0, work)
    if s != OK:
        return s, t, 0.0
    f0 = K[0, 0]
    f1 = K[0, 1]
    interval_length = abs(end - t)
    if interval_length == 0.0:
        return OK, math.nan, 0.0
    sc0 = atol + abs(y0) * rtol
    sc1 = atol + abs(y1) * rtol
    d0 = _rms2(y0 / sc0, y1 / sc1)
    d1 = _rms2(f0 / sc0, f1 / sc1)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = _pymin(h0, interval_length)
    s = _fun(problem, chart, load, t + h0 * 1.0, y0 + h0 * 1.0 * f0, y1 + h0 * 1.0 * f1, K, P, 1, work)
    if s != OK:
        return s, t + h0, 0.0
    d2 = _rms2((K[1, 0] - f0) / sc0, (K[1, 1] - f1) / sc1) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = _pymax(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / _pymax(d1, d2)) ** (1 / (ERROR_ESTIMATOR_ORDER + 1))
    h = _pymin(_pymin(_pymin(100 * h0, h1), interval_length), max_step)
    return OK, math.nan, (_pymin(h, restart_cap) if restart_cap > 0.0 else h)


@njit(cache=True, **NO_RUNTIME)
def _rk_step(problem, chart, load, t, y0, y1, h, rtol, atol, K, P, work, scratch):
    """rk_step and DOP853._estimate_error_norm for one attempt (K[0] = f at (t, y) on entry;
    K[12] = f_new on exit; scratch (3, 2) is overwritten). Returns (status, fail_time, y_new0,
    y_new1, error_norm)."""
    dy = scratch[0]
    for si in range(1, N_STAGES):
        _dot_kt(K, A[si], si, dy)  # scipy: dy = np.dot(K[:s].T, a[:s]) * h, then y + dy
        s = _fun(problem, chart, load, t + C[si] * h, y0 + dy[0] * h, y1 + dy[1] * h, K, P, si, work)
        if s != OK:
            return s, t + C[si] * h, 0.0, 0.0, 0.0
    bk = dy
    _dot_kt(K, B, N_STAGES, bk)
    yn0 = y0 + h * bk[0]
    yn1 = y1 + h * bk[1]
    s = _fun(problem, chart, load, t + h, yn0, yn1, K, P, N_STAGES, work)
    if s != OK:
        return s, t + h, 0.0, 0.0, 0.0
    sc0 = atol + _npmax(abs(y0), abs(yn0)) * rtol
    sc1 = atol + _npmax(abs(y1), abs(yn1)) * rtol
    e5 = scratch[1]
    e3 = scratch[2]
    _dot_kt(K, E5, N_STAGES + 1, e5)
    _dot_kt(K, E3, N_STAGES + 1, e3)
    err5_norm_2 = _norm2(e5[0] / sc0, e5[1] / sc1) ** 2
    err3_norm_2 = _norm2(e3[0] / sc0, e3[1] / sc1) ** 2
    if err5_norm_2 == 0 and err3_norm_2 == 0:
        return OK, math.nan, yn0, yn1, 0.0
    denom = err5_norm_2 + 0.01 * err3_norm_2
    return OK, math.nan, yn0, yn1, abs(h) * err5_norm_2 / math.sqrt(denom * 2)


@njit(cache=True, inline="always")
def _interpolant(sF, sy, n, h, R, col, c):
    """Step n's dense coefficients F of component ``col`` (from sy[n] to sy[n + 1]) from its
    rates R[:, c] at the 16 stages, in DOP853._dense_output_impl's order: Δ, h f_old − Δ,
    2Δ − h (f_new + f_old), then h D·R (numpy: BLAS dgemm; the order differs, by round-off, in
    the dense output only)."""
    dl = sy[n + 1, col] - sy[n, col]
    sF[n, 0, col] = dl
    sF[n, 1, col] = h * R[0, c] - dl
    sF[n, 2, col] = 2 * dl - h * (R[N_STAGES, c] + R[0, c])
    for r in range(INTERPOLATOR_POWER - 3):
        p = 0.0
        for j in range(N_STAGES_EXTENDED):
            p += D[r, j] * R[j, c]
        sF[n, 3 + r, col] = h * p


@njit(cache=True, **NO_RUNTIME)
def _dense_coefficients(problem, chart, load, t_old, yo0, yo1, h, K, P, work, sF, sy, n, dy):
    """DOP853._dense_output_impl: 3 extra stages into K[13:16] (and P), then the interpolant of
    each component of sy from step n to n + 1 (both set) into sF[n]: q and q̇ from K, the energy
    flows from P (dy (2,) is overwritten). Returns (status, fail_time)."""
    for si in range(N_STAGES + 1, N_STAGES_EXTENDED):
        _dot_kt(K, A[si], si, dy)
        s = _fun(problem, chart, load, t_old + C[si] * h, yo0 + dy[0] * h, yo1 + dy[1] * h, K, P, si,
                 work)
        if s != OK:
            return s, t_old + C[si] * h
    for c in range(2):
        _interpolant(sF, sy, n, h, K, c, c)
        _interpolant(sF, sy, n, h, P, 2 + c, c)
    return OK, math.nan


@njit(cache=True, **RUNTIME)
def _piece(problem, chart, load, start, end, q0, v0, w0, d0, rtol, atol, max_step, restart_cap, use_stop,
           work, st, sh, sy, sF):
    """One solve_ivp call on [start, end] (its first step at most ``restart_cap`` if > 0) from
    (q0, v0), the work done w0 and the energy dissipated d0 (J): steps into st (times), sh (dense h),
    sy (states: q, q̇, work, dissipated), sF (dense coefficients), grown as needed.

    The energy flows ride along: each accepted step adds h Σ b_s P_s of their stage rates
    (DOP853's order-8 quadrature) and gets DOP853's dense output; they take no part in the
    error estimate, so the steps are scipy's. Returns (status, n_steps, stopped, fail_time,
    st, sh, sy, sF). One exit: each return of the tuple costs compile time."""
    K = np.empty((N_STAGES_EXTENDED, 2))
    P = np.empty((N_STAGES_EXTENDED, 2))
    pb = np.empty(2)  # h Σ b_s P_s / h of a step
    scratch = np.empty((3, 2))  # the stages' increments and error estimates (_rk_step)
    t = start
    y0 = q0
    y1 = v0
    st[0] = t
    sy[0, 0] = y0
    sy[0, 1] = y1
    sy[0, 2] = w0
    sy[0, 3] = d0
    n = 0
    stopped = False
    status, fail_time, h_abs = _initial_step(problem, chart, load, t, end, y0, y1, rtol, atol,
                                             max_step, restart_cap, K, P, work)
    f0 = K[0, 0]
    f1 = K[0, 1]
    p0 = P[0, 0]
    p1 = P[0, 1]
    g = 0.0
    if use_stop and status == OK:
        g = stop_margin(problem, chart, t, y0, y1)
    while status == OK:
        if t == end:  # OdeSolver.step's corner case (an empty piece)
            break
        # ---- RungeKutta._step_impl ----
        min_step = 10 * abs(math.nextafter(t, math.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        step_rejected = False
        while True:
            if h_abs < min_step:
                status = STEP_SIZE
                fail_time = t
                break
            h = h_abs * 1.0
            t_new = t + h
            if 1.0 * (t_new - end) > 0:
                t_new = end
            h = t_new - t
            h_abs = abs(h)
            K[0, 0] = f0
            K[0, 1] = f1
            P[0, 0] = p0
            P[0, 1] = p1
            status, fail_time, yn0, yn1, error_norm = _rk_step(problem, chart, load, t, y0, y1, h,
                                                               rtol, atol, K, P, work, scratch)
            if status != OK:
                break
            if error_norm < 1:
                if error_norm == 0:
                    factor = MAX_FACTOR
                else:
                    factor = _pymin(MAX_FACTOR, SAFETY * error_norm ** ERROR_EXPONENT)
                if step_rejected:
                    factor = _pymin(1.0, factor)
                h_abs *= factor
                break
            else:
                h_abs *= _pymax(MIN_FACTOR, SAFETY * error_norm ** ERROR_EXPONENT)
                step_rejected = True
        if status != OK:
            break
        # accepted: t_old = t, t = t_new, y_old = y, y = y_new, f = f_new
        t_old = t
        yo0 = y0
        yo1 = y1
        t = t_new
        y0 = yn0
        y1 = yn1
        f0 = K[N_STAGES, 0]
        f1 = K[N_STAGES, 1]
        p0 = P[N_STAGES, 0]
        p1 = P[N_STAGES, 1]
        if n + 1 >= st.shape[0]:
            st = _grow1(st, n + 1)
            sh = _grow1(sh, n)
            sy, sF = _grow_steps(sy, sF, n + 1)
        sy[n + 1, 0] = y0
        sy[n + 1, 1] = y1
        _dot_kt(P, B, N_STAGES, pb)  # the energy flows' step, with the state's weights
        sy[n + 1, 2] = sy[n, 2] + h * pb[0]
        sy[n + 1, 3] = sy[n, 3] + h * pb[1]
        status, fail_time = _dense_coefficients(problem, chart, load, t_old, yo0, yo1, h, K, P, work, sF, sy, n,
                                                scratch[0])
        if status != OK:
            break
        sh[n] = t - t_old
        st[n + 1] = t
        n += 1
        if use_stop:
            g_new = stop_margin(problem, chart, t, y0, y1)
            if g >= 0 and g_new <= 0:  # find_active_events, direction -1
                root = _brentq_stop(problem, chart, t_old, t, t_old, sh[n - 1], yo0, yo1, sF, n - 1)
                q, v = _dense_eval(root, t_old, sh[n - 1], yo0, yo1, sF, n - 1)
                w, d = _dense_eval(root, t_old, sh[n - 1], sy[n - 1, 2], sy[n - 1, 3], sF, n - 1, 2)
                if root == t_old and n > 1:
                    n -= 1  # solve_ivp's donot_append: ts[-1] == t, the step is dropped
                else:
                    st[n] = root
                    sy[n, 0] = q
                    sy[n, 1] = v
                    sy[n, 2] = w
                    sy[n, 3] = d
                stopped = True
                break
            g = g_new
        if t - end >= 0:
            break
    return status, n, stopped, fail_time, st, sh, sy, sF


@njit(cache=True, inline="always")
def _parts(h, sample_interval, per_step):
    """Equal parts a step of h (s) is cut into for sampling: max(per_step, ⌈h / sample_interval⌉)."""
    return max(per_step, int(math.ceil(h / sample_interval)))


@njit(cache=True, **RUNTIME)
def _sample_piece(problem, chart, load, st, sh, sy, sF, n, sample_interval, per_step):
    """xval's dense_samples on one piece: sorted unique times, states (2, m), q̈, what the
    problem observes at each (m, observation_size) and the energy flows (m, 2)."""
    # each step [t_j, t_j + h_j] cut into max(per_step, ⌈h_j / sample_interval⌉) equal parts:
    # samples no further apart than sample_interval nor h_j / per_step; in order (t_j + h_j·(k/p)
    # is non-decreasing in k and at most t_j + h_j), so a tie is the only repair needed
    m = 1
    for j in range(n):
        m += _parts(st[j + 1] - st[j], sample_interval, per_step)
    times = np.empty(m)
    times[0] = st[0]
    m = 1
    for j in range(n):
        dt = st[j + 1] - st[j]
        parts = _parts(dt, sample_interval, per_step)
        for i in range(1, parts + 1):
            x = st[j] + dt * (i / parts) if i < parts else st[j + 1]
            if x != times[m - 1]:
                times[m] = x
                m += 1
    times = times[:m]
    q = np.empty(m)
    v = np.empty(m)
    energy = np.empty((m, 2))
    # OdeSolution: segment = clip(searchsorted(ts, t, 'left') - 1, 0, n - 1)
    seg = 0
    for i in range(m):
        x = times[i]
        while seg < n - 1 and st[seg + 1] < x:
            seg += 1
        q[i], v[i] = _dense_eval(x, st[seg], sh[seg], sy[seg, 0], sy[seg, 1], sF, seg)
        energy[i, 0], energy[i, 1] = _dense_eval(x, st[seg], sh[seg], sy[seg, 2], sy[seg, 3], sF, seg, 2)
    # states at the step times are the solver's own
    i = 0
    for j in range(n + 1):
        while times[i] < st[j]:
            i += 1
        q[i] = sy[j, 0]
        v[i] = sy[j, 1]
        energy[i, 0] = sy[j, 2]
        energy[i, 1] = sy[j, 3]
    acc = np.empty(m)
    obs = np.empty((m, observation_size(problem)))
    for i in range(m):
        acc[i] = acceleration(problem, chart, load, times[i], q[i], v[i])
        observe(problem, chart, obs[i])
    return times, q, v, acc, obs, energy


@njit(cache=True, **RUNTIME)
def dop853_run(problem, chart, piece_edges, piece_load, q0, v0, rtol, atol, sample_interval,
               per_step, speed_limit, max_evaluations, max_step, use_stop):
    """Integrate q̈ = acceleration(problem, chart, load, t, q, q̇) over the pieces.

    Parameters
    ----------
    problem, chart : opaque, passed to ``acceleration`` and ``stop_margin``
    piece_edges : float64 (p+1,), increasing; piece_load : float64 (p,), the load on each piece
    q0, v0 : initial state at piece_edges[0]
    rtol, atol : scipy's tolerances (same for q and q̇)
    sample_interval, per_step : each accepted step of h (s) is cut into max(per_step,
        ⌈h / sample_interval⌉) equal parts for sampling (:func:`_parts`)
    speed_limit : |q̇| beyond which a sample ends the run with SPEED
    max_evaluations : budget of f evaluations over all pieces (as scipy's nfev counts them)
    max_step : scipy's max_step (math.inf for none)
    use_stop : bool; the terminal event stop_margin (direction -1)

    Returns
    -------
    (status, t, q, v, a, n_steps, n_evaluations, n_sample_evaluations, stopped, t_reached,
    fail_time, fail_value, observed, energy): see :class:`RunResult`. On a failure, the samples of the pieces
    completed before it.
    """
    cap = 256
    ot = np.empty(cap)
    oq = np.empty(cap)
    ov = np.empty(cap)
    oa = np.empty(cap)
    oo = np.empty((cap, observation_size(problem)))
    oe = np.empty((cap, 2))
    no = 0
    st = np.empty(64)
    sh = np.empty(64)
    sy = np.empty((64, 4))
    sF = np.empty((64, INTERPOLATOR_POWER, 4))
    work = np.zeros(2, dtype=np.int64)
    work[1] = max_evaluations
    n_steps = 0
    n_samp = 0
    stopped = False
    t_reached = piece_edges[0]
    status = OK
    fail_time = math.nan
    fail_value = math.nan
    if not (math.isfinite(q0) and math.isfinite(v0)):
        status = NONFINITE
        fail_time = t_reached
    elif abs(v0) > speed_limit:
        status = SPEED
        fail_time = t_reached
        fail_value = v0
    q = q0
    v = v0
    w = 0.0
    d = 0.0
    previous_step = 0.0  # none: the first piece selects its own
    # one exit (each return of this 12-tuple costs compile time)
    for p in range(piece_load.shape[0] if status == OK else 0):
        start = piece_edges[p]
        end = piece_edges[p + 1]
        load = piece_load[p]
        marked = mark(problem, chart)
        status, n, stopped, fail_time, st, sh, sy, sF = _piece(
            problem, chart, load, start, end, q, v, w, d, rtol, atol, max_step, previous_step, use_stop,
            work, st, sh, sy, sF)
        n_steps += n
        if status != OK:
            stopped = False
            break
        rewind(problem, chart, marked)  # the samples in order from the piece's start
        times, qs, vs, acc, obs, energy = _sample_piece(problem, chart, load, st, sh, sy, sF, n,
                                                        sample_interval, per_step)
        m = times.shape[0]
        n_samp += m
        for i in range(m):
            if not (math.isfinite(qs[i]) and math.isfinite(vs[i]) and math.isfinite(acc[i])):
                status = NONFINITE
                fail_time = times[i]
                break
        if status == OK:
            for i in range(m):
                if abs(vs[i]) > speed_limit:
                    status = SPEED
                    fail_time = times[i]
                    fail_value = vs[i]
                    break
        if status != OK:
            stopped = False
            break
        while no + m > ot.shape[0]:
            ot = _grow1(ot, no)
            oq = _grow1(oq, no)
            ov = _grow1(ov, no)
            oa = _grow1(oa, no)
            oo = _grow_rows(oo, no)
            oe = _grow_rows(oe, no)
        for i in range(m):
            ot[no + i] = times[i]
            oq[no + i] = qs[i]
            ov[no + i] = vs[i]
            oa[no + i] = acc[i]
            for c in range(obs.shape[1]):
                oo[no + i, c] = obs[i, c]
            oe[no + i, 0] = energy[i, 0]
            oe[no + i, 1] = energy[i, 1]
        no += m
        q = sy[n, 0]
        v = sy[n, 1]
        w = sy[n, 2]
        d = sy[n, 3]
        t_reached = st[n]
        if stopped:
            break
        previous_step = 0.0
        for i in range(_pymax(n - RESTART_STEPS, 0), n):
            previous_step = _pymax(previous_step, sh[i])
    return (status, ot[:no], oq[:no], ov[:no], oa[:no], n_steps, work[0], n_samp, stopped,
            t_reached, fail_time, fail_value, oo[:no], oe[:no])


def run(problem, chart, piece_edges, piece_load, q0, v0, *, rtol=1e-12, atol=None,
        sample_interval=1e-3, per_step=4, speed_limit=1e6, max_evaluations=1_000_000,
        max_step=math.inf, use_stop=False) -> RunResult:
    """Python convenience wrapper of :func:`dop853_run` (atol defaults to rtol)."""
    atol = rtol if atol is None else atol
    out = dop853_run(problem, chart, np.ascontiguousarray(piece_edges, dtype=np.float64),
                     np.ascontiguousarray(piece_load, dtype=np.float64), float(q0), float(v0),
                     float(rtol), float(atol), float(sample_interval), int(per_step),
                     float(speed_limit), int(max_evaluations), float(max_step), bool(use_stop))
    return RunResult(*out)
