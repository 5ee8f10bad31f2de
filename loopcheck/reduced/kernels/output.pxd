# C-level declaration of loopcheck/reduced/kernels/output.py (Cython's augmenting .pxd).

cdef class Samples:
    cdef public Py_ssize_t n, width
    cdef double[::1] t, q, v, a
    cdef double[:, ::1] observed, energy
    cdef _allocate(self, Py_ssize_t capacity)
    cpdef reserve(self, Py_ssize_t extra)
    cpdef clear(self)


cdef class Outcome:
    cdef public int status
    cdef public bint stopped
    cdef public Py_ssize_t n_steps, n_evaluations, n_sample_evaluations
    cdef public double t_reached, fail_time, fail_value
    cdef public double[::1] detail


cpdef check_run(Samples out, Py_ssize_t width, Py_ssize_t edges, Py_ssize_t pieces)
