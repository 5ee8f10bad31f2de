"""Loop kinematics of a one-DOF planar linkage on packed term tables, compiled (Cython).

The one implementation of the linkage's kinematics: term-table positions and rates, the
constraints Φ and their Jacobian Φ_x, a small dense LU, Newton's assembly at an input, the
velocity and acceleration coefficients K and L, and the singular-position measure (the
conditioning). :mod:`loopcheck.kinematics` packs a :class:`~loopcheck.kinematics.LoopSystem` into these
arrays for the engines' set-up (scene assembly, MuJoCo's initial state, drawings); the reduced
engine's compiled charts (:mod:`loopcheck.reduced.kernels.physics`) hold a :class:`Loops` and call its
C methods at every evaluation. Debug with ``LOOPCHECK_PURE_PYTHON=1``: this file then runs as plain
Python (:mod:`loopcheck.kernels`), the slow reference.

Term tables: row k of a table is r_k(x) = offset_k + Σ_t m_t R(θ_t) w_t with m_t = x[mag_t] (or
1), θ_t = x[angle_t] (or 0 for ground) and w_t = coef_t e(phase_t) (:mod:`loopcheck.kinematics`
documents the tables). With u_t = R(θ_t) w_t and u⊥ = (−u_y, u_x):

    ∂r/∂x[angle] = m u⊥,  ∂r/∂x[mag] = u,
    K_r = ṁ u + m θ̇ u⊥,  L_r = m̈ u + (2 ṁ θ̇ + m θ̈) u⊥ − m θ̇² u     (ṁ = K[mag], θ̇ = K[angle], …)

With A = [Φ_x; row], row the driving row of the coordinate p = row·x (the input's, or e_i for a
chart's coordinate x_i), K = dx/dp and L = d²x/dp² solve

    A K = (0, …, 0, 1),      A L = (−γ, 0),   γ = Σ_t 2 ṁ θ̇ u⊥ − m θ̇² u

with the same factorization.

Rows of the LINEAR block (N_LINEAR of them, after the loops' rows) are polynomial rows, each
2n + 7 floats: r_y (n), r_x (n), x_ref, y_ref, a0 … a4, the row

    Φ_c = (r_y·x − y_ref) − p(r_x·x − x_ref),   p(s) = a0 + a1 s + … + a4 s⁴,

Φ_x = r_y − p'(s) r_x and γ_c = −p''(s) (r_x·K)² (d²Φ_c/dp² = Φ_x L + γ_c). A linear row
(a slider keeps its angle: r_y·x = 0) has r_x = 0 and p = 0; a joint coupling (MuJoCo's
``equality/joint``: joint y follows joint x) has r_y, r_x the two joints' own coordinates.

Conditioning of p (the project's one singular-position measure,
:data:`loopcheck.kinematics.SINGULAR_CONDITIONING`): the Hadamard ratio of the dependent Jacobian,
|det A| / (|row_i| Π_{l≠i} ‖Φ_x[:, l] − (row_l / row_i) Φ_x[:, i]‖), i the row's largest |entry|;
for coordinate j with K taken w.r.t. any coordinate (Cramer's rule) c_j = |K_j| |det A| /
Π_{l≠j} ‖Φ_x[:, l]‖.

Compiled: the integer constants of the packed layout (below) are C constants declared in
``loops.pxd`` (a ``cpdef enum``: importable from Python with the same values; the block
``if not cython.compiled`` here defines them for plain Python, and
``tests/core/test_loops_kernel.py`` checks that the two agree). The arithmetic keeps the order of
every expression (the build does not contract a*b+c or reassociate), so that it gives the same
numbers as plain Python.
"""

import math

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import cos, fabs, isfinite, sin, sqrt
else:
    from math import cos, fabs, isfinite, sin, sqrt

# -- the packed layout -------------------------------------------------------------------
# A linkage's kinematics is two flat arrays, F (float64) and I (int64), which a user (the reduced
# engine's model) may extend past KIN_HEADER with its own header entries and arrays.
#
# I[0:KIN_HEADER] is the header: n (coordinates), the body angles among them (the first
# N_ANGLES), the linear (polynomial) constraint rows, the most rows of any table, the offset in F
# of the linear rows (N_LINEAR, ROW_WIDTH(n): module docstring), then N_TABLES term tables of TABLE_ENTRIES entries each: rows, terms,
# and the offsets of offset (rows, 2) and w (terms, 2) in F and of row, mag, angle (terms,) in I.
# Table LOOPS holds the loop-closure vectors (2 constraint rows each); the others are the user's.
# Compiled, these are the C constants of loops.pxd (module docstring): keep both in step.
if not cython.compiled:
    N, N_ANGLES, N_LINEAR, MAX_ROWS, LINEAR = range(5)
    TABLES = 5
    TABLE_ENTRIES = 7
    N_TABLES = 4
    LOOPS = 0
    KIN_HEADER = TABLES + N_TABLES * TABLE_ENTRIES
    # what assemble returns: closed; a non-finite residual; a singular Jacobian before
    # convergence; no convergence in the iterations allowed
    CLOSED, NON_FINITE, SINGULAR_JACOBIAN, NOT_CLOSED = range(4)
    # a linear row's floats beyond its two rows r_y, r_x (2n): x_ref, y_ref, a0 … a4
    ROW_EXTRA = 7

# A redundantly closed loop's basis (Loops._basis): a row whose part outside the rows already taken
# is below BASIS_RTOL × the largest row's norm adds nothing (the rank of the loop equations has
# dropped there: a singular position), as in :func:`loopcheck.kinematics.independent_rows` (RANK_RTOL).
BASIS_RTOL = 1e-9
_c_basis_rtol = cython.declare(cython.double, BASIS_RTOL)


@cython.final
@cython.cclass
class Loops:
    """The kinematics of one packed linkage (compiled): its arrays and scratch.

    ``Loops(F, I, select)`` keeps the packed arrays (module docstring) and allocates B (float64: x (n),
    trig (2, n), A (n, n), rhs (n), norms (n), rows (MAX_ROWS, 4), kin (3, n): x, K, L) and piv
    (int64, n), with typed views of their parts made once here, and C (float64: Φ (m,) and Φ_x
    (m, n) of all m = 2 loops + linear rows). ``select`` (n − 1 indices into the m rows, default
    all of them when m = n − 1) is the independent rows
    (:func:`loopcheck.kinematics.independent_rows`, chosen once at an assembled configuration):
    Newton's assembly, K, L and the conditioning use those rows only.

    A redundantly closed loop has m > n − 1 rows. Without ``select`` its kernel runs on an
    orthonormal basis of the rows of Φ_x, taken at every evaluation (:meth:`_basis`: Gram-Schmidt
    with the largest remaining row first) and applied to Φ and γ alike, rather than on rows chosen
    once: the rows a configuration can drop change along the motion (a parallelogram with an
    extra crank, its rows chosen at q = 0.6 rad, lost their rank at q = π/2). K and L do not
    depend on the basis (the rows are consistent); the conditioning, taken on the basis, is a
    property of Φ_x's row space; det A's sign (a chart's branch without redundant rows) depends
    on the basis' orientation, which no configuration fixes, so det A is reported as |det A|
    there. Its scratch is G (float64: W (m, n), the rows under elimination; E (m, m), their
    combinations of the rows of Φ; T (n − 1, m), the basis' combinations; used (m,)).

    The C methods read and write
    these views and take no array argument (compiled, an array argument is a view passed by
    value: :mod:`loopcheck.reduced.kernels.physics`'s chart calls them at every evaluation). The
    Python methods (``positions`` … ``assemble``) copy their arguments in and their results out.
    """

    def __init__(self, F, I, select=None):
        F = np.ascontiguousarray(F, dtype=np.float64)
        I = np.ascontiguousarray(I, dtype=np.int64)
        self.arrays = (F, I)
        self.F = F
        self.I = I
        n = int(I[N])
        self.n = n
        m = 2 * int(I[TABLES + TABLE_ENTRIES * LOOPS]) + int(I[N_LINEAR])
        self.m = m
        # A redundant loop without a selection: the basis of Φ_x's rows (a table of points packed as
        # LOOPS, whose constraints are never asked for, takes this branch too, harmlessly).
        self.adaptive = select is None and m > max(n - 1, 0)
        if select is None:  # every row (a table of points, not loops, has none to select)
            select = np.arange(min(m, max(n - 1, 0)), dtype=np.int64)
        elif np.ndim(select) != 1 or len(select) != max(n - 1, 0) or (
                len(select) and (np.min(select) < 0 or np.max(select) >= m or len(np.unique(select)) != len(select))):
            raise ValueError(f"select must be {max(n - 1, 0)} distinct rows of the {m} constraint rows, "
                             f"got {list(select)}")
        select = np.ascontiguousarray(select, dtype=np.int64)
        self.S = select
        self.sel = select
        self.C = np.zeros(m + m * n + 1)
        b = m if self.adaptive else 0
        nb = max(n - 1, 0) if self.adaptive else 0
        self.G = np.zeros(b * n + b * b + nb * b + b + 1)
        self.W = self.G[0:b * n].reshape(b, n)
        self.E = self.G[b * n:b * n + b * b].reshape(b, b)
        self.T = self.G[b * n + b * b:b * n + b * b + nb * b].reshape(nb, b)
        self.used = self.G[b * n + b * b + nb * b:b * n + b * b + nb * b + b]
        self.phi = self.C[0:m]
        self.Phi = self.C[m:m + m * n].reshape(m, n)
        self.Phi_flat = self.C[m:m + m * n]  # Phi as one row: zeroed in one loop
        rows = max(int(I[MAX_ROWS]), 1)
        self.B = np.zeros(n + 2 * n + n * n + n + n + 4 * rows + 3 * n)
        self.P = np.zeros(max(n, 1), np.int64)
        self.piv = self.P
        views = []
        starts = []
        o = 0
        for shape in ((n,), (2, n), (n, n), (n,), (n,), (rows, 4), (3, n)):
            size = math.prod(shape)
            views.append(self.B[o:o + size].reshape(shape))
            starts.append(o)
            o += size
        self.x, self.trig, self.A, self.rhs, self.norms, self.rows, self.kin = views
        self.K = views[6][1]
        self.L = views[6][2]
        self.b = self.B
        # where rhs, K and L start in B: what _lu_solve solves in place
        self.rhs_at, self.K_at, self.L_at = starts[3], starts[6] + n, starts[6] + 2 * n

    # -- small dense linear algebra (n ≲ 50: no LAPACK call overhead) --------------------------

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _lu_factor(self) -> cython.double:
        """LU with partial pivoting of A (n, n) in place, pivots into piv, U's diagonal stored
        as its reciprocals (a solve then multiplies: its divisions were most of its latency);
        returns det A (0.0 if singular; |det A| on a redundant loop's basis, :meth:`_basis`).
        At n = 3 by :meth:`_lu_factor3`, the same arithmetic unrolled."""
        if self.n == 3:
            return self._lu_factor3()
        return self._lu_factor_general()

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _lu_factor_general(self) -> cython.double:
        """:meth:`_lu_factor` at any n."""
        n: cython.Py_ssize_t = self.n
        k: cython.Py_ssize_t
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        p: cython.Py_ssize_t
        det: cython.double = 1.0
        big: cython.double
        d: cython.double
        inverse: cython.double
        f: cython.double
        swap: cython.double
        for k in range(n):
            p = k
            big = fabs(self.A[k, k])
            for r in range(k + 1, n):
                if fabs(self.A[r, k]) > big:
                    big = fabs(self.A[r, k])
                    p = r
            self.piv[k] = p
            if big == 0.0:
                return 0.0
            if p != k:
                det = -det
                for c in range(n):
                    swap = self.A[k, c]
                    self.A[k, c] = self.A[p, c]
                    self.A[p, c] = swap
            d = self.A[k, k]
            det *= d
            inverse = 1.0 / d
            self.A[k, k] = inverse
            for r in range(k + 1, n):
                f = self.A[r, k] * inverse
                self.A[r, k] = f
                for c in range(k + 1, n):
                    self.A[r, c] -= f * self.A[k, c]
        if self.adaptive:  # a redundant loop's basis has no orientation of its own: only |det A| means something
            return fabs(det)
        return det

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _lu_factor3(self) -> cython.double:
        """:meth:`_lu_factor` of a 3 × 3 A (a four-bar's, a slider-crank's: most linkages), its
        entries held in locals: the same operations in the same order (the same pivots, factors
        and det to the bit), without the loops' and the views' bookkeeping, which were most of
        the general one's instructions at n = 3."""
        a00: cython.double = self.A[0, 0]
        a01: cython.double = self.A[0, 1]
        a02: cython.double = self.A[0, 2]
        a10: cython.double = self.A[1, 0]
        a11: cython.double = self.A[1, 1]
        a12: cython.double = self.A[1, 2]
        a20: cython.double = self.A[2, 0]
        a21: cython.double = self.A[2, 1]
        a22: cython.double = self.A[2, 2]
        det: cython.double = 1.0
        big: cython.double
        inverse: cython.double
        f: cython.double
        p: cython.Py_ssize_t = 0
        singular: cython.bint = False
        # column 0: the pivot, the rows swapped, the multipliers and the update of rows 1, 2
        big = fabs(a00)
        if fabs(a10) > big:
            big = fabs(a10)
            p = 1
        if fabs(a20) > big:
            big = fabs(a20)
            p = 2
        self.piv[0] = p
        if big == 0.0:
            singular = True
        else:
            if p == 1:
                det = -det
                a00, a01, a02, a10, a11, a12 = a10, a11, a12, a00, a01, a02
            elif p == 2:
                det = -det
                a00, a01, a02, a20, a21, a22 = a20, a21, a22, a00, a01, a02
            det *= a00
            inverse = 1.0 / a00
            a00 = inverse
            f = a10 * inverse
            a10 = f
            a11 -= f * a01
            a12 -= f * a02
            f = a20 * inverse
            a20 = f
            a21 -= f * a01
            a22 -= f * a02
            # column 1
            p = 1
            big = fabs(a11)
            if fabs(a21) > big:
                big = fabs(a21)
                p = 2
            self.piv[1] = p
            if big == 0.0:
                singular = True
            else:
                if p == 2:
                    det = -det
                    a10, a11, a12, a20, a21, a22 = a20, a21, a22, a10, a11, a12
                det *= a11
                inverse = 1.0 / a11
                a11 = inverse
                f = a21 * inverse
                a21 = f
                a22 -= f * a12
                # column 2
                self.piv[2] = 2
                if fabs(a22) == 0.0:
                    singular = True
                else:
                    det *= a22
                    a22 = 1.0 / a22
        self.A[0, 0] = a00
        self.A[0, 1] = a01
        self.A[0, 2] = a02
        self.A[1, 0] = a10
        self.A[1, 1] = a11
        self.A[1, 2] = a12
        self.A[2, 0] = a20
        self.A[2, 1] = a21
        self.A[2, 2] = a22
        if singular:
            return 0.0
        if self.adaptive:
            return fabs(det)
        return det

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _lu_solve(self, at: cython.Py_ssize_t) -> cython.int:
        """Solve with :meth:`_lu_factor`'s factors; b = B[at:at + n] (rhs, K or L: rhs_at, K_at,
        L_at) is overwritten by the solution. (An offset, not a view: a view argument is a
        struct of 26 words copied at every call.) At n = 3 by :meth:`_lu_solve3`."""
        if self.n == 3:
            return self._lu_solve3(at)
        return self._lu_solve_general(at)

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _lu_solve_general(self, at: cython.Py_ssize_t) -> cython.int:
        """:meth:`_lu_solve` at any n."""
        n: cython.Py_ssize_t = self.n
        k: cython.Py_ssize_t
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        p: cython.Py_ssize_t
        s: cython.double
        for k in range(n):
            p = self.piv[k]
            if p != k:
                s = self.b[at + k]
                self.b[at + k] = self.b[at + p]
                self.b[at + p] = s
        for r in range(n):
            s = self.b[at + r]
            for c in range(r):
                s -= self.A[r, c] * self.b[at + c]
            self.b[at + r] = s
        for r in range(n - 1, -1, -1):
            s = self.b[at + r]
            for c in range(r + 1, n):
                s -= self.A[r, c] * self.b[at + c]
            self.b[at + r] = s * self.A[r, r]
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _lu_solve3(self, at: cython.Py_ssize_t) -> cython.int:
        """:meth:`_lu_solve` with the factors of :meth:`_lu_factor3` (n = 3), b in locals: the
        same operations in the same order."""
        b0: cython.double = self.b[at]
        b1: cython.double = self.b[at + 1]
        b2: cython.double = self.b[at + 2]
        p: cython.Py_ssize_t = self.piv[0]
        if p == 1:
            b0, b1 = b1, b0
        elif p == 2:
            b0, b2 = b2, b0
        if self.piv[1] == 2:
            b1, b2 = b2, b1
        b1 = b1 - self.A[1, 0] * b0
        b2 = (b2 - self.A[2, 0] * b0) - self.A[2, 1] * b1
        b2 = b2 * self.A[2, 2]
        b1 = (b1 - self.A[1, 2] * b2) * self.A[1, 1]
        b0 = ((b0 - self.A[0, 1] * b1) - self.A[0, 2] * b2) * self.A[0, 0]
        self.b[at] = b0
        self.b[at + 1] = b1
        self.b[at + 2] = b2
        return 0

    # -- term tables -----------------------------------------------------------------------

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _angle_trig(self) -> cython.int:
        """cos and sin of every body angle of Newton's x[:n_angles] into trig (2, n)."""
        j: cython.Py_ssize_t
        for j in range(self.I[N_ANGLES]):
            self.trig[0, j] = cos(self.x[j])
            self.trig[1, j] = sin(self.x[j])
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _table_positions(self, table: cython.Py_ssize_t) -> cython.int:
        """r of every row of a table at kin's x into rows[:, 0:2] (m), leaving columns 2, 3 alone."""
        return self._table_points(table, False)

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _table_points(self, table: cython.Py_ssize_t, with_rates: cython.bint) -> cython.int:
        """:meth:`_table_positions`, and with ``with_rates`` K_r into rows[:, 2:4] in the same walk
        of the table, each as :meth:`_table_rates` computes it into rows[:, 0:2] (the same
        numbers): a chart's line elements read both of their ends, walked once rather than twice."""
        tb: cython.Py_ssize_t = TABLES + TABLE_ENTRIES * table
        off: cython.Py_ssize_t = self.I[tb + 2]
        w_at: cython.Py_ssize_t = self.I[tb + 3]
        rows_at: cython.Py_ssize_t = self.I[tb + 4]
        mags_at: cython.Py_ssize_t = self.I[tb + 5]
        angles_at: cython.Py_ssize_t = self.I[tb + 6]
        k: cython.Py_ssize_t
        t: cython.Py_ssize_t
        g: cython.Py_ssize_t
        a: cython.Py_ssize_t
        wx: cython.double
        wy: cython.double
        c: cython.double
        s: cython.double
        m: cython.double
        md: cython.double
        td: cython.double
        for k in range(self.I[tb]):
            self.rows[k, 0] = self.F[off + 2 * k]
            self.rows[k, 1] = self.F[off + 2 * k + 1]
            if with_rates:
                self.rows[k, 2] = 0.0
                self.rows[k, 3] = 0.0
        for t in range(self.I[tb + 1]):  # term t: m u, u = R(θ) w (module docstring)
            k = self.I[rows_at + t]
            g = self.I[mags_at + t]
            a = self.I[angles_at + t]
            wx = self.F[w_at + 2 * t]
            wy = self.F[w_at + 2 * t + 1]
            if a >= 0:
                c = self.trig[0, a]
                s = self.trig[1, a]
                wx, wy = wx * c - wy * s, wx * s + wy * c
            m = self.kin[0, g] if g >= 0 else 1.0
            self.rows[k, 0] += m * wx
            self.rows[k, 1] += m * wy
            if with_rates:  # K_r = ṁ u + m θ̇ u⊥ (module docstring)
                md = self.kin[1, g] if g >= 0 else 0.0
                td = self.kin[1, a] if a >= 0 else 0.0
                self.rows[k, 2] += md * wx - m * td * wy
                self.rows[k, 3] += md * wy + m * td * wx
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _table_rates(self, table: cython.Py_ssize_t, with_l: cython.bint) -> cython.int:
        """K_r into rows[:, 0:2] and L_r into rows[:, 2:4] (γ, the part without L, unless
        with_l), at kin's x, K and L."""
        tb: cython.Py_ssize_t = TABLES + TABLE_ENTRIES * table
        w_at: cython.Py_ssize_t = self.I[tb + 3]
        rows_at: cython.Py_ssize_t = self.I[tb + 4]
        mags_at: cython.Py_ssize_t = self.I[tb + 5]
        angles_at: cython.Py_ssize_t = self.I[tb + 6]
        k: cython.Py_ssize_t
        c: cython.Py_ssize_t
        t: cython.Py_ssize_t
        g: cython.Py_ssize_t
        a: cython.Py_ssize_t
        m: cython.double
        ux: cython.double
        uy: cython.double
        md: cython.double
        td: cython.double
        cu: cython.double
        cn: cython.double
        cs: cython.double
        sn: cython.double
        for k in range(self.I[tb]):
            for c in range(4):
                self.rows[k, c] = 0.0
        for t in range(self.I[tb + 1]):  # term t: m u, u = R(θ) w (module docstring)
            k = self.I[rows_at + t]
            g = self.I[mags_at + t]
            a = self.I[angles_at + t]
            ux = self.F[w_at + 2 * t]
            uy = self.F[w_at + 2 * t + 1]
            if a >= 0:
                cs = self.trig[0, a]
                sn = self.trig[1, a]
                ux, uy = ux * cs - uy * sn, ux * sn + uy * cs
            m = self.kin[0, g] if g >= 0 else 1.0
            md = self.kin[1, g] if g >= 0 else 0.0
            td = self.kin[1, a] if a >= 0 else 0.0
            cu = 2.0 * md * td  # coefficient of u⊥ in L_r
            cn = -m * td * td  # coefficient of u
            if with_l:
                if g >= 0:
                    cn += self.kin[2, g]
                if a >= 0:
                    cu += m * self.kin[2, a]
            self.rows[k, 0] += md * ux - m * td * uy
            self.rows[k, 1] += md * uy + m * td * ux
            self.rows[k, 2] += cn * ux - cu * uy
            self.rows[k, 3] += cn * uy + cu * ux
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _poly(self, lin: cython.Py_ssize_t, newton: cython.bint) -> cython.double:
        """The polynomial of the linear row at F[lin] (module docstring) at s = r_x·x − x_ref, x
        Newton's (``newton``) or kin's: p(s), p'(s), p''(s) into poly_p, poly_dp, poly_ddp, and
        r_x·K (kin's K) into poly_rate; returns s."""
        n: cython.Py_ssize_t = self.n
        c: cython.Py_ssize_t
        s: cython.double = 0.0
        rate: cython.double = 0.0
        for c in range(n):
            s += self.F[lin + n + c] * (self.x[c] if newton else self.kin[0, c])
            rate += self.F[lin + n + c] * self.kin[1, c]
        s -= self.F[lin + 2 * n]
        a0: cython.double = self.F[lin + 2 * n + 2]
        a1: cython.double = self.F[lin + 2 * n + 3]
        a2: cython.double = self.F[lin + 2 * n + 4]
        a3: cython.double = self.F[lin + 2 * n + 5]
        a4: cython.double = self.F[lin + 2 * n + 6]
        self.poly_p = a0 + s * (a1 + s * (a2 + s * (a3 + s * a4)))
        self.poly_dp = a1 + s * (2.0 * a2 + s * (3.0 * a3 + s * 4.0 * a4))
        self.poly_ddp = 2.0 * a2 + s * (6.0 * a3 + s * 12.0 * a4)
        self.poly_rate = rate
        return s

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _constraints(self) -> cython.double:
        """Φ(x) into phi (m,) and Φ_x into Phi (m, n) (loop rows, then the linear rows), and their
        selected rows (select) into rhs[:n−1] and A[:n−1, :], x Newton's. Returns the sum of the magnitudes of Φ's terms (m or rad), its round-off
        scale, and leaves in spread Σ |m w| |θ| over the turning terms (m·rad): the scale of
        the rounding of their angles."""
        n: cython.Py_ssize_t = self.n
        tb: cython.Py_ssize_t = TABLES + TABLE_ENTRIES * LOOPS
        nl: cython.Py_ssize_t = 2 * self.I[tb]
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        t: cython.Py_ssize_t
        k: cython.Py_ssize_t
        g: cython.Py_ssize_t
        a: cython.Py_ssize_t
        m: cython.double
        ux: cython.double
        uy: cython.double
        lever: cython.double
        v: cython.double
        for r in range(self.m * n):
            self.Phi_flat[r] = 0.0
        off: cython.Py_ssize_t = self.I[tb + 2]
        w_at: cython.Py_ssize_t = self.I[tb + 3]
        rows_at: cython.Py_ssize_t = self.I[tb + 4]
        mags_at: cython.Py_ssize_t = self.I[tb + 5]
        angles_at: cython.Py_ssize_t = self.I[tb + 6]
        cs: cython.double
        sn: cython.double
        scale: cython.double = 0.0
        spread: cython.double = 0.0
        for r in range(nl):
            self.phi[r] = self.F[off + r]
            scale += fabs(self.F[off + r])
        for t in range(self.I[tb + 1]):  # term t: m u, u = R(θ) w (module docstring), m and θ of Newton's x
            k = self.I[rows_at + t]
            g = self.I[mags_at + t]
            a = self.I[angles_at + t]
            ux = self.F[w_at + 2 * t]
            uy = self.F[w_at + 2 * t + 1]
            if a >= 0:
                cs = self.trig[0, a]
                sn = self.trig[1, a]
                ux, uy = ux * cs - uy * sn, ux * sn + uy * cs
            m = self.x[g] if g >= 0 else 1.0
            self.phi[2 * k] += m * ux
            self.phi[2 * k + 1] += m * uy
            lever = fabs(m) * (fabs(ux) + fabs(uy))
            scale += lever
            if a >= 0:
                self.Phi[2 * k, a] -= m * uy
                self.Phi[2 * k + 1, a] += m * ux
                spread += lever * fabs(self.x[a])
            if g >= 0:
                self.Phi[2 * k, g] += ux
                self.Phi[2 * k + 1, g] += uy
        lin: cython.Py_ssize_t
        s: cython.double
        for r in range(self.I[N_LINEAR]):
            # Φ_c = (r_y·x − y_ref) − p(s), s = r_x·x − x_ref (module docstring)
            lin = self.I[LINEAR] + r * (2 * n + ROW_EXTRA)
            s = self._poly(lin, True)
            v = -self.F[lin + 2 * n + 1] - self.poly_p
            scale += fabs(self.F[lin + 2 * n + 1]) + fabs(self.poly_p)
            for c in range(n):
                self.Phi[nl + r, c] = self.F[lin + c] - self.poly_dp * self.F[lin + n + c]
                v += self.F[lin + c] * self.x[c]
                scale += fabs(self.F[lin + c] * self.x[c])
            self.phi[nl + r] = v
        if self.adaptive:  # a redundant loop: the orthonormal basis of Φ_x's rows
            self._basis()
            self.spread = spread
            return scale
        for r in range(n - 1):  # the independent rows (select)
            if r < self.sel.shape[0]:
                k = self.sel[r]
                self.rhs[r] = self.phi[k]
                for c in range(n):
                    self.A[r, c] = self.Phi[k, c]
            else:
                for c in range(n):
                    self.A[r, c] = 0.0
        self.spread = spread
        return scale

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _basis(self) -> cython.int:
        """A redundant loop's rows (:meth:`_constraints`): into A[:n−1] an orthonormal basis of the
        rows of Φ_x by modified Gram-Schmidt, the largest remaining row first, and into rhs[:n−1]
        and T the same combinations of Φ (T: of γ in :meth:`_finish`). A row left below BASIS_RTOL ×
        the first row's norm is not normalized (noise): its A row and rhs are 0, det A is 0 there."""
        n: cython.Py_ssize_t = self.n
        m: cython.Py_ssize_t = self.m
        r: cython.Py_ssize_t
        k: cython.Py_ssize_t
        c: cython.Py_ssize_t
        best: cython.Py_ssize_t
        v: cython.double
        big: cython.double
        first: cython.double = 0.0
        inverse: cython.double
        for k in range(m):
            self.used[k] = 0.0
            for c in range(n):
                self.W[k, c] = self.Phi[k, c]
            for c in range(m):
                self.E[k, c] = 0.0
            self.E[k, k] = 1.0
        for r in range(n - 1):
            best = -1
            big = 0.0
            for k in range(m):
                if self.used[k] == 0.0:
                    v = 0.0
                    for c in range(n):
                        v += self.W[k, c] * self.W[k, c]
                    if v > big:
                        big = v
                        best = k
            if r == 0:
                first = big
            if best < 0 or not big > _c_basis_rtol * _c_basis_rtol * first:
                for c in range(n):
                    self.A[r, c] = 0.0
                for c in range(m):
                    self.T[r, c] = 0.0
                self.rhs[r] = 0.0
                continue
            self.used[best] = 1.0
            inverse = 1.0 / sqrt(big)
            for c in range(n):
                self.W[best, c] *= inverse
                self.A[r, c] = self.W[best, c]
            v = 0.0
            for c in range(m):
                self.E[best, c] *= inverse
                self.T[r, c] = self.E[best, c]
                v += self.E[best, c] * self.phi[c]
            self.rhs[r] = v
            for k in range(m):
                if self.used[k] == 0.0:
                    v = 0.0
                    for c in range(n):
                        v += self.W[k, c] * self.W[best, c]
                    for c in range(n):
                        self.W[k, c] -= v * self.W[best, c]
                    for c in range(m):
                        self.E[k, c] -= v * self.E[best, c]
        return 0

    # -- one configuration ------------------------------------------------------------------

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _factor_row(self, row: cython.double[::1]) -> cython.double:
        """A = [Φ_x; row] factored, Φ_x the constraints' (:meth:`_constraints`) at Newton's x;
        returns det A and leaves it in det, and in hadamard the denominator of the conditioning
        of p = row·x, |row_i| Π_{l≠i} ‖column l of the dependent Jacobian‖ (module docstring),
        and the column norms of Φ_x in norms."""
        n: cython.Py_ssize_t = self.n
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        v: cython.double
        w: cython.double
        ratio: cython.double
        i: cython.Py_ssize_t = 0  # the coordinate p replaces: the row's largest |entry|, the first of equals
        for c in range(1, n):
            if fabs(row[c]) > fabs(row[i]):
                i = c
        hadamard: cython.double = fabs(row[i])
        for c in range(n):
            v = 0.0
            for r in range(n - 1):
                v += self.A[r, c] * self.A[r, c]
            self.norms[c] = sqrt(v)
            if c != i:
                ratio = row[c] / row[i] if row[i] != 0.0 else 0.0
                v = 0.0
                for r in range(n - 1):
                    w = self.A[r, c] - ratio * self.A[r, i]
                    v += w * w
                hadamard *= sqrt(v)
        for c in range(n):
            self.A[n - 1, c] = row[c]
        self.hadamard = hadamard
        self.det = self._lu_factor()
        return self.det

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _finish(self, det: cython.double, i: cython.Py_ssize_t) -> cython.int:
        """x (Newton's), K and L into kin (3, n) from the factors of A (at x, or round-off from
        it) whose determinant is det; the conditioning of every coordinate from the column norms:
        of coordinate i (−1: none) into own, the best and its coordinate into best, best_j."""
        n: cython.Py_ssize_t = self.n
        j: cython.Py_ssize_t
        k: cython.Py_ssize_t
        for j in range(n):
            self.kin[0, j] = self.x[j]
        for j in range(n):
            self.K[j] = 0.0
        self.K[n - 1] = 1.0
        self._lu_solve(self.K_at)
        self._table_rates(LOOPS, False)
        nl: cython.Py_ssize_t = self.I[TABLES + TABLE_ENTRIES * LOOPS]
        for k in range(nl):
            self.phi[2 * k] = -self.rows[k, 2]
            self.phi[2 * k + 1] = -self.rows[k, 3]
        for j in range(2 * nl, self.m):  # the linear rows: −γ_c = p''(s) (r_x·K)²
            self._poly(self.I[LINEAR] + (j - 2 * nl) * (2 * n + ROW_EXTRA), False)
            self.phi[j] = self.poly_ddp * self.poly_rate * self.poly_rate
        v: cython.double
        if self.adaptive:  # γ in the basis' combinations
            for j in range(n):
                v = 0.0
                if j < n - 1:
                    for k in range(self.m):
                        v += self.T[j, k] * self.phi[k]
                self.L[j] = v
        else:
            for j in range(n):
                self.L[j] = self.phi[self.sel[j]] if j < self.sel.shape[0] else 0.0
        self._lu_solve(self.L_at)
        # conditioning of every coordinate: c_j = |K_j| |det A| / Π_{l≠j} ‖col_l‖
        product: cython.double = 1.0
        zeros: cython.Py_ssize_t = 0
        for j in range(n):
            if self.norms[j] > 0.0:
                product *= self.norms[j]
            else:
                zeros += 1
        best: cython.double = 0.0
        best_j: cython.Py_ssize_t = 0
        own: cython.double = 0.0
        c: cython.double
        for j in range(n):
            c = self._cramer_ratio(j, det, product, zeros)
            if j == i:
                own = c
            if c > best:
                best = c
                best_j = j
        self.own = own
        self.best = best
        self.best_j = best_j
        return 0

    @cython.cfunc
    @cython.inline
    @cython.exceptval(-1, check=True)
    def _cramer_ratio(self, j: cython.Py_ssize_t, det: cython.double, product: cython.double,
                         zeros: cython.Py_ssize_t) -> cython.double:
        """c_j = |K_j| |det A| / Π_{l≠j} ‖col_l‖ (K solved), product the product of the nonzero
        column norms and zeros the count of zero columns."""
        if zeros > 1 or (zeros == 1 and self.norms[j] > 0.0):
            return 0.0
        return fabs(self.K[j]) * fabs(det) / (product / self.norms[j] if self.norms[j] > 0.0 else product)

    # -- the Python interface (loopcheck.kinematics) ---------------------------------------------

    def _load(self, x) -> None:
        """x (n,) into Newton's x and kin's, and the cos and sin of its angles into trig."""
        if len(x) != self.n:
            raise ValueError(f"x of {self.n} coordinates, not {len(x)}")
        for j in range(self.n):
            self.x[j] = x[j]
            self.kin[0, j] = x[j]
        self._angle_trig()

    def _rows_of(self, table: int) -> np.ndarray:
        """A copy of the rows scratch's rows of table ``table``, shape (rows, 4)."""
        return np.array(np.asarray(self.rows)[:self.I[TABLES + TABLE_ENTRIES * table]])

    def positions(self, table: int, x) -> np.ndarray:
        """r(x) of every row of table ``table``, shape (rows, 2) (m)."""
        self._load(x)
        self._table_positions(table)
        return self._rows_of(table)[:, 0:2]

    def rates(self, table: int, x, K, L) -> np.ndarray:
        """K_r and L_r of every row of table ``table`` at x, K (and L), shape (rows, 4): K_r's x,
        y, then L_r's (γ, the part without L, where L is None)."""
        self._load(x)
        for j in range(self.n):
            self.kin[1, j] = K[j]
            self.kin[2, j] = L[j] if L is not None else 0.0
        self._table_rates(table, L is not None)
        return self._rows_of(table)

    def constraints(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Φ(x) (n − 1,) and Φ_x (n − 1, n)."""
        n = self.n
        self._load(x)
        self._constraints()
        return np.array(np.asarray(self.rhs)[:n - 1]), np.array(np.asarray(self.A)[:n - 1])

    def all_constraints(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Φ(x) (m,) and Φ_x (m, n) of every constraint row, the dependent ones too (a redundant
        loop's dependent rows must stay satisfied along the motion)."""
        self._load(x)
        self._constraints()
        return np.array(self.phi), np.array(self.Phi)

    def jacobians(self, X: cython.double[:, ::1]) -> np.ndarray:
        """Φ_x at each row of X (samples, n), C-contiguous: shape (samples, n − 1, n). A loop in C
        over the samples (the reduced engine asks for the assembly modes of every output sample)."""
        n: cython.Py_ssize_t = self.n
        s: cython.Py_ssize_t
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        if X.shape[1] != n:
            raise ValueError(f"x of {n} coordinates, not {X.shape[1]}")
        out = np.empty((X.shape[0], n - 1, n))
        J: cython.double[:, :, ::1] = out
        for s in range(X.shape[0]):
            for j in range(n):
                self.x[j] = X[s, j]
                self.kin[0, j] = X[s, j]
            self._angle_trig()
            self._constraints()
            for r in range(n - 1):
                for j in range(n):
                    J[s, r, j] = self.A[r, j]
        return out

    def driving_conditioning(self, x, row) -> float:
        """The conditioning of p = row·x at x (module docstring): between 0 (A = [Φ_x; row]
        singular) and 1 (orthogonal columns)."""
        self._load(x)
        self._constraints()
        det = self._factor_row(np.ascontiguousarray(row, dtype=np.float64))
        if det == 0.0 or not isfinite(det) or not self.hadamard > 0.0:
            return 0.0
        return fabs(det) / self.hadamard

    def coefficients(self, x, row) -> tuple[float, np.ndarray, np.ndarray]:
        """The conditioning of p = row·x, and K = dx/dp, L = d²x/dp² (n,) at an assembled x;
        K and L are NaN where A = [Φ_x; row] is singular (conditioning 0)."""
        c = self.driving_conditioning(x, row)
        if c == 0.0:
            return 0.0, np.full(self.n, math.nan), np.full(self.n, math.nan)
        self._finish(self.det, -1)
        return c, np.array(self.K), np.array(self.L)

    def conditioning(self, x) -> np.ndarray:
        """The conditioning of each coordinate x_j as the independent one, shape (n,)."""
        row = np.zeros(self.n)
        out = np.empty(self.n)
        for j in range(self.n):
            row[:] = 0.0
            row[j] = 1.0
            out[j] = self.driving_conditioning(x, row)
        return out

    def assemble(self, q: float, x, row, tol: float, max_iter: int, singular: float) -> tuple[int, int, float]:
        """Newton's method on (Φ(x), row·x − q) = 0 from x (n,), overwritten with the result:
        converged when every residual is ≤ tol (m or rad), then one more step to round-off.
        Returns (status, iteration, largest residual): CLOSED; NON_FINITE (a residual not finite
        at that iteration); SINGULAR_JACOBIAN (the conditioning of p = row·x below ``singular``
        before convergence); NOT_CLOSED (no convergence in ``max_iter`` iterations)."""
        n = self.n
        drive = np.ascontiguousarray(row, dtype=np.float64)
        self._load(x)
        polished = False
        for iteration in range(1, max_iter + 1):
            largest = self._residual(q, drive)
            if not isfinite(largest):
                return NON_FINITE, iteration, largest
            if polished:
                break
            converged = largest <= tol
            det = self._factor_row(drive)
            self.rhs[n - 1] = self._drive_residual(q, drive)
            if det == 0.0 or not isfinite(det) or fabs(det) < singular * self.hadamard:
                if converged:
                    break
                return SINGULAR_JACOBIAN, iteration, largest
            self._lu_solve(self.rhs_at)
            for j in range(n):
                self.x[j] -= self.rhs[j]
            self._angle_trig()
            polished = converged
        else:
            return NOT_CLOSED, max_iter, self._residual(q, drive)
        for j in range(n):
            x[j] = self.x[j]
        return CLOSED, iteration, largest

    def _drive_residual(self, q: float, row) -> float:
        """row·x − q at Newton's x."""
        v = 0.0
        for j in range(self.n):
            v += row[j] * self.x[j]
        return v - q

    def _residual(self, q: float, row) -> float:
        """The largest |residual| of (Φ(x), row·x − q) at Newton's x, NaN if one is not finite;
        Φ and Φ_x into rhs[:n−1] and A[:n−1]."""
        self._constraints()
        largest = abs(self._drive_residual(q, row))
        if not isfinite(largest):
            return math.nan
        for r in range(self.n - 1):
            if not isfinite(self.rhs[r]):
                return math.nan
            largest = max(largest, fabs(self.rhs[r]))
        return largest
