"""Fixed-step Runge-Kutta-Nyström methods (RKN4) for q̈ = f(t, q, q̇) in n ≥ 1 coordinates, compiled.

:func:`vector_rkn_chart` is :func:`.fixed_step.rkn_chart` for a
:class:`.vector_problem.VectorRightHandSide`: the same tableau (:class:`.fixed_step.RKNTableau`,
:data:`.fixed_step.RKN4`), applied to each coordinate with the same operations in the same order
(a stage sums only its nonzero entries, left to right; the update's numerators over their common
denominator), so that at n = 1 it gives :func:`.fixed_step.rkn_chart`'s bits. Every piece gets a
whole number of equal steps (⌈ℓ/step⌉); the energy flows are integrated with the velocity's
weights, as there (:mod:`.fixed_step`'s docstring).

Every ``STABILITY_CHECK_EVERY`` steps the step is checked against the stability region of the
locally linearized problem (:func:`check_stability`): the Jacobian of (q, q̇) ↦ (q̇, f) by
one-sided differences (2n + 1 evaluations), its 2n modes (at n = 1 :func:`.fixed_step.check_stability`'s
closed form; at n ≥ 2 the Jacobian's eigenvalues by EISPACK's QR algorithm, :func:`eigenvalues`,
in the run's workspace), each mode hλ against RK4's amplification with :mod:`.fixed_step`'s margins.

A stop (the problem's ``stop_margin`` ≤ 0 after a step) ends the run after that step, unless the
problem asks for it to be located (``locate``): then the step is taken again from its start, to
the margin's root on the step's cubic Hermite interpolants of each coordinate (q from q and q̇
at its ends, q̇ from q̇ and q̈), and its sample replaced by the one there.
"""

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import atan2, ceil, cos, fabs, isfinite, pow, sin, sqrt
    from cython.cimports.loopcheck.reduced.kernels.fixed_step import RKNTableau, amplification_limit, rk4_amplification
    from cython.cimports.loopcheck.reduced.kernels.output import Outcome
    from cython.cimports.loopcheck.reduced.kernels.vector_output import VectorSamples, check_vector_run
    from cython.cimports.loopcheck.reduced.kernels.vector_problem import VectorRightHandSide
else:
    from math import atan2, ceil, cos, fabs, isfinite, pow, sin, sqrt

    from loopcheck.reduced.kernels.fixed_step import RKNTableau, amplification_limit, rk4_amplification
    from loopcheck.reduced.kernels.output import Outcome
    from loopcheck.reduced.kernels.vector_output import VectorSamples, check_vector_run
    from loopcheck.reduced.kernels.vector_problem import VectorRightHandSide

from loopcheck.reduced.kernels import fixed_step as _scalar
from loopcheck.reduced.kernels import output as _output

STABILITY_CHECK_EVERY = _scalar.STABILITY_CHECK_EVERY

# the statuses (loopcheck.reduced.kernels.output) as C constants
_OK = cython.declare(cython.int, _output.OK)
_NONFINITE = cython.declare(cython.int, _output.NONFINITE)
_SPEED = cython.declare(cython.int, _output.SPEED)
_UNSTABLE = cython.declare(cython.int, _output.UNSTABLE)
_FAILED = cython.declare(cython.int, _output.FAILED)
_CHECK_EVERY = cython.declare(cython.Py_ssize_t, _scalar.STABILITY_CHECK_EVERY)


@cython.cclass
class _Work:
    """A run's buffers (n coordinates, s stages): the stages' q̈, P and D, the stage point handed
    to the problem, its q̈, a step's results and its start, the stability check's Jacobian."""

    def __init__(self, n: cython.Py_ssize_t, s: cython.Py_ssize_t):
        self.n = n
        self.kk = np.empty((s, n))
        self.pp = np.empty(s)
        self.dd = np.empty(s)
        self.qs = np.empty(n)
        self.vs = np.empty(n)
        self.acc = np.empty(n)
        self.rq = np.empty(n)
        self.rv = np.empty(n)
        self.re = np.empty(2)
        self.q0 = np.empty(n)
        self.v0 = np.empty(n)
        self.a0 = np.empty(n)
        self.a1 = np.empty(n)
        self.jacobian = np.zeros((2 * n, 2 * n))
        self.jac = self.jacobian
        self.hess = np.zeros((2 * n + 1, 2 * n + 1))
        self.wr = np.zeros(2 * n + 1)
        self.wi = np.zeros(2 * n + 1)


@cython.cfunc
def _evaluate(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, w: _Work,
              q: cython.double[::1], v: cython.double[::1], row: cython.Py_ssize_t) -> cython.bint:
    """q̈ at (t, q, v) (copied into the stage point w.qs, w.vs) into w.acc and w.kk[row], P and D
    into w.pp[row], w.dd[row]. False where the problem cannot be evaluated or q̈ is not finite."""
    i: cython.Py_ssize_t
    for i in range(w.n):
        w.qs[i] = q[i]
        w.vs[i] = v[i]
    if rhs.acceleration(load, t, w.qs, w.vs, w.acc) != 0:
        return False
    finite: cython.bint = True
    for i in range(w.n):
        w.kk[row, i] = w.acc[i]
        finite = finite and isfinite(w.acc[i])
    w.pp[row] = rhs.power(load, w.vs)
    w.dd[row] = rhs.dissipation(w.vs)
    return finite


@cython.ccall
def check_stability(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1],
                    v: cython.double[::1], h: cython.double, outcome: Outcome) -> cython.int:
    """OK if every mode of the linearization at (q, v) is inside RK4's stability region (or grows
    no faster in the method than in the problem: :func:`.fixed_step.amplification_limit`); else
    UNSTABLE with outcome.detail = (Re hλ, Im hλ, |R|, limit) of the first such mode, or FAILED
    when f cannot be evaluated. Uses 2n + 1 evaluations.

    The Jacobian of (q, q̇) ↦ (q̇, f) is [[0, I], [F_q, F_q̇]], F by one-sided differences of
    step 1e-7 max(1, |xⱼ|) in each coordinate (:func:`.fixed_step.check_stability`'s); its modes
    at n = 1 as :func:`.fixed_step.check_stability` finds them (the same verdict and detail to the
    bit), at n ≥ 2 the eigenvalues of the Jacobian (:func:`eigenvalues`)."""
    return _check(rhs, load, t, q, v, h, outcome, _Work(q.shape[0], 1))


@cython.cfunc
def _mode(zr: cython.double, zi: cython.double, outcome: Outcome) -> cython.bint:
    """Whether the mode z = hλ is amplified beyond its limit (then its detail into outcome)."""
    amplification: cython.double = rk4_amplification(zr, zi)
    limit: cython.double = amplification_limit(zr, zi)
    if amplification > limit:
        outcome.detail[0] = zr
        outcome.detail[1] = zi
        outcome.detail[2] = amplification
        outcome.detail[3] = limit
        return True
    return False


@cython.cfunc
def _check(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1],
           v: cython.double[::1], h: cython.double, outcome: Outcome, w: _Work) -> cython.int:
    """:func:`check_stability` in the workspace ``w`` (of n coordinates, its own: the run's stages
    are left as they were)."""
    n: cython.Py_ssize_t = w.n
    i: cython.Py_ssize_t
    j: cython.Py_ssize_t
    dx: cython.double
    x: cython.double
    if not _evaluate(rhs, load, t, w, q, v, 0):
        return _FAILED
    for i in range(n):
        w.a0[i] = w.acc[i]  # f at (q, v)
        w.jac[i, n + i] = 1.0
    for j in range(2 * n):  # column j: q_j, then v_(j - n), moved by dx
        for i in range(n):
            w.rq[i] = q[i]
            w.rv[i] = v[i]
        if j < n:
            x = q[j]
            dx = 1e-7 * max(1.0, fabs(x))
            w.rq[j] = x + dx
        else:
            x = v[j - n]
            dx = 1e-7 * max(1.0, fabs(x))
            w.rv[j - n] = x + dx
        if not _evaluate(rhs, load, t, w, w.rq, w.rv, 0):
            return _FAILED
        for i in range(n):
            w.jac[n + i, j] = (w.acc[i] - w.a0[i]) / dx
    k: cython.Py_ssize_t
    if n == 1:  # λ² − f_q̇ λ − f_q = 0, as fixed_step.check_stability solves it
        f_q: cython.double = w.jac[1, 0]
        f_v: cython.double = w.jac[1, 1]
        disc: cython.double = f_v * f_v + 4.0 * f_q
        root_r: cython.double = 0.0
        root_i: cython.double = 0.0
        if disc != 0.0:  # CPython's _Py_c_pow for complex(disc) ** 0.5
            length: cython.double = pow(fabs(disc), 0.5)
            phase: cython.double = atan2(0.0, disc) * 0.5
            root_r = length * cos(phase)
            root_i = length * sin(phase)
        for k in range(2):
            lr: cython.double = 0.5 * (f_v + root_r) if k == 0 else 0.5 * (f_v - root_r)
            li: cython.double = 0.5 * root_i if k == 0 else 0.5 * (0.0 - root_i)
            if _mode(h * lr, h * li, outcome):
                return _UNSTABLE
        return _OK
    for i in range(2 * n):
        for j in range(2 * n):
            if not isfinite(w.jac[i, j]):
                return _FAILED
            w.hess[i + 1, j + 1] = w.jac[i, j]
    if not _eigenvalues(w.hess, 2 * n, w.wr, w.wi):  # (not converged in 30 iterations a value: LAPACK's)
        modes = np.linalg.eigvals(w.jacobian)
        for k in range(2 * n):
            w.wr[k + 1] = modes[k].real
            w.wi[k + 1] = modes[k].imag
    for k in range(1, 2 * n + 1):
        if _mode(h * w.wr[k], h * w.wi[k], outcome):
            return _UNSTABLE
    return _OK


# ---- the eigenvalues of a small real matrix (the stability check's, n ≥ 2) -------------------
# EISPACK's balanc, elmhes and hqr, as Press et al. give them (Numerical Recipes in C, 2nd ed.,
# §11.5–11.6), in double precision and their 1-based indexing: a[1..N, 1..N] of an (N+1, N+1)
# array, row and column 0 unused. No allocation: the check runs every STABILITY_CHECK_EVERY steps
# (numpy's eigvals, with its allocations and LAPACK's call, cost ~25 µs a check at n = 2).

@cython.cfunc
def _balance(a: cython.double[:, ::1], N: cython.Py_ssize_t) -> cython.void:
    """balanc: a similar matrix whose rows and columns have comparable norms (powers of 2: exact)."""
    last: cython.bint = False
    i: cython.Py_ssize_t
    j: cython.Py_ssize_t
    r: cython.double
    c: cython.double
    f: cython.double
    g: cython.double
    s: cython.double
    while not last:
        last = True
        for i in range(1, N + 1):
            r = 0.0
            c = 0.0
            for j in range(1, N + 1):
                if j != i:
                    c += fabs(a[j, i])
                    r += fabs(a[i, j])
            if c != 0.0 and r != 0.0:
                g = r / 2.0
                f = 1.0
                s = c + r
                while c < g:
                    f *= 2.0
                    c *= 4.0
                g = r * 2.0
                while c > g:
                    f /= 2.0
                    c /= 4.0
                if (c + r) / f < 0.95 * s:
                    last = False
                    g = 1.0 / f
                    for j in range(1, N + 1):
                        a[i, j] *= g
                    for j in range(1, N + 1):
                        a[j, i] *= f


@cython.cfunc
def _hessenberg(a: cython.double[:, ::1], N: cython.Py_ssize_t) -> cython.void:
    """elmhes: a similar upper Hessenberg matrix by elimination with pivoting (the multipliers
    left below the subdiagonal, which _hqr ignores)."""
    m: cython.Py_ssize_t
    i: cython.Py_ssize_t
    j: cython.Py_ssize_t
    x: cython.double
    y: cython.double
    for m in range(2, N):
        x = 0.0
        i = m
        for j in range(m, N + 1):
            if fabs(a[j, m - 1]) > fabs(x):
                x = a[j, m - 1]
                i = j
        if i != m:
            for j in range(m - 1, N + 1):
                a[i, j], a[m, j] = a[m, j], a[i, j]
            for j in range(1, N + 1):
                a[j, i], a[j, m] = a[j, m], a[j, i]
        if x != 0.0:
            for i in range(m + 1, N + 1):
                y = a[i, m - 1]
                if y != 0.0:
                    y /= x
                    a[i, m - 1] = y
                    for j in range(m, N + 1):
                        a[i, j] -= y * a[m, j]
                    for j in range(1, N + 1):
                        a[j, m] += y * a[j, i]


@cython.cfunc
@cython.inline
@cython.exceptval(check=False)
def _sign(a: cython.double, b: cython.double) -> cython.double:
    """NR's SIGN(a, b): |a| with the sign of b (b ≥ 0: positive)."""
    return fabs(a) if b >= 0.0 else -fabs(a)


@cython.cfunc
def _hqr(a: cython.double[:, ::1], N: cython.Py_ssize_t, wr: cython.double[::1], wi: cython.double[::1]) -> cython.bint:
    """hqr: the eigenvalues of the upper Hessenberg a[1..N, 1..N] (destroyed) into wr[1..N] +
    i wi[1..N], by the shifted double-step QR algorithm. Where NR gives up after 30 iterations
    (an exceptional shift at the 10th and the 20th), this one shifts so every 10 and gives up
    after 30 max(10, N), as LAPACK's dlahqr: several complex pairs of one modulus (random
    [[0, I], [F_q, F_q̇]] of n = 4, 5) took more than 30. False where it gives up."""
    nn: cython.Py_ssize_t
    m: cython.Py_ssize_t
    l: cython.Py_ssize_t
    k: cython.Py_ssize_t
    j: cython.Py_ssize_t
    i: cython.Py_ssize_t
    its: cython.int
    mmin: cython.Py_ssize_t
    z: cython.double = 0.0
    y: cython.double = 0.0
    x: cython.double = 0.0
    w: cython.double = 0.0
    v: cython.double = 0.0
    u: cython.double = 0.0
    t: cython.double = 0.0
    s: cython.double = 0.0
    r: cython.double = 0.0
    q: cython.double = 0.0
    p: cython.double = 0.0
    anorm: cython.double = 0.0
    for i in range(1, N + 1):
        for j in range(max(i - 1, 1), N + 1):
            anorm += fabs(a[i, j])
    nn = N
    while nn >= 1:
        its = 0
        while True:
            l = nn
            while l >= 2:
                s = fabs(a[l - 1, l - 1]) + fabs(a[l, l])
                if s == 0.0:
                    s = anorm
                if fabs(a[l, l - 1]) + s == s:
                    a[l, l - 1] = 0.0
                    break
                l -= 1
            x = a[nn, nn]
            if l == nn:  # one root found
                wr[nn] = x + t
                wi[nn] = 0.0
                nn -= 1
            else:
                y = a[nn - 1, nn - 1]
                w = a[nn, nn - 1] * a[nn - 1, nn]
                if l == nn - 1:  # two roots found
                    p = 0.5 * (y - x)
                    q = p * p + w
                    z = sqrt(fabs(q))
                    x += t
                    if q >= 0.0:  # a real pair
                        z = p + _sign(z, p)
                        wr[nn - 1] = x + z
                        wr[nn] = x + z
                        if z != 0.0:
                            wr[nn] = x - w / z
                        wi[nn - 1] = 0.0
                        wi[nn] = 0.0
                    else:  # a complex pair
                        wr[nn - 1] = x + p
                        wr[nn] = x + p
                        wi[nn - 1] = -z
                        wi[nn] = z
                    nn -= 2
                else:  # no roots found yet: continue the iteration
                    if its == 30 * max(10, N):
                        return False
                    if its % 10 == 0 and its > 0:  # an exceptional shift
                        t += x
                        for i in range(1, nn + 1):
                            a[i, i] -= x
                        s = fabs(a[nn, nn - 1]) + fabs(a[nn - 1, nn - 2])
                        x = 0.75 * s
                        y = x
                        w = -0.4375 * s * s
                    its += 1
                    m = nn - 2
                    while m >= l:  # two consecutive small subdiagonal elements
                        z = a[m, m]
                        r = x - z
                        s = y - z
                        p = (r * s - w) / a[m + 1, m] + a[m, m + 1]
                        q = a[m + 1, m + 1] - z - r - s
                        r = a[m + 2, m + 1]
                        s = fabs(p) + fabs(q) + fabs(r)
                        p /= s
                        q /= s
                        r /= s
                        if m == l:
                            break
                        u = fabs(a[m, m - 1]) * (fabs(q) + fabs(r))
                        v = fabs(p) * (fabs(a[m - 1, m - 1]) + fabs(z) + fabs(a[m + 1, m + 1]))
                        if u + v == v:
                            break
                        m -= 1
                    for i in range(m + 2, nn + 1):
                        a[i, i - 2] = 0.0
                        if i != m + 2:
                            a[i, i - 3] = 0.0
                    for k in range(m, nn):  # the double QR step on rows l..nn, columns m..nn
                        if k != m:
                            p = a[k, k - 1]
                            q = a[k + 1, k - 1]
                            r = 0.0
                            if k != nn - 1:
                                r = a[k + 2, k - 1]
                            x = fabs(p) + fabs(q) + fabs(r)
                            if x != 0.0:
                                p /= x
                                q /= x
                                r /= x
                        s = _sign(sqrt(p * p + q * q + r * r), p)
                        if s != 0.0:
                            if k == m:
                                if l != m:
                                    a[k, k - 1] = -a[k, k - 1]
                            else:
                                a[k, k - 1] = -s * x
                            p += s
                            x = p / s
                            y = q / s
                            z = r / s
                            q /= p
                            r /= p
                            for j in range(k, nn + 1):
                                p = a[k, j] + q * a[k + 1, j]
                                if k != nn - 1:
                                    p += r * a[k + 2, j]
                                    a[k + 2, j] -= p * z
                                a[k + 1, j] -= p * y
                                a[k, j] -= p * x
                            mmin = nn if nn < k + 3 else k + 3
                            for i in range(l, mmin + 1):
                                p = x * a[i, k] + y * a[i, k + 1]
                                if k != nn - 1:
                                    p += z * a[i, k + 2]
                                    a[i, k + 2] -= p * r
                                a[i, k + 1] -= p * q
                                a[i, k] -= p
            if not (nn >= 1 and l < nn - 1):
                break
    return True


@cython.cfunc
def _eigenvalues(a: cython.double[:, ::1], N: cython.Py_ssize_t, wr: cython.double[::1],
                 wi: cython.double[::1]) -> cython.bint:
    """The eigenvalues of a[1..N, 1..N] (destroyed) into wr[1..N] + i wi[1..N]: balanced, reduced
    to Hessenberg form, then hqr. False where hqr does not converge."""
    _balance(a, N)
    _hessenberg(a, N)
    return _hqr(a, N, wr, wi)


def eigenvalues(matrix) -> np.ndarray:
    """The eigenvalues of a real square matrix (N ≥ 1) as the stability check finds them (complex,
    (N,); in no particular order; ValueError where hqr does not converge). For the tests."""
    matrix = np.asarray(matrix, dtype=np.float64)
    N = matrix.shape[0]
    if matrix.ndim != 2 or matrix.shape[1] != N or N < 1:
        raise ValueError(f"a square matrix, not of shape {matrix.shape}")
    a = np.zeros((N + 1, N + 1))
    a[1:, 1:] = matrix
    wr = np.zeros(N + 1)
    wi = np.zeros(N + 1)
    if not _eigenvalues(a, N, wr, wi):
        raise ValueError("hqr did not converge")
    return wr[1:] + 1j * wi[1:]


@cython.cfunc
def _sample(rhs: VectorRightHandSide, out: VectorSamples, t: cython.double, q: cython.double[::1],
            v: cython.double[::1], accel: cython.double[::1], work: cython.double,
            dissipated: cython.double) -> cython.void:
    """Append one sample (q̈ = accel just evaluated at it, so observe() records it)."""
    i: cython.Py_ssize_t = out.n
    c: cython.Py_ssize_t
    out.t[i] = t
    for c in range(q.shape[0]):
        out.q[i, c] = q[c]
        out.v[i, c] = v[c]
        out.a[i, c] = accel[c]
    rhs.observe(out.observed, i)
    out.energy[i, 0] = work
    out.energy[i, 1] = dissipated
    out.n = i + 1


@cython.cfunc
def _step(rhs: VectorRightHandSide, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1],
          v: cython.double[::1], h: cython.double, c: cython.double[::1], a: cython.double[:, ::1],
          abar: cython.double[:, ::1], b: cython.double[::1], bbar: cython.double[::1], den: cython.double,
          w: _Work) -> cython.bint:
    """One step of h from (t, q, v), its first stage's q̈, P, D in w.kk[0], w.pp[0], w.dd[0]: q⁺,
    q̇⁺ into w.rq, w.rv and the increments of the work done and of the energy dissipated into
    w.re. Each coordinate's sums as :func:`.fixed_step._step` makes them. False where a stage's
    q̈ is not finite or the problem cannot be evaluated there."""
    s: cython.Py_ssize_t = w.kk.shape[0]
    n: cython.Py_ssize_t = w.n
    kk: cython.double[:, ::1] = w.kk
    i: cython.Py_ssize_t
    j: cython.Py_ssize_t
    k: cython.Py_ssize_t
    started: cython.bint
    sq: cython.double
    sv: cython.double
    sp: cython.double
    sd: cython.double
    Q: cython.double
    V: cython.double
    finite: cython.bint = True
    for i in range(1, s):
        for k in range(n):
            # nonzero entries only, left to right (fixed_step's docstring: RKN4 to the bit)
            started = False
            sq = 0.0
            sv = 0.0
            for j in range(i):
                if abar[i, j] != 0.0:
                    sq = sq + abar[i, j] * kk[j, k] if started else abar[i, j] * kk[j, k]
                    started = True
            Q = q[k] + c[i] * h * v[k]
            if started:
                Q = Q + h * h * sq
            started = False
            for j in range(i):
                if a[i, j] != 0.0:
                    sv = sv + a[i, j] * kk[j, k] if started else a[i, j] * kk[j, k]
                    started = True
            V = v[k]
            if started:
                V = V + h * sv
            w.rq[k] = Q  # the stage point (w.rq, w.rv: free until the update)
            w.rv[k] = V
        if not _evaluate(rhs, load, t + c[i] * h, w, w.rq, w.rv, i):
            finite = False
            break
    if not finite:
        return False
    sp = 0.0
    sd = 0.0
    for k in range(n):
        sq = 0.0
        sv = 0.0
        started = False
        for i in range(s):
            if bbar[i] != 0.0:
                sq = sq + bbar[i] * kk[i, k] if started else bbar[i] * kk[i, k]
                started = True
        started = False
        for i in range(s):
            if b[i] != 0.0:
                sv = sv + b[i] * kk[i, k] if started else b[i] * kk[i, k]
                started = True
        w.rq[k] = q[k] + h * v[k] + h * h * sq / den
        w.rv[k] = v[k] + h * sv / den
    started = False
    for i in range(s):
        if b[i] != 0.0:
            if started:
                sp = sp + b[i] * w.pp[i]
                sd = sd + b[i] * w.dd[i]
            else:
                sp = b[i] * w.pp[i]
                sd = b[i] * w.dd[i]
            started = True
    w.re[0] = h * sp / den
    w.re[1] = h * sd / den
    return True


@cython.cfunc
def _root(rhs: VectorRightHandSide, t: cython.double, w: _Work, q1: cython.double[::1], v1: cython.double[::1],
          h: cython.double) -> cython.double:
    """The part of the step [t, t + h] to the stop margin's root: bisection (to the spacing of
    the floats) of the margin on the step's cubic Hermite interpolants of each coordinate, q
    from (q, q̇) and q̇ from (q̇, q̈) at its ends (the start in w.q0, w.v0, w.a0; the end q1,
    v1, w.a1); the margin is > 0 at its start and ≤ 0 at its end (:func:`.fixed_step._root`)."""
    lo: cython.double = 0.0
    hi: cython.double = 1.0
    x: cython.double
    x2: cython.double
    x3: cython.double
    k: cython.Py_ssize_t
    it: cython.int
    for it in range(60):
        x = 0.5 * (lo + hi)
        if x <= lo or x >= hi:
            break
        x2 = x * x
        x3 = x2 * x
        for k in range(w.n):
            w.qs[k] = ((2 * x3 - 3 * x2 + 1) * w.q0[k] + (x3 - 2 * x2 + x) * h * w.v0[k] + (3 * x2 - 2 * x3) * q1[k]
                       + (x3 - x2) * h * v1[k])
            w.vs[k] = ((2 * x3 - 3 * x2 + 1) * w.v0[k] + (x3 - 2 * x2 + x) * h * w.a0[k]
                       + (3 * x2 - 2 * x3) * v1[k] + (x3 - x2) * h * w.a1[k])
        if rhs.stop_margin(t + x * h, w.qs, w.vs) > 0.0:
            lo = x
        else:
            hi = x
    return hi * h


@cython.ccall
def vector_rkn_chart(rhs: VectorRightHandSide, tableau: RKNTableau, edges: cython.double[::1],
                     loads: cython.Py_ssize_t[::1], t0: cython.double, q0: cython.double[::1],
                     v0: cython.double[::1], step: cython.double, speed_limit: cython.double,
                     stability: cython.bint, use_stop: cython.bint, out: VectorSamples) -> Outcome:
    """Integrate q̈ = f(t, q, q̇) (rhs.acceleration) with ``tableau`` from t0 to edges[-1]; the
    load history is loads[k] on [edges[k], edges[k+1]] (pieces before t0 are skipped, the one
    holding t0 starts there).

    Parameters (:func:`.fixed_step.rkn_chart`'s, with q0, v0 of n = rhs.dimension() values)
    ----------
    rhs : the problem; tableau : the method (c[0] = 0)
    edges : (p+1,) s, increasing; loads : (p,) the load index of each piece
    t0 : the start (s); q0, v0 : (n,) the state there
    step : the largest step (s): a piece of length ℓ gets ⌈ℓ/step − 1e-9⌉ equal steps
    speed_limit : max |q̇ᵢ| beyond which the run ends with SPEED
    stability : check the step every STABILITY_CHECK_EVERY steps (:func:`check_stability`)
    use_stop : end the run after the first step where rhs.stop_margin ≤ 0 (outcome.stopped), or
        at a piece's first sample where rhs.stop_at_start; where rhs.locate says so, that step is
        taken again from its start, to the margin's root on the step's interpolants
    out : the samples are appended to it (n coordinates, width rhs.observation_size()): one at
        every step, and at each piece's start one repeating the previous piece's last time with
        q̈ on the new side; with each, what rhs.observe records and the work done and the energy
        dissipated since t0 (J)

    Returns
    -------
    Outcome: status OK, NONFINITE (fail_time), SPEED (fail_time, fail_value = q̇ᵢ, detail[0] = i),
    UNSTABLE (fail_time, detail) or FAILED (fail_time: f not finite or not evaluated there);
    t_reached, the last sample's time; n_evaluations counts every evaluation of f (the stability
    checks' too). On a failure the samples before it stay appended.
    """
    outcome: Outcome = Outcome()
    n: cython.Py_ssize_t = rhs.dimension()
    check_vector_run(out, n, rhs.observation_size(), q0, v0, edges.shape[0], loads.shape[0])
    if tableau.c[0] != 0.0:
        raise ValueError("the kernel reuses f at a step's end as the next first stage: c[0] must be 0")
    if not step > 0.0:
        raise ValueError(f"step {step}: positive and finite")
    npieces: cython.Py_ssize_t = loads.shape[0]
    s: cython.Py_ssize_t = tableau.stages
    first: cython.Py_ssize_t = 0
    while first < npieces - 1 and edges[first + 1] <= t0:
        first += 1
    total: cython.Py_ssize_t = 0
    k: cython.Py_ssize_t
    start: cython.double
    end: cython.double
    for k in range(first, npieces):
        start = max(edges[k], t0)
        if edges[k + 1] > start:
            total += 1 + max(1, cython.cast(cython.Py_ssize_t, ceil((edges[k + 1] - start) / step - 1e-9)))
    out.reserve(total)
    w: _Work = _Work(n, s)
    check: _Work = _Work(n, 1)  # the stability check's
    c: cython.double[::1] = tableau.c
    a: cython.double[:, ::1] = tableau.a
    abar: cython.double[:, ::1] = tableau.abar
    b: cython.double[::1] = tableau.b
    bbar: cython.double[::1] = tableau.bbar
    den: cython.double = tableau.denominator
    q_array = np.array(q0)
    v_array = np.array(v0)
    q: cython.double[::1] = q_array  # the state
    v: cython.double[::1] = v_array
    work: cython.double = 0.0
    dissipated: cython.double = 0.0
    n_steps: cython.Py_ssize_t = 0
    n_eval: cython.Py_ssize_t = 0
    t: cython.double
    t_next: cython.double
    h: cython.double
    hs: cython.double
    load: cython.Py_ssize_t
    ns: cython.Py_ssize_t
    m: cython.Py_ssize_t
    i: cython.Py_ssize_t
    status: cython.int
    bad: cython.Py_ssize_t
    outcome.t_reached = t0
    for i in range(n):
        if not (isfinite(q[i]) and isfinite(v[i])):
            outcome.status = _NONFINITE
            outcome.fail_time = t0
            return outcome
    for i in range(n):
        if fabs(v[i]) > speed_limit:
            outcome.status = _SPEED
            outcome.fail_time = t0
            outcome.fail_value = v[i]
            outcome.detail[0] = i
            return outcome
    for k in range(first, npieces):
        start = max(edges[k], t0)
        end = edges[k + 1]
        if end <= start:
            continue
        load = loads[k]
        ns = max(1, cython.cast(cython.Py_ssize_t, ceil((end - start) / step - 1e-9)))
        h = (end - start) / ns
        n_eval += 1
        if not _evaluate(rhs, load, start, w, q, v, 0):
            outcome.status = _FAILED
            outcome.fail_time = start
            break
        _sample(rhs, out, start, q, v, w.acc, work, dissipated)
        outcome.t_reached = start
        if use_stop and rhs.stop_at_start(start, w.qs, w.vs):  # an event at the piece's start (a load edge)
            outcome.stopped = True
            break
        for m in range(ns):
            t = start + m * h
            if stability and n_steps % _CHECK_EVERY == 0:
                status = _check(rhs, load, t, q, v, h, outcome, check)
                n_eval += 2 * n + 1
                if status != _OK:
                    outcome.status = status
                    outcome.fail_time = t
                    break
            for i in range(n):  # the step's start (kk[0], pp[0], dd[0]: its first stage; the check has its own)
                w.q0[i] = q[i]
                w.v0[i] = v[i]
                w.a0[i] = w.kk[0, i]
            if not _step(rhs, load, t, q, v, h, c, a, abar, b, bbar, den, w):
                outcome.status = _FAILED
                outcome.fail_time = t
                break
            for i in range(n):
                q[i] = w.rq[i]
                v[i] = w.rv[i]
            work += w.re[0]
            dissipated += w.re[1]
            t_next = end if m + 1 == ns else start + (m + 1) * h
            bad = -1
            for i in range(n):
                if not (isfinite(q[i]) and isfinite(v[i])):
                    bad = i
                    break
            if bad >= 0:
                outcome.status = _NONFINITE
                outcome.fail_time = t_next
                break
            for i in range(n):
                if fabs(v[i]) > speed_limit:
                    bad = i
                    break
            if bad >= 0:
                outcome.status = _SPEED
                outcome.fail_time = t_next
                outcome.fail_value = v[bad]
                outcome.detail[0] = bad
                break
            n_eval += s
            n_steps += 1
            if not _evaluate(rhs, load, t_next, w, q, v, 0):  # also the next step's first stage
                outcome.status = _FAILED
                outcome.fail_time = t_next
                break
            _sample(rhs, out, t_next, q, v, w.acc, work, dissipated)
            outcome.t_reached = t_next
            if use_stop and rhs.stop_margin(t_next, w.qs, w.vs) <= 0.0:
                outcome.stopped = True
                if rhs.locate(t_next, w.qs, w.vs):  # the step again, to the event's root
                    for i in range(n):
                        w.a1[i] = w.acc[i]
                        q[i] = w.q0[i]  # the step's start again
                        v[i] = w.v0[i]
                    work -= w.re[0]
                    dissipated -= w.re[1]
                    hs = _root(rhs, t, w, w.rq, w.rv, t_next - t)
                    if not _evaluate(rhs, load, t, w, q, v, 0):
                        outcome.status = _FAILED
                        outcome.fail_time = t
                        break
                    if not _step(rhs, load, t, q, v, hs, c, a, abar, b, bbar, den, w):
                        outcome.status = _FAILED
                        outcome.fail_time = t
                        break
                    for i in range(n):
                        q[i] = w.rq[i]
                        v[i] = w.rv[i]
                    work += w.re[0]
                    dissipated += w.re[1]
                    n_eval += s + 1
                    if not _evaluate(rhs, load, t + hs, w, q, v, 0):
                        outcome.status = _FAILED
                        outcome.fail_time = t + hs
                        break
                    out.n -= 1
                    _sample(rhs, out, t + hs, q, v, w.acc, work, dissipated)
                    outcome.t_reached = t + hs
                break
        if outcome.status != _OK or outcome.stopped:
            break
    outcome.n_steps = n_steps
    outcome.n_evaluations = n_eval
    return outcome
