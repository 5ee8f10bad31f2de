# C-level declaration of loopcheck/reduced/kernels/fixed_step.py (Cython's augmenting .pxd).

from loopcheck.reduced.kernels.output cimport Outcome, Samples, check_run
from loopcheck.reduced.kernels.problem cimport RightHandSide


cdef class RKNTableau:
    cdef readonly str name
    cdef readonly int order
    cdef readonly Py_ssize_t stages
    cdef readonly double[::1] c, bbar, b
    cdef readonly double[:, ::1] abar, a
    cdef readonly double denominator


cpdef double rk4_amplification(double zr, double zi)
cpdef double amplification_limit(double zr, double zi)
cpdef int check_stability(RightHandSide rhs, Py_ssize_t load, double t, double q, double v, double h,
                          Outcome outcome)
cpdef Outcome rkn_chart(RightHandSide rhs, RKNTableau tableau, double[::1] edges, Py_ssize_t[::1] loads,
                        double t0, double q0, double v0, double step, double speed_limit, bint stability,
                        bint use_stop, Samples out)
