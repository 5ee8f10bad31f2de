# C-level declaration of loopcheck/reduced/kernels/problem.py (Cython's augmenting .pxd): the table of
# methods the compiled integrators call.

cdef class RightHandSide:
    cpdef double acceleration(self, Py_ssize_t load, double t, double q, double v)
    cpdef double power(self, Py_ssize_t load, double v)
    cpdef double dissipation(self, double v)
    cpdef double stop_margin(self, double t, double q, double v)
    cpdef bint locate(self, double t, double q, double v)
    cpdef bint stop_at_start(self, double t, double q, double v)
    cpdef Py_ssize_t observation_size(self)
    cpdef observe(self, double[:, ::1] out, Py_ssize_t row)
    cpdef mark(self)
    cpdef rewind(self)
