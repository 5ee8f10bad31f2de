# C-level declaration of loopcheck/reduced/kernels/vector_output.py (Cython's augmenting .pxd).

cdef class VectorSamples:
    cdef public Py_ssize_t n, width
    cdef readonly Py_ssize_t dimension
    cdef double[::1] t
    cdef double[:, ::1] q, v, a, observed, energy
    cdef _allocate(self, Py_ssize_t capacity)
    cpdef reserve(self, Py_ssize_t extra)
    cpdef clear(self)


cpdef check_vector_run(VectorSamples out, Py_ssize_t dimension, Py_ssize_t width, double[::1] q0, double[::1] v0,
                       Py_ssize_t edges, Py_ssize_t pieces)
