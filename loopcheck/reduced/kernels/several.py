"""Eksergian's reduction in k ≥ 1 independent coordinates (a linkage of several DOF), compiled (Cython).

The n-DOF chart of the reduced engine, on the same packed model arrays as the one-DOF chart
(:func:`loopcheck.reduced.dynamics.build_arrays`, layout in :mod:`.physics`) and the same loop
kinematics (:class:`loopcheck.kernels.loops.Loops`: term tables, Φ, Φ_x, the dense LU). Debug with
``LOOPCHECK_PURE_PYTHON=1``: this file then runs as plain Python.

Coordinates. A chart holds k independent coordinates q = R x, R (k, n) rows of the joints' own
coordinates (``system.joint_rows``: relative angles, slide displacements). With the m = n − k
constraint rows Φ(x) = 0, A = [Φ_x; R] is square. A redundantly closed loop has more rows than
n − k: the chart then runs on n − k of them, ``select`` (the independent rows at the assembled
start, :func:`loopcheck.kinematics.independent_rows`; the run checks that the others stay closed),
Φ, Φ_x and γ below meaning the selected rows.

Configuration at q: Newton's method on (Φ(x), R x − q) = 0 from the quadratic predictor
x_last + K_last Δ + ½ ẍ0(K_last Δ), Δ = q − q_last, of the chart's last configuration (ẍ0 below:
one solve with the last factors; the one-DOF chart's x + K Δ + ½ L Δ²); converged when
every residual is ≤ NEWTON_TOL (or the round-off floor NEWTON_ROUND_OFF × Σ |m w| |θ|, as
:mod:`.physics`), then the step computed there applied (polish) and A factored once more at the
polished x. A Newton correction larger than PREDICTOR_TRUST × the predicted motion (+
TRUSTED_CORRECTION) or a determinant of the other sign (another assembly branch) fails the
closure, and the jump is walked in 2, 4, … equal parts (at most 2^WALK_HALVINGS).

Velocity coefficients: K = dx/dq (rows K_a, a = 1…k) by k solves with A's factors,
A K_a = (0, e_a). ẋ = Σ_a K_a q̇_a.

Velocity-squared terms by ONE extra solve with the actual rates: ẍ0, the acceleration of every
coordinate at q̈ = 0, solves A ẍ0 = (−γ(ẋ), 0), γ(ẋ) = Σ_t 2 ṁ θ̇ u⊥ − m θ̇² u the loop vectors'
second derivative without ẍ (Loops' table rates with kin = (x, ẋ, 0)), and for a polynomial row
−γ = p''(s) (r_x·ẋ)². Then ẍ = ẍ0 + Σ_a K_a q̈_a, and with a_G0 the centres' acceleration at
(ẋ, ẍ0) (the table rates with kin = (x, ẋ, ẍ0)),

    c_a = Σ_b m_b K_Gb,a·a_Gb0 + I_b K_a[θ_b] ẍ0[θ_b] + Σ_inertias c_u K_u,a (row_u·ẍ0)
    𝔍_ac = Σ_b m_b K_Gb,a·K_Gb,c + I_b K_a[θ_b] K_c[θ_b] + Σ_inertias c_u K_u,a K_u,c
    Q_a = Σ_b m_b g_b·K_Gb,a − Σ_springs k (D − D0) K_D,a − Σ_joint springs k (u − u0) K_u,a
          − Σ_c B_ac q̇_c + Σ_timed F_p(t) e_p·K_P,a + Σ_actuators gear f K_l,a + T(t) drive·K_a
    B_ac = Σ_dampers b K_D,a K_D,c + Σ_joint dampers c K_u,a K_u,c
    (and − Σ_frictions f s K_u,a in Q: a joint friction slipping in direction s = ±1, set by the
    run, :meth:`Several.set_slip`; its margin s u̇ in the stop event, f s u̇ in the dissipation;
    a stuck one, s = 0, holds its coordinate: one more row r_e q̈ = −row_e·ẍ0 and its multiplier
    λ_e in a KKT system, :meth:`Several._stuck_solve`, its margin f − |λ_e| in the stop event; more
    stuck rows than their rank, a statically indeterminate hold: :meth:`Several._indeterminate`,
    the margin max_μ min_e f_e − |λ_p,e + N_e μ| by :meth:`Several._max_margin`)
    (T(t) the input load of a one-DOF scene on its input q = drive·x; several inputs take
    actuators)
    f = clamp(gain·ctrl(t) + b0 + b1·l + b2·l̇, lo, hi)   (l = row·x, l̇ = Σ_a K_l,a q̇_a;
        on a force that depends on the state, a clamp mode per actuator (:mod:`.physics`'s
        CLAMP_FREE: f unclamped, CLAMP_HI: hi, CLAMP_LO: lo; CLAMP_AUTO: by value), switched by the
        run at the stop event's root (:meth:`Several.clamp_margin`, :meth:`Several.set_clamps`))
    𝔍 q̈ = Q − c   (a k×k dense solve, partial pivoting)

(K_G, K_D = dD/dq_a, K_P, K_u = row·K_a, K_l: the velocity coefficients per coordinate.) The
energy: T = ½ q̇ᵀ𝔍q̇, V = −Σ m g·r_G + Σ ½ k (D − D0)² + Σ ½ k (u − u0)², power
P = Σ_a (input load + timed + actuators)_a q̇_a, dissipation D = q̇ᵀ B q̇. At k = 1, c = ζ q̇² of :mod:`.physics`
(ẍ0 = L q̇²): the same equation.

Linear solves per evaluation (a new configuration): one for the predictor, the Newton
factorizations (an LU of A each, all but the last followed by a solve), k solves for K, one for
ẍ0, one k×k solve for q̈; ``counts`` records them (benchmarks/several_dof.py prints them).

Conditioning of a coordinate set S (rows R_S): with Z an orthonormal basis (n − k vectors) of the
motions that hold the set's coordinates, null(R_S), the dependent block's Jacobian is
D_S = Φ_x Zᵀ ((n − k) × (n − k); for S = k of the coordinates x themselves it is Φ_x's columns of
the others, the classical dependent block), and the conditioning is σ_min(D_S) / σ_max(D_S)
(one-sided Jacobi SVD: relative accuracy in the small singular values), 0 where R_S is rank
deficient, 1 without constraints. D_S is singular exactly where A_S = [Φ_x; R_S] is. The best set
is chosen by pivoted QR (greedy Gram-Schmidt with column pivoting) on the joints' rates per unit
motion, M = JR Nᵀ (joints × k), N an orthonormal basis of null(Φ_x) (from K's rows): the k joints
whose rates are the most independent. stop_margin = c_S(current) − HYSTERESIS × c_S(best): the
run switches where it crosses zero.

Compiled: the constants below have C copies (``_c_…``); the arithmetic keeps each expression's
order (the build does not contract a*b+c).
"""

import math

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import fabs, isfinite, sqrt
    from cython.cimports.loopcheck.kernels.loops import LOOPS, N, N_ANGLES, N_LINEAR, LINEAR, ROW_EXTRA, TABLES, \
        TABLE_ENTRIES, Loops
    from cython.cimports.loopcheck.reduced.kernels.physics import (
        ACT_PARAMS, ACT_PIECE, ACT_ROWS, CENTRES, ELEMENT_COEF, ELEMENT_REST, ENDS, FORCE_POINTS, GRAVITY,
        HAS_GRAVITY, INERTIAS, JOINT_COEF, JOINT_REST, JOINT_ROWS, MASSES, N_ACTUATORS, N_DAMPERS, N_ELEMENTS,
        N_FORCES, N_JOINT_DAMPERS, N_JOINT_ELEMENTS, N_JOINT_INERTIAS, N_RANGES, N_TIMED, PIECE_VALUES,
        RANGE_BOUNDS, RANGE_ROWS, TIMED_DIR, DRIVE, N_CLAMPED, CLAMP_FREE, CLAMP_HI, CLAMP_LO, CLAMP_AUTO,
        N_FRICTION, FRICTION_ROWS, FRICTION_COEF)
    from cython.cimports.loopcheck.reduced.kernels.vector_problem import VectorRightHandSide
else:
    from math import fabs, isfinite, sqrt

    from loopcheck.kernels.loops import LOOPS, N, N_ANGLES, N_LINEAR, LINEAR, ROW_EXTRA, TABLES, TABLE_ENTRIES, \
        Loops
    from loopcheck.reduced.kernels.physics import (
        ACT_PARAMS, ACT_PIECE, ACT_ROWS, CENTRES, ELEMENT_COEF, ELEMENT_REST, ENDS, FORCE_POINTS, GRAVITY,
        HAS_GRAVITY, INERTIAS, JOINT_COEF, JOINT_REST, JOINT_ROWS, MASSES, N_ACTUATORS, N_DAMPERS, N_ELEMENTS,
        N_FORCES, N_JOINT_DAMPERS, N_JOINT_ELEMENTS, N_JOINT_INERTIAS, N_RANGES, N_TIMED, PIECE_VALUES,
        RANGE_BOUNDS, RANGE_ROWS, TIMED_DIR, DRIVE, N_CLAMPED, CLAMP_FREE, CLAMP_HI, CLAMP_LO, CLAMP_AUTO,
        N_FRICTION, FRICTION_ROWS, FRICTION_COEF)
    from loopcheck.reduced.kernels.vector_problem import VectorRightHandSide

from loopcheck.reduced.kernels import physics as _physics

NEWTON_TOL = _physics.NEWTON_TOL
NEWTON_MAX_ITER = _physics.NEWTON_MAX_ITER
NEWTON_ROUND_OFF = _physics.NEWTON_ROUND_OFF
PREDICTOR_TRUST = _physics.PREDICTOR_TRUST
TRUSTED_CORRECTION = _physics.TRUSTED_CORRECTION
HYSTERESIS = _physics.HYSTERESIS
# A jump whose closure fails is walked in 2, 4, … equal parts, at most 2^WALK_HALVINGS.
WALK_HALVINGS = 8
# One-sided Jacobi SVD: sweeps at most, and the relative orthogonality at which a pair is left.
JACOBI_SWEEPS = 60
JACOBI_TOL = 1e-15
# The stuck joints' KKT system is singular where a pivot is at most this × max(|𝔍|, |R_S|²/|𝔍|).
STUCK_PIVOT = 1e-12
# A statically indeterminate hold (:meth:`Several._indeterminate`): the stuck rows' rank is the count
# of pivots of G = R_S 𝔍⁻¹ R_Sᵀ above STUCK_RANK × its largest diagonal; the dependent rows'
# right-hand sides must agree to STUCK_CONSISTENT × the largest |g|; at most STUCK_LP stuck rows
# with a null space (the margin's LP enumerates the vertices: C(2s, d + 1) small solves).
STUCK_RANK = 1e-10
STUCK_CONSISTENT = 1e-8
STUCK_LP = 8

_c_newton_tol = cython.declare(cython.double, NEWTON_TOL)
_c_newton_max_iter = cython.declare(cython.Py_ssize_t, NEWTON_MAX_ITER)
_c_newton_round_off = cython.declare(cython.double, NEWTON_ROUND_OFF)
_c_predictor_trust = cython.declare(cython.double, PREDICTOR_TRUST)
_c_trusted_correction = cython.declare(cython.double, TRUSTED_CORRECTION)
_c_hysteresis = cython.declare(cython.double, HYSTERESIS)
_c_clamp_hysteresis = cython.declare(cython.double, _physics.CLAMP_HYSTERESIS)
_c_walk_halvings = cython.declare(cython.Py_ssize_t, WALK_HALVINGS)
_c_jacobi_sweeps = cython.declare(cython.Py_ssize_t, JACOBI_SWEEPS)
_c_jacobi_tol = cython.declare(cython.double, JACOBI_TOL)
_c_nan = cython.declare(cython.double, math.nan)
_c_stuck_pivot = cython.declare(cython.double, STUCK_PIVOT)
_c_stuck_rank = cython.declare(cython.double, STUCK_RANK)
_c_stuck_consistent = cython.declare(cython.double, STUCK_CONSISTENT)
_c_stuck_lp = cython.declare(cython.Py_ssize_t, STUCK_LP)

# counts (Several.counts): LU factorizations of A, solves with them, k×k solves, closures, evaluations
(FACTORS, SOLVES, SMALL_SOLVES, CLOSURES, EVALUATIONS) = range(5)


@cython.final
@cython.cclass
class Several(VectorRightHandSide):
    """The compiled chart of a linkage in k independent joint coordinates (module docstring).

    ``Several(F, I, joint_rows, k, singular, select=None)``: the packed model (F, I), the joints'
    own coordinate rows (joints, n) (the candidates of the partitioning), k the degrees of freedom,
    ``singular`` the conditioning below which no set can drive the linkage (reported; the run
    decides), ``select`` the n − k constraint rows to run on (a redundant loop's independent
    rows; None: every row, which must then be n − k).
    :meth:`start` makes it a chart of one set of joints at an assembled x.

    A :class:`.vector_problem.VectorRightHandSide`: the compiled n-coordinate integrators
    (:mod:`.vector_adaptive`, :mod:`.vector_fixed_step`) call its methods through its table of C
    function pointers, without Python: ``dimension()`` (k), ``acceleration(load, t, q, v, a) ->
    int`` (0, or 1 where the configuration could not be found: a holds NaN), ``power(load, v)``,
    ``dissipation(v)``, ``stop_margin(t, q, v)`` (> 0 while the set serves and every ranged joint
    is inside its range), ``locate`` (a range's bound is located at its root, a switch is not),
    ``observation_size()`` and ``observe(out, row)`` (x, ẋ, ẍ, V, T at the latest acceleration),
    ``mark()``, ``rewind()``.
    """

    def __init__(self, F, I, joint_rows, k: int, singular: float, select=None):
        F = np.ascontiguousarray(F, dtype=np.float64)
        I = np.ascontiguousarray(I, dtype=np.int64)
        self.F = F
        self.I = I
        self.arrays = (F, I)
        n = int(I[N])
        self.n = n
        self.k = int(k)
        if not 1 <= self.k <= n:
            raise ValueError(f"Several: k = {k} degrees of freedom of {n} coordinates")
        m_all = 2 * int(I[TABLES + TABLE_ENTRIES * LOOPS]) + int(I[N_LINEAR])
        # Loops on n − 1 of its rows (never its adaptive basis: this chart reads Φ and Φ_x whole)
        self.loops = Loops(F, I, np.arange(n - 1, dtype=np.int64) if m_all > n - 1 else None)
        m_all = self.loops.m
        if select is None:
            if m_all != n - self.k:
                raise ValueError(f"Several: {m_all} constraint rows for {n} coordinates and {k} degrees of freedom "
                                 f"(a redundant loop or a wrong count): n − k = {n - self.k} rows are needed, "
                                 "or a selection of them")
            select = np.arange(m_all, dtype=np.int64)
        select = np.asarray(select, dtype=np.int64).reshape(-1)
        if len(select) != n - self.k or (len(select) and (np.min(select) < 0 or np.max(select) >= m_all
                                                          or len(np.unique(select)) != len(select))):
            raise ValueError(f"Several: select must be n − k = {n - self.k} distinct rows of the {m_all} constraint "
                             f"rows, got {select.tolist()}")
        self.sel = np.ascontiguousarray(select)
        self.gam = np.zeros(max(m_all, 1))
        m = n - self.k
        self.mr = m
        self.singular = singular
        JR = np.ascontiguousarray(joint_rows, dtype=np.float64).reshape(-1, n)
        self.JR = JR
        self.nj = JR.shape[0]
        kk = self.k
        nb = int(I[N_ANGLES])
        na = int(I[N_ACTUATORS])
        nt = int(I[N_TIMED])
        ne = int(I[N_ELEMENTS])
        nje = int(I[N_JOINT_ELEMENTS])
        self.R = np.zeros((kk, n))
        self.Rmark = np.zeros((kk, n))
        self.K = np.zeros((kk, n))
        self.KG = np.zeros((kk, max(nb, 1), 2))
        self.Jm = np.zeros((kk, kk))
        self.Bm = np.zeros((kk, kk))
        self.Qp = np.zeros(kk)
        self.drive_rate = np.zeros(kk)
        self.Qa = np.zeros(kk)
        self.cv = np.zeros(kk)
        self.qdd = np.zeros(kk)
        self.qv = np.zeros(kk)
        self.rate = np.zeros(kk)
        self.small = np.zeros((kk, kk + 1))
        self.timed = np.zeros((kk, max(nt, 1)))
        self.act_l = np.zeros(max(na, 1))
        # each actuator's clamp mode (physics' CLAMP_FREE, CLAMP_HI, CLAMP_LO, CLAMP_AUTO: set_clamps)
        self.clampm = np.full(max(na, 1), float(CLAMP_AUTO))
        # joint friction (slipping only): each one's K_u per coordinate and its direction of slip s = ±1
        # (set by the run: set_slip), its force −f s on its joint's coordinate
        nfr = int(I[N_FRICTION])
        self.fric_k = np.zeros((kk, max(nfr, 1)))
        self.slip = np.ones(max(nfr, 1))
        # a stuck joint (slip 0): its holding force λ (the KKT system's multiplier, latest acceleration)
        self.lam = np.zeros(max(nfr, 1))
        self.kkt = np.zeros((kk + nfr, kk + nfr + 1))
        # a statically indeterminate hold (_indeterminate): [𝔍 | R_Sᵀ | b] solved in place, G = R_S 𝔍⁻¹ R_Sᵀ
        # with g, the stuck joints' indices, G's pivot order, λ_p and N (stuck order), the LP's system
        self.wk = np.zeros((kk, kk + nfr + 1))
        self.G = np.zeros((max(nfr, 1), max(nfr, 1) + 1))
        self.sidx = np.zeros(max(nfr, 1), np.int64)
        self.perm = np.zeros(max(nfr, 1), np.int64)
        self.lamp = np.zeros(max(nfr, 1))
        self.nul = np.zeros((max(nfr, 1), max(nfr, 1)))
        self.lpa = np.zeros((max(nfr, 1) + 1, max(nfr, 1) + 2))
        self.lpx = np.zeros(max(nfr, 1) + 1)
        self.comb = np.zeros(2 * max(nfr, 1), np.int64)
        self.nullity = 0
        self.fresh = True
        self.ksol = np.zeros(kk + nfr)
        self.scratch = np.zeros(kk)
        self.act_k = np.zeros((kk, max(na, 1)))
        self.ku = np.zeros((kk, max(nje, 1)))
        self.kd = np.zeros((kk, max(ne, 1)))
        self.xdot = np.zeros(n)
        self.xdd0 = np.zeros(n)
        self.xdd = np.zeros(n)
        self.LU = np.zeros((n, n))
        self.piv = np.zeros(max(n, 1), np.int64)
        self.Phx = np.zeros((max(m, 1), n))
        self.lastx = np.zeros(n)
        self.lastq = np.zeros(kk)
        self.lastK = np.zeros((kk, n))
        self.basex = np.zeros(n)
        self.baseq = np.zeros(kk)
        self.baseK = np.zeros((kk, n))
        self.startx = np.zeros(n)
        self.startq = np.zeros(kk)
        self.startK = np.zeros((kk, n))
        self.markx = np.zeros(n)
        self.markq = np.zeros(kk)
        self.markK = np.zeros((kk, n))
        self.target = np.zeros(kk)
        self.pred = np.zeros(n)
        self.U = np.zeros((kk, n))
        self.Z = np.zeros((n, n))
        self.D = np.zeros((max(m, 1), max(m, 1)))
        self.resid = np.zeros(n)
        self.M = np.zeros((max(self.nj, 1), kk))
        self.used = np.zeros(max(self.nj, 1))
        self.best = np.zeros(kk, np.int64)
        self.current = np.zeros(kk, np.int64) - 1
        self.counts = np.zeros(5, np.int64)
        self.valid = 0
        self.sign = 0
        self.starting = False
        self.piece = 0
        self.potential = 0.0
        self.c_current = 0.0
        self.c_best = 0.0

    # -- small dense linear algebra ----------------------------------------------------------

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _save_factors(self) -> cython.int:
        """Copy Loops' factors of A (and its pivots) into LU, piv: they serve K and ẍ0."""
        n: cython.Py_ssize_t = self.n
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        for r in range(n):
            self.piv[r] = self.loops.piv[r]
            for c in range(n):
                self.LU[r, c] = self.loops.A[r, c]
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _solve(self, b: cython.double[::1]) -> cython.int:
        """Solve A y = b with the saved factors (Loops._lu_solve's arithmetic: U's diagonal stored
        as reciprocals); b (n,) overwritten."""
        n: cython.Py_ssize_t = self.n
        k: cython.Py_ssize_t
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        p: cython.Py_ssize_t
        s: cython.double
        for k in range(n):
            p = self.piv[k]
            if p != k:
                s = b[k]
                b[k] = b[p]
                b[p] = s
        for r in range(n):
            s = b[r]
            for c in range(r):
                s -= self.LU[r, c] * b[c]
            b[r] = s
        for r in range(n - 1, -1, -1):
            s = b[r]
            for c in range(r + 1, n):
                s -= self.LU[r, c] * b[c]
            b[r] = s * self.LU[r, r]
        self.counts[SOLVES] += 1
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _second_order(self, out: cython.double[::1]) -> cython.int:
        """ẍ0 (n,) into out: A ẍ0 = (−γ(ẋ), 0) with the saved factors, ẋ in Loops' kin[1] and x in its
        kin[0] and trig (kin[2] = 0): the loops' γ from the table rates, a polynomial row's
        −γ_c = p''(s) (r_x·ẋ)²."""
        n: cython.Py_ssize_t = self.n
        mr: cython.Py_ssize_t = self.mr
        nl: cython.Py_ssize_t = 2 * self.I[TABLES + TABLE_ENTRIES * LOOPS]
        nlin: cython.Py_ssize_t = self.I[N_LINEAR]
        j: cython.Py_ssize_t
        self.loops._table_rates(LOOPS, False)
        for j in range(nl // 2):  # every row's −γ into gam, the selected ones into out
            self.gam[2 * j] = -self.loops.rows[j, 2]
            self.gam[2 * j + 1] = -self.loops.rows[j, 3]
        for j in range(nlin):
            self.loops._poly(self.I[LINEAR] + j * (2 * n + ROW_EXTRA), False)
            self.gam[nl + j] = self.loops.poly_ddp * self.loops.poly_rate * self.loops.poly_rate
        for j in range(mr):
            out[j] = self.gam[self.sel[j]]
        for j in range(mr, n):
            out[j] = 0.0
        self._solve(out)
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _eliminate(self, M: cython.double[:, ::1], m: cython.Py_ssize_t, w: cython.Py_ssize_t,
                   tiny: cython.double) -> cython.int:
        """Solve the m × m block of M (m, w) against each of its columns m..w−1 in place: Gaussian
        elimination with partial pivoting, then back substitution, those columns left holding the
        solutions. Returns 1 (M part-way) where a pivot is at most ``tiny`` (0: exactly singular).
        The small dense solves of this chart (:meth:`_small_solve`, :meth:`_stuck_solve`,
        :meth:`_indeterminate`, :meth:`_max_margin`) are this one elimination."""
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        j: cython.Py_ssize_t
        p: cython.Py_ssize_t
        big: cython.double
        f: cython.double
        s: cython.double
        for j in range(m):
            p = j
            big = fabs(M[j, j])
            for r in range(j + 1, m):
                if fabs(M[r, j]) > big:
                    big = fabs(M[r, j])
                    p = r
            if not big > tiny:
                return 1
            if p != j:  # (the columns before j are never read again)
                for c in range(j, w):
                    s = M[j, c]
                    M[j, c] = M[p, c]
                    M[p, c] = s
            for r in range(j + 1, m):
                f = M[r, j] / M[j, j]
                for c in range(j, w):
                    M[r, c] -= f * M[j, c]
        for c in range(m, w):
            for r in range(m - 1, -1, -1):
                s = M[r, c]
                for j in range(r + 1, m):
                    s -= M[r, j] * M[j, c]
                M[r, c] = s / M[r, r]
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _small_solve(self) -> cython.int:
        """q̈ from 𝔍 q̈ = Q − c: :meth:`_eliminate` on small (k, k+1) ([𝔍 | Q − c]); the solution
        into qdd. Returns 1 where 𝔍 is singular."""
        kk: cython.Py_ssize_t = self.k
        r: cython.Py_ssize_t
        self.counts[SMALL_SOLVES] += 1
        if self._eliminate(self.small, kk, kk + 1, 0.0):
            return 1
        for r in range(kk):
            self.qdd[r] = self.small[r, kk]
        return 0

    # -- one configuration ------------------------------------------------------------------

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _stuck_count(self) -> cython.Py_ssize_t:
        """The number of stuck joint frictions (slip 0)."""
        e: cython.Py_ssize_t
        s: cython.Py_ssize_t = 0
        for e in range(self.I[N_FRICTION]):
            if self.slip[e] == 0.0:
                s += 1
        return s

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _row_xdd0(self, e: cython.Py_ssize_t) -> cython.double:
        """row_e·ẍ0: friction e's coordinate's acceleration at q̈ = 0 (its stuck row's right-hand side,
        with the sign turned)."""
        n: cython.Py_ssize_t = self.n
        j: cython.Py_ssize_t
        s: cython.double = 0.0
        for j in range(n):
            s += self.F[self.I[FRICTION_ROWS] + e * n + j] * self.xdd0[j]
        return s

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _stuck_solve(self) -> cython.int:
        """q̈ and the stuck joints' holding forces λ from the KKT system (s stuck joints, rows
        r_e = K_u,e per coordinate):

            [𝔍  −R_Sᵀ] [q̈]   [Q − c      ]
            [R_S   0 ] [λ] = [−row_S·ẍ0  ]

        (ü_e = r_e q̈ + row_e·ẍ0 = 0: each stuck joint's coordinate held; λ_e the generalized
        force its friction applies on u_e), from small ([𝔍 | Q − c]) and fric_k; Gaussian
        elimination with partial pivoting on kkt ((k + s) × (k + s + 1): :meth:`_eliminate`). q̈
        into qdd, λ into lam.
        Where a pivot is at most STUCK_PIVOT × max(|𝔍|, |R_S|²/|𝔍|) (the stuck rows dependent: a
        statically indeterminate hold, or more stuck joints than k) the hold is solved by
        :meth:`_indeterminate` instead. Returns 1 where neither solves it."""
        kk: cython.Py_ssize_t = self.k
        nfr: cython.Py_ssize_t = self.I[N_FRICTION]
        m: cython.Py_ssize_t = kk + self._stuck_count()
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        p: cython.Py_ssize_t
        e: cython.Py_ssize_t
        jmax: cython.double = 0.0
        rmax: cython.double = 0.0
        self.counts[SMALL_SOLVES] += 1
        for r in range(m):
            for c in range(m + 1):
                self.kkt[r, c] = 0.0
        for r in range(kk):
            for c in range(kk):
                self.kkt[r, c] = self.small[r, c]
                jmax = max(jmax, fabs(self.small[r, c]))
            self.kkt[r, m] = self.small[r, kk]
        p = kk
        for e in range(nfr):
            if self.slip[e] != 0.0:
                continue
            for r in range(kk):
                self.kkt[r, p] = -self.fric_k[r, e]
                self.kkt[p, r] = self.fric_k[r, e]
                rmax = max(rmax, fabs(self.fric_k[r, e]))
            self.kkt[p, m] = -self._row_xdd0(e)
            p += 1
        if not jmax > 0.0:
            return 1
        tiny: cython.double = _c_stuck_pivot * max(jmax, rmax * rmax / jmax)
        if self._eliminate(self.kkt, m, m + 1, tiny):  # the stuck rows dependent: a statically indeterminate hold
            return self._indeterminate()
        for r in range(kk):
            self.qdd[r] = self.kkt[r, m]
        p = kk
        for e in range(nfr):
            if self.slip[e] == 0.0:
                self.lam[e] = self.kkt[p, m]
                p += 1
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _indeterminate(self) -> cython.int:
        """A statically indeterminate hold: s stuck rows R_S of rank r < s. q̈ is unique (the motion
        with the rows' span held), λ is not: with Y = 𝔍⁻¹R_Sᵀ, z = 𝔍⁻¹(Q − c) (one elimination of 𝔍
        with partial pivoting on [𝔍 | R_Sᵀ | Q − c]), G = R_S Y and g = −row_S·ẍ0 − R_S z, every λ
        with G λ = g holds the rows (q̈ = z + Y λ the same for each: Y N = 0). G (s × s, symmetric
        positive semidefinite, its null space null(R_Sᵀ)) is eliminated with diagonal pivoting:
        r pivots above STUCK_RANK × its largest diagonal, the d = s − r rows left must have their
        g reduced to at most STUCK_CONSISTENT × max |g| (else the rows are inconsistent: 1). Then
        λ = λ_p + N μ: λ_p (the pivots' solve, 0 on the others) into lamp, N's d columns (1 on one
        dependent row, the pivots' solve of its column) into nul, both in stuck order; λ_p into
        lam (the max-margin λ is chosen on demand: :meth:`_max_margin`, fresh False), q̈ into qdd.
        Returns 1 where 𝔍 is singular, no row is independent, the rows are inconsistent, or d ≥ 1
        with more than STUCK_LP stuck rows."""
        kk: cython.Py_ssize_t = self.k
        n: cython.Py_ssize_t = self.n
        nfr: cython.Py_ssize_t = self.I[N_FRICTION]
        ns: cython.Py_ssize_t = 0
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        j: cython.Py_ssize_t
        i: cython.Py_ssize_t
        p: cython.Py_ssize_t
        e: cython.Py_ssize_t
        w: cython.Py_ssize_t
        rank: cython.Py_ssize_t
        big: cython.double
        f: cython.double
        v: cython.double
        gmax: cython.double = 0.0
        gscale: cython.double = 0.0
        for e in range(nfr):
            if self.slip[e] == 0.0:
                self.sidx[ns] = e
                ns += 1
        w = kk + ns + 1
        for r in range(kk):
            for c in range(kk):
                self.wk[r, c] = self.small[r, c]
            for j in range(ns):
                self.wk[r, kk + j] = self.fric_k[r, self.sidx[j]]
            self.wk[r, kk + ns] = self.small[r, kk]
        if self._eliminate(self.wk, kk, w, 0.0):  # in place: Y = wk[:, k:k+s], z = wk[:, k+s]
            return 1
        for i in range(ns):
            e = self.sidx[i]
            v = -self._row_xdd0(e)
            for r in range(kk):
                v -= self.fric_k[r, e] * self.wk[r, kk + ns]
            self.G[i, ns] = v
            gscale = max(gscale, fabs(v))
            for j in range(ns):
                v = 0.0
                for r in range(kk):
                    v += self.fric_k[r, e] * self.wk[r, kk + j]
                self.G[i, j] = v
            gmax = max(gmax, fabs(self.G[i, i]))
            self.perm[i] = i
        rank = 0
        for j in range(ns):  # diagonal pivoting: rows and columns swapped together
            p = j
            big = fabs(self.G[j, j])
            for r in range(j + 1, ns):
                if fabs(self.G[r, r]) > big:
                    big = fabs(self.G[r, r])
                    p = r
            if not big > _c_stuck_rank * gmax:
                break
            if p != j:
                for c in range(ns + 1):
                    v = self.G[j, c]
                    self.G[j, c] = self.G[p, c]
                    self.G[p, c] = v
                for r in range(ns):
                    v = self.G[r, j]
                    self.G[r, j] = self.G[r, p]
                    self.G[r, p] = v
                i = self.perm[j]
                self.perm[j] = self.perm[p]
                self.perm[p] = i
            for r in range(j + 1, ns):
                f = self.G[r, j] / self.G[j, j]
                for c in range(j, ns + 1):
                    self.G[r, c] -= f * self.G[j, c]
            rank += 1
        if rank == 0:
            return 1
        for r in range(rank, ns):
            if fabs(self.G[r, ns]) > _c_stuck_consistent * gscale:
                return 1
        self.nullity = ns - rank
        if self.nullity > 0 and ns > _c_stuck_lp:
            return 1
        # λ_p and N in pivot order into ksol (λ_p) and nul (then permuted to stuck order)
        for r in range(ns):
            self.ksol[r] = 0.0
            for c in range(self.nullity):
                self.nul[r, c] = 1.0 if r == rank + c else 0.0
        for r in range(rank - 1, -1, -1):
            v = self.G[r, ns]
            for j in range(r + 1, rank):
                v -= self.G[r, j] * self.ksol[j]
            self.ksol[r] = v / self.G[r, r]
            for c in range(self.nullity):
                v = -self.G[r, rank + c]
                for j in range(r + 1, rank):
                    v -= self.G[r, j] * self.nul[j, c]
                self.nul[r, c] = v / self.G[r, r]
        for r in range(ns):
            self.lamp[self.perm[r]] = self.ksol[r]
        for c in range(self.nullity):  # permute N's rows through lpx (a column at a time)
            for r in range(ns):
                self.lpx[self.perm[r]] = self.nul[r, c]
            for r in range(ns):
                self.nul[r, c] = self.lpx[r]
        for r in range(kk):
            v = self.wk[r, kk + ns]
            for j in range(ns):
                v += self.wk[r, kk + j] * self.lamp[j]
            self.qdd[r] = v
        for j in range(ns):
            self.lam[self.sidx[j]] = self.lamp[j]
        self.fresh = self.nullity == 0
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _max_margin(self) -> cython.int:
        """The max-margin holding forces of an indeterminate hold (:meth:`_indeterminate`'s λ_p, N,
        d = nullity ≥ 1): max over μ of t subject to t ≤ f_e − |λ_p,e + N_e μ| for every stuck e, a
        linear programme in (μ, t) whose 2s constraints σ(λ_p,e + N_e μ) + t ≤ f_e (σ = ±1) bound a
        pointed polyhedron (N has a unit row per dependent row): its maximum is at a vertex, d + 1
        constraints active. Every such set is tried (a (d+1)-square solve with partial pivoting,
        skipped where a pivot is at most 1e-12 of the set's largest entry), the feasible vertices
        (each constraint within 1e-9 × (max f + max |λ_p|)) kept, the first of the largest t taken:
        λ = λ_p + N μ into lam (fresh). The LP's value is then min_e f_e − |λ_e|, a continuous
        function of the state while the rank holds (of the set of admissible λ, not of its basis).
        Returns 1 where no vertex is feasible (lam left at λ_p)."""
        ns: cython.Py_ssize_t = 0
        nfr: cython.Py_ssize_t = self.I[N_FRICTION]
        d: cython.Py_ssize_t = self.nullity
        dd: cython.Py_ssize_t = d + 1
        nc: cython.Py_ssize_t
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        j: cython.Py_ssize_t
        e: cython.Py_ssize_t
        i: cython.Py_ssize_t
        sg: cython.double
        v: cython.double
        amax: cython.double
        tol: cython.double = 0.0
        best: cython.double = -math.inf
        found: cython.bint = False
        ok: cython.bint
        for e in range(nfr):
            if self.slip[e] == 0.0:
                tol = max(tol, self.F[self.I[FRICTION_COEF] + e] + fabs(self.lamp[ns]))
                ns += 1
        tol *= 1e-9
        nc = 2 * ns
        if dd > nc:
            return 1
        for j in range(dd):
            self.comb[j] = j
        while True:
            # the system of the active constraints comb[0..dd): rows (σ N_e, 1 | f_e − σ λ_p,e)
            amax = 0.0
            for r in range(dd):
                i = self.comb[r]
                e = i // 2
                sg = 1.0 if i % 2 == 0 else -1.0
                for c in range(d):
                    self.lpa[r, c] = sg * self.nul[e, c]
                    amax = max(amax, fabs(self.lpa[r, c]))
                self.lpa[r, d] = 1.0
                self.lpa[r, dd] = self.F[self.I[FRICTION_COEF] + self.sidx[e]] - sg * self.lamp[e]
            amax = max(amax, 1.0)
            ok = self._eliminate(self.lpa, dd, dd + 1, 1e-12 * amax) == 0
            if ok:
                for r in range(dd):
                    self.lpx[r] = self.lpa[r, dd]
                if self.lpx[d] > best:
                    for e in range(ns):  # feasible: every constraint within tol
                        v = self.lamp[e]
                        for c in range(d):
                            v += self.nul[e, c] * self.lpx[c]
                        if fabs(v) + self.lpx[d] > self.F[self.I[FRICTION_COEF] + self.sidx[e]] + tol:
                            ok = False
                            break
                    if ok:
                        best = self.lpx[d]
                        found = True
                        for e in range(ns):
                            v = self.lamp[e]
                            for c in range(d):
                                v += self.nul[e, c] * self.lpx[c]
                            self.lam[self.sidx[e]] = v
            # the next combination of dd of the nc constraints
            j = dd - 1
            while j >= 0 and self.comb[j] == nc - dd + j:
                j -= 1
            if j < 0:
                break
            self.comb[j] += 1
            for c in range(j + 1, dd):
                self.comb[c] = self.comb[c - 1] + 1
        self.fresh = True
        return 0 if found else 1

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _residual(self) -> cython.double:
        """Φ (selected rows) and R x − target into Loops' rhs, A = [Φ_x; R] into Loops' A, at
        Newton's x; returns the largest |residual| (NaN if one is not finite), and leaves the
        tolerance (NEWTON_TOL or the round-off floor) in tol."""
        n: cython.Py_ssize_t = self.n
        mr: cython.Py_ssize_t = self.mr
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        v: cython.double
        self.loops._constraints()
        largest: cython.double = 0.0
        for r in range(mr):
            self.loops.rhs[r] = self.loops.phi[self.sel[r]]
            for c in range(n):
                self.loops.A[r, c] = self.loops.Phi[self.sel[r], c]
        for r in range(self.k):
            v = 0.0
            for c in range(n):
                self.loops.A[mr + r, c] = self.R[r, c]
                v += self.R[r, c] * self.loops.x[c]
            self.loops.rhs[mr + r] = v - self.target[r]
        for r in range(n):
            v = self.loops.rhs[r]
            if not isfinite(v):
                return _c_nan
            if fabs(v) > largest:
                largest = fabs(v)
        self.tol = max(_c_newton_tol, _c_newton_round_off * self.loops.spread)
        return largest

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _close(self) -> cython.int:
        """Newton from the predictor of last (x, q, K) to q = target (module docstring); on success
        x and K into last (and Loops' kin[0] = x), the factors saved, Φ_x kept in Phx. Returns 0, or
        1 (no convergence, a singular A, another branch, a correction beyond the predictor's trust)."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        j: cython.Py_ssize_t
        a: cython.Py_ssize_t
        r: cython.Py_ssize_t
        it: cython.Py_ssize_t
        v: cython.double
        det: cython.double = 0.0
        largest: cython.double
        motion: cython.double = 0.0
        correction: cython.double = 0.0
        polished: cython.bint = False
        converged: cython.bint
        self.counts[CLOSURES] += 1
        # the quadratic predictor x + K Δ + ½ ẍ0(K Δ): the second-order term by one solve, with the
        # factors of the last closure, of A ẍ0 = (−γ(K Δ), 0) at last's x
        for j in range(n):
            v = 0.0
            for a in range(kk):
                v += self.lastK[a, j] * (self.target[a] - self.lastq[a])
            self.loops.kin[0, j] = self.lastx[j]
            self.loops.kin[1, j] = v
            self.loops.kin[2, j] = 0.0
            self.loops.x[j] = self.lastx[j]
        self.loops._angle_trig()
        self._second_order(self.pred)
        for j in range(n):
            v = self.lastx[j] + self.loops.kin[1, j] + 0.5 * self.pred[j]
            self.pred[j] = v
            if fabs(v - self.lastx[j]) > motion:
                motion = fabs(v - self.lastx[j])
            self.loops.x[j] = v
        self.loops._angle_trig()
        for it in range(_c_newton_max_iter + 1):
            largest = self._residual()
            if not isfinite(largest):
                return 1
            det = self.loops._lu_factor()
            self.counts[FACTORS] += 1
            if det == 0.0 or not isfinite(det):
                return 1
            if polished:
                break
            converged = largest <= self.tol
            self.loops._lu_solve(self.loops.rhs_at)
            self.counts[SOLVES] += 1
            for j in range(n):
                self.loops.x[j] -= self.loops.rhs[j]
            self.loops._angle_trig()
            polished = converged
        else:
            return 1
        if self.sign != 0 and (det > 0.0) != (self.sign > 0):
            return 1
        for j in range(n):
            if fabs(self.loops.x[j] - self.pred[j]) > correction:
                correction = fabs(self.loops.x[j] - self.pred[j])
        if correction > _c_predictor_trust * motion + _c_trusted_correction and not self.starting:
            return 1
        self._save_factors()
        for r in range(self.mr):
            for j in range(n):
                self.Phx[r, j] = self.loops.Phi[self.sel[r], j]
        for j in range(n):
            self.loops.kin[0, j] = self.loops.x[j]
            self.lastx[j] = self.loops.x[j]
        for a in range(kk):
            self.lastq[a] = self.target[a]
            for j in range(n):
                self.resid[j] = 0.0
            self.resid[self.mr + a] = 1.0
            self._solve(self.resid)
            for j in range(n):
                self.K[a, j] = self.resid[j]
                self.lastK[a, j] = self.resid[j]
        self.det = det
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _walk(self, q: cython.double[::1]) -> cython.int:
        """From last to q: one closure, else the jump in 2, 4, … equal parts (module docstring).
        Returns 0, or 1 where every division failed (last is left as it was)."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        a: cython.Py_ssize_t
        j: cython.Py_ssize_t
        p: cython.Py_ssize_t
        h: cython.Py_ssize_t
        parts: cython.Py_ssize_t = 1
        ok: cython.bint
        for j in range(n):
            self.basex[j] = self.lastx[j]
        for a in range(kk):
            self.baseq[a] = self.lastq[a]
            for j in range(n):
                self.baseK[a, j] = self.lastK[a, j]
        for h in range(_c_walk_halvings + 1):
            ok = True
            for p in range(1, parts + 1):
                for a in range(kk):
                    self.target[a] = q[a] if p == parts else self.baseq[a] + (q[a] - self.baseq[a]) * ((1.0 * p) / parts)
                if self._close() != 0:
                    ok = False
                    break
            if ok:
                return 0
            for j in range(n):
                self.lastx[j] = self.basex[j]
            for a in range(kk):
                self.lastq[a] = self.baseq[a]
                for j in range(n):
                    self.lastK[a, j] = self.baseK[a, j]
            parts *= 2
        return 1

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _coefficients(self) -> cython.int:
        """𝔍, B, the configuration's generalized forces Qp = −∂V/∂q, V, and the per-coordinate
        rates of the timed forces, actuators, joint elements and line elements at last's x, K."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        nb: cython.Py_ssize_t = self.I[N_ANGLES]
        ms: cython.Py_ssize_t = self.I[MASSES]
        ins: cython.Py_ssize_t = self.I[INERTIAS]
        ne: cython.Py_ssize_t = self.I[N_ELEMENTS]
        nje: cython.Py_ssize_t = self.I[N_JOINT_ELEMENTS]
        nt: cython.Py_ssize_t = self.I[N_TIMED]
        nf: cython.Py_ssize_t = self.I[N_FORCES]
        na: cython.Py_ssize_t = self.I[N_ACTUATORS]
        a: cython.Py_ssize_t
        c: cython.Py_ssize_t
        b: cython.Py_ssize_t
        e: cython.Py_ssize_t
        j: cython.Py_ssize_t
        p: cython.Py_ssize_t
        v: cython.double
        dx: cython.double
        dy: cython.double
        gx: cython.double
        gy: cython.double
        length: cython.double
        coef: cython.double
        u: cython.double
        rows_at: cython.Py_ssize_t
        first_inertia: cython.Py_ssize_t = nje - self.I[N_JOINT_INERTIAS]
        V: cython.double = 0.0
        for j in range(n):
            self.loops.kin[2, j] = 0.0
        for a in range(kk):  # the centres' velocity coefficients K_G per coordinate
            for j in range(n):
                self.loops.kin[1, j] = self.K[a, j]
            self.loops._table_rates(CENTRES, False)
            for b in range(nb):
                self.KG[a, b, 0] = self.loops.rows[b, 0]
                self.KG[a, b, 1] = self.loops.rows[b, 1]
        for a in range(kk):
            self.Qp[a] = 0.0
            v = 0.0
            for j in range(n):  # dq_input/dq_a: the first input's load (a one-DOF scene's [torque]) acts on it
                v += self.F[self.I[DRIVE] + j] * self.K[a, j]
            self.drive_rate[a] = v
            for c in range(kk):
                v = 0.0
                for b in range(nb):
                    v += self.F[ms + b] * (self.KG[a, b, 0] * self.KG[c, b, 0] + self.KG[a, b, 1] * self.KG[c, b, 1]) \
                        + self.F[ins + b] * self.K[a, b] * self.K[c, b]
                self.Jm[a, c] = v
                self.Bm[a, c] = 0.0
        if self.I[HAS_GRAVITY]:
            for a in range(kk):
                v = 0.0
                for b in range(nb):
                    gx = self.F[self.I[GRAVITY] + 2 * b]
                    gy = self.F[self.I[GRAVITY] + 2 * b + 1]
                    v += self.F[ms + b] * (gx * self.KG[a, b, 0] + gy * self.KG[a, b, 1])
                self.Qp[a] += v
            self.loops._table_positions(CENTRES)
            for b in range(nb):
                gx = self.F[self.I[GRAVITY] + 2 * b]
                gy = self.F[self.I[GRAVITY] + 2 * b + 1]
                V -= self.F[ms + b] * (gx * self.loops.rows[b, 0] + gy * self.loops.rows[b, 1])
        if ne:
            for a in range(kk):  # K_D,a = d̂·(K_a(end a) − K_a(end b))
                for j in range(n):
                    self.loops.kin[1, j] = self.K[a, j]
                self.loops._table_rates(ENDS, False)
                for e in range(ne):
                    self.loops.rows[2 * e, 2] = self.loops.rows[2 * e, 0] - self.loops.rows[2 * e + 1, 0]
                    self.loops.rows[2 * e, 3] = self.loops.rows[2 * e, 1] - self.loops.rows[2 * e + 1, 1]
                self.loops._table_positions(ENDS)
                for e in range(ne):
                    dx = self.loops.rows[2 * e, 0] - self.loops.rows[2 * e + 1, 0]
                    dy = self.loops.rows[2 * e, 1] - self.loops.rows[2 * e + 1, 1]
                    length = sqrt(dx * dx + dy * dy)
                    self.kd[a, e] = (dx * self.loops.rows[2 * e, 2] + dy * self.loops.rows[2 * e, 3]) / length
            self.loops._table_positions(ENDS)
            for e in range(ne):
                dx = self.loops.rows[2 * e, 0] - self.loops.rows[2 * e + 1, 0]
                dy = self.loops.rows[2 * e, 1] - self.loops.rows[2 * e + 1, 1]
                length = sqrt(dx * dx + dy * dy)
                coef = self.F[self.I[ELEMENT_COEF] + e]
                if e < self.I[N_DAMPERS]:
                    for a in range(kk):
                        for c in range(kk):
                            self.Bm[a, c] += coef * self.kd[a, e] * self.kd[c, e]
                else:
                    u = length - self.F[self.I[ELEMENT_REST] + e]
                    V += 0.5 * coef * u * u
                    for a in range(kk):
                        self.Qp[a] -= coef * u * self.kd[a, e]
        if nje:
            rows_at = self.I[JOINT_ROWS]
            for e in range(nje):
                u = 0.0
                for j in range(n):
                    u += self.F[rows_at + e * n + j] * self.loops.kin[0, j]
                for a in range(kk):
                    v = 0.0
                    for j in range(n):
                        v += self.F[rows_at + e * n + j] * self.K[a, j]
                    self.ku[a, e] = v
                coef = self.F[self.I[JOINT_COEF] + e]
                if e < self.I[N_JOINT_DAMPERS]:
                    for a in range(kk):
                        for c in range(kk):
                            self.Bm[a, c] += coef * self.ku[a, e] * self.ku[c, e]
                elif e >= first_inertia:
                    for a in range(kk):
                        for c in range(kk):
                            self.Jm[a, c] += coef * self.ku[a, e] * self.ku[c, e]
                else:
                    u -= self.F[self.I[JOINT_REST] + e]
                    V += 0.5 * coef * u * u
                    for a in range(kk):
                        self.Qp[a] -= coef * u * self.ku[a, e]
        if nt:
            for a in range(kk):
                for j in range(n):
                    self.loops.kin[1, j] = self.K[a, j]
                self.loops._table_rates(FORCE_POINTS, False)
                for p in range(nt):
                    self.timed[a, p] = (self.loops.rows[nf + p, 0] * self.F[self.I[TIMED_DIR] + 2 * p]
                                        + self.loops.rows[nf + p, 1] * self.F[self.I[TIMED_DIR] + 2 * p + 1])
        if na:
            rows_at = self.I[ACT_ROWS]
            for e in range(na):
                u = 0.0
                for j in range(n):
                    u += self.F[rows_at + e * n + j] * self.loops.kin[0, j]
                self.act_l[e] = u
                for a in range(kk):
                    v = 0.0
                    for j in range(n):
                        v += self.F[rows_at + e * n + j] * self.K[a, j]
                    self.act_k[a, e] = v
        for e in range(self.I[N_FRICTION]):
            for a in range(kk):
                v = 0.0
                for j in range(n):
                    v += self.F[self.I[FRICTION_ROWS] + e * n + j] * self.K[a, j]
                self.fric_k[a, e] = v
        self.potential = V
        return 0

    # -- the chart interface ----------------------------------------------------------------

    @cython.ccall
    @cython.exceptval(-1, check=False)
    def evaluate(self, q: cython.double[::1]) -> cython.bint:
        """The configuration and its coefficients at q (k,) (memoized): True on success, False
        where the walk from the last configuration could not close the loops on the chart's
        branch."""
        kk: cython.Py_ssize_t = self.k
        a: cython.Py_ssize_t
        same: cython.bint = self.valid == 1
        if same:
            for a in range(kk):
                if q[a] != self.qv[a]:
                    same = False
                    break
        if same:
            return True
        self.valid = 0
        self.counts[EVALUATIONS] += 1
        if self._walk(q) != 0:
            return False
        self._coefficients()
        for a in range(kk):
            self.qv[a] = q[a]
        self.valid = 1
        return True

    @cython.ccall
    def dimension(self) -> cython.Py_ssize_t:
        """k, the number of independent coordinates (the integrators' n)."""
        return self.k

    @cython.ccall
    def acceleration(self, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1], v: cython.double[::1],
                     out: cython.double[::1]) -> cython.int:
        """q̈ (k,) into out at q, q̇ = v on load piece ``load`` (module docstring): 0, or 1 where
        the configuration could not be found (out holds NaN)."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        mr: cython.Py_ssize_t = self.mr
        nb: cython.Py_ssize_t = self.I[N_ANGLES]
        ms: cython.Py_ssize_t = self.I[MASSES]
        ins: cython.Py_ssize_t = self.I[INERTIAS]
        nje: cython.Py_ssize_t = self.I[N_JOINT_ELEMENTS]
        nt: cython.Py_ssize_t = self.I[N_TIMED]
        na: cython.Py_ssize_t = self.I[N_ACTUATORS]
        nl: cython.Py_ssize_t = 2 * self.I[TABLES + TABLE_ENTRIES * LOOPS]
        a: cython.Py_ssize_t
        c: cython.Py_ssize_t
        b: cython.Py_ssize_t
        e: cython.Py_ssize_t
        j: cython.Py_ssize_t
        w: cython.double
        f: cython.double
        rate: cython.double
        prm: cython.Py_ssize_t
        self.piece = load
        for a in range(kk):
            self.rate[a] = v[a]
        if not self.evaluate(q):
            for a in range(kk):
                out[a] = _c_nan
            return 1
        for j in range(n):  # ẋ = Σ K_a q̇_a
            w = 0.0
            for a in range(kk):
                w += self.K[a, j] * v[a]
            self.xdot[j] = w
            self.loops.kin[1, j] = w
            self.loops.kin[2, j] = 0.0
        # ẍ0: A ẍ0 = (−γ(ẋ), 0), one solve with the configuration's factors
        self._second_order(self.xdd0)
        # c = Σ m K_Gᵀ a_G0 + I k_θᵀ θ̈0 (+ the joint inertias'), a_G0 at (ẋ, ẍ0)
        for j in range(n):
            self.loops.kin[2, j] = self.xdd0[j]
        self.loops._table_rates(CENTRES, True)
        for a in range(kk):
            w = 0.0
            for b in range(nb):
                w += self.F[ms + b] * (self.KG[a, b, 0] * self.loops.rows[b, 2] + self.KG[a, b, 1] * self.loops.rows[b, 3]) \
                    + self.F[ins + b] * self.K[a, b] * self.xdd0[b]
            self.cv[a] = w
        if nje:
            for e in range(nje - self.I[N_JOINT_INERTIAS], nje):
                f = 0.0
                for j in range(n):
                    f += self.F[self.I[JOINT_ROWS] + e * n + j] * self.xdd0[j]
                f *= self.F[self.I[JOINT_COEF] + e]
                for a in range(kk):
                    self.cv[a] += f * self.ku[a, e]
        # the applied generalized forces of the piece: timed forces and actuators
        for a in range(kk):
            w = self.F[self.I[PIECE_VALUES] + load * (1 + nt)] * self.drive_rate[a]
            for e in range(nt):
                w += self.F[self.I[PIECE_VALUES] + load * (1 + nt) + 1 + e] * self.timed[a, e]
            self.Qa[a] = w
        prm = self.I[ACT_PARAMS]
        for e in range(na):
            rate = 0.0
            for a in range(kk):
                rate += self.act_k[a, e] * v[a]
            f = (self.F[self.I[ACT_PIECE] + load * na + e] + self.F[prm + 5 * e] * self.act_l[e]
                 + self.F[prm + 5 * e + 1] * rate)
            if self.clampm[e] == CLAMP_HI:
                f = self.F[prm + 5 * e + 4]
            elif self.clampm[e] == CLAMP_LO:
                f = self.F[prm + 5 * e + 3]
            elif self.clampm[e] != CLAMP_FREE:
                f = min(max(f, self.F[prm + 5 * e + 3]), self.F[prm + 5 * e + 4])
            for a in range(kk):
                self.Qa[a] += self.F[prm + 5 * e + 2] * f * self.act_k[a, e]
        for a in range(kk):
            w = self.Qp[a] + self.Qa[a] - self.cv[a]
            for e in range(self.I[N_FRICTION]):  # a slipping joint's friction −f s K_u (in the dissipation)
                w -= self.F[self.I[FRICTION_COEF] + e] * self.slip[e] * self.fric_k[a, e]
            for c in range(kk):
                w -= self.Bm[a, c] * v[c]
                self.small[a, c] = self.Jm[a, c]
            self.small[a, kk] = w
        for e in range(self.I[N_FRICTION]):
            self.lam[e] = 0.0
        self.nullity = 0
        self.fresh = True
        if self._stuck_count() > 0:
            if self._stuck_solve() != 0:
                for a in range(kk):
                    out[a] = _c_nan
                return 1
        elif self._small_solve() != 0:
            for a in range(kk):
                out[a] = _c_nan
            return 1
        for j in range(n):
            w = self.xdd0[j]
            for a in range(kk):
                w += self.K[a, j] * self.qdd[a]
            self.xdd[j] = w
        for a in range(kk):
            out[a] = self.qdd[a]
        return 0

    @cython.ccall
    def accelerations(self, load: cython.Py_ssize_t, T: cython.double[::1], Q: cython.double[:, ::1],
                      V: cython.double[:, ::1], out: cython.double[:, ::1]) -> cython.Py_ssize_t:
        """:meth:`acceleration` at each row of Q, V (m, k) at the times T (m,) in turn, into out (m, k),
        a loop in C (the benchmark's: no Python call per evaluation). Returns the number evaluated."""
        s: cython.Py_ssize_t
        if not (Q.shape[0] == V.shape[0] == out.shape[0] == T.shape[0] and Q.shape[1] == V.shape[1] == out.shape[1]
                == self.k):
            raise ValueError(f"accelerations: T (m,), Q, V and out (m, {self.k})")
        for s in range(Q.shape[0]):
            if self.acceleration(load, T[s], Q[s], V[s], out[s]) != 0:
                return s
        return Q.shape[0]

    @cython.ccall
    def power(self, load: cython.Py_ssize_t, v: cython.double[::1]) -> cython.double:
        """Σ_a (timed forces + actuators)_a q̇_a (W), right after an acceleration on ``load``."""
        w: cython.double = 0.0
        a: cython.Py_ssize_t
        for a in range(self.k):
            w += self.Qa[a] * v[a]
        return w

    @cython.ccall
    def dissipation(self, v: cython.double[::1]) -> cython.double:
        """q̇ᵀ B q̇ (W): the dampers' dissipation, right after an acceleration."""
        w: cython.double = 0.0
        a: cython.Py_ssize_t
        c: cython.Py_ssize_t
        e: cython.Py_ssize_t
        u: cython.double
        for a in range(self.k):
            for c in range(self.k):
                w += v[a] * self.Bm[a, c] * v[c]
        for e in range(self.I[N_FRICTION]):  # f s u̇ = f |u̇| while slipping
            u = 0.0
            for a in range(self.k):
                u += self.fric_k[a, e] * v[a]
            w += self.F[self.I[FRICTION_COEF] + e] * self.slip[e] * u
        return w

    @cython.ccall
    def slip_margin(self, v: cython.double[::1]) -> cython.double:
        """The least margin over the joint frictions at the configuration last evaluated, q̇ = v:
        s u̇ of each slipping in its direction s, f − |λ| of each stuck (λ its holding force at the
        latest acceleration: :meth:`stop_margin` computes one there; an indeterminate hold's
        max-margin λ, :meth:`_max_margin` run here first, so that lam holds it after this call);
        > 0 while each slips its way or holds (inf without friction; NaN where an indeterminate
        hold's LP finds no vertex)."""
        g: cython.double = math.inf
        e: cython.Py_ssize_t
        a: cython.Py_ssize_t
        u: cython.double
        if not self.fresh:  # an indeterminate hold: its max-margin λ (the LP's value is the least margin)
            if self._max_margin() != 0:
                return _c_nan
        for e in range(self.I[N_FRICTION]):
            if self.slip[e] == 0.0:
                g = min(g, self.F[self.I[FRICTION_COEF] + e] - fabs(self.lam[e]))
                continue
            u = 0.0
            for a in range(self.k):
                u += self.fric_k[a, e] * v[a]
            g = min(g, self.slip[e] * u)
        return g

    def set_slip(self, e: int, direction: float) -> None:
        """Joint friction e slips in ``direction`` (±1), or sticks (0: its joint's coordinate held,
        :meth:`_stuck_solve`)."""
        if direction not in (1.0, -1.0, 0.0) or not 0 <= e < self.I[N_FRICTION]:
            raise ValueError(f"set_slip: friction {e} of {self.I[N_FRICTION]}, direction ±1 or 0, not {direction}")
        self.slip[e] = direction

    def friction_capacity(self, e: int) -> float:
        """Joint friction e's f (N·m or N): the largest holding force it gives."""
        if not 0 <= e < self.I[N_FRICTION]:
            raise ValueError(f"friction_capacity: friction {e} of {self.I[N_FRICTION]}")
        return float(self.F[self.I[FRICTION_COEF] + e])

    @cython.ccall
    def kinetic(self, v: cython.double[::1]) -> cython.double:
        """½ q̇ᵀ𝔍q̇ (J) at the configuration last evaluated."""
        w: cython.double = 0.0
        a: cython.Py_ssize_t
        c: cython.Py_ssize_t
        for a in range(self.k):
            for c in range(self.k):
                w += v[a] * self.Jm[a, c] * v[c]
        return 0.5 * w

    @cython.ccall
    def observation_size(self) -> cython.Py_ssize_t:
        return 3 * self.n + 2

    @cython.ccall
    def observe(self, out: cython.double[:, ::1], row: cython.Py_ssize_t):
        """x, ẋ, ẍ (n each), V and T = ½ q̇ᵀ𝔍q̇ at the latest acceleration into out[row]."""
        j: cython.Py_ssize_t
        n: cython.Py_ssize_t = self.n
        for j in range(n):
            out[row, j] = self.lastx[j]
            out[row, n + j] = self.xdot[j]
            out[row, 2 * n + j] = self.xdd[j]
        out[row, 3 * n] = self.potential
        out[row, 3 * n + 1] = self.kinetic(self.rate)

    @cython.ccall
    def mark(self):
        """Remember the last configuration (a piece's start) for :meth:`rewind`."""
        self.markx[:] = self.lastx
        self.markq[:] = self.lastq
        self.markK[:, :] = self.lastK

    @cython.ccall
    def rewind(self):
        """Walk again from the configuration :meth:`mark` kept."""
        self.lastx[:] = self.markx
        self.lastq[:] = self.markq
        self.lastK[:, :] = self.markK
        self.valid = 0

    @cython.ccall
    def reset(self):
        """Walk again from the chart's start."""
        self.lastx[:] = self.startx
        self.lastq[:] = self.startq
        self.lastK[:, :] = self.startK
        self.valid = 0

    # -- coordinate sets ----------------------------------------------------------------------

    @cython.cfunc
    @cython.exceptval(check=False)
    def _project_out(self, a: cython.double[:, ::1], i: cython.Py_ssize_t, b: cython.double[:, ::1],
                     count: cython.Py_ssize_t) -> cython.void:
        """One pass of modified Gram-Schmidt: row i of ``a`` less its components along the first
        ``count`` rows of ``b`` (orthonormal), one after the other."""
        n: cython.Py_ssize_t = self.n
        l: cython.Py_ssize_t
        j: cython.Py_ssize_t
        v: cython.double
        for l in range(count):
            v = 0.0
            for j in range(n):
                v += b[l, j] * a[i, j]
            for j in range(n):
                a[i, j] -= v * b[l, j]

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _sigma_ratio(self, S: cython.longlong[::1]) -> cython.double:
        """σ_min/σ_max of the dependent block D_S = Φ_x Zᵀ of the joints S (k indices into the joint
        rows) at the configuration last closed (module docstring)."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        mr: cython.Py_ssize_t = self.mr
        i: cython.Py_ssize_t
        l: cython.Py_ssize_t
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        p: cython.Py_ssize_t
        best: cython.Py_ssize_t
        sweep: cython.Py_ssize_t
        v: cython.double
        big: cython.double
        alpha: cython.double
        beta: cython.double
        gamma: cython.double
        zeta: cython.double
        tt: cython.double
        cs: cython.double
        sn: cython.double
        rotated: cython.bint
        # U: orthonormal rows spanning R_S (modified Gram-Schmidt, twice)
        for i in range(kk):
            for j in range(n):
                self.U[i, j] = self.JR[S[i], j]
            big = 0.0
            for j in range(n):
                big += self.U[i, j] * self.U[i, j]
            for p in range(2):
                self._project_out(self.U, i, self.U, i)
            v = 0.0
            for j in range(n):
                v += self.U[i, j] * self.U[i, j]
            if not v > 1e-24 * big:
                return 0.0
            v = 1.0 / sqrt(v)
            for j in range(n):
                self.U[i, j] *= v
        if mr == 0:
            return 1.0
        # Z: n − k orthonormal rows orthogonal to U, greedily from the unit vectors
        for r in range(mr):
            best = -1
            big = 0.0
            for c in range(n):
                for j in range(n):
                    self.resid[j] = 0.0
                self.resid[c] = 1.0
                for p in range(2):
                    for l in range(kk):
                        v = self.U[l, c] if p == 0 else 0.0
                        if p == 1:
                            for j in range(n):
                                v += self.U[l, j] * self.resid[j]
                        for j in range(n):
                            self.resid[j] -= v * self.U[l, j]
                    for l in range(r):
                        v = 0.0
                        for j in range(n):
                            v += self.Z[l, j] * self.resid[j]
                        for j in range(n):
                            self.resid[j] -= v * self.Z[l, j]
                v = 0.0
                for j in range(n):
                    v += self.resid[j] * self.resid[j]
                if v > big:
                    big = v
                    best = c
            # the best unit vector again, into Z[r]
            for j in range(n):
                self.Z[r, j] = 0.0
            self.Z[r, best] = 1.0
            for p in range(2):
                self._project_out(self.Z, r, self.U, kk)
                self._project_out(self.Z, r, self.Z, r)
            v = 0.0
            for j in range(n):
                v += self.Z[r, j] * self.Z[r, j]
            v = 1.0 / sqrt(v)
            for j in range(n):
                self.Z[r, j] *= v
        # D = Φ_x Zᵀ, then one-sided Jacobi on its columns
        for r in range(mr):
            for c in range(mr):
                v = 0.0
                for j in range(n):
                    v += self.Phx[r, j] * self.Z[c, j]
                self.D[r, c] = v
        for sweep in range(_c_jacobi_sweeps):
            rotated = False
            for p in range(mr - 1):
                for c in range(p + 1, mr):
                    alpha = 0.0
                    beta = 0.0
                    gamma = 0.0
                    for r in range(mr):
                        alpha += self.D[r, p] * self.D[r, p]
                        beta += self.D[r, c] * self.D[r, c]
                        gamma += self.D[r, p] * self.D[r, c]
                    if not fabs(gamma) > _c_jacobi_tol * sqrt(alpha * beta):
                        continue
                    rotated = True
                    zeta = (beta - alpha) / (2.0 * gamma)
                    tt = (1.0 if zeta >= 0.0 else -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta))
                    cs = 1.0 / sqrt(1.0 + tt * tt)
                    sn = cs * tt
                    for r in range(mr):
                        v = self.D[r, p]
                        self.D[r, p] = cs * v - sn * self.D[r, c]
                        self.D[r, c] = sn * v + cs * self.D[r, c]
            if not rotated:
                break
        lo: cython.double = math.inf
        hi: cython.double = 0.0
        for c in range(mr):
            v = 0.0
            for r in range(mr):
                v += self.D[r, c] * self.D[r, c]
            v = sqrt(v)
            lo = min(lo, v)
            hi = max(hi, v)
        if not hi > 0.0 or not isfinite(lo / hi):
            return 0.0
        return lo / hi

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _best_set(self) -> cython.int:
        """The best k joints into best (ascending) by pivoted QR on M = JR Nᵀ, N an orthonormal
        basis of null(Φ_x) (K's rows, Gram-Schmidt)."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        nj: cython.Py_ssize_t = self.nj
        i: cython.Py_ssize_t
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        p: cython.Py_ssize_t
        pick: cython.Py_ssize_t
        v: cython.double
        big: cython.double
        for i in range(kk):  # N into U (orthonormal rows spanning K's)
            for j in range(n):
                self.U[i, j] = self.K[i, j]
            for p in range(2):
                self._project_out(self.U, i, self.U, i)
            v = 0.0
            for j in range(n):
                v += self.U[i, j] * self.U[i, j]
            v = 1.0 / sqrt(v)
            for j in range(n):
                self.U[i, j] *= v
        for r in range(nj):
            self.used[r] = 0.0
            for i in range(kk):
                v = 0.0
                for j in range(n):
                    v += self.JR[r, j] * self.U[i, j]
                self.M[r, i] = v
        for p in range(kk):
            pick = -1
            big = 0.0
            for r in range(nj):
                if self.used[r] == 0.0:
                    v = 0.0
                    for i in range(kk):
                        v += self.M[r, i] * self.M[r, i]
                    if v > big:
                        big = v
                        pick = r
            if pick < 0:
                return 1
            self.used[pick] = 1.0
            v = 1.0 / sqrt(big)
            for i in range(kk):
                self.M[pick, i] *= v
            for r in range(nj):
                if self.used[r] == 0.0:
                    v = 0.0
                    for i in range(kk):
                        v += self.M[r, i] * self.M[pick, i]
                    for i in range(kk):
                        self.M[r, i] -= v * self.M[pick, i]
        p = 0
        for r in range(nj):
            if self.used[r] != 0.0:
                self.best[p] = r
                p += 1
        return 0

    @cython.ccall
    def stop_margin(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.double:
        """The least of c(current set) − HYSTERESIS × c(best set) (the switch) and
        :meth:`range_margin` (a ranged joint at a bound) at q (NaN where q cannot be evaluated);
        leaves the two conditionings in c_current, c_best and the best set in best."""
        if self.current[0] < 0:
            raise ValueError("stop_margin: the chart has no coordinates yet: start() it first")
        if not self.evaluate(q):
            return _c_nan
        if self._stuck_count() > 0:  # the holding forces at (t, q, v): an acceleration there
            if self.acceleration(self.piece, t, q, v, self.scratch) != 0:
                return _c_nan
        self._best_set()
        self.c_current = self._sigma_ratio(self.current)
        self.c_best = self._sigma_ratio(self.best)
        return min(self.c_current - _c_hysteresis * self.c_best, self.range_margin(), self.clamp_margin(v),
                   self.slip_margin(v))

    @cython.ccall
    def clamp_margin(self, v: cython.double[::1]) -> cython.double:
        """The least clamp margin of the clamped actuators (a force that depends on the state,
        with a forcerange) at the configuration last evaluated, q̇ = v, on the latest
        acceleration's piece: > 0 while each one's force is in its mode (physics' rule: CLAMP_FREE
        min(hi − f_u, f_u − lo) + ε, CLAMP_HI f_u − hi + ε, CLAMP_LO lo − f_u + ε, ε =
        CLAMP_HYSTERESIS × the larger finite bound's magnitude); inf without one or in CLAMP_AUTO."""
        g: cython.double = math.inf
        e: cython.Py_ssize_t
        if self.I[N_CLAMPED] == 0:
            return g
        prm: cython.Py_ssize_t
        lo: cython.double
        hi: cython.double
        f: cython.double
        eps: cython.double
        for e in range(self.I[N_ACTUATORS]):
            if not self._clamped(e):
                continue
            prm = self.I[ACT_PARAMS] + 5 * e
            lo = self.F[prm + 3]
            hi = self.F[prm + 4]
            eps = 0.0
            if isfinite(lo):
                eps = fabs(lo)
            if isfinite(hi):
                eps = max(eps, fabs(hi))
            eps *= _c_clamp_hysteresis
            f = self._unclamped(e, self.piece, v)
            if self.clampm[e] == CLAMP_HI:
                g = min(g, f - hi + eps)
            elif self.clampm[e] == CLAMP_LO:
                g = min(g, lo - f + eps)
            elif self.clampm[e] == CLAMP_FREE:
                g = min(g, min(hi - f, f - lo) + eps)
        return g

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _clamped(self, e: cython.Py_ssize_t) -> cython.bint:
        """Whether actuator e's clamp switches with the state (physics' rule): b1 or b2 nonzero,
        lo < hi, a finite bound."""
        prm: cython.Py_ssize_t = self.I[ACT_PARAMS] + 5 * e
        lo: cython.double = self.F[prm + 3]
        hi: cython.double = self.F[prm + 4]
        return (self.F[prm] != 0.0 or self.F[prm + 1] != 0.0) and lo < hi and (isfinite(lo) or isfinite(hi))

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _unclamped(self, e: cython.Py_ssize_t, piece: cython.Py_ssize_t, v: cython.double[::1]) -> cython.double:
        """Actuator e's force before its clamp, c + b1·gear·l + b2·gear·l̇ at the configuration
        last evaluated, q̇ = v, on load piece ``piece``."""
        prm: cython.Py_ssize_t = self.I[ACT_PARAMS] + 5 * e
        rate: cython.double = 0.0
        a: cython.Py_ssize_t
        for a in range(self.k):
            rate += self.act_k[a, e] * v[a]
        return (self.F[self.I[ACT_PIECE] + piece * self.I[N_ACTUATORS] + e] + self.F[prm] * self.act_l[e]
                + self.F[prm + 1] * rate)

    @cython.ccall
    def set_clamps(self, load: cython.Py_ssize_t, q: cython.double[::1], v: cython.double[::1]) -> cython.Py_ssize_t:
        """Set each clamped actuator's mode by its unclamped force at q, q̇ = v on load piece
        ``load`` (physics' rule: CLAMP_HI above hi, CLAMP_LO below lo, else CLAMP_FREE). Returns the
        count of modes changed, −1 where the configuration fails."""
        if not self.evaluate(q):
            return -1
        self.piece = load
        changed: cython.Py_ssize_t = 0
        e: cython.Py_ssize_t
        prm: cython.Py_ssize_t
        f: cython.double
        mode: cython.double
        for e in range(self.I[N_ACTUATORS]):
            if not self._clamped(e):
                continue
            prm = self.I[ACT_PARAMS] + 5 * e
            f = self._unclamped(e, load, v)
            mode = CLAMP_HI if f > self.F[prm + 4] else (CLAMP_LO if f < self.F[prm + 3] else CLAMP_FREE)
            if mode != self.clampm[e]:
                changed += 1
                self.clampm[e] = mode
        return changed

    @cython.ccall
    def stop_at_start(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.bint:
        """True at a load piece's start (right after its first acceleration) where a clamped
        actuator's force is out of its mode (a control step past a bound, or back inside), or a
        stuck joint's holding force beyond its friction (a load step that breaks it loose)."""
        stuck: cython.bint = self._stuck_count() > 0
        if self.I[N_CLAMPED] == 0 and not stuck:
            return False
        if not self.evaluate(q):
            return True
        if stuck:
            if self.acceleration(self.piece, t, q, v, self.scratch) != 0:
                return True
            if self.slip_margin(v) < 0.0:
                return True
        return self.clamp_margin(v) < 0.0

    def clamp_modes(self) -> tuple:
        """The actuators' clamp modes (physics' CLAMP_* values)."""
        return tuple(int(m) for m in self.clampm[:self.I[N_ACTUATORS]])

    @cython.ccall
    def range_margin(self) -> cython.double:
        """The nearest bound's distance, min over the ranged joints of u − lo and hi − u (rad or
        m), at the configuration last evaluated: > 0 while every one is inside its range (inf
        without ranged joints)."""
        n: cython.Py_ssize_t = self.n
        r: cython.Py_ssize_t
        j: cython.Py_ssize_t
        u: cython.double
        g: cython.double = math.inf
        for r in range(self.I[N_RANGES]):
            u = 0.0
            for j in range(n):
                u += self.F[self.I[RANGE_ROWS] + r * n + j] * self.lastx[j]
            g = min(g, u - self.F[self.I[RANGE_BOUNDS] + 2 * r])
            g = min(g, self.F[self.I[RANGE_BOUNDS] + 2 * r + 1] - u)
        return g

    @cython.ccall
    def locate(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.bint:
        """At a stop after a fixed step: a range's bound is located at its root (the time the joint
        reaches it); a switch of coordinates is not (it may happen anywhere near its own root)."""
        g: cython.double = self.stop_margin(t, q, v)
        return g == g and min(self.range_margin(), self.clamp_margin(v), self.slip_margin(v)) < \
            self.c_current - _c_hysteresis * self.c_best

    def conditioning_of(self, joints) -> float:
        """The conditioning of the joints ``joints`` (k indices into the joint rows) at the
        configuration last evaluated."""
        S = np.ascontiguousarray(joints, dtype=np.int64)
        if S.shape != (self.k,) or np.any(S < 0) or np.any(S >= self.nj):
            raise ValueError(f"conditioning_of: {self.k} joint indices in [0, {self.nj}), not {list(joints)}")
        return self._sigma_ratio(S)

    def best_joints(self) -> tuple:
        """The best set of k joints (pivoted QR) at the configuration last evaluated, ascending."""
        self._best_set()
        return tuple(int(b) for b in self.best)

    @cython.ccall
    @cython.exceptval(-1, check=False)
    def start(self, x: cython.double[::1], joints: cython.longlong[::1]) -> cython.bint:
        """Make this a chart of the joints ``joints`` (k indices into the joint rows) at the
        assembled x (n,): its q = R x, K and the sign of det A there. False where A is singular."""
        n: cython.Py_ssize_t = self.n
        kk: cython.Py_ssize_t = self.k
        a: cython.Py_ssize_t
        j: cython.Py_ssize_t
        v: cython.double
        if x.shape[0] != n or joints.shape[0] != kk:
            raise ValueError(f"start: x of {n} coordinates and {kk} joints, not {x.shape[0]} and {joints.shape[0]}")
        for a in range(kk):
            if not 0 <= joints[a] < self.nj:
                raise ValueError(f"start: joint index {joints[a]} outside [0, {self.nj})")
            self.current[a] = joints[a]
            v = 0.0
            for j in range(n):
                self.R[a, j] = self.JR[joints[a], j]
                v += self.R[a, j] * x[j]
            self.target[a] = v
            self.lastq[a] = v
        for j in range(n):
            self.lastx[j] = x[j]
            self.loops.x[j] = x[j]
        # K at x: factor A there (no Newton: x is assembled), any sign
        self.sign = 0
        for a in range(kk):
            for j in range(n):
                self.lastK[a, j] = 0.0
        self.loops._angle_trig()
        self._residual()
        det: cython.double = self.loops._lu_factor()
        self.counts[FACTORS] += 1
        if det == 0.0 or not isfinite(det):
            self.valid = 0
            return False
        self.sign = 1 if det > 0.0 else -1
        self._save_factors()
        self.valid = 0
        for a in range(kk):
            self.startq[a] = self.target[a]
        self.starting = True  # the first closure polishes x, however ill-conditioned: no trust test
        closed: cython.bint = self.evaluate(self.startq)
        self.starting = False
        if not closed:
            return False
        self.startx[:] = self.lastx
        self.startq[:] = self.lastq
        self.startK[:, :] = self.lastK
        return True

    def state(self) -> dict:
        """Copies of the chart's last configuration (x, q, K), the current set and the counts."""
        return {"x": np.array(self.lastx), "q": np.array(self.lastq), "K": np.array(self.K),
                "joints": tuple(int(j) for j in self.current), "counts": np.array(self.counts),
                "J": np.array(self.Jm), "potential": self.potential, "xdot": np.array(self.xdot),
                "xdd0": np.array(self.xdd0), "xdd": np.array(self.xdd), "c": np.array(self.cv)}
