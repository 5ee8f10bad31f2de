# C-level declaration of loopcheck/reduced/kernels/vector_problem.py (Cython's augmenting .pxd): the table of
# methods the compiled n-coordinate integrators call.

from loopcheck.reduced.kernels.problem cimport RightHandSide


cdef class VectorRightHandSide:
    cpdef Py_ssize_t dimension(self)
    cpdef int acceleration(self, Py_ssize_t load, double t, double[::1] q, double[::1] v, double[::1] a)
    cpdef double power(self, Py_ssize_t load, double[::1] v)
    cpdef double dissipation(self, double[::1] v)
    cpdef double stop_margin(self, double t, double[::1] q, double[::1] v)
    cpdef bint locate(self, double t, double[::1] q, double[::1] v)
    cpdef bint stop_at_start(self, double t, double[::1] q, double[::1] v)
    cpdef Py_ssize_t observation_size(self)
    cpdef observe(self, double[:, ::1] out, Py_ssize_t row)
    cpdef mark(self)
    cpdef rewind(self)


cdef class ScalarAsVector(VectorRightHandSide):
    cdef readonly RightHandSide scalar
