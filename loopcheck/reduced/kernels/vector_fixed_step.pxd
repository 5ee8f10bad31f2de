# C-level declaration of loopcheck/reduced/kernels/vector_fixed_step.py (Cython's augmenting .pxd).

from loopcheck.reduced.kernels.fixed_step cimport RKNTableau, amplification_limit, rk4_amplification
from loopcheck.reduced.kernels.output cimport Outcome
from loopcheck.reduced.kernels.vector_output cimport VectorSamples, check_vector_run
from loopcheck.reduced.kernels.vector_problem cimport VectorRightHandSide


cdef class _Work:
    cdef Py_ssize_t n
    cdef double[:, ::1] kk, jac, hess
    cdef double[::1] pp, dd, qs, vs, acc, rq, rv, re, q0, v0, a0, a1, wr, wi
    cdef object jacobian


cpdef int check_stability(VectorRightHandSide rhs, Py_ssize_t load, double t, double[::1] q, double[::1] v,
                          double h, Outcome outcome)
cpdef Outcome vector_rkn_chart(VectorRightHandSide rhs, RKNTableau tableau, double[::1] edges,
                               Py_ssize_t[::1] loads, double t0, double[::1] q0, double[::1] v0, double step,
                               double speed_limit, bint stability, bint use_stop, VectorSamples out)
