"""A compiled DOP853 driver for q̈ = f(t, q, q̇) in n ≥ 1 coordinates (y = (q, q̇) ∈ R²ⁿ).

:func:`vector_dop853_run` is :func:`.adaptive.dop853_run` for a
:class:`.vector_problem.VectorRightHandSide`: the load history is constant on pieces; on each
piece it runs scipy's ``solve_ivp(method="DOP853", dense_output=True, events=[stop])`` algorithm
step for step on the first-order system y' = (q̇, f) (``scipy/integrate/_ivp/rk.py``:
``RungeKutta._step_impl``, ``DOP853._estimate_error_norm`` with its RMS norm over the 2n
components, ``DOP853._dense_output_impl`` and ``Dop853DenseOutput``; ``select_initial_step`` in
``common.py``; the terminal event as in ``ivp.py`` with scipy's Brent root finder), restarting at
every piece edge with :data:`.adaptive.RESTART_STEPS`'s cap on the first step, and samples the
result with loopcheck's rule (``dense_samples`` in ``loopcheck/reduced/integrators.py``). Its
constants and coefficients are :mod:`.adaptive`'s (one home: scipy's, from ``dop853_tableau``).

Every sum is :mod:`.adaptive`'s, component by component, in the same order (the stages' weighted
sums in blocks of four, the norms summed plainly from the first component), so that at n = 1 the
two kernels give the same bits, and scipy summed in this order (the tests patch numpy's dot and
norm so) the same steps at any n.

The energy flows (the work done on the system and the energy dissipated, from the problem's
``power`` and ``dissipation`` at each stage) ride along as two more components, integrated with
the state's weights and given DOP853's dense output, but outside the error estimate: the steps
are scipy's on (q, q̇) alone.

The problem is opaque here (its methods only). The samples are appended to the caller's
:class:`.vector_output.VectorSamples`; the accepted steps and every stage are kept in a
:class:`VectorSteps` workspace (sized for n, grown by doubling, reusable across runs): nothing
is allocated per step.

Failures are status codes of :mod:`.output` (``OK``, ``STEP_SIZE``, ``NONFINITE``, ``SPEED``) in
the returned :class:`.output.Outcome`, never exceptions; for SPEED, ``fail_value`` is the
offending q̇ᵢ and ``detail[0]`` its coordinate i.

Not here (the scalar kernel's summary runs, ``peak_column``): every run is a full run.

Debugging: ``LOOPCHECK_PURE_PYTHON=1`` runs this same source as plain Python (:mod:`loopcheck.reduced.kernels`).
"""

from typing import NamedTuple

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import INFINITY, NAN, ceil, copysign, fabs, isfinite, nextafter, pow, sqrt
    from cython.cimports.loopcheck.reduced.kernels.output import Outcome
    from cython.cimports.loopcheck.reduced.kernels.vector_output import VectorSamples, check_vector_run
    from cython.cimports.loopcheck.reduced.kernels.vector_problem import VectorRightHandSide
else:
    from math import ceil, copysign, fabs, isfinite, nextafter, pow, sqrt
    from math import inf as INFINITY
    from math import nan as NAN

    from loopcheck.reduced.kernels.output import Outcome
    from loopcheck.reduced.kernels.vector_output import VectorSamples, check_vector_run
    from loopcheck.reduced.kernels.vector_problem import VectorRightHandSide

from loopcheck.reduced.kernels import adaptive as _scalar
from loopcheck.reduced.kernels import output as _output

RESTART_STEPS = _scalar.RESTART_STEPS

# C copies of adaptive's constants and coefficients, and of the statuses, for the compiled loops
_OK = cython.declare(cython.int, _output.OK)
_STEP_SIZE = cython.declare(cython.int, _output.STEP_SIZE)
_NONFINITE = cython.declare(cython.int, _output.NONFINITE)
_SPEED = cython.declare(cython.int, _output.SPEED)
_NS = cython.declare(cython.Py_ssize_t, _scalar.N_STAGES)
_NSE = cython.declare(cython.Py_ssize_t, _scalar.N_STAGES_EXTENDED)
_IP = cython.declare(cython.Py_ssize_t, _scalar.INTERPOLATOR_POWER)
_RESTART = cython.declare(cython.Py_ssize_t, _scalar.RESTART_STEPS)
_SAFETY = cython.declare(cython.double, _scalar.SAFETY)
_MIN_FACTOR = cython.declare(cython.double, _scalar.MIN_FACTOR)
_MAX_FACTOR = cython.declare(cython.double, _scalar.MAX_FACTOR)
_ERROR_EXPONENT = cython.declare(cython.double, _scalar.ERROR_EXPONENT)
_INITIAL_EXPONENT = cython.declare(cython.double, 1.0 / (_scalar.ERROR_ESTIMATOR_ORDER + 1.0))
_EPS = cython.declare(cython.double, _scalar.EPS)
_A = cython.declare(cython.double[:, ::1], _scalar.A)
_C = cython.declare(cython.double[::1], _scalar.C)
_D = cython.declare(cython.double[:, ::1], _scalar.D)
# B, E5, E3 as rows (1, s) for _dot_kt_row
_B_ROW = cython.declare(cython.double[:, ::1], _scalar.B.reshape(1, -1))
_E3_ROW = cython.declare(cython.double[:, ::1], _scalar.E3.reshape(1, -1))
_E5_ROW = cython.declare(cython.double[:, ::1], _scalar.E5.reshape(1, -1))

# rows of VectorSteps.Y (the states a step works on, 2n each)
_Y = cython.declare(cython.Py_ssize_t, 0)      # y at the step's start
_YN = cython.declare(cython.Py_ssize_t, 1)     # y_new
_YO = cython.declare(cython.Py_ssize_t, 2)     # y_old (the accepted step's start)
_F = cython.declare(cython.Py_ssize_t, 3)      # f at y (the next step's first stage)
_SC = cython.declare(cython.Py_ssize_t, 4)     # scale, then the scaled vector a norm is taken of
# rows of VectorSteps.S (the stages' weighted sums, 2n each)
_DY = cython.declare(cython.Py_ssize_t, 0)
_E5 = cython.declare(cython.Py_ssize_t, 1)
_E3 = cython.declare(cython.Py_ssize_t, 2)

# What run() returns
VectorRunResult = NamedTuple("VectorRunResult", [
    ("status", int),              # OK, STEP_SIZE, NONFINITE or SPEED (loopcheck.reduced.kernels.output)
    ("t", np.ndarray),            # (m,) sample times (pieces concatenated; a piece's first time repeats
    ("q", np.ndarray),            # the previous piece's last); (m, n) states and q̈ at every sample
    ("v", np.ndarray),
    ("a", np.ndarray),
    ("n_steps", int),             # accepted steps over all pieces (a step cut by the stop event counts)
    ("n_evaluations", int),       # scipy's nfev summed over pieces
    ("n_sample_evaluations", int),  # evaluations of f at the samples (not in n_evaluations)
    ("stopped", bool),            # the stop event ended the run
    ("t_reached", float),         # the last time integrated (the event's root if stopped)
    ("fail_time", float),         # where a failure happened (nan if OK)
    ("fail_value", float),        # q̇ᵢ for SPEED, else nan
    ("observed", np.ndarray),     # what the problem observed at each sample (m, observation_size)
    ("energy", np.ndarray),       # the work done and the energy dissipated since the start (m, 2), J
])


@cython.cclass
class VectorSteps:
    """The workspace of :func:`vector_dop853_run` for n coordinates (reusable across runs of the
    same n): the accepted steps of a piece, st (times, s), sh (each step's h of the dense output,
    s), sy (the state after each: q (n), q̇ (n), the work done, the energy dissipated) and sF
    (each step's dense coefficients, (INTERPOLATOR_POWER, 2n + 2)), grown by doubling when full
    (:meth:`grow`); and the stages' buffers: K (16, 2n) the stages' y', P (16, 2) their energy
    rates, Y and S the step's states and weighted sums, qs, vs, acc (n) what the problem is handed."""

    def __init__(self, n: cython.Py_ssize_t, capacity: cython.Py_ssize_t = 64):
        if n < 1 or capacity < 2:
            raise ValueError(f"VectorSteps(n={n}, capacity={capacity}): n at least 1, capacity at least 2")
        self.dimension = n
        self._allocate(capacity)
        self.K = np.empty((_scalar.N_STAGES_EXTENDED, 2 * n))
        self.P = np.empty((_scalar.N_STAGES_EXTENDED, 2))
        self.Y = np.empty((5, 2 * n))
        self.S = np.empty((3, 2 * n))
        self.pb = np.empty((1, 2))
        self.qs = np.empty(n)
        self.vs = np.empty(n)
        self.acc = np.empty(n)
        self.work = np.zeros(2, dtype=np.int64)

    @cython.cfunc
    def _allocate(self, capacity: cython.Py_ssize_t):
        width = 2 * self.dimension + 2
        self.st = np.empty(capacity)
        self.sh = np.empty(capacity)
        self.sy = np.empty((capacity, width))
        self.sF = np.empty((capacity, _scalar.INTERPOLATOR_POWER, width))

    @cython.ccall
    def capacity(self) -> cython.Py_ssize_t:
        """Steps it holds without growing (+1: st and sy also hold the start)."""
        return self.st.shape[0]

    @cython.ccall
    def grow(self, keep: cython.Py_ssize_t):
        """Double the capacity, keeping the first ``keep`` entries."""
        st, sh, sy, sF = np.asarray(self.st), np.asarray(self.sh), np.asarray(self.sy), np.asarray(self.sF)
        self._allocate(2 * st.shape[0])
        np.asarray(self.st)[:keep] = st[:keep]
        np.asarray(self.sh)[:keep] = sh[:keep]
        np.asarray(self.sy)[:keep] = sy[:keep]
        np.asarray(self.sF)[:keep] = sF[:keep]


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
@cython.inline
@cython.exceptval(check=False)
def _norm_row(x: cython.double[:, ::1], r: cython.Py_ssize_t, m: cython.Py_ssize_t) -> cython.double:
    """np.linalg.norm(x[r, :m]) summed plainly from the first component (adaptive._norm2 at m = 2)."""
    acc: cython.double = x[r, 0] * x[r, 0]
    i: cython.Py_ssize_t
    for i in range(1, m):
        acc = acc + x[r, i] * x[r, i]
    return sqrt(acc)


@cython.ccall
def _norm(x: cython.double[::1]) -> cython.double:
    """:func:`_norm_row`'s sum of a vector (cpdef: the tests sum scipy's norm with it)."""
    acc: cython.double = x[0] * x[0]
    i: cython.Py_ssize_t
    for i in range(1, x.shape[0]):
        acc = acc + x[i] * x[i]
    return sqrt(acc)


@cython.cfunc
@cython.inline
@cython.exceptval(-1, check=False)
def _dot_kt_row(K: cython.double[:, ::1], a: cython.double[:, ::1], ra: cython.Py_ssize_t, s: cython.Py_ssize_t,
                out: cython.double[:, ::1], ro: cython.Py_ssize_t, m: cython.Py_ssize_t) -> cython.int:
    """out[ro, :m] = np.dot(K[:s, :m].T, a[ra, :s]), each column summed as adaptive._dot_kt sums
    it (blocks of four, t += (p0 + p1), t += (p2 + p3), then the rest one by one; no FMA)."""
    nb: cython.Py_ssize_t = s - s % 4
    r: cython.Py_ssize_t
    i: cython.Py_ssize_t
    acc: cython.double
    for r in range(m):
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


@cython.ccall
def _dot_kt(K: cython.double[:, ::1], a: cython.double[::1], s: cython.Py_ssize_t, out: cython.double[::1]):
    """out = np.dot(K[:s].T, a[:s]) in :func:`_dot_kt_row`'s order, for any number of columns
    (cpdef: the tests sum scipy's stages with it)."""
    nb: cython.Py_ssize_t = s - s % 4
    r: cython.Py_ssize_t
    i: cython.Py_ssize_t
    acc: cython.double
    for r in range(K.shape[1]):
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
@cython.exceptval(check=False)
def _dense(t: cython.double, t_old: cython.double, h: cython.double, sy: cython.double[:, ::1],
           F: cython.double[:, :, ::1], j: cython.Py_ssize_t, c: cython.Py_ssize_t) -> cython.double:
    """Dop853DenseOutput._call_impl at t for step j (from sy[j]), component c, same operation order."""
    x: cython.double = (t - t_old) / h
    y: cython.double = 0.0
    i: cython.Py_ssize_t
    for i in range(_IP):
        y += F[j, _IP - 1 - i, c]
        if i % 2 == 0:
            y *= x
        else:
            y *= 1.0 - x
    return y + sy[j, c]


@cython.cfunc
@cython.inline
def _dense_state(t: cython.double, j: cython.Py_ssize_t, steps: VectorSteps) -> cython.void:
    """q and q̇ of step j's dense output at t into steps.qs, steps.vs."""
    n: cython.Py_ssize_t = steps.dimension
    t_old: cython.double = steps.st[j]
    h: cython.double = steps.sh[j]
    i: cython.Py_ssize_t
    for i in range(n):
        steps.qs[i] = _dense(t, t_old, h, steps.sy, steps.sF, j, i)
        steps.vs[i] = _dense(t, t_old, h, steps.sy, steps.sF, j, n + i)


@cython.cfunc
def _margin(rhs: VectorRightHandSide, t: cython.double, j: cython.Py_ssize_t, steps: VectorSteps) -> cython.double:
    """The stop margin on step j's dense output at t."""
    _dense_state(t, j, steps)
    return rhs.stop_margin(t, steps.qs, steps.vs)


@cython.cfunc
def _brentq_stop(rhs: VectorRightHandSide, xa: cython.double, xb: cython.double, j: cython.Py_ssize_t,
                 steps: VectorSteps) -> cython.double:
    """scipy.optimize.brentq (Zeros/brentq.c) of stop_margin on step j's dense output,
    xtol = rtol = 4 EPS, maxiter 100, as solve_ivp's solve_event_equation calls it
    (adaptive._brentq_stop's iteration)."""
    xtol: cython.double = 4.0 * _EPS
    rtol: cython.double = 4.0 * _EPS
    xpre: cython.double = xa
    xcur: cython.double = xb
    xblk: cython.double = 0.0
    fblk: cython.double = 0.0
    spre: cython.double = 0.0
    scur: cython.double = 0.0
    delta: cython.double
    sbis: cython.double
    stry: cython.double
    dpre: cython.double
    dblk: cython.double
    fpre: cython.double = _margin(rhs, xpre, j, steps)
    fcur: cython.double = _margin(rhs, xcur, j, steps)
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
        fcur = _margin(rhs, xcur, j, steps)
    return xcur  # scipy would raise (no convergence in 100 iterations); not reachable for a
    #              bracketed continuous g at these tolerances


@cython.cfunc
def _fun(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, steps: VectorSteps,
         row: cython.Py_ssize_t) -> cython.int:
    """The first-order system (q̇, f) at (t, steps.qs, steps.vs) into K[row] and the energy flows'
    rates there into P[row]; steps.work = [nfev, max_evaluations].
    Returns a status: STEP_SIZE when the budget is spent (f not called), NONFINITE where the
    problem cannot be evaluated or q̈ is not finite."""
    if steps.work[0] >= steps.work[1]:
        return _STEP_SIZE
    steps.work[0] += 1
    n: cython.Py_ssize_t = steps.dimension
    if rhs.acceleration(load, t, steps.qs, steps.vs, steps.acc) != 0:
        return _NONFINITE
    i: cython.Py_ssize_t
    finite: cython.bint = True
    for i in range(n):
        steps.K[row, i] = steps.vs[i]
        steps.K[row, n + i] = steps.acc[i]
        finite = finite and isfinite(steps.acc[i])
    steps.P[row, 0] = rhs.power(load, steps.vs)
    steps.P[row, 1] = rhs.dissipation(steps.vs)
    return _OK if finite else _NONFINITE


@cython.cfunc
@cython.inline
def _stage_point(steps: VectorSteps, y: cython.Py_ssize_t, h: cython.double) -> cython.void:
    """steps.qs, steps.vs = Y[y] + S[DY] · h (scipy: y + dy with dy = np.dot(K[:s].T, a[:s]) * h)."""
    n: cython.Py_ssize_t = steps.dimension
    i: cython.Py_ssize_t
    for i in range(n):
        steps.qs[i] = steps.Y[y, i] + steps.S[_DY, i] * h
        steps.vs[i] = steps.Y[y, n + i] + steps.S[_DY, n + i] * h


@cython.cfunc
def _initial_step(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, end: cython.double,
                  rtol: cython.double, atol: cython.double, max_step: cython.double, restart_cap: cython.double,
                  steps: VectorSteps) -> tuple[cython.int, cython.double, cython.double]:
    """RungeKutta.__init__: f0 = fun(t0, y0) (y0 = Y[_Y]) into K[0], then select_initial_step
    (common.py), at most ``restart_cap`` when that is > 0 (a restart at a load edge:
    RESTART_STEPS). Returns (status, fail_time, h_abs)."""
    n: cython.Py_ssize_t = steps.dimension
    m: cython.Py_ssize_t = 2 * n
    i: cython.Py_ssize_t
    for i in range(n):
        steps.qs[i] = steps.Y[_Y, i]
        steps.vs[i] = steps.Y[_Y, n + i]
    s: cython.int = _fun(rhs, load, t, steps, 0)
    if s != _OK:
        return s, t, 0.0
    interval_length: cython.double = fabs(end - t)
    if interval_length == 0.0:
        return _OK, NAN, 0.0
    sqrt_m: cython.double = pow(cython.cast(cython.double, m), 0.5)  # x.size ** 0.5
    for i in range(m):
        steps.Y[_SC, i] = steps.Y[_Y, i] / (atol + fabs(steps.Y[_Y, i]) * rtol)
    d0: cython.double = _norm_row(steps.Y, _SC, m) / sqrt_m
    for i in range(m):
        steps.Y[_SC, i] = steps.K[0, i] / (atol + fabs(steps.Y[_Y, i]) * rtol)
    d1: cython.double = _norm_row(steps.Y, _SC, m) / sqrt_m
    h0: cython.double
    h1: cython.double
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = _pymin(h0, interval_length)
    for i in range(n):
        steps.qs[i] = steps.Y[_Y, i] + h0 * 1.0 * steps.K[0, i]
        steps.vs[i] = steps.Y[_Y, n + i] + h0 * 1.0 * steps.K[0, n + i]
    s = _fun(rhs, load, t + h0 * 1.0, steps, 1)
    if s != _OK:
        return s, t + h0, 0.0
    for i in range(m):
        steps.Y[_SC, i] = (steps.K[1, i] - steps.K[0, i]) / (atol + fabs(steps.Y[_Y, i]) * rtol)
    d2: cython.double = _norm_row(steps.Y, _SC, m) / sqrt_m / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = _pymax(1e-6, h0 * 1e-3)
    else:
        h1 = pow(0.01 / _pymax(d1, d2), _INITIAL_EXPONENT)
    h: cython.double = _pymin(_pymin(_pymin(100 * h0, h1), interval_length), max_step)
    return _OK, NAN, (_pymin(h, restart_cap) if restart_cap > 0.0 else h)


@cython.cfunc
def _rk_step(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, h: cython.double,
             rtol: cython.double, atol: cython.double, steps: VectorSteps
             ) -> tuple[cython.int, cython.double, cython.double]:
    """rk_step and DOP853._estimate_error_norm for one attempt from y = Y[_Y] (K[0] = f there on
    entry; K[12] = f_new on exit, y_new into Y[_YN]). Returns (status, fail_time, error_norm)."""
    n: cython.Py_ssize_t = steps.dimension
    m: cython.Py_ssize_t = 2 * n
    si: cython.Py_ssize_t
    i: cython.Py_ssize_t
    s: cython.int
    for si in range(1, _NS):
        _dot_kt_row(steps.K, _A, si, si, steps.S, _DY, m)  # scipy: dy = np.dot(K[:s].T, a[:s]) * h, then y + dy
        _stage_point(steps, _Y, h)
        s = _fun(rhs, load, t + _C[si] * h, steps, si)
        if s != _OK:
            return s, t + _C[si] * h, 0.0
    _dot_kt_row(steps.K, _B_ROW, 0, _NS, steps.S, _DY, m)  # y_new = y + h * np.dot(K[:-1].T, B)
    for i in range(m):
        steps.Y[_YN, i] = steps.Y[_Y, i] + h * steps.S[_DY, i]
    for i in range(n):
        steps.qs[i] = steps.Y[_YN, i]
        steps.vs[i] = steps.Y[_YN, n + i]
    s = _fun(rhs, load, t + h, steps, _NS)
    if s != _OK:
        return s, t + h, 0.0
    _dot_kt_row(steps.K, _E5_ROW, 0, _NS + 1, steps.S, _E5, m)
    _dot_kt_row(steps.K, _E3_ROW, 0, _NS + 1, steps.S, _E3, m)
    sc: cython.double
    for i in range(m):  # scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol; err / scale
        sc = atol + _npmax(fabs(steps.Y[_Y, i]), fabs(steps.Y[_YN, i])) * rtol
        steps.S[_E5, i] = steps.S[_E5, i] / sc
        steps.S[_E3, i] = steps.S[_E3, i] / sc
    n5: cython.double = _norm_row(steps.S, _E5, m)
    n3: cython.double = _norm_row(steps.S, _E3, m)
    err5_norm_2: cython.double = n5 * n5  # x ** 2, as numpy's power computes it: one product
    err3_norm_2: cython.double = n3 * n3
    if err5_norm_2 == 0 and err3_norm_2 == 0:
        return _OK, NAN, 0.0
    denom: cython.double = err5_norm_2 + 0.01 * err3_norm_2
    return _OK, NAN, fabs(h) * err5_norm_2 / sqrt(denom * cython.cast(cython.double, m))


@cython.cfunc
@cython.inline
def _interpolant(sF: cython.double[:, :, ::1], sy: cython.double[:, ::1], j: cython.Py_ssize_t,
                 h: cython.double, R: cython.double[:, ::1], col: cython.Py_ssize_t,
                 c: cython.Py_ssize_t) -> cython.void:
    """Step j's dense coefficients F of component ``col`` (from sy[j] to sy[j + 1]) from its rates
    R[:, c] at the 16 stages, in adaptive._interpolant's order: Δ, h f_old − Δ,
    2Δ − h (f_new + f_old), then h D·R."""
    dl: cython.double = sy[j + 1, col] - sy[j, col]
    sF[j, 0, col] = dl
    sF[j, 1, col] = h * R[0, c] - dl
    sF[j, 2, col] = 2 * dl - h * (R[_NS, c] + R[0, c])
    r: cython.Py_ssize_t
    k: cython.Py_ssize_t
    p: cython.double
    for r in range(_IP - 3):
        p = 0.0
        for k in range(_NSE):
            p += _D[r, k] * R[k, c]
        sF[j, 3 + r, col] = h * p


@cython.cfunc
def _dense_coefficients(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t_old: cython.double,
                        h: cython.double, steps: VectorSteps, j: cython.Py_ssize_t) -> tuple[cython.int, cython.double]:
    """DOP853._dense_output_impl from y_old = Y[_YO]: 3 extra stages into K[13:16] (and P), then
    the interpolant of each component of steps.sy from step j to j + 1 (both set) into
    steps.sF[j]: q and q̇ from K, the energy flows from P. Returns (status, fail_time)."""
    m: cython.Py_ssize_t = 2 * steps.dimension
    si: cython.Py_ssize_t
    s: cython.int
    c: cython.Py_ssize_t
    for si in range(_NS + 1, _NSE):
        _dot_kt_row(steps.K, _A, si, si, steps.S, _DY, m)
        _stage_point(steps, _YO, h)
        s = _fun(rhs, load, t_old + _C[si] * h, steps, si)
        if s != _OK:
            return s, t_old + _C[si] * h
    for c in range(m):
        _interpolant(steps.sF, steps.sy, j, h, steps.K, c, c)
    for c in range(2):
        _interpolant(steps.sF, steps.sy, j, h, steps.P, m + c, c)
    return _OK, NAN


@cython.cfunc
@cython.inline
def _state_q(steps: VectorSteps) -> cython.void:
    """steps.qs, steps.vs = q, q̇ of Y[_Y] (the state the stop margin is read at)"""
    n: cython.Py_ssize_t = steps.dimension
    i: cython.Py_ssize_t
    for i in range(n):
        steps.qs[i] = steps.Y[_Y, i]
        steps.vs[i] = steps.Y[_Y, n + i]


@cython.cfunc
def _piece(rhs: VectorRightHandSide, load: cython.Py_ssize_t, start: cython.double, end: cython.double,
           w0: cython.double, d0: cython.double, rtol: cython.double, atol: cython.double, max_step: cython.double,
           restart_cap: cython.double, use_stop: cython.bint, steps: VectorSteps
           ) -> tuple[cython.int, cython.Py_ssize_t, cython.int, cython.double]:
    """One solve_ivp call on [start, end] (its first step at most ``restart_cap`` if > 0) from
    y = steps.Y[_Y] (q, q̇), the work done w0 and the energy dissipated d0 (J): the accepted steps
    into ``steps`` (st times, sh dense h, sy states: q, q̇, work, dissipated; sF dense
    coefficients), grown as needed.

    The energy flows ride along: each accepted step adds h Σ b_s P_s of their stage rates
    (DOP853's order-8 quadrature) and gets DOP853's dense output; they take no part in the
    error estimate, so the steps are scipy's. Returns (status, n_steps, stopped, fail_time)."""
    n: cython.Py_ssize_t = steps.dimension
    m: cython.Py_ssize_t = 2 * n
    W: cython.Py_ssize_t = m + 2
    t: cython.double = start
    i: cython.Py_ssize_t
    steps.st[0] = t
    for i in range(m):
        steps.sy[0, i] = steps.Y[_Y, i]
    steps.sy[0, m] = w0
    steps.sy[0, m + 1] = d0
    ns: cython.Py_ssize_t = 0
    stopped: cython.int = 0
    status: cython.int
    fail_time: cython.double
    h_abs: cython.double
    status, fail_time, h_abs = _initial_step(rhs, load, t, end, rtol, atol, max_step, restart_cap, steps)
    for i in range(m):
        steps.Y[_F, i] = steps.K[0, i]
    p0: cython.double = steps.P[0, 0]
    p1: cython.double = steps.P[0, 1]
    g: cython.double = 0.0
    g_new: cython.double
    min_step: cython.double
    step_rejected: cython.bint
    h: cython.double = 0.0      # (set by every accepted attempt: gcc cannot see it)
    t_new: cython.double = t
    t_old: cython.double
    error_norm: cython.double
    factor: cython.double
    root: cython.double
    if use_stop and status == _OK:
        _state_q(steps)
        g = rhs.stop_margin(t, steps.qs, steps.vs)
        if rhs.stop_at_start(t, steps.qs, steps.vs):  # an event at the piece's start (a load edge)
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
            for i in range(m):
                steps.K[0, i] = steps.Y[_F, i]
            steps.P[0, 0] = p0
            steps.P[0, 1] = p1
            status, fail_time, error_norm = _rk_step(rhs, load, t, h, rtol, atol, steps)
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
        t = t_new
        for i in range(m):
            steps.Y[_YO, i] = steps.Y[_Y, i]
            steps.Y[_Y, i] = steps.Y[_YN, i]
            steps.Y[_F, i] = steps.K[_NS, i]
        p0 = steps.P[_NS, 0]
        p1 = steps.P[_NS, 1]
        if ns + 1 >= steps.st.shape[0]:
            steps.grow(ns + 1)
        for i in range(m):
            steps.sy[ns + 1, i] = steps.Y[_Y, i]
        _dot_kt_row(steps.P, _B_ROW, 0, _NS, steps.pb, 0, 2)  # the energy flows' step, with the state's weights
        steps.sy[ns + 1, m] = steps.sy[ns, m] + h * steps.pb[0, 0]
        steps.sy[ns + 1, m + 1] = steps.sy[ns, m + 1] + h * steps.pb[0, 1]
        status, fail_time = _dense_coefficients(rhs, load, t_old, h, steps, ns)
        if status != _OK:
            break
        steps.sh[ns] = t - t_old
        steps.st[ns + 1] = t
        ns += 1
        if use_stop:
            _state_q(steps)
            g_new = rhs.stop_margin(t, steps.qs, steps.vs)
            if g >= 0 and g_new <= 0:  # find_active_events, direction -1
                root = _brentq_stop(rhs, t_old, t, ns - 1, steps)
                if root == t_old and ns > 1:
                    ns -= 1  # solve_ivp's donot_append: ts[-1] == t, the step is dropped
                else:
                    steps.st[ns] = root
                    for i in range(W):
                        steps.sy[ns, i] = _dense(root, t_old, steps.sh[ns - 1], steps.sy, steps.sF, ns - 1, i)
                stopped = 1
                break
            g = g_new
        if t - end >= 0:
            break
    return status, ns, stopped, fail_time


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _parts(h: cython.double, sample_interval: cython.double, per_step: cython.Py_ssize_t) -> cython.Py_ssize_t:
    """Equal parts a step of h (s) is cut into for sampling: max(per_step, ⌈h / sample_interval⌉)."""
    return max(per_step, cython.cast(cython.Py_ssize_t, ceil(h / sample_interval)))


@cython.cfunc
def _sample_piece(rhs: VectorRightHandSide, load: cython.Py_ssize_t, steps: VectorSteps, ns: cython.Py_ssize_t,
                  sample_interval: cython.double, per_step: cython.Py_ssize_t, out: VectorSamples
                  ) -> tuple[cython.Py_ssize_t, cython.int, cython.double]:
    """loopcheck's dense_samples on one piece (adaptive._sample_piece), written into ``out`` from
    out.n (room reserved here) without advancing out.n: sorted unique times, states, q̈, what
    the problem observes at each and the energy flows. Returns (their number, status,
    fail_time): NONFINITE where the problem cannot be evaluated at a sample."""
    n: cython.Py_ssize_t = steps.dimension
    mm: cython.Py_ssize_t = 2 * n
    st: cython.double[::1] = steps.st
    sh: cython.double[::1] = steps.sh
    sy: cython.double[:, ::1] = steps.sy
    sF: cython.double[:, :, ::1] = steps.sF
    qs: cython.double[::1] = steps.qs
    vs: cython.double[::1] = steps.vs
    acc: cython.double[::1] = steps.acc
    # each step [t_j, t_j + h_j] cut into max(per_step, ⌈h_j / sample_interval⌉) equal parts
    m: cython.Py_ssize_t = 1
    j: cython.Py_ssize_t
    i: cython.Py_ssize_t
    c: cython.Py_ssize_t
    parts: cython.Py_ssize_t
    dt: cython.double
    x: cython.double
    for j in range(ns):
        m += _parts(st[j + 1] - st[j], sample_interval, per_step)
    out.reserve(m)
    o: cython.Py_ssize_t = out.n
    times: cython.double[::1] = out.t
    oq: cython.double[:, ::1] = out.q
    ov: cython.double[:, ::1] = out.v
    oa: cython.double[:, ::1] = out.a
    oe: cython.double[:, ::1] = out.energy
    times[o] = st[0]
    m = 1
    for j in range(ns):
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
        while seg < ns - 1 and st[seg + 1] < x:
            seg += 1
        for c in range(n):
            oq[o + i, c] = _dense(x, st[seg], sh[seg], sy, sF, seg, c)
            ov[o + i, c] = _dense(x, st[seg], sh[seg], sy, sF, seg, n + c)
        oe[o + i, 0] = _dense(x, st[seg], sh[seg], sy, sF, seg, mm)
        oe[o + i, 1] = _dense(x, st[seg], sh[seg], sy, sF, seg, mm + 1)
    # states at the step times are the solver's own
    i = 0
    for j in range(ns + 1):
        while times[o + i] < st[j]:
            i += 1
        for c in range(n):
            oq[o + i, c] = sy[j, c]
            ov[o + i, c] = sy[j, n + c]
        oe[o + i, 0] = sy[j, mm]
        oe[o + i, 1] = sy[j, mm + 1]
    for i in range(m):
        for c in range(n):
            qs[c] = oq[o + i, c]
            vs[c] = ov[o + i, c]
        if rhs.acceleration(load, times[o + i], qs, vs, acc) != 0:
            return m, _NONFINITE, times[o + i]
        for c in range(n):
            oa[o + i, c] = acc[c]
        rhs.observe(out.observed, o + i)
    return m, _OK, NAN


@cython.ccall
def vector_dop853_run(rhs: VectorRightHandSide, piece_edges: cython.double[::1],
                      piece_load: cython.Py_ssize_t[::1], q0: cython.double[::1], v0: cython.double[::1],
                      rtol: cython.double, atol: cython.double, sample_interval: cython.double,
                      per_step: cython.Py_ssize_t, speed_limit: cython.double, max_evaluations: cython.Py_ssize_t,
                      max_step: cython.double, use_stop: cython.bint, out: VectorSamples,
                      steps: VectorSteps) -> Outcome:
    """Integrate q̈ = f(t, q, q̇) (rhs.acceleration(load, t, q, q̇, q̈)) over the pieces.

    Parameters (:func:`.adaptive.dop853_run`'s, with q0, v0 of n = rhs.dimension() values)
    ----------
    rhs : the problem (:class:`.vector_problem.VectorRightHandSide`)
    piece_edges : (p+1,) s, increasing; piece_load : (p,), the load index of each piece
    q0, v0 : (n,) initial state at piece_edges[0]
    rtol, atol : scipy's tolerances (same for every component of q and q̇)
    sample_interval, per_step : each accepted step of h (s) is cut into max(per_step,
        ⌈h / sample_interval⌉) equal parts for sampling
    speed_limit : max |q̇ᵢ| beyond which a sample ends the run with SPEED
    max_evaluations : budget of f evaluations over all pieces (as scipy's nfev counts them)
    max_step : scipy's max_step (inf for none)
    use_stop : the terminal event rhs.stop_margin (direction -1); rhs.stop_at_start at a piece's
        start ends the run there (one sample, no step)
    out : the samples are appended to it (n coordinates; its width rhs.observation_size())
    steps : the workspace (:class:`VectorSteps` of n; any capacity: it grows)

    Returns
    -------
    Outcome (:mod:`.output`; n_evaluations counted as scipy's nfev, n_sample_evaluations the
    evaluations at the samples; SPEED: fail_value the q̇ᵢ, detail[0] its i). On a failure, the
    samples of the pieces completed before it stay appended; a piece's samples are appended
    only once they pass the checks (non-finite, speed).
    """
    n: cython.Py_ssize_t = rhs.dimension()
    check_vector_run(out, n, rhs.observation_size(), q0, v0, piece_edges.shape[0], piece_load.shape[0])
    if steps.dimension != n:
        raise ValueError(f"VectorSteps of {steps.dimension} coordinates != the problem's dimension() {n}")
    if not (rtol > 0.0 and atol > 0.0 and sample_interval > 0.0 and per_step >= 1):
        raise ValueError(f"rtol {rtol}, atol {atol}, sample_interval {sample_interval} positive; per_step "
                         f"{per_step} at least 1")
    outcome: Outcome = Outcome()
    mm: cython.Py_ssize_t = 2 * n
    Y: cython.double[:, ::1] = steps.Y
    work: cython.longlong[::1] = steps.work
    work[0] = 0
    work[1] = max_evaluations
    n_steps: cython.Py_ssize_t = 0
    n_samp: cython.Py_ssize_t = 0
    stopped: cython.int = 0
    t_reached: cython.double = piece_edges[0]
    status: cython.int = _OK
    fail_time: cython.double = NAN
    fail_value: cython.double = NAN
    p: cython.Py_ssize_t
    i: cython.Py_ssize_t
    c: cython.Py_ssize_t
    ns: cython.Py_ssize_t
    m: cython.Py_ssize_t
    o: cython.Py_ssize_t
    load: cython.Py_ssize_t
    for c in range(n):
        Y[_Y, c] = q0[c]
        Y[_Y, n + c] = v0[c]
    for c in range(mm):
        if not isfinite(Y[_Y, c]):
            status = _NONFINITE
            fail_time = t_reached
    for c in range(n):
        if status == _OK and fabs(v0[c]) > speed_limit:
            status = _SPEED
            fail_time = t_reached
            fail_value = v0[c]
            outcome.detail[0] = c
    w: cython.double = 0.0
    d: cython.double = 0.0
    previous_step: cython.double = 0.0  # none: the first piece selects its own
    for p in range(piece_load.shape[0] if status == _OK else 0):
        load = piece_load[p]
        rhs.mark()
        status, ns, stopped, fail_time = _piece(rhs, load, piece_edges[p], piece_edges[p + 1], w, d, rtol, atol,
                                                max_step, previous_step, use_stop, steps)
        n_steps += ns
        if status != _OK:
            stopped = 0
            break
        rhs.rewind()  # the samples in order from the piece's start
        m, status, fail_time = _sample_piece(rhs, load, steps, ns, sample_interval, per_step, out)
        n_samp += m
        o = out.n
        for i in range(m if status == _OK else 0):
            for c in range(n):
                if not (isfinite(out.q[o + i, c]) and isfinite(out.v[o + i, c]) and isfinite(out.a[o + i, c])):
                    status = _NONFINITE
                    fail_time = out.t[o + i]
                    break
            if status != _OK:
                break
        if status == _OK:
            for i in range(m):
                for c in range(n):
                    if fabs(out.v[o + i, c]) > speed_limit:
                        status = _SPEED
                        fail_time = out.t[o + i]
                        fail_value = out.v[o + i, c]
                        outcome.detail[0] = c
                        break
                if status != _OK:
                    break
        if status != _OK:
            stopped = 0
            break
        out.n = o + m
        for c in range(mm):
            Y[_Y, c] = steps.sy[ns, c]
        w = steps.sy[ns, mm]
        d = steps.sy[ns, mm + 1]
        t_reached = steps.st[ns]
        if stopped:
            break
        previous_step = 0.0
        for i in range(max(ns - _RESTART, 0), ns):
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
        steps=None) -> VectorRunResult:
    """Python convenience wrapper of :func:`vector_dop853_run` (atol defaults to rtol): fresh
    VectorSamples (and VectorSteps unless given), the samples returned as arrays."""
    atol = rtol if atol is None else atol
    q0 = np.array(q0, dtype=np.float64, ndmin=1)
    v0 = np.array(v0, dtype=np.float64, ndmin=1)
    n = rhs.dimension()
    out = VectorSamples(n, rhs.observation_size())
    outcome = vector_dop853_run(rhs, np.ascontiguousarray(piece_edges, dtype=np.float64),
                                np.ascontiguousarray(piece_load, dtype=np.intp), q0, v0, float(rtol), float(atol),
                                float(sample_interval), int(per_step), float(speed_limit), int(max_evaluations),
                                float(max_step), bool(use_stop), out, VectorSteps(n) if steps is None else steps)
    t, q, v, a, observed, energy = out.arrays()
    return VectorRunResult(outcome.status, t, q, v, a, outcome.n_steps, outcome.n_evaluations,
                           outcome.n_sample_evaluations, outcome.stopped, outcome.t_reached, outcome.fail_time,
                           outcome.fail_value, observed, energy)
