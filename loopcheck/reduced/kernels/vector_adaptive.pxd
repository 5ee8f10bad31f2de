# C-level declaration of loopcheck/reduced/kernels/vector_adaptive.py (Cython's augmenting .pxd).

from loopcheck.reduced.kernels.output cimport Outcome
from loopcheck.reduced.kernels.vector_output cimport VectorSamples, check_vector_run
from loopcheck.reduced.kernels.vector_problem cimport VectorRightHandSide


cdef class VectorSteps:
    cdef readonly Py_ssize_t dimension
    cdef double[::1] st, sh, qs, vs, acc
    cdef double[:, ::1] sy, K, P, Y, S, pb
    cdef double[:, :, ::1] sF
    cdef long long[::1] work
    cdef _allocate(self, Py_ssize_t capacity)
    cpdef Py_ssize_t capacity(self)
    cpdef grow(self, Py_ssize_t keep)


cpdef double _norm(double[::1] x)
cpdef _dot_kt(double[:, ::1] K, double[::1] a, Py_ssize_t s, double[::1] out)
cpdef Outcome vector_dop853_run(VectorRightHandSide rhs, double[::1] piece_edges, Py_ssize_t[::1] piece_load,
                                double[::1] q0, double[::1] v0, double rtol, double atol, double sample_interval,
                                Py_ssize_t per_step, double speed_limit, Py_ssize_t max_evaluations,
                                double max_step, bint use_stop, VectorSamples out, VectorSteps steps)
