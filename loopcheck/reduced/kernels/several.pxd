# C-level declaration of loopcheck/reduced/kernels/several.py (Cython's augmenting .pxd).

from loopcheck.kernels.loops cimport Loops
from loopcheck.reduced.kernels.vector_problem cimport VectorRightHandSide

cdef double _c_newton_tol, _c_newton_round_off, _c_predictor_trust, _c_trusted_correction, _c_hysteresis
cdef double _c_jacobi_tol, _c_nan, _c_clamp_hysteresis, _c_stuck_pivot, _c_stuck_rank, _c_stuck_consistent
cdef Py_ssize_t _c_newton_max_iter, _c_walk_halvings, _c_jacobi_sweeps, _c_stuck_lp


cdef class Several(VectorRightHandSide):
    cdef readonly object arrays
    cdef double[::1] F
    cdef long long[::1] I
    cdef readonly Py_ssize_t n, k, mr, nj, valid, piece
    cdef readonly Loops loops
    cdef readonly double singular, potential, c_current, c_best, tol, det
    cdef readonly int sign
    cdef bint starting
    cdef readonly double[:, ::1] JR, R, K, Jm, Bm
    cdef double[:, ::1] Rmark, small, timed, act_k, ku, kd, LU, Phx, lastK, baseK, startK, markK, U, Z, D, M
    cdef double[:, :, ::1] KG
    cdef readonly double[::1] Qp, drive_rate, Qa, cv, qdd, xdot, xdd0, xdd, lastx, lastq, rate
    cdef double[::1] qv, act_l, basex, baseq, startx, startq, markx, markq, target, pred, resid, used
    cdef long long[::1] piv
    cdef readonly long long[::1] sel
    cdef double[::1] gam
    cdef readonly double[::1] clampm, slip, lam
    cdef double[:, ::1] kkt
    cdef double[::1] ksol, scratch
    cdef Py_ssize_t _stuck_count(self) except -1
    cdef int _stuck_solve(self) except -1
    cdef int _indeterminate(self) except -1
    cdef int _max_margin(self) except -1
    cdef double[:, ::1] wk, G, nul, lpa
    cdef double[::1] lamp, lpx
    cdef long long[::1] sidx, perm, comb
    cdef readonly Py_ssize_t nullity
    cdef readonly bint fresh
    cdef double[:, ::1] fric_k
    cpdef double slip_margin(self, double[::1] v)
    cpdef double clamp_margin(self, double[::1] v)
    cdef bint _clamped(self, Py_ssize_t e) except -1
    cdef double _unclamped(self, Py_ssize_t e, Py_ssize_t piece, double[::1] v) except? -1
    cpdef bint stop_at_start(self, double t, double[::1] q, double[::1] v)
    cpdef Py_ssize_t set_clamps(self, Py_ssize_t load, double[::1] q, double[::1] v)
    cdef readonly long long[::1] best, current, counts

    cdef int _save_factors(self) except -1
    cdef int _solve(self, double[::1] b) except -1
    cdef int _second_order(self, double[::1] out) except -1
    cdef int _eliminate(self, double[:, ::1] M, Py_ssize_t m, Py_ssize_t w, double tiny) except -1
    cdef int _small_solve(self) except -1
    cdef double _row_xdd0(self, Py_ssize_t e) except? -1
    cdef double _residual(self) except? -1
    cdef int _close(self) except -1
    cdef int _walk(self, double[::1] q) except -1
    cdef int _coefficients(self) except -1
    cpdef bint evaluate(self, double[::1] q) except -1
    cpdef Py_ssize_t dimension(self)
    cpdef int acceleration(self, Py_ssize_t load, double t, double[::1] q, double[::1] v, double[::1] out)
    cpdef Py_ssize_t accelerations(self, Py_ssize_t load, double[::1] T, double[:, ::1] Q, double[:, ::1] V,
                                   double[:, ::1] out)
    cpdef double power(self, Py_ssize_t load, double[::1] v)
    cpdef double dissipation(self, double[::1] v)
    cpdef double kinetic(self, double[::1] v)
    cpdef Py_ssize_t observation_size(self)
    cpdef observe(self, double[:, ::1] out, Py_ssize_t row)
    cpdef mark(self)
    cpdef rewind(self)
    cpdef reset(self)
    cdef void _project_out(self, double[:, ::1] a, Py_ssize_t i, double[:, ::1] b, Py_ssize_t count) noexcept
    cdef double _sigma_ratio(self, long long[::1] S) except? -1
    cdef int _best_set(self) except -1
    cpdef double stop_margin(self, double t, double[::1] q, double[::1] v)
    cpdef double range_margin(self)
    cpdef bint locate(self, double t, double[::1] q, double[::1] v)
    cpdef bint start(self, double[::1] x, long long[::1] joints) except -1
