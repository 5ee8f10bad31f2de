# C-level declaration of loopcheck/kernels/loops.py (Cython's augmenting .pxd).

# The integer constants of the packed layout (loops.py documents them; its block
# `if not cython.compiled` holds the same values for plain Python: keep both in step,
# tests/core/test_loops_kernel.py compares them). A cpdef enum: C constants, importable from Python.
cpdef enum:
    N = 0
    N_ANGLES = 1
    N_LINEAR = 2
    MAX_ROWS = 3
    LINEAR = 4
    TABLES = 5
    TABLE_ENTRIES = 7
    N_TABLES = 4
    LOOPS = 0
    KIN_HEADER = 33
    CLOSED = 0
    NON_FINITE = 1
    SINGULAR_JACOBIAN = 2
    NOT_CLOSED = 3
    ROW_EXTRA = 7


cdef class Loops:
    cdef readonly object arrays, B, P, C, S
    cdef readonly Py_ssize_t m
    # the m constraint rows (phi, Phi: views of C) and the n − 1 independent ones among them (sel: S)
    cdef long long[::1] sel
    # a redundant loop without a selection: the basis of Φ_x's rows at every evaluation (_basis), its
    # scratch G and views W (m, n), E (m, m), T (n − 1, m), used (m,)
    cdef readonly bint adaptive
    cdef readonly object G
    cdef double[:, ::1] W, E, T
    cdef double[::1] used
    # Φ (m,) and Φ_x (m, n), views of C; Phi_flat is Φ_x as one row (m·n,)
    cdef double[::1] phi, Phi_flat
    cdef double[:, ::1] Phi
    cdef double[::1] F
    cdef long long[::1] I
    cdef readonly Py_ssize_t n
    # views of B and P (loops.py: Loops), made once at construction; K and L are kin's rows
    cdef long long[::1] piv
    cdef double[::1] x, rhs, norms, K, L
    cdef double[:, ::1] trig, A, rows, kin
    # B as one view, and where rhs, K and L start in it (what _lu_solve solves in place)
    cdef double[::1] b
    cdef readonly Py_ssize_t rhs_at, K_at, L_at
    # what _constraints, _factor_row and _finish leave
    cdef Py_ssize_t best_j
    cdef double spread, det, hadamard, own, best
    # what _poly leaves: p, p', p'' of a linear row's polynomial, and r_x·K
    cdef double poly_p, poly_dp, poly_ddp, poly_rate

    cdef double _lu_factor(self) except? -1
    cdef int _lu_solve(self, Py_ssize_t at) except -1
    cdef double _lu_factor_general(self) except? -1
    cdef double _lu_factor3(self) except? -1
    cdef int _lu_solve_general(self, Py_ssize_t at) except -1
    cdef int _lu_solve3(self, Py_ssize_t at) except -1
    cdef int _angle_trig(self) except -1
    cdef int _table_positions(self, Py_ssize_t table) except -1
    cdef int _table_points(self, Py_ssize_t table, bint with_rates) except -1
    cdef int _table_rates(self, Py_ssize_t table, bint with_l) except -1
    cdef double _poly(self, Py_ssize_t lin, bint newton) except? -1
    cdef double _constraints(self) except? -1
    cdef int _basis(self) except -1
    cdef double _factor_row(self, double[::1] row) except? -1
    cdef int _finish(self, double det, Py_ssize_t i) except -1
    cdef inline double _cramer_ratio(self, Py_ssize_t j, double det, double product, Py_ssize_t zeros) except? -1
