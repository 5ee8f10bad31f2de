"""A compiled DOP853 driver for one scalar second-order ODE q̈ = f(t, q, q̇).

:func:`dop853_run` does, in one call of compiled code, what ``loopcheck.reduced.integrators.solve_adaptive``
does with scipy: the load history is constant on pieces; on each piece it runs scipy's
``solve_ivp(method="DOP853", dense_output=True, events=[stop])`` algorithm step for step
(``scipy/integrate/_ivp/rk.py``: ``RungeKutta._step_impl``, ``DOP853._estimate_error_norm``,
``DOP853._dense_output_impl`` and ``Dop853DenseOutput``; ``select_initial_step`` in
``common.py``; the terminal event as in ``ivp.py`` with scipy's Brent root finder), restarting
at every piece edge, and samples the result with loopcheck's rule (``dense_samples`` in
``loopcheck/reduced/integrators.py``). The coefficients are scipy's (``dop853_tableau``), read at
import time into module-level C views.

The problem is opaque here: the kernel calls the methods of a :class:`.problem.RightHandSide`
(``acceleration``, ``power``, ``dissipation``, ``stop_margin``, ``observe``, ``mark``,
``rewind``) and knows nothing else of it. The samples are appended to the caller's
:class:`.output.Samples`; the accepted steps are kept in a :class:`Steps` workspace that grows by
doubling and can be reused across runs: nothing is allocated per step.

Failures are status codes of :mod:`.output`, never exceptions (``OK``, ``STEP_SIZE``,
``NONFINITE``, ``SPEED``) in the returned :class:`.output.Outcome`.

Debugging: ``LOOPCHECK_PURE_PYTHON=1`` runs this same source as plain Python (:mod:`loopcheck.reduced.kernels`).
"""

from typing import NamedTuple, Optional

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import INFINITY, NAN, ceil, copysign, fabs, isfinite, nextafter, pow, sqrt
    from cython.cimports.loopcheck.reduced.kernels.output import Outcome, Samples, check_run
    from cython.cimports.loopcheck.reduced.kernels.problem import RightHandSide
else:
    from math import ceil, copysign, fabs, isfinite, nextafter, pow, sqrt
    from math import inf as INFINITY
    from math import nan as NAN

    from loopcheck.reduced.kernels.output import Outcome, Samples, check_run
    from loopcheck.reduced.kernels.problem import RightHandSide

from loopcheck.reduced.kernels import dop853_tableau as _coef
from loopcheck.reduced.kernels import output as _output

# Restarts at load edges: a piece after an edge starts with scipy's select_initial_step (Hairer,
# Nørsett & Wanner II.4), but at most the largest of the previous piece's last RESTART_STEPS
# steps (its last is cut short by the edge): the edge changes the load, not the mechanism's time
# scale. On seed variants (damper 61–63 N·s/m, coupler 36.1–36.2 kg) the selection alone gave
# 8.0 ms after the pulse's end where the steps before were 1.3 ms; DOP853's error estimate
# accepted it and the run's energy balance missed by 1.1e-8 (the nominal seed: 1.3e-11; with
# the cap, at most 2.8e-11 over those variants). The selection stays the bound near a dead centre,
# where it is the smaller. The scipy path (loopcheck.reduced.integrators.restart) does the same.
RESTART_STEPS = 2

# ---- scipy's DOP853 constants ---------------------------------------------------------------
# (Python values; the C copies the kernel reads are below. Write float literals: the build's
# cdivision makes an int / int C division, 1 / 8 == 0.)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
N_STAGES = _coef.N_STAGES                    # 12
N_STAGES_EXTENDED = _coef.N_STAGES_EXTENDED  # 16
INTERPOLATOR_POWER = _coef.INTERPOLATOR_POWER  # 7
ERROR_ESTIMATOR_ORDER = 7
ERROR_EXPONENT = -1.0 / (ERROR_ESTIMATOR_ORDER + 1.0)
EPS = float(np.finfo(float).eps)
SQRT_N = 2.0 ** 0.5  # x.size ** 0.5 in scipy's RMS norm, n = 2

A = np.ascontiguousarray(_coef.A, dtype=np.float64)          # (16, 16)
B = np.ascontiguousarray(_coef.B, dtype=np.float64)          # (12,)
C = np.ascontiguousarray(_coef.C, dtype=np.float64)          # (16,)
E3 = np.ascontiguousarray(_coef.E3, dtype=np.float64)        # (13,)
E5 = np.ascontiguousarray(_coef.E5, dtype=np.float64)        # (13,)
D = np.ascontiguousarray(_coef.D, dtype=np.float64)          # (4, 16)

# C copies of the above and of the statuses (loopcheck.reduced.kernels.output) for the compiled loops
_OK = cython.declare(cython.int, _output.OK)
_STEP_SIZE = cython.declare(cython.int, _output.STEP_SIZE)
_NONFINITE = cython.declare(cython.int, _output.NONFINITE)
_SPEED = cython.declare(cython.int, _output.SPEED)
_NS = cython.declare(cython.Py_ssize_t, N_STAGES)
_NSE = cython.declare(cython.Py_ssize_t, N_STAGES_EXTENDED)
_IP = cython.declare(cython.Py_ssize_t, INTERPOLATOR_POWER)
_RESTART = cython.declare(cython.Py_ssize_t, RESTART_STEPS)
_SAFETY = cython.declare(cython.double, SAFETY)
_MIN_FACTOR = cython.declare(cython.double, MIN_FACTOR)
_MAX_FACTOR = cython.declare(cython.double, MAX_FACTOR)
_ERROR_EXPONENT = cython.declare(cython.double, ERROR_EXPONENT)
_INITIAL_EXPONENT = cython.declare(cython.double, 1.0 / (ERROR_ESTIMATOR_ORDER + 1.0))
_EPS = cython.declare(cython.double, EPS)
_SQRT_N = cython.declare(cython.double, SQRT_N)
_A = cython.declare(cython.double[:, ::1], A)
_B = cython.declare(cython.double[::1], B)
_C = cython.declare(cython.double[::1], C)
_E3 = cython.declare(cython.double[::1], E3)
_E5 = cython.declare(cython.double[::1], E5)
# B, E5, E3 as rows (1, n) for _dot_kt_row
_B_ROW = cython.declare(cython.double[:, ::1], B.reshape(1, -1))
_E3_ROW = cython.declare(cython.double[:, ::1], E3.reshape(1, -1))
_E5_ROW = cython.declare(cython.double[:, ::1], E5.reshape(1, -1))
_D = cython.declare(cython.double[:, ::1], D)

# What run() returns
RunResult = NamedTuple("RunResult", [
    ("status", int),              # OK, STEP_SIZE, NONFINITE or SPEED (loopcheck.reduced.kernels.output)
    ("t", np.ndarray),            # sample times (pieces concatenated; a piece's first time repeats
    ("q", np.ndarray),            # the previous piece's last), states and q̈ at every sample
    ("v", np.ndarray),
    ("a", np.ndarray),
    ("n_steps", int),             # accepted steps over all pieces (a step cut by the stop event counts)
    ("n_evaluations", int),       # scipy's nfev summed over pieces (initial f, initial-step probe,
    #                               12 per attempted step, 3 per dense output)
    ("n_sample_evaluations", int),  # evaluations of f at the samples (not in n_evaluations)
    ("stopped", bool),            # the stop event ended the run
    ("t_reached", float),         # the last time integrated (the event's root if stopped)
    ("fail_time", float),         # where a failure happened (nan if OK)
    ("fail_value", float),        # q̇ for SPEED, else nan
    ("observed", np.ndarray),     # what the problem observed at each sample (m, observation_size)
    ("energy", np.ndarray),       # the work done and the energy dissipated since the start (m, 2), J
])


@cython.cclass
class Steps:
    """The accepted steps of a piece (a workspace, reusable across runs): st (times, s), sh
    (each step's h of the dense output, s), sy (the state after each: q, q̇, the work done and
    the energy dissipated) and sF (each step's dense coefficients, (n, INTERPOLATOR_POWER, 4));
    a summary run's deferred dense outputs: sD (1 where sF holds the step's coefficients) and sK
    (its 13 stages' K and P, (n, N_STAGES + 1, 4), to compute them later).
    Grows by doubling when full (:meth:`grow`), never per step."""

    def __init__(self, capacity: cython.Py_ssize_t = 64):
        if capacity < 2:
            raise ValueError(f"Steps(capacity={capacity}): at least 2")
        self._allocate(capacity)

    @cython.cfunc
    def _allocate(self, capacity: cython.Py_ssize_t):
        self.st = np.empty(capacity)
        self.sh = np.empty(capacity)
        self.sy = np.empty((capacity, 4))
        self.sF = np.empty((capacity, INTERPOLATOR_POWER, 4))
        self.sK = np.empty((capacity, N_STAGES + 1, 4))
        self.sD = np.zeros(capacity, dtype=np.uint8)

    @cython.ccall
    def capacity(self) -> cython.Py_ssize_t:
        """Steps it holds without growing (+1: st and sy also hold the start)."""
        return self.st.shape[0]

    @cython.ccall
    def grow(self, keep: cython.Py_ssize_t):
        """Double the capacity, keeping the first ``keep`` entries."""
        st, sh, sy, sF, sK, sD = self.st, self.sh, self.sy, self.sF, self.sK, self.sD
        self._allocate(2 * st.shape[0])
        i: cython.Py_ssize_t
        c: cython.Py_ssize_t
        r: cython.Py_ssize_t
        for i in range(keep):
            self.st[i] = st[i]
            self.sh[i] = sh[i]
            self.sD[i] = sD[i]
            for c in range(4):
                self.sy[i, c] = sy[i, c]
                for r in range(_IP):
                    self.sF[i, r, c] = sF[i, r, c]
                for r in range(_NS + 1):
                    self.sK[i, r, c] = sK[i, r, c]


# ---- helpers --------------------------------------------------------------------------------

@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _pymin(a: cython.double, b: cython.double) -> cython.double:
    """Python's min(a, b): a unless b < a (NaN handling as in Python)."""
    return b if b < a else a


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _pymax(a: cython.double, b: cython.double) -> cython.double:
    """Python's max(a, b): a unless b > a."""
    return b if b > a else a


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _npmax(a: cython.double, b: cython.double) -> cython.double:
    """np.maximum(a, b) of two floats (NaN if either is)."""
    if a != a or b != b:
        return NAN
    return a if a >= b else b


@cython.cfunc
@cython.exceptval(check=False)
def _dense_eval(t: cython.double, t_old: cython.double, h: cython.double, y_old0: cython.double,
                y_old1: cython.double, F: cython.double[:, :, ::1], j: cython.Py_ssize_t,
                c: cython.Py_ssize_t) -> tuple[cython.double, cython.double]:
    """Dop853DenseOutput._call_impl at t for step j, components c and c + 1 (F: (n_steps, 7, 4):
    q, q̇, then the energy flows), same operation order."""
    x: cython.double = (t - t_old) / h
    y0: cython.double = 0.0
    y1: cython.double = 0.0
    i: cython.Py_ssize_t
    r: cython.Py_ssize_t
    for i in range(_IP):
        r = _IP - 1 - i
        y0 += F[j, r, c]
        y1 += F[j, r, c + 1]
        if i % 2 == 0:
            y0 *= x
            y1 *= x
        else:
            y0 *= 1.0 - x
            y1 *= 1.0 - x
    return y0 + y_old0, y1 + y_old1


@cython.cfunc
def _brentq_stop(rhs: RightHandSide, xa: cython.double, xb: cython.double, t_old: cython.double,
                 h: cython.double, y_old0: cython.double, y_old1: cython.double, F: cython.double[:, :, ::1],
                 j: cython.Py_ssize_t) -> cython.double:
    """scipy.optimize.brentq (Zeros/brentq.c) of stop_margin on step j's dense output,
    xtol = rtol = 4 EPS, maxiter 100, as solve_ivp's solve_event_equation calls it."""
    xtol: cython.double = 4.0 * _EPS
    rtol: cython.double = 4.0 * _EPS
    xpre: cython.double = xa
    xcur: cython.double = xb
    xblk: cython.double = 0.0
    fblk: cython.double = 0.0
    spre: cython.double = 0.0
    scur: cython.double = 0.0
    q: cython.double
    v: cython.double
    delta: cython.double
    sbis: cython.double
    stry: cython.double
    dpre: cython.double
    dblk: cython.double
    q, v = _dense_eval(xpre, t_old, h, y_old0, y_old1, F, j, 0)
    fpre: cython.double = rhs.stop_margin(xpre, q, v)
    q, v = _dense_eval(xcur, t_old, h, y_old0, y_old1, F, j, 0)
    fcur: cython.double = rhs.stop_margin(xcur, q, v)
    if fpre == 0:
        return xpre
    if fcur == 0:
        return xcur
    it: cython.int
    for it in range(100):
        if fpre != 0 and fcur != 0 and ((copysign(1.0, fpre) < 0) != (copysign(1.0, fcur) < 0)):
            xblk = xpre
            fblk = fpre
            spre = xcur - xpre
            scur = spre
        if fabs(fblk) < fabs(fcur):
            xpre = xcur
            xcur = xblk
            xblk = xpre
            fpre = fcur
            fcur = fblk
            fblk = fpre
        delta = (xtol + rtol * fabs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0 or fabs(sbis) < delta:
            return xcur
        if fabs(spre) > delta and fabs(fcur) < fabs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * fabs(stry) < min(fabs(spre), 3.0 * fabs(sbis) - delta):
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
        if fabs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        q, v = _dense_eval(xcur, t_old, h, y_old0, y_old1, F, j, 0)
        fcur = rhs.stop_margin(xcur, q, v)
    return xcur  # scipy would raise (no convergence in 100 iterations); not reachable for a
    #              bracketed continuous g at these tolerances


@cython.ccall
@cython.exceptval(check=False)
def _norm2(x0: cython.double, x1: cython.double) -> cython.double:
    """np.linalg.norm((x0, x1)) summed plainly (numpy: sqrt(x.dot(x)), by the BLAS).
    (cpdef: tests/helpers.py sums scipy's norm with it.)"""
    return sqrt(x0 * x0 + x1 * x1)


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _rms2(x0: cython.double, x1: cython.double) -> cython.double:
    """scipy's norm of (x0, x1): np.linalg.norm(x) / x.size ** 0.5."""
    return _norm2(x0, x1) / _SQRT_N


@cython.ccall
def _dot_kt(K: cython.double[:, ::1], a: cython.double[::1], s: cython.Py_ssize_t,
            out: cython.double[::1]):
    """out = np.dot(K[:s].T, a[:s]) summed in one fixed order: columns in blocks of four,
    t += (p0 + p1), t += (p2 + p3), then the rest one by one; no FMA. It is OpenBLAS's dgemv_n on
    the Intel machine it was measured on (bit-equal to numpy on 2100 random cases), not on every
    CPU (on an AMD EPYC 1085 of 2000 cases differ in the last bit): OpenBLAS picks its kernels at
    run time. The order matters where runs are compared step for step (at tight tolerances the
    error estimate is mostly round-off, and another order moves the step sequence by ~1e-6
    relative at rtol 1e-12), so the tests that do run scipy in this order
    (tests/helpers.py, scipy_in_kernel_order, which calls this function: cpdef)."""
    nb: cython.Py_ssize_t = s - s % 4
    r: cython.Py_ssize_t
    i: cython.Py_ssize_t
    acc: cython.double
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


@cython.cfunc
@cython.inline
@cython.exceptval(-1, check=False)
def _dot_kt_row(K: cython.double[:, ::1], a: cython.double[:, ::1], ra: cython.Py_ssize_t, s: cython.Py_ssize_t,
                out: cython.double[:, ::1], ro: cython.Py_ssize_t) -> cython.int:
    """:func:`_dot_kt` with the weights a[ra] and the result into out[ro]: the same sums in the
    same order. It takes the rows by index because a view of a row (``_A[si]``, ``scratch[0]``)
    is reference-counted atomically, twice a view: 30 atomic operations a step in _rk_step."""
    nb: cython.Py_ssize_t = s - s % 4
    r: cython.Py_ssize_t
    i: cython.Py_ssize_t
    acc: cython.double
    for r in range(2):
        acc = 0.0
        i = 0
        while i < nb:
            acc = acc + (K[i, r] * a[ra, i] + K[i + 1, r] * a[ra, i + 1])
            acc = acc + (K[i + 2, r] * a[ra, i + 2] + K[i + 3, r] * a[ra, i + 3])
            i += 4
        while i < s:
            acc = acc + K[i, r] * a[ra, i]
            i += 1
        out[ro, r] = acc
    return 0


@cython.cfunc
@cython.inline
def _fun(rhs: RightHandSide, load: cython.Py_ssize_t, t: cython.double, q: cython.double,
         v: cython.double, K: cython.double[:, ::1], P: cython.double[:, ::1], row: cython.Py_ssize_t,
         work: cython.longlong[::1]) -> cython.int:
    """The first-order system (q̇, f) into K[row] and the energy flows' rates (P, D) there
    into P[row]; work = [nfev, max_evaluations].
    Returns a status: STEP_SIZE when the budget is spent (f not called), NONFINITE if f is."""
    if work[0] >= work[1]:
        return _STEP_SIZE
    work[0] += 1
    acc: cython.double = rhs.acceleration(load, t, q, v)
    K[row, 0] = v
    K[row, 1] = acc
    P[row, 0] = rhs.power(load, v)
    P[row, 1] = rhs.dissipation(v)
    if not isfinite(acc):
        return _NONFINITE
    return _OK


@cython.cfunc
def _initial_step(rhs: RightHandSide, load: cython.Py_ssize_t, t: cython.double, end: cython.double,
                  y0: cython.double, y1: cython.double, rtol: cython.double, atol: cython.double,
                  max_step: cython.double, restart_cap: cython.double, K: cython.double[:, ::1],
                  P: cython.double[:, ::1], work: cython.longlong[::1]
                  ) -> tuple[cython.int, cython.double, cython.double]:
    """RungeKutta.__init__: f0 = fun(t0, y0) into K[0], then select_initial_step (common.py),
    at most ``restart_cap`` when that is > 0 (a restart at a load edge: RESTART_STEPS).
    Returns (status, fail_time, h_abs)."""
    s: cython.int = _fun(rhs, load, t, y0, y1, K, P, 0, work)
    if s != _OK:
        return s, t, 0.0
    f0: cython.double = K[0, 0]
    f1: cython.double = K[0, 1]
    interval_length: cython.double = fabs(end - t)
    if interval_length == 0.0:
        return _OK, NAN, 0.0
    sc0: cython.double = atol + fabs(y0) * rtol
    sc1: cython.double = atol + fabs(y1) * rtol
    d0: cython.double = _rms2(y0 / sc0, y1 / sc1)
    d1: cython.double = _rms2(f0 / sc0, f1 / sc1)
    h0: cython.double
    h1: cython.double
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = _pymin(h0, interval_length)
    s = _fun(rhs, load, t + h0 * 1.0, y0 + h0 * 1.0 * f0, y1 + h0 * 1.0 * f1, K, P, 1, work)
    if s != _OK:
        return s, t + h0, 0.0
    d2: cython.double = _rms2((K[1, 0] - f0) / sc0, (K[1, 1] - f1) / sc1) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = _pymax(1e-6, h0 * 1e-3)
    else:
        h1 = pow(0.01 / _pymax(d1, d2), _INITIAL_EXPONENT)
    h: cython.double = _pymin(_pymin(_pymin(100 * h0, h1), interval_length), max_step)
    return _OK, NAN, (_pymin(h, restart_cap) if restart_cap > 0.0 else h)


@cython.cfunc
def _rk_step(rhs: RightHandSide, load: cython.Py_ssize_t, t: cython.double, y0: cython.double,
             y1: cython.double, h: cython.double, rtol: cython.double, atol: cython.double,
             K: cython.double[:, ::1], P: cython.double[:, ::1], work: cython.longlong[::1],
             scratch: cython.double[:, ::1]
             ) -> tuple[cython.int, cython.double, cython.double, cython.double, cython.double]:
    """rk_step and DOP853._estimate_error_norm for one attempt (K[0] = f at (t, y) on entry;
    K[12] = f_new on exit; scratch (3, 2) is overwritten). Returns (status, fail_time, y_new0,
    y_new1, error_norm)."""
    si: cython.Py_ssize_t
    s: cython.int
    for si in range(1, _NS):  # dy in scratch[0]
        _dot_kt_row(K, _A, si, si, scratch, 0)  # scipy: dy = np.dot(K[:s].T, a[:s]) * h, then y + dy
        s = _fun(rhs, load, t + _C[si] * h, y0 + scratch[0, 0] * h, y1 + scratch[0, 1] * h, K, P, si, work)
        if s != _OK:
            return s, t + _C[si] * h, 0.0, 0.0, 0.0
    _dot_kt_row(K, _B_ROW, 0, _NS, scratch, 0)  # bk in scratch[0]
    yn0: cython.double = y0 + h * scratch[0, 0]
    yn1: cython.double = y1 + h * scratch[0, 1]
    s = _fun(rhs, load, t + h, yn0, yn1, K, P, _NS, work)
    if s != _OK:
        return s, t + h, 0.0, 0.0, 0.0
    sc0: cython.double = atol + _npmax(fabs(y0), fabs(yn0)) * rtol
    sc1: cython.double = atol + _npmax(fabs(y1), fabs(yn1)) * rtol
    _dot_kt_row(K, _E5_ROW, 0, _NS + 1, scratch, 1)  # e5 in scratch[1]
    _dot_kt_row(K, _E3_ROW, 0, _NS + 1, scratch, 2)  # e3 in scratch[2]
    n5: cython.double = _norm2(scratch[1, 0] / sc0, scratch[1, 1] / sc1)
    n3: cython.double = _norm2(scratch[2, 0] / sc0, scratch[2, 1] / sc1)
    err5_norm_2: cython.double = n5 * n5  # x ** 2, as numba lowers it: one product
    err3_norm_2: cython.double = n3 * n3
    if err5_norm_2 == 0 and err3_norm_2 == 0:
        return _OK, NAN, yn0, yn1, 0.0
    denom: cython.double = err5_norm_2 + 0.01 * err3_norm_2
    return _OK, NAN, yn0, yn1, fabs(h) * err5_norm_2 / sqrt(denom * 2)


@cython.cfunc
@cython.inline
def _interpolant(sF: cython.double[:, :, ::1], sy: cython.double[:, ::1], n: cython.Py_ssize_t,
                 h: cython.double, R: cython.double[:, ::1], col: cython.Py_ssize_t,
                 c: cython.Py_ssize_t) -> cython.void:
    """Step n's dense coefficients F of component ``col`` (from sy[n] to sy[n + 1]) from its
    rates R[:, c] at the 16 stages, in DOP853._dense_output_impl's order: Δ, h f_old − Δ,
    2Δ − h (f_new + f_old), then h D·R (numpy: BLAS dgemm; the order differs, by round-off, in
    the dense output only)."""
    dl: cython.double = sy[n + 1, col] - sy[n, col]
    sF[n, 0, col] = dl
    sF[n, 1, col] = h * R[0, c] - dl
    sF[n, 2, col] = 2 * dl - h * (R[_NS, c] + R[0, c])
    r: cython.Py_ssize_t
    j: cython.Py_ssize_t
    p: cython.double
    for r in range(_IP - 3):
        p = 0.0
        for j in range(_NSE):
            p += _D[r, j] * R[j, c]
        sF[n, 3 + r, col] = h * p


@cython.cfunc
def _dense_coefficients(rhs: RightHandSide, load: cython.Py_ssize_t, t_old: cython.double,
                        yo0: cython.double, yo1: cython.double, h: cython.double, K: cython.double[:, ::1],
                        P: cython.double[:, ::1], work: cython.longlong[::1], steps: Steps,
                        n: cython.Py_ssize_t, dy: cython.double[::1]) -> tuple[cython.int, cython.double]:
    """DOP853._dense_output_impl: 3 extra stages into K[13:16] (and P), then the interpolant of
    each component of steps.sy from step n to n + 1 (both set) into steps.sF[n]: q and q̇ from K,
    the energy flows from P (dy (2,) is overwritten). Returns (status, fail_time)."""
    si: cython.Py_ssize_t
    s: cython.int
    c: cython.Py_ssize_t
    for si in range(_NS + 1, _NSE):
        _dot_kt(K, _A[si], si, dy)
        s = _fun(rhs, load, t_old + _C[si] * h, yo0 + dy[0] * h, yo1 + dy[1] * h, K, P, si, work)
        if s != _OK:
            return s, t_old + _C[si] * h
    for c in range(2):
        _interpolant(steps.sF, steps.sy, n, h, K, c, c)
        _interpolant(steps.sF, steps.sy, n, h, P, 2 + c, c)
    return _OK, NAN


@cython.cfunc
@cython.inline
def _keep_stages(steps: Steps, n: cython.Py_ssize_t, K: cython.double[:, ::1], P: cython.double[:, ::1]) -> cython.void:
    """Step n's 13 stages (K and P rows 0.._NS) into steps.sK[n], its dense output not yet made."""
    r: cython.Py_ssize_t
    for r in range(_NS + 1):
        steps.sK[n, r, 0] = K[r, 0]
        steps.sK[n, r, 1] = K[r, 1]
        steps.sK[n, r, 2] = P[r, 0]
        steps.sK[n, r, 3] = P[r, 1]
    steps.sD[n] = 0


@cython.cfunc
def _deferred_dense(rhs: RightHandSide, load: cython.Py_ssize_t, steps: Steps, j: cython.Py_ssize_t,
                    K: cython.double[:, ::1], P: cython.double[:, ::1], work: cython.longlong[::1],
                    dy: cython.double[::1]) -> tuple[cython.int, cython.double]:
    """Step j's dense output from its kept stages (:func:`_keep_stages`): what
    :func:`_dense_coefficients` made right after the step in a full run."""
    r: cython.Py_ssize_t
    for r in range(_NS + 1):
        K[r, 0] = steps.sK[j, r, 0]
        K[r, 1] = steps.sK[j, r, 1]
        P[r, 0] = steps.sK[j, r, 2]
        P[r, 1] = steps.sK[j, r, 3]
    status: cython.int
    fail_time: cython.double
    status, fail_time = _dense_coefficients(rhs, load, steps.st[j], steps.sy[j, 0], steps.sy[j, 1], steps.sh[j],
                                            K, P, work, steps, j, dy)
    if status == _OK:
        steps.sD[j] = 1
    return status, fail_time


@cython.cfunc
def _piece(rhs: RightHandSide, load: cython.Py_ssize_t, start: cython.double, end: cython.double,
           q0: cython.double, v0: cython.double, w0: cython.double, d0: cython.double, rtol: cython.double,
           atol: cython.double, max_step: cython.double, restart_cap: cython.double, use_stop: cython.bint,
           work: cython.longlong[::1], steps: Steps, K: cython.double[:, ::1], P: cython.double[:, ::1],
           scratch: cython.double[:, ::1], ends: Optional[Samples]
           ) -> tuple[cython.int, cython.Py_ssize_t, cython.int, cython.double]:
    """One solve_ivp call on [start, end] (its first step at most ``restart_cap`` if > 0) from
    (q0, v0), the work done w0 and the energy dissipated d0 (J): steps into ``steps`` (st times,
    sh dense h, sy states: q, q̇, work, dissipated; sF dense coefficients), grown as needed.
    K, P (16, 2) and scratch (3, 2) are the stages' workspace.

    The energy flows ride along: each accepted step adds h Σ b_s P_s of their stage rates
    (DOP853's order-8 quadrature) and gets DOP853's dense output; they take no part in the
    error estimate, so the steps are scipy's. With ``ends`` (a summary run's, else None), each
    accepted step's end gets q̈ and the problem's observation there from the step's last stage,
    evaluated at that very state (f_new), into ends.a and ends.observed at row n + 1 (the rows
    indexed like steps.st; ends.n is not advanced). Returns (status, n_steps, stopped, fail_time)."""
    t: cython.double = start
    y0: cython.double = q0
    y1: cython.double = v0
    steps.st[0] = t
    steps.sy[0, 0] = y0
    steps.sy[0, 1] = y1
    steps.sy[0, 2] = w0
    steps.sy[0, 3] = d0
    n: cython.Py_ssize_t = 0
    stopped: cython.int = 0
    status: cython.int
    fail_time: cython.double
    h_abs: cython.double
    pb: cython.double[::1] = scratch[1]  # Σ b_s P_s of a step (the energy flows' rates)
    status, fail_time, h_abs = _initial_step(rhs, load, t, end, y0, y1, rtol, atol, max_step, restart_cap,
                                             K, P, work)
    f0: cython.double = K[0, 0]
    f1: cython.double = K[0, 1]
    p0: cython.double = P[0, 0]
    p1: cython.double = P[0, 1]
    g: cython.double = 0.0
    g_new: cython.double
    min_step: cython.double
    step_rejected: cython.bint
    h: cython.double = 0.0      # (set by every accepted attempt: gcc cannot see it)
    t_new: cython.double = t
    t_old: cython.double
    yn0: cython.double = 0.0
    yn1: cython.double = 0.0
    yo0: cython.double
    yo1: cython.double
    error_norm: cython.double
    factor: cython.double
    root: cython.double
    q: cython.double
    v: cython.double
    w: cython.double
    d: cython.double
    if use_stop and status == _OK:
        g = rhs.stop_margin(t, y0, y1)
        if rhs.stop_at_start(t, y0, y1):  # an event at the piece's start (a load edge breaks a stick loose)
            return status, 0, 1, fail_time
    while status == _OK:
        if t == end:  # OdeSolver.step's corner case (an empty piece)
            break
        # ---- RungeKutta._step_impl ----
        min_step = 10 * fabs(nextafter(t, INFINITY) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        step_rejected = False
        while True:
            if h_abs < min_step:
                status = _STEP_SIZE
                fail_time = t
                break
            h = h_abs * 1.0
            t_new = t + h
            if 1.0 * (t_new - end) > 0:
                t_new = end
            h = t_new - t
            h_abs = fabs(h)
            K[0, 0] = f0
            K[0, 1] = f1
            P[0, 0] = p0
            P[0, 1] = p1
            status, fail_time, yn0, yn1, error_norm = _rk_step(rhs, load, t, y0, y1, h, rtol, atol, K, P,
                                                               work, scratch)
            if status != _OK:
                break
            if error_norm < 1:
                if error_norm == 0:
                    factor = _MAX_FACTOR
                else:
                    factor = _pymin(_MAX_FACTOR, _SAFETY * pow(error_norm, _ERROR_EXPONENT))
                if step_rejected:
                    factor = _pymin(1.0, factor)
                h_abs *= factor
                break
            else:
                h_abs *= _pymax(_MIN_FACTOR, _SAFETY * pow(error_norm, _ERROR_EXPONENT))
                step_rejected = True
        if status != _OK:
            break
        # accepted: t_old = t, t = t_new, y_old = y, y = y_new, f = f_new
        t_old = t
        yo0 = y0
        yo1 = y1
        t = t_new
        y0 = yn0
        y1 = yn1
        f0 = K[_NS, 0]
        f1 = K[_NS, 1]
        p0 = P[_NS, 0]
        p1 = P[_NS, 1]
        if n + 1 >= steps.st.shape[0]:
            steps.grow(n + 1)
        steps.sy[n + 1, 0] = y0
        steps.sy[n + 1, 1] = y1
        if ends is not None:  # the last stage was f at (t, y): the configuration is the step end's
            ends.n = n + 1  # rows 0..n kept when it grows
            ends.reserve(1)
            ends.a[n + 1] = f1
            rhs.observe(ends.observed, n + 1)
        _dot_kt(P, _B, _NS, pb)  # the energy flows' step, with the state's weights
        steps.sy[n + 1, 2] = steps.sy[n, 2] + h * pb[0]
        steps.sy[n + 1, 3] = steps.sy[n, 3] + h * pb[1]
        if ends is None:
            status, fail_time = _dense_coefficients(rhs, load, t_old, yo0, yo1, h, K, P, work, steps, n,
                                                    scratch[0])
            if status != _OK:
                break
            steps.sD[n] = 1
        else:  # a summary run: the dense output later, and only where a sample or the stop event needs it
            _keep_stages(steps, n, K, P)
        steps.sh[n] = t - t_old
        steps.st[n + 1] = t
        n += 1
        if use_stop:
            g_new = rhs.stop_margin(t, y0, y1)
            if g >= 0 and g_new <= 0:  # find_active_events, direction -1
                if not steps.sD[n - 1]:
                    status, fail_time = _dense_coefficients(rhs, load, t_old, yo0, yo1, h, K, P, work, steps,
                                                            n - 1, scratch[0])
                    if status != _OK:
                        break
                    steps.sD[n - 1] = 1
                root = _brentq_stop(rhs, t_old, t, t_old, steps.sh[n - 1], yo0, yo1, steps.sF, n - 1)
                q, v = _dense_eval(root, t_old, steps.sh[n - 1], yo0, yo1, steps.sF, n - 1, 0)
                w, d = _dense_eval(root, t_old, steps.sh[n - 1], steps.sy[n - 1, 2], steps.sy[n - 1, 3],
                                   steps.sF, n - 1, 2)
                if root == t_old and n > 1:
                    n -= 1  # solve_ivp's donot_append: ts[-1] == t, the step is dropped
                else:
                    steps.st[n] = root
                    steps.sy[n, 0] = q
                    steps.sy[n, 1] = v
                    steps.sy[n, 2] = w
                    steps.sy[n, 3] = d
                stopped = 1
                break
            g = g_new
        if t - end >= 0:
            break
    return status, n, stopped, fail_time


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _parts(h: cython.double, sample_interval: cython.double, per_step: cython.Py_ssize_t) -> cython.Py_ssize_t:
    """Equal parts a step of h (s) is cut into for sampling: max(per_step, ⌈h / sample_interval⌉)."""
    return max(per_step, cython.cast(cython.Py_ssize_t, ceil(h / sample_interval)))


@cython.cfunc
def _sample_piece(rhs: RightHandSide, load: cython.Py_ssize_t, steps: Steps, n: cython.Py_ssize_t,
                  sample_interval: cython.double, per_step: cython.Py_ssize_t, out: Samples) -> cython.Py_ssize_t:
    """loopcheck's dense_samples on one piece, written into ``out`` from out.n (room reserved here)
    without advancing out.n: sorted unique times, states, q̈, what the problem observes at each
    and the energy flows. Returns their number m."""
    st: cython.double[::1] = steps.st
    sh: cython.double[::1] = steps.sh
    sy: cython.double[:, ::1] = steps.sy
    sF: cython.double[:, :, ::1] = steps.sF
    # each step [t_j, t_j + h_j] cut into max(per_step, ⌈h_j / sample_interval⌉) equal parts:
    # samples no further apart than sample_interval nor h_j / per_step; in order (t_j + h_j·(k/p)
    # is non-decreasing in k and at most t_j + h_j), so a tie is the only repair needed
    m: cython.Py_ssize_t = 1
    j: cython.Py_ssize_t
    i: cython.Py_ssize_t
    parts: cython.Py_ssize_t
    dt: cython.double
    x: cython.double
    for j in range(n):
        m += _parts(st[j + 1] - st[j], sample_interval, per_step)
    out.reserve(m)
    o: cython.Py_ssize_t = out.n
    times: cython.double[::1] = out.t
    times[o] = st[0]
    m = 1
    for j in range(n):
        dt = st[j + 1] - st[j]
        parts = _parts(dt, sample_interval, per_step)
        for i in range(1, parts + 1):
            x = st[j] + dt * (cython.cast(cython.double, i) / parts) if i < parts else st[j + 1]
            if x != times[o + m - 1]:
                times[o + m] = x
                m += 1
    # OdeSolution: segment = clip(searchsorted(ts, t, 'left') - 1, 0, n - 1)
    seg: cython.Py_ssize_t = 0
    for i in range(m):
        x = times[o + i]
        while seg < n - 1 and st[seg + 1] < x:
            seg += 1
        out.q[o + i], out.v[o + i] = _dense_eval(x, st[seg], sh[seg], sy[seg, 0], sy[seg, 1], sF, seg, 0)
        out.energy[o + i, 0], out.energy[o + i, 1] = _dense_eval(x, st[seg], sh[seg], sy[seg, 2], sy[seg, 3],
                                                                 sF, seg, 2)
    # states at the step times are the solver's own
    i = 0
    for j in range(n + 1):
        while times[o + i] < st[j]:
            i += 1
        out.q[o + i] = sy[j, 0]
        out.v[o + i] = sy[j, 1]
        out.energy[o + i, 0] = sy[j, 2]
        out.energy[o + i, 1] = sy[j, 3]
    for i in range(m):
        out.a[o + i] = rhs.acceleration(load, times[o + i], out.q[o + i], out.v[o + i])
        rhs.observe(out.observed, o + i)
    return m


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _score(ends: Samples, j: cython.Py_ssize_t, column: cython.Py_ssize_t) -> cython.double:
    """|observed[j, column] · q̇| at endpoint j: the rate whose peak a summary run keeps."""
    return fabs(ends.observed[j, column] * ends.v[j])


@cython.cfunc
def _sample_piece_summary(rhs: RightHandSide, load: cython.Py_ssize_t, steps: Steps, n: cython.Py_ssize_t,
                          sample_interval: cython.double, per_step: cython.Py_ssize_t,
                          peak_column: cython.Py_ssize_t, stopped: cython.bint, ends: Samples, out: Samples,
                          K: cython.double[:, ::1], P: cython.double[:, ::1], work: cython.longlong[::1],
                          dy: cython.double[::1]
                          ) -> tuple[cython.Py_ssize_t, cython.Py_ssize_t, cython.int, cython.double]:
    """A summary run's samples of one piece (:func:`dop853_run` with ``peak_column`` ≥ 0), written
    as :func:`_sample_piece` writes them: every step's end, and :func:`_sample_piece`'s cuts only in
    the steps where the peak can lie: the two steps on either side of each step end where the rate
    of interest |observed[peak_column] · q̇| is a local maximum over the step ends (the piece's ends
    included). There the samples are a full run's, at the same times, so the peak refined between
    them (:meth:`loopcheck.trajectory.Trajectory.peak_rate`) is the full run's; elsewhere q̈ is
    not evaluated at all: a step end's q̈ and observation are its last stage's, kept by :func:`_piece`
    in ``ends`` (a workspace), where a full run evaluates max(per_step, ⌈h / sample_interval⌉) samples
    a step. Only the piece's start, its end if the stop event (``stopped``) cut the last step, and the
    cuts are evaluated, in time order from the piece's start (:meth:`RightHandSide.rewind`), after
    the dense output of each step cut, deferred by :func:`_piece` (3 evaluations a step, counted
    in ``work``; K, P and dy are its workspace). Returns (samples m, evaluations of q̈ at the
    samples, status, fail_time): a status other than OK (the budget spent, a non-finite stage)
    leaves ``out`` as it was."""
    st: cython.double[::1] = steps.st
    sh: cython.double[::1] = steps.sh
    sy: cython.double[:, ::1] = steps.sy
    sF: cython.double[:, :, ::1] = steps.sF
    width: cython.Py_ssize_t = out.width
    j: cython.Py_ssize_t
    i: cython.Py_ssize_t
    k: cython.Py_ssize_t
    c: cython.Py_ssize_t
    parts: cython.Py_ssize_t
    dt: cython.double
    x: cython.double
    s: cython.double
    ends.n = 0  # (rows 1..n are _piece's, which grew it to hold them)
    ends.reserve(n + 1)
    for j in range(n + 1):  # the step ends: the solver's own states and energy flows
        ends.t[j] = st[j]
        ends.q[j] = sy[j, 0]
        ends.v[j] = sy[j, 1]
        ends.energy[j, 0] = sy[j, 2]
        ends.energy[j, 1] = sy[j, 3]
    # q̈ and the observation at each step's end were recorded by _piece from the step's last stage;
    # the piece's start, and its end where the stop event cut the last step, are evaluated here
    ends.a[0] = rhs.acceleration(load, st[0], sy[0, 0], sy[0, 1])
    rhs.observe(ends.observed, 0)
    evaluations: cython.Py_ssize_t = 1
    if stopped and n > 0:
        ends.a[n] = rhs.acceleration(load, st[n], sy[n, 0], sy[n, 1])
        rhs.observe(ends.observed, n)
        evaluations += 1
    fine: cython.uchar[::1] = np.zeros(n + 1, dtype=np.uint8)
    for j in range(n + 1):
        s = _score(ends, j, peak_column)
        if (j == 0 or s > _score(ends, j - 1, peak_column)) and (j == n or s >= _score(ends, j + 1, peak_column)):
            for k in range(max(j - 2, 0), min(j + 2, n)):
                fine[k] = 1
    m: cython.Py_ssize_t = 1
    for j in range(n):
        m += _parts(st[j + 1] - st[j], sample_interval, per_step) if fine[j] else 1
    out.reserve(m)
    o: cython.Py_ssize_t = out.n
    times: cython.double[::1] = out.t
    times[o] = st[0]
    m = 1
    for j in range(n):  # the times _sample_piece gives, in the steps cut
        dt = st[j + 1] - st[j]
        parts = _parts(dt, sample_interval, per_step) if fine[j] else 1
        for i in range(1, parts + 1):
            x = st[j] + dt * (cython.cast(cython.double, i) / parts) if i < parts else st[j + 1]
            if x != times[o + m - 1]:
                times[o + m] = x
                m += 1
    status: cython.int
    fail_time: cython.double
    rhs.rewind()
    for j in range(n):  # the dense outputs of the steps cut, in time order
        if fine[j] and not steps.sD[j]:
            status, fail_time = _deferred_dense(rhs, load, steps, j, K, P, work, dy)
            if status != _OK:
                return 0, evaluations, status, fail_time
    source: cython.Py_ssize_t[::1] = np.full(m, -1, dtype=np.intp)  # the step end a sample is, or -1
    i = 0
    for j in range(n + 1):
        while times[o + i] < st[j]:
            i += 1
        source[i] = j
    rhs.rewind()
    seg: cython.Py_ssize_t = 0
    for i in range(m):
        k = source[i]
        if k >= 0:
            out.q[o + i] = ends.q[k]
            out.v[o + i] = ends.v[k]
            out.a[o + i] = ends.a[k]
            out.energy[o + i, 0] = ends.energy[k, 0]
            out.energy[o + i, 1] = ends.energy[k, 1]
            for c in range(width):
                out.observed[o + i, c] = ends.observed[k, c]
            continue
        x = times[o + i]
        while seg < n - 1 and st[seg + 1] < x:
            seg += 1
        out.q[o + i], out.v[o + i] = _dense_eval(x, st[seg], sh[seg], sy[seg, 0], sy[seg, 1], sF, seg, 0)
        out.energy[o + i, 0], out.energy[o + i, 1] = _dense_eval(x, st[seg], sh[seg], sy[seg, 2], sy[seg, 3],
                                                                 sF, seg, 2)
        out.a[o + i] = rhs.acceleration(load, x, out.q[o + i], out.v[o + i])
        rhs.observe(out.observed, o + i)
        evaluations += 1
    return m, evaluations, _OK, NAN


@cython.ccall
def dop853_run(rhs: RightHandSide, piece_edges: cython.double[::1], piece_load: cython.Py_ssize_t[::1],
               q0: cython.double, v0: cython.double, rtol: cython.double, atol: cython.double,
               sample_interval: cython.double, per_step: cython.Py_ssize_t, speed_limit: cython.double,
               max_evaluations: cython.Py_ssize_t, max_step: cython.double, use_stop: cython.bint,
               out: Samples, steps: Steps, peak_column: cython.Py_ssize_t = -1) -> Outcome:
    """Integrate q̈ = rhs.acceleration(load, t, q, q̇) over the pieces.

    Parameters
    ----------
    rhs : the problem (:class:`.problem.RightHandSide`)
    piece_edges : (p+1,) s, increasing; piece_load : (p,), the load index of each piece
    q0, v0 : initial state at piece_edges[0]
    rtol, atol : scipy's tolerances (same for q and q̇)
    sample_interval, per_step : each accepted step of h (s) is cut into max(per_step,
        ⌈h / sample_interval⌉) equal parts for sampling (:func:`_parts`)
    speed_limit : |q̇| beyond which a sample ends the run with SPEED
    max_evaluations : budget of f evaluations over all pieces (as scipy's nfev counts them)
    max_step : scipy's max_step (inf for none)
    use_stop : the terminal event rhs.stop_margin (direction -1); rhs.stop_at_start at a piece's
        start ends the run there (one sample, no step)
    out : the samples are appended to it (its width must be rhs.observation_size())
    steps : the step workspace (:class:`Steps`; any capacity: it grows)
    peak_column : -1 (a full run): every step cut as above. Else a summary run: the observed
        column whose product with q̇ is the rate whose peak is kept; only the steps beside that
        rate's local maxima are cut, every other step sampled at its end only
        (:func:`_sample_piece_summary`): the peak and the energy flows as a full run's, at a
        fraction of the evaluations at the samples

    Returns
    -------
    Outcome (:mod:`.output`; n_evaluations counted as scipy's nfev, n_sample_evaluations the
    evaluations at the samples). On a failure, the samples of the pieces completed before it
    stay appended; a piece's samples are appended only once they pass the checks (non-finite,
    speed).
    """
    check_run(out, rhs.observation_size(), piece_edges.shape[0], piece_load.shape[0])
    if not (rtol > 0.0 and atol > 0.0 and sample_interval > 0.0 and per_step >= 1):
        raise ValueError(f"rtol {rtol}, atol {atol}, sample_interval {sample_interval} positive; per_step "
                         f"{per_step} at least 1")
    if peak_column >= rhs.observation_size():
        raise ValueError(f"peak_column {peak_column}: the problem observes {rhs.observation_size()} values")
    outcome: Outcome = Outcome()
    ends: Samples = Samples(rhs.observation_size()) if peak_column >= 0 else None
    evaluated: cython.Py_ssize_t
    K: cython.double[:, ::1] = np.empty((_NSE, 2))
    P: cython.double[:, ::1] = np.empty((_NSE, 2))
    scratch: cython.double[:, ::1] = np.empty((3, 2))  # the stages' increments and error estimates
    work: cython.longlong[::1] = np.zeros(2, dtype=np.int64)
    work[1] = max_evaluations
    n_steps: cython.Py_ssize_t = 0
    n_samp: cython.Py_ssize_t = 0
    stopped: cython.int = 0
    t_reached: cython.double = piece_edges[0]
    status: cython.int = _OK
    fail_time: cython.double = NAN
    fail_value: cython.double = NAN
    if not (isfinite(q0) and isfinite(v0)):
        status = _NONFINITE
        fail_time = t_reached
    elif fabs(v0) > speed_limit:
        status = _SPEED
        fail_time = t_reached
        fail_value = v0
    q: cython.double = q0
    v: cython.double = v0
    w: cython.double = 0.0
    d: cython.double = 0.0
    previous_step: cython.double = 0.0  # none: the first piece selects its own
    p: cython.Py_ssize_t
    i: cython.Py_ssize_t
    n: cython.Py_ssize_t
    m: cython.Py_ssize_t
    o: cython.Py_ssize_t
    load: cython.Py_ssize_t
    for p in range(piece_load.shape[0] if status == _OK else 0):
        load = piece_load[p]
        rhs.mark()
        status, n, stopped, fail_time = _piece(rhs, load, piece_edges[p], piece_edges[p + 1], q, v, w, d, rtol,
                                               atol, max_step, previous_step, use_stop, work, steps, K, P,
                                               scratch, ends)
        n_steps += n
        if status != _OK:
            stopped = 0
            break
        rhs.rewind()  # the samples in order from the piece's start
        if peak_column >= 0:
            m, evaluated, status, fail_time = _sample_piece_summary(rhs, load, steps, n, sample_interval, per_step,
                                                                    peak_column, stopped != 0, ends, out, K, P,
                                                                    work, scratch[0])
            if status != _OK:
                stopped = 0
                break
        else:
            m = _sample_piece(rhs, load, steps, n, sample_interval, per_step, out)
            evaluated = m
        n_samp += evaluated
        o = out.n
        for i in range(m):
            if not (isfinite(out.q[o + i]) and isfinite(out.v[o + i]) and isfinite(out.a[o + i])):
                status = _NONFINITE
                fail_time = out.t[o + i]
                break
        if status == _OK:
            for i in range(m):
                if fabs(out.v[o + i]) > speed_limit:
                    status = _SPEED
                    fail_time = out.t[o + i]
                    fail_value = out.v[o + i]
                    break
        if status != _OK:
            stopped = 0
            break
        out.n = o + m
        q = steps.sy[n, 0]
        v = steps.sy[n, 1]
        w = steps.sy[n, 2]
        d = steps.sy[n, 3]
        t_reached = steps.st[n]
        if stopped:
            break
        previous_step = 0.0
        for i in range(max(n - _RESTART, 0), n):
            previous_step = _pymax(previous_step, steps.sh[i])
    outcome.status = status
    outcome.stopped = stopped != 0
    outcome.n_steps = n_steps
    outcome.n_evaluations = work[0]
    outcome.n_sample_evaluations = n_samp
    outcome.t_reached = t_reached
    outcome.fail_time = fail_time
    outcome.fail_value = fail_value
    return outcome


def run(rhs, piece_edges, piece_load, q0, v0, *, rtol=1e-12, atol=None, sample_interval=1e-3, per_step=4,
        speed_limit=1e6, max_evaluations=1_000_000, max_step=float("inf"), use_stop=False,
        steps=None, peak_column=-1) -> RunResult:
    """Python convenience wrapper of :func:`dop853_run` (atol defaults to rtol): fresh Samples
    (and Steps unless given), the samples returned as arrays in a :data:`RunResult`."""
    atol = rtol if atol is None else atol
    out = Samples(rhs.observation_size())
    outcome = dop853_run(rhs, np.ascontiguousarray(piece_edges, dtype=np.float64),
                         np.ascontiguousarray(piece_load, dtype=np.intp), float(q0), float(v0),
                         float(rtol), float(atol), float(sample_interval), int(per_step),
                         float(speed_limit), int(max_evaluations), float(max_step), bool(use_stop), out,
                         Steps() if steps is None else steps, int(peak_column))
    t, q, v, a, observed, energy = out.arrays()
    return RunResult(outcome.status, t, q, v, a, outcome.n_steps, outcome.n_evaluations,
                     outcome.n_sample_evaluations, outcome.stopped, outcome.t_reached, outcome.fail_time,
                     outcome.fail_value, observed, energy)
