# C-level declaration of loopcheck/reduced/kernels/adaptive.py (Cython's augmenting .pxd).

from loopcheck.reduced.kernels.output cimport Outcome, Samples, check_run
from loopcheck.reduced.kernels.problem cimport RightHandSide


cdef class Steps:
    cdef double[::1] st, sh
    cdef double[:, ::1] sy
    cdef double[:, :, ::1] sF, sK
    cdef unsigned char[::1] sD
    cdef _allocate(self, Py_ssize_t capacity)
    cpdef Py_ssize_t capacity(self)
    cpdef grow(self, Py_ssize_t keep)


cpdef double _norm2(double x0, double x1) noexcept
cpdef _dot_kt(double[:, ::1] K, double[::1] a, Py_ssize_t s, double[::1] out)
cpdef Outcome dop853_run(RightHandSide rhs, double[::1] piece_edges, Py_ssize_t[::1] piece_load, double q0,
                         double v0, double rtol, double atol, double sample_interval, Py_ssize_t per_step,
                         double speed_limit, Py_ssize_t max_evaluations, double max_step, bint use_stop,
                         Samples out, Steps steps, Py_ssize_t peak_column=*)
