"""Compiled kinematics and Eksergian coefficients of a one-DOF planar linkage (numba).

The one implementation of the reduced model's physics. Everything here works on plain
arrays (:class:`Model`, :class:`Chart`), so that the integrators' loops run without a Python
object; :mod:`reduced.dynamics` builds the arrays from a scene and wraps these functions for
Python callers. Debug with ``NUMBA_DISABLE_JIT=1``: the same functions then run as Python.

Term tables (:mod:`reduced.loops`): row k of a table is r_k(x) = offset_k + Σ_t m_t R(θ_t) w_t
with m_t = x[mag_t] (or 1), θ_t = x[angle_t] (or 0 for ground) and w_t = coef_t e(phase_t).
With u_t = R(θ_t) w_t and u⊥ = (−u_y, u_x):

    ∂r/∂x[angle] = m u⊥,  ∂r/∂x[mag] = u,
    K_r = ṁ u + m θ̇ u⊥,  L_r = m̈ u + (2 ṁ θ̇ + m θ̈) u⊥ − m θ̇² u     (ṁ = K[mag], θ̇ = K[angle], …)

A chart integrates in one coordinate x_i. Its configuration at x_i = value is found in closed
form where the chart's loops are RRR dyads (:func:`_dyads`), else by Newton's method on
A = [Φ_x; e_i] from the quadratic predictor x + K Δ + ½ L Δ² of the chart's last configuration;
K = dx/dx_i and L = d²x/dx_i² solve

    A K = (0, …, 0, 1),      A L = (−γ, 0),   γ = Σ_t 2 ṁ θ̇ u⊥ − m θ̇² u

with the same factorization. Conditioning of coordinate j (Cramer's rule, K w.r.t. x_i):
c_j = |det J_{−j}| / Π_{l≠j} ‖Φ_x[:, l]‖ with |det J_{−j}| = |K_j| |det A|.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, overload
from numba.np.arrayobj import make_array, populate_array

from ._options import NO_RUNTIME, RUNTIME

# Newton: converged when every residual is ≤ NEWTON_TOL (m or rad); the step computed there
# is still applied (polish to round-off) and Φ_x factored once more at the polished x, so that
# K, L and the coefficients are those of the x returned, whatever the walk's history (with the
# factors of the iterate before, f(t, q, q̇) varied by 4e-12 relative with the previous call,
# and DOP853's steps with it). From the quadratic predictor: 2 steps, 3 factorizations.
NEWTON_TOL = 1e-12
NEWTON_MAX_ITER = 20
# A loop's residual cannot fall below the rounding of its angles: ε|θ| of each term's lever
# |m w|. Newton's tolerance is never below NEWTON_ROUND_OFF × Σ |m w| |θ| (4 ulps of it): at
# |θ| ≈ 1e4 rad and 1 m that is 1e-11 m. Without it a drag link coasting at 100 rad/s failed
# after 75 s (7 400 rad), reported as a singular position. Below ~1 000 rad·m it is NEWTON_TOL.
NEWTON_ROUND_OFF = 4 * 2.220446049250313e-16
# Below this conditioning a coordinate cannot drive the linkage (a dead-centre position).
SINGULAR_CONDITIONING = 1e-9
# A Newton correction larger than PREDICTOR_TRUST × the predicted motion |K Δ| (plus
# TRUSTED_CORRECTION, rad or m) means the jump was too long for the predictor: it is taken in
# halves, at most MAX_HALVINGS deep.
PREDICTOR_TRUST = 0.25
TRUSTED_CORRECTION = 1e-9
MAX_HALVINGS = 30
# The halvings of one walk may nest MAX_HALVINGS deep, a tree of up to 2^30 closures: a walk
# whose closures keep failing (seen: a prismatic column of Φ_x written into the wrong row, where
# Newton never converges) would spin for hours. A walk that needs more than MAX_WALK_CLOSURES
# closures fails instead (S[STATUS] = WORK_SPENT), and the run with it. Measured: at most 2
# closures in one walk on every shipped scene with dop853, rkn4 and scipy-dop853; 61 in the
# tests' walks (a chart started at a fold, tests/test_long_walks.py). With the fault planted, a
# walk spent the 20 000 in 0.07 s, and the runs that had spun failed in under 0.1 s.
MAX_WALK_CLOSURES = 20_000
# Beyond a predicted motion of LONG_JUMP (rad, or m) the quadratic predictor cannot tell a
# dependent angle's turn, and the closure nearest to it can be whole turns away: a jump that long
# is halved without trying it. (Closed at once, walks of hundreds of rad had left a crank-rocker's
# coupler and rocker at thousands of rad, where round-off no longer let the loops close; taking
# each angle's turn nearest its base instead put a drag link's rotating angles whole turns off,
# and a force tabulated on q of a dependent input read there: 8e-2 rad of error at rtol 1e-6.)
# Beyond FAR_JUMP a jump is no motion of the run but a trial stage of a blown-up step (seen at
# 4e5 to 3e7 rad at loose rtol, a step the solver then rejects): walked in halves it cost
# seconds to minutes an evaluation, so it is closed at once, each dependent angle on the turn
# nearest its base. A walk of FAR_JUMP costs ~100 closures. Such a jump starts from the base's
# configuration with only x_i moved, not from the predictor: K Δ + ½ L Δ² put the dependent
# angles of a 3e7-rad jump near 1e15 rad, where their rounding alone is 0.1 rad and Newton's
# round-off floor (NEWTON_ROUND_OFF) let configurations 1e-2 rad off pass as closed.
LONG_JUMP = 2.0
FAR_JUMP = 200.0
# Coordinate partitioning: leave a chart when its coordinate is less than HYSTERESIS times as
# well conditioned as the best one (c_i < HYSTERESIS · max_j c_j).
HYSTERESIS = 0.5

# -- the packed layout -------------------------------------------------------------------
# A model is two flat arrays, F (float64) and I (int64); a chart two more, S (int64) and W
# (float64). Few, flat arguments keep numba's compile time small (a named tuple of thirty
# arrays costs ~0.5 s of compilation per function that takes it).
#
# I[0:HEADER] is the header: counts, then offsets of each array in F (or in I).
N, N_ANGLES, N_LINEAR, N_DAMPERS, N_ELEMENTS, N_FORCES, HAS_GRAVITY, MAX_ROWS = range(8)
(DRIVE, MASSES, INERTIAS, GRAVITY, ELEMENT_COEF, ELEMENT_REST, FORCE_DIR, LINEAR, SPLINE_KNOTS, SPLINE_COEF,
 SPLINE_LO, SPLINE_HI, SPLINE_PERIOD, KNOT_START, COEF_START, SPLINE_DEGREE) = range(8, 24)
# Dyads (:func:`_dyads`): DYAD_PLAN, the offset in I of one entry per coordinate i, the first
# step of its plan in DYAD_STEPS or −1 (no plan: Newton alone); DYAD_STEPS, the offset in I of
# (loop, a, b) per step; DYAD_W, the offset in F of (W_a, W_b, φ_a, φ_b) per step (6 floats; φ the
# angle of W).
DYAD_PLAN, DYAD_STEPS, DYAD_W = 24, 25, 26
# Joint elements (dampers, then springs, on a joint's own coordinate u = row·x): their count,
# the count of dampers among them, and the offsets in F of their rows (count, n), coefficients
# and rest values (count,).
N_JOINT_ELEMENTS, N_JOINT_DAMPERS, JOINT_ROWS, JOINT_COEF, JOINT_REST = range(27, 32)
# Timed forces (F(t) along a fixed direction at a point; their points follow the point forces'
# in the FORCE_POINTS table): their count, the offset in F of their directions (count, 2), and of
# the loads on each piece of the run's load history (pieces, 1 + count): the input load, then
# each timed force's value. The integrators pass a piece's index as its ``load``.
N_TIMED, TIMED_DIR, PIECE_VALUES = range(32, 35)
# Term tables (module docstring), 7 header entries each: rows, terms, and the offsets of
# offset (rows, 2) and w (terms, 2) in F and of row, mag, angle (terms,) in I.
LOOPS, CENTRES, ENDS, FORCE_POINTS = range(4)
TABLES = 35
TABLE_ENTRIES = 7
HEADER = TABLES + 4 * TABLE_ENTRIES

# S: INDEPENDENT, SIGN (of det A on the chart's branch; 0 unchecked), STATUS, VALID (the memo
# holds chart.value), then the pivots (n) and the walk's halving budgets (DEPTH).
INDEPENDENT, SIGN, STATUS, VALID = range(4)
S_HEADER = 4
# S[STATUS]: WORK_SPENT, a walk that needed more than MAX_WALK_CLOSURES closures
OK, SINGULAR, WORK_SPENT = 0, 1, 2
# fields: the coefficients at the memo's value, with respect to x_i
(INERTIA, CENTRIFUGAL, POTENTIAL_GRADIENT, DAMPING, POTENTIAL, INPUT_RATE, POINT_FORCE,
 INPUT_CURVATURE, CONDITIONING, BEST_CONDITIONING, BEST, DETERMINANT) = range(12)
N_FIELDS = 12  # then one field per timed force: its generalized rate e·K_P (field_count)
DEPTH = MAX_HALVINGS + 2


class Model(NamedTuple):
    """A scene's reduced model, packed (built by :func:`reduced.dynamics.build_arrays`)."""

    F: np.ndarray
    I: np.ndarray


class Chart(NamedTuple):
    """One chart's state (mutable): S int64, W float64 (layout in :func:`_views`)."""

    S: np.ndarray
    W: np.ndarray


def new_chart(n: int, rows: int, timed: int = 0) -> Chart:
    """An empty chart for a model of n coordinates whose largest table has ``rows`` rows and
    with ``timed`` timed forces."""
    size = 1 + 9 * n + N_FIELDS + timed + n * n + 6 * n + DEPTH * 3 * n + DEPTH + 4 * max(rows, 1)
    return Chart(np.zeros(S_HEADER + n + DEPTH, np.int64), np.zeros(size))


def _view(W, offset, shape):
    """W (C-contiguous) flattened, [offset:offset + prod(shape)], as a C-contiguous view of that
    shape (reshape in Python; in compiled code, :func:`_compiled_view`)."""
    size = 1
    for s in shape:
        size *= s
    return W.reshape(-1)[offset:offset + size].reshape(shape)


@intrinsic
def _compiled_view(typingctx, W, offset, shape):
    """:func:`_view` with the array header built inline, unchecked: numba's ``reshape`` calls a
    C helper on every use (25 ns, most of an evaluation's overhead: the chart's views are taken
    several times per evaluation), and a strided view has a non-contiguous type, on which
    ravel() copies."""
    if W.layout != "C":  # the view is computed from the data pointer: only a C-contiguous W has one
        raise TypeError(f"_view of a {W.layout}-layout array: only C-contiguous arrays have flat views")
    sig = types.Array(W.dtype, len(shape), "C")(W, offset, shape)

    def codegen(context, builder, signature, args):
        source_type = signature.args[0]
        source = make_array(source_type)(context, builder, value=args[0])
        view = make_array(signature.return_type)(context, builder)
        dims = cgutils.unpack_tuple(builder, args[2])
        itemsize = context.get_constant(types.intp, context.get_abi_sizeof(
            context.get_data_type(source_type.dtype)))
        strides = [itemsize]
        for d in reversed(dims[1:]):
            strides.insert(0, builder.mul(strides[0], d))
        # no meminfo: the view is not reference-counted (an atomic increment and decrement per
        # view, 14 views per call of _views), so it must not outlive W: kernels only use
        # views while W is alive in their caller, and never return one
        null = cgutils.get_null_value(source.meminfo.type)
        populate_array(view, data=builder.gep(source.data, [args[1]]), shape=dims, strides=strides,
                       itemsize=itemsize, meminfo=null, parent=cgutils.get_null_value(source.parent.type))
        return view._getvalue()

    return sig, codegen


@overload(_view, jit_options=RUNTIME)
def _view_overload(W, offset, shape):
    return lambda W, offset, shape: _compiled_view(W, offset, shape)


@njit(cache=True, error_model="numpy", **RUNTIME)
def _views(I, W):
    """Views into W: value (1,), start, last, kin (3, n), fields, A (n, n), rhs, trig (2, n),
    norms, x, guess (n,), base (DEPTH, 3, n), target (DEPTH,), rows (MAX_ROWS, 4)."""
    n = I[N]
    o = 0
    value = _view(W, o, (1,))
    o += 1
    start = _view(W, o, (3, n))
    o += 3 * n
    last = _view(W, o, (3, n))
    o += 3 * n
    kin = _view(W, o, (3, n))
    o += 3 * n
    fields = _view(W, o, (N_FIELDS + I[N_TIMED],))
    o += N_FIELDS + I[N_TIMED]
    A = _view(W, o, (n, n))
    o += n * n
    rhs = _view(W, o, (n,))
    o += n
    trig = _view(W, o, (2, n))
    o += 2 * n
    norms = _view(W, o, (n,))
    o += n
    x = _view(W, o, (n,))
    o += n
    guess = _view(W, o, (n,))
    o += n
    base = _view(W, o, (DEPTH, 3, n))
    o += DEPTH * 3 * n
    target = _view(W, o, (DEPTH,))
    o += DEPTH
    rows = _view(W, o, (max(I[MAX_ROWS], 1), 4))
    return value, start, last, kin, fields, A, rhs, trig, norms, x, guess, base, target, rows


# -- small dense linear algebra (n ≲ 50: no LAPACK call overhead) ------------------------

@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def lu_factor(A, piv):
    """LU with partial pivoting of A (n, n) in place, U's diagonal stored as its reciprocals
    (a solve then multiplies: its divisions were most of its latency); returns det A (0.0 if
    singular)."""
    n = A.shape[0]
    det = 1.0
    for k in range(n):
        p = k
        big = abs(A[k, k])
        for r in range(k + 1, n):
            if abs(A[r, k]) > big:
                big = abs(A[r, k])
                p = r
        piv[k] = p
        if big == 0.0:
            return 0.0
        if p != k:
            det = -det
            for c in range(n):
                A[k, c], A[p, c] = A[p, c], A[k, c]
        d = A[k, k]
        det *= d
        inverse = 1.0 / d
        A[k, k] = inverse
        for r in range(k + 1, n):
            f = A[r, k] * inverse
            A[r, k] = f
            for c in range(k + 1, n):
                A[r, c] -= f * A[k, c]
    return det


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def lu_solve(A, piv, b):
    """Solve with :func:`lu_factor`'s factors; b (n,) is overwritten by the solution."""
    n = A.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    for r in range(n):
        s = b[r]
        for c in range(r):
            s -= A[r, c] * b[c]
        b[r] = s
    for r in range(n - 1, -1, -1):
        s = b[r]
        for c in range(r + 1, n):
            s -= A[r, c] * b[c]
        b[r] = s * A[r, r]


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _copy(src, dst):
    """dst[:] = src for two C-contiguous arrays of the same shape (an explicit loop: numba types
    a slice assignment in seconds, this in milliseconds; flat views by :func:`_view`, since
    ravel() goes through reshape's C helper, 25 ns a call, twice per step of a walk)."""
    a = _view(src, 0, (src.size,))
    b = _view(dst, 0, (dst.size,))
    for k in range(a.shape[0]):
        b[k] = a[k]


# -- term tables -----------------------------------------------------------------------

@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def angle_trig(I, x, trig):
    """cos and sin of every body angle x[:n_angles] into trig (2, n)."""
    for j in range(I[N_ANGLES]):
        trig[0, j] = math.cos(x[j])
        trig[1, j] = math.sin(x[j])


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _term(F, I, tb, t, x, trig):
    """Term t of the table whose header starts at tb: (row, mag index, angle index, m, u_x, u_y)
    with u = R(θ) w (module docstring) and m = x[mag] or 1."""
    row, g, a = I[I[tb + 4] + t], I[I[tb + 5] + t], I[I[tb + 6] + t]
    wx, wy = F[I[tb + 3] + 2 * t], F[I[tb + 3] + 2 * t + 1]
    if a >= 0:
        c, s = trig[0, a], trig[1, a]
        wx, wy = wx * c - wy * s, wx * s + wy * c
    return row, g, a, (x[g] if g >= 0 else 1.0), wx, wy


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def table_positions(F, I, table, x, trig, out):
    """r of every row of a table into out[:, 0:2] (m), leaving columns 2, 3 alone."""
    tb = TABLES + TABLE_ENTRIES * table
    off = I[tb + 2]
    for k in range(I[tb]):
        out[k, 0] = F[off + 2 * k]
        out[k, 1] = F[off + 2 * k + 1]
    for t in range(I[tb + 1]):
        k, _, _, m, ux, uy = _term(F, I, tb, t, x, trig)
        out[k, 0] += m * ux
        out[k, 1] += m * uy


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def table_rates(F, I, table, x, trig, K, L, with_l, out):
    """K_r into out[:, 0:2] and L_r into out[:, 2:4] (γ, the part without L, unless with_l)."""
    tb = TABLES + TABLE_ENTRIES * table
    for k in range(I[tb]):
        for c in range(4):
            out[k, c] = 0.0
    for t in range(I[tb + 1]):
        k, g, a, m, ux, uy = _term(F, I, tb, t, x, trig)
        md = K[g] if g >= 0 else 0.0
        td = K[a] if a >= 0 else 0.0
        cu = 2.0 * md * td  # coefficient of u⊥ in L_r
        cn = -m * td * td  # coefficient of u
        if with_l:
            if g >= 0:
                cn += L[g]
            if a >= 0:
                cu += m * L[a]
        out[k, 0] += md * ux - m * td * uy
        out[k, 1] += md * uy + m * td * ux
        out[k, 2] += cn * ux - cu * uy
        out[k, 3] += cn * uy + cu * ux


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def constraints(F, I, x, trig, A, res):
    """Φ(x) into res[:n−1] and Φ_x into A[:n−1, :] (loop rows, then the linear rows).
    Returns the sum of the magnitudes of Φ's terms (m or rad), its round-off scale, and
    Σ |m w| |θ| over the turning terms (m·rad): the scale of the rounding of their angles."""
    n = I[N]
    tb = TABLES + TABLE_ENTRIES * LOOPS
    nl = 2 * I[tb]
    for r in range(n - 1):
        for c in range(n):
            A[r, c] = 0.0
    off = I[tb + 2]
    scale = 0.0
    spread = 0.0
    for r in range(nl):
        res[r] = F[off + r]
        scale += abs(F[off + r])
    for t in range(I[tb + 1]):
        k, g, a, m, ux, uy = _term(F, I, tb, t, x, trig)
        res[2 * k] += m * ux
        res[2 * k + 1] += m * uy
        lever = abs(m) * (abs(ux) + abs(uy))
        scale += lever
        if a >= 0:
            A[2 * k, a] -= m * uy
            A[2 * k + 1, a] += m * ux
            spread += lever * abs(x[a])
        if g >= 0:
            A[2 * k, g] += ux
            A[2 * k + 1, g] += uy
    lin = I[LINEAR]
    for r in range(I[N_LINEAR]):
        v = 0.0
        for c in range(n):
            A[nl + r, c] = F[lin + r * n + c]
            v += F[lin + r * n + c] * x[c]
            scale += abs(F[lin + r * n + c] * x[c])
        res[nl + r] = v
    return scale, spread


# -- closed-form dyads ------------------------------------------------------------------

# cos ψ beyond ±1 by round-off is a flat dyad (the circles touch), beyond this no assembly.
DYAD_ROUND_OFF = 1e-12
# A closed-form configuration is taken as it is when every residual is within this many ε of
# the loop's size (the sum of its terms' magnitudes): near a flat dyad acos loses digits (ψ to
# ~1e-8), and the residual, though ≤ NEWTON_TOL, would leave x off by NEWTON_TOL / σ_min(Φ_x);
# there Newton polishes it as it polishes its own iterates.
CLOSED_FORM_RESIDUAL = 64 * 2.220446049250313e-16
# The closed form gives each angle modulo 2π; the turn is the predictor's. Beyond this predicted
# motion (rad) the predictor cannot tell the turn (a walk back over a whole piece: hundreds of
# rad), and the configuration is left to Newton's method and the walk's halving, which follow it.
CLOSED_FORM_REACH = 0.5


@njit(cache=True, error_model="numpy", **NO_RUNTIME, inline="always")
def _nearest(angle, target):
    """angle + 2πk closest to target (rad)."""
    return target + (angle - target) - 2.0 * math.pi * math.floor((angle - target) / (2.0 * math.pi) + 0.5)


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _dyads(F, I, first, x, base, trig, i):
    """The dependent angles of x by closed form, loop after loop of the plan that starts at step
    ``first`` (:data:`DYAD_PLAN`): each loop k with two unknown angles a, b (the others known:
    the chart's coordinate or solved by an earlier step) and only fixed-length terms reads

        R(θ_a) W_a + R(θ_b) W_b = d,   d = −(offset_k + Σ_known R(θ_t) w_t),

    two circles: the angle ψ of R(θ_a) W_a from d satisfies cos ψ = (|d|² + |W_a|² − |W_b|²) /
    (2 |d| |W_a|). Of the two assemblies (±ψ) the one of the chart's last configuration
    ``base`` (n,) is taken: the sign of R(θ_a) W_a × R(θ_b) W_b, which cannot change along a chart
    (the dyad's 2×2 block of Φ_x would be singular, and so [Φ_x; e_i]); θ_b follows from
    R(θ_b) W_b = d − R(θ_a) W_a; both angles are the 2π-turns nearest x's (the predictor's).
    The cos and sin of every angle (the chart's coordinate i and the solved ones: with a plan,
    all) go into trig (2, n) as they are computed, as :func:`angle_trig` would compute them.
    Returns False where the circles do not meet (no closed loop)."""
    tb = TABLES + TABLE_ENTRIES * LOOPS
    n_loops = I[tb]
    trig[0, i] = math.cos(x[i])
    trig[1, i] = math.sin(x[i])
    for step in range(first, first + n_loops):
        k, a, b = I[I[DYAD_STEPS] + 3 * step], I[I[DYAD_STEPS] + 3 * step + 1], I[I[DYAD_STEPS] + 3 * step + 2]
        w = I[DYAD_W] + 6 * step
        wax, way, wbx, wby, phi_a, phi_b = F[w], F[w + 1], F[w + 2], F[w + 3], F[w + 4], F[w + 5]
        dx, dy = -F[I[tb + 2] + 2 * k], -F[I[tb + 2] + 2 * k + 1]
        for t in range(I[tb + 1]):
            g = I[I[tb + 6] + t]
            if I[I[tb + 4] + t] != k or g == a or g == b:
                continue
            ux, uy = F[I[tb + 3] + 2 * t], F[I[tb + 3] + 2 * t + 1]
            if g >= 0:  # a known angle: i's or solved by an earlier step
                c, sn = trig[0, g], trig[1, g]
                ux, uy = ux * c - uy * sn, ux * sn + uy * c
            dx -= ux
            dy -= uy
        d2 = dx * dx + dy * dy
        ra2 = wax * wax + way * way
        cos_psi = (d2 + ra2 - (wbx * wbx + wby * wby)) / (2.0 * math.sqrt(d2 * ra2))
        if not abs(cos_psi) <= 1.0 + DYAD_ROUND_OFF:
            return False
        # R(θ_a) W_a × (d − R(θ_a) W_a) = −|W_a| |d| sin(±ψ): the +ψ assembly has a negative cross
        # product; in the last configuration R(θ_a) W_a × R(θ_b) W_b = |W_a| |W_b| sin(θ_b + φ_b − θ_a − φ_a)
        last = math.sin(base[b] + phi_b - base[a] - phi_a)
        cos_psi = min(max(cos_psi, -1.0), 1.0)  # a flat dyad, to round-off: Newton polishes it
        sin_psi = math.sqrt(1.0 - cos_psi * cos_psi) if last < 0.0 else -math.sqrt(1.0 - cos_psi * cos_psi)
        # the direction of R(θ_a) W_a, at θ_a + φ_a: d's turned by ±ψ; cos θ_a, sin θ_a turned back by φ_a
        norm = math.sqrt(d2)
        ux, uy = (dx * cos_psi - dy * sin_psi) / norm, (dy * cos_psi + dx * sin_psi) / norm
        ra = math.sqrt(ra2)
        c, sn = (ux * wax + uy * way) / ra, (uy * wax - ux * way) / ra
        x[a] = _nearest(math.atan2(uy, ux) - phi_a, x[a])
        trig[0, a], trig[1, a] = c, sn
        qx, qy = dx - (wax * c - way * sn), dy - (wax * sn + way * c)  # R(θ_b) W_b
        x[b] = _nearest(math.atan2(qy, qx) - phi_b, x[b])
        rq = math.sqrt(qx * qx + qy * qy) * math.sqrt(wbx * wbx + wby * wby)
        if rq > 0.0:
            trig[0, b], trig[1, b] = (qx * wbx + qy * wby) / rq, (qy * wbx - qx * wby) / rq
        else:
            trig[0, b], trig[1, b] = math.cos(x[b]), math.sin(x[b])
    return True


# -- one configuration of a chart --------------------------------------------------------

@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _finish(F, I, S, W, x, det, out):
    """x, K and L into out (3, n) from the factors of A (at x, or round-off from it), and the
    conditioning of every coordinate into the fields."""
    n = I[N]
    _, _, _, _, fields, A, _, trig, norms, _, _, _, _, rows = _views(I, W)
    piv = S[S_HEADER:S_HEADER + n]
    K = out[1]
    for j in range(n):
        K[j] = 0.0
    K[n - 1] = 1.0
    lu_solve(A, piv, K)
    L = out[2]
    table_rates(F, I, LOOPS, x, trig, K, L, False, rows)
    nl = I[TABLES + TABLE_ENTRIES * LOOPS]
    for k in range(nl):
        L[2 * k] = -rows[k, 2]
        L[2 * k + 1] = -rows[k, 3]
    for j in range(2 * nl, n):
        L[j] = 0.0
    lu_solve(A, piv, L)
    for j in range(n):
        out[0, j] = x[j]
    # conditioning of every coordinate: c_j = |K_j| |det A| / Π_{l≠j} ‖col_l‖
    product = 1.0
    zeros = 0
    for j in range(n):
        if norms[j] > 0.0:
            product *= norms[j]
        else:
            zeros += 1
    i = S[INDEPENDENT]
    best, best_j, own = 0.0, 0, 0.0
    for j in range(n):
        if zeros > 1 or (zeros == 1 and norms[j] > 0.0):
            c = 0.0
        else:
            c = abs(K[j]) * abs(det) / (product / norms[j] if norms[j] > 0.0 else product)
        if j == i:
            own = c
        if c > best:
            best, best_j = c, j
    fields[CONDITIONING] = own
    fields[BEST_CONDITIONING] = best
    fields[BEST] = best_j
    fields[DETERMINANT] = det


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _close(F, I, S, W, base, value, reach, out):
    """Newton from base's predictor (rows x, K, L) to x_i = value, whose predicted motion
    max_j |K_j Δ| + ½ |L_j| Δ² is ``reach``; x, K, L into out (3, n).

    Returns 0 (closed, on the chart's branch, not singular) or 1 (failed: no convergence,
    singular, or another branch). Leaves the conditioning and det in the fields.
    """
    n = I[N]
    i = S[INDEPENDENT]
    _, _, _, _, fields, A, res, trig, norms, x, guess, _, _, _ = _views(I, W)
    piv = S[S_HEADER:S_HEADER + n]
    delta = value - base[0, i]
    far = reach > FAR_JUMP  # from the base's configuration (FAR_JUMP)
    for j in range(n):
        x[j] = base[0, j] if far else base[0, j] + base[1, j] * delta + 0.5 * base[2, j] * delta * delta
    x[i] = value
    _copy(x, guess)
    det = 0.0
    converged = False
    factored = False  # at the polished x
    plan = I[I[DYAD_PLAN] + i]
    closed = plan >= 0 and (reach <= CLOSED_FORM_REACH or far)  # x by closed form: taken as it is if it closes the loops
    if closed and not _dyads(F, I, plan, x, base[0], trig, i):
        return 1
    for _ in range(NEWTON_MAX_ITER + 1):
        if not closed:  # the closed form left trig at x
            angle_trig(I, x, trig)
        scale, spread = constraints(F, I, x, trig, A, res)
        largest = 0.0
        for r in range(n - 1):
            if not math.isfinite(res[r]):
                return 1
            largest = max(largest, abs(res[r]))
        for c in range(n):
            v = 0.0
            for r in range(n - 1):
                v += A[r, c] * A[r, c]
            norms[c] = math.sqrt(v)
            A[n - 1, c] = 0.0
        A[n - 1, i] = 1.0
        res[n - 1] = 0.0
        det = lu_factor(A, piv)
        if det == 0.0 or not math.isfinite(det):
            return 1
        if converged or (closed and largest <= CLOSED_FORM_RESIDUAL * scale):
            factored = True
            break
        closed = False  # not closed to round-off: Newton from there
        lu_solve(A, piv, res)
        for j in range(n):
            x[j] -= res[j]
        # converged: the step just taken polishes to round-off
        converged = largest <= max(NEWTON_TOL, NEWTON_ROUND_OFF * spread)
    if not factored:
        return 1
    for j in range(n):
        if not math.isfinite(x[j]):
            return 1
    _finish(F, I, S, W, x, det, out)
    if fields[CONDITIONING] < SINGULAR_CONDITIONING:
        return 1
    if S[SIGN] != 0 and (1 if det >= 0.0 else -1) != S[SIGN]:
        return 1
    return 0


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _walk(F, I, S, W, value):
    """Continue the chart from its last configuration to x_i = value, halving untrusted
    jumps; the result in kin and last. Returns OK, SINGULAR (no closure within the halvings)
    or WORK_SPENT (more than MAX_WALK_CLOSURES closures)."""
    n = I[N]
    i = S[INDEPENDENT]
    _, _, last, kin, _, _, _, _, _, _, guess, base, target, _ = _views(I, W)
    budget = S[S_HEADER + n:S_HEADER + n + DEPTH]
    _copy(last, base[0])
    target[0] = value
    budget[0] = MAX_HALVINGS
    depth = 0  # base[d] is the configuration from which target[d] is sought
    closures = 0
    while True:
        delta = target[depth] - base[depth, 0, i]
        predicted = 0.0  # the jump's predicted motion, max_j |K_j Δ| + ½ |L_j| Δ²
        for j in range(n):
            predicted = max(predicted, abs(base[depth, 1, j] * delta) + 0.5 * abs(base[depth, 2, j]) * delta * delta)
        failed = trusted = False  # a jump beyond LONG_JUMP (up to FAR_JUMP) is halved untried
        if predicted <= LONG_JUMP or predicted > FAR_JUMP or budget[depth] <= 0:
            if closures == MAX_WALK_CLOSURES:
                return WORK_SPENT
            closures += 1
            failed = _close(F, I, S, W, base[depth], target[depth], predicted, kin) != 0
            if not failed:
                moved = 0.0
                for j in range(n):
                    moved = max(moved, abs(kin[0, j] - guess[j]))
                trusted = moved <= PREDICTOR_TRUST * predicted + TRUSTED_CORRECTION
        if failed and budget[depth] <= 0:
            return SINGULAR
        if trusted or budget[depth] <= 0:
            if predicted > LONG_JUMP:  # closed at once: the turns nearest the base's
                for j in range(I[N_ANGLES]):
                    if j != i:
                        kin[0, j] = _nearest(kin[0, j], base[depth, 0, j])
            if depth == 0:
                break
            # the midpoint is reached: it is the base of the second half, one level down
            depth -= 1
            _copy(kin, base[depth])
            budget[depth] -= 1
            continue
        # halve: seek the midpoint first, then the target from there
        _copy(base[depth], base[depth + 1])
        target[depth + 1] = base[depth, 0, i] + 0.5 * (target[depth] - base[depth, 0, i])
        budget[depth + 1] = budget[depth] - 1
        depth += 1
    _copy(kin, last)
    return OK


@njit(cache=True, error_model="numpy", **RUNTIME)
def point_force_value(F, I, p, q):
    """F_p(q) (N): the B-spline of point force p at the input coordinate q (de Boor)."""
    lo, hi, period = F[I[SPLINE_LO] + p], F[I[SPLINE_HI] + p], F[I[SPLINE_PERIOD] + p]
    if period > 0.0:
        q = lo + (q - lo) - period * math.floor((q - lo) / period)
    else:
        q = min(max(q, lo), hi)
    t0 = I[SPLINE_KNOTS] + I[I[KNOT_START] + p]
    c0 = I[SPLINE_COEF] + I[I[COEF_START] + p]
    nc = I[I[COEF_START] + p + 1] - I[I[COEF_START] + p]
    k = I[I[SPLINE_DEGREE] + p]
    l = k
    while l < nc - 1 and F[t0 + l + 1] <= q:
        l += 1
    d = np.empty(k + 1)
    for j in range(k + 1):
        d[j] = F[c0 + l - k + j]
    for r in range(1, k + 1):
        for j in range(k, r - 1, -1):
            left = F[t0 + j + l - k]
            alpha = (q - left) / (F[t0 + j + 1 + l - r] - left)
            d[j] = (1.0 - alpha) * d[j - 1] + alpha * d[j]
    return d[k]


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _coefficients(F, I, S, W):
    """Eksergian's coefficients at the chart's kin into its fields (reduced.dynamics documents
    them). Uses the trig of the last Newton iteration (round-off from kin's x)."""
    _, _, _, kin, fields, _, _, trig, _, _, _, _, _, rows = _views(I, W)
    x, K, L = kin[0], kin[1], kin[2]
    nb = I[N_ANGLES]
    ms, ins = I[MASSES], I[INERTIAS]
    table_rates(F, I, CENTRES, x, trig, K, L, True, rows)
    J, zeta = 0.0, 0.0
    for b in range(nb):
        m, inertia = F[ms + b], F[ins + b]
        J += m * (rows[b, 0] * rows[b, 0] + rows[b, 1] * rows[b, 1]) + inertia * K[b] * K[b]
        zeta += m * (rows[b, 0] * rows[b, 2] + rows[b, 1] * rows[b, 3]) + inertia * K[b] * L[b]
    dV, V, damping, force = 0.0, 0.0, 0.0, 0.0
    if I[HAS_GRAVITY]:
        gx, gy = F[I[GRAVITY]], F[I[GRAVITY] + 1]
        for b in range(nb):
            dV -= F[ms + b] * (gx * rows[b, 0] + gy * rows[b, 1])
        table_positions(F, I, CENTRES, x, trig, rows)
        for b in range(nb):
            V -= F[ms + b] * (gx * rows[b, 0] + gy * rows[b, 1])
    ne = I[N_ELEMENTS]
    if ne:
        table_rates(F, I, ENDS, x, trig, K, L, False, rows)
        for e in range(ne):  # K_a − K_b into columns 2, 3 of row 2e, kept by table_positions
            rows[2 * e, 2] = rows[2 * e, 0] - rows[2 * e + 1, 0]
            rows[2 * e, 3] = rows[2 * e, 1] - rows[2 * e + 1, 1]
        table_positions(F, I, ENDS, x, trig, rows)
        for e in range(ne):
            dx = rows[2 * e, 0] - rows[2 * e + 1, 0]
            dy = rows[2 * e, 1] - rows[2 * e + 1, 1]
            length = math.sqrt(dx * dx + dy * dy)
            k_d = (dx * rows[2 * e, 2] + dy * rows[2 * e, 3]) / length  # K_D = dD/dx_i
            c = F[I[ELEMENT_COEF] + e]
            if e < I[N_DAMPERS]:
                damping += c * k_d * k_d
            else:
                stretch = length - F[I[ELEMENT_REST] + e]
                dV += c * stretch * k_d
                V += 0.5 * c * stretch * stretch
    nj = I[N_JOINT_ELEMENTS]
    if nj:
        n = I[N]
        rows_at = I[JOINT_ROWS]
        for e in range(nj):  # u = row·x, K_u = du/dx_i = row·K
            u, k_u = 0.0, 0.0
            for j in range(n):
                r = F[rows_at + e * n + j]
                u += r * x[j]
                k_u += r * K[j]
            c = F[I[JOINT_COEF] + e]
            if e < I[N_JOINT_DAMPERS]:
                damping += c * k_u * k_u
            else:
                stretch = u - F[I[JOINT_REST] + e]
                dV += c * stretch * k_u
                V += 0.5 * c * stretch * stretch
    rate, curvature, q = 0.0, 0.0, 0.0
    for j in range(I[N]):
        d = F[I[DRIVE] + j]
        rate += d * K[j]
        curvature += d * L[j]
        q += d * x[j]
    nf, nt = I[N_FORCES], I[N_TIMED]
    if nf or nt:
        table_rates(F, I, FORCE_POINTS, x, trig, K, L, False, rows)
        fd = I[FORCE_DIR]
        for p in range(nf):
            along = rows[p, 0] * F[fd + 2 * p] + rows[p, 1] * F[fd + 2 * p + 1]
            force += point_force_value(F, I, p, q) * along
        td = I[TIMED_DIR]
        for p in range(nt):  # the generalized rate of timed force p: its force is F_p(t) times this
            fields[N_FIELDS + p] = rows[nf + p, 0] * F[td + 2 * p] + rows[nf + p, 1] * F[td + 2 * p + 1]
    fields[INERTIA] = J
    fields[CENTRIFUGAL] = zeta
    fields[POTENTIAL_GRADIENT] = dV
    fields[DAMPING] = damping
    fields[POTENTIAL] = V
    fields[INPUT_RATE] = rate
    fields[POINT_FORCE] = force
    fields[INPUT_CURVATURE] = curvature


# -- the chart interface -------------------------------------------------------------------

@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def evaluate(model, chart, value):
    """The chart's configuration and coefficients at x_i = value (memoized): True on success,
    else S[STATUS] = SINGULAR (no closed loop, a singular position or another branch within
    reach of the walk) or WORK_SPENT (the walk needed more than MAX_WALK_CLOSURES closures)."""
    F, I = model
    S, W = chart
    if S[VALID] == 1 and W[0] == value:
        return True
    S[VALID] = 0
    status = _walk(F, I, S, W, value)
    if status != OK:
        S[STATUS] = status
        return False
    _coefficients(F, I, S, W)
    W[0] = value
    S[VALID] = 1
    return True


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def _applied(F, I, f, piece):
    """The generalized force of the loads (N·m or N) at fields f on load piece ``piece`` (its
    index, a float): T·dq/dx_i + Σ F_p(q) e·K_P + Σ F_p(t) e·K_P, the loads over time those of
    the piece (PIECE_VALUES)."""
    nt = I[N_TIMED]
    row = I[PIECE_VALUES] + int(piece) * (1 + nt)
    g = F[row] * f[INPUT_RATE] + f[POINT_FORCE]
    for p in range(nt):
        g += F[row + 1 + p] * f[N_FIELDS + p]
    return g


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def acceleration(model, chart, load, t, value, rate):
    """ẍ_i from Eksergian's equation on load piece ``load`` (its index: the loads over time are
    constant on it, :func:`_applied`): (Q_applied − b ẋ_i − ζ ẋ_i² − dV/dx_i) / 𝔍. NaN when the
    configuration cannot be found (the chart's S[STATUS] says why)."""
    if not evaluate(model, chart, value):
        return math.nan
    f = _views(model[1], chart[1])[4]
    Q = _applied(model[0], model[1], f, load) - f[DAMPING] * rate
    return (Q - f[CENTRIFUGAL] * rate * rate - f[POTENTIAL_GRADIENT]) / f[INERTIA]


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def power(model, chart, load, rate):
    """(P, D) at the configuration last evaluated, right after its ``acceleration``: the power
    P = Q_applied ẋ_i of the input load and the point forces over q and t on load piece ``load``
    (W) and the dampers' dissipation rate D = Σ b K_D² ẋ_i² (W); the energy audit integrates both."""
    f = _views(model[1], chart[1])[4]
    return _applied(model[0], model[1], f, load) * rate, f[DAMPING] * rate * rate


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def observation_size(model):
    """Length of :func:`observe`'s row: the fields, then x, K and L (N_FIELDS + timed + 3 n)."""
    return N_FIELDS + model[1][N_TIMED] + 3 * model[1][N]


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def observe(model, chart, out):
    """The chart's configuration last evaluated, into ``out`` (:func:`observation_size`,): its
    coefficient fields, then x, K and L (n each) — what the outputs and the energy audit need
    at a sample, recorded where the integrator evaluated it instead of walked to again."""
    views = _views(model[1], chart[1])
    fields, kin = views[4], views[3]
    n = model[1][N]
    nf = N_FIELDS + model[1][N_TIMED]
    for k in range(nf):
        out[k] = fields[k]
    for r in range(3):
        for j in range(n):
            out[nf + r * n + j] = kin[r, j]


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def stop_margin(model, chart, t, value, rate):
    """> 0 while the chart's coordinate is good enough; ≤ 0 when another is better by more
    than the hysteresis (c_i < HYSTERESIS · max_j c_j). −1 where the configuration fails."""
    if not evaluate(model, chart, value):
        return -1.0
    f = _views(model[1], chart[1])[4]
    return f[CONDITIONING] - HYSTERESIS * f[BEST_CONDITIONING]


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def kinematics_at(model, chart, x, row):
    """K = dx/dp, L = d²x/dp² and the coefficients at an assembled x (n,) for the coordinate
    p = row·x (the input's drive row, or e_i), into the chart's kin and fields. Returns False
    where p cannot drive the linkage: the Hadamard ratio |det A| / Π ‖A[:, l]‖ of
    A = [Φ_x; row] below SINGULAR_CONDITIONING. S[INDEPENDENT] should be −1 unless row is e_i."""
    F, I = model
    S, W = chart
    n = I[N]
    _, _, _, kin, _, A, res, trig, norms, _, _, _, _, _ = _views(I, W)
    angle_trig(I, x, trig)
    constraints(F, I, x, trig, A, res)
    hadamard = 1.0
    for c in range(n):
        v = 0.0
        for r in range(n - 1):
            v += A[r, c] * A[r, c]
        norms[c] = math.sqrt(v)
        A[n - 1, c] = row[c]
        hadamard *= math.sqrt(v + row[c] * row[c])
    det = lu_factor(A, S[S_HEADER:S_HEADER + n])
    S[VALID] = 0  # not a chart value: the memo is not valid for evaluate()
    if det == 0.0 or not math.isfinite(det) or abs(det) < SINGULAR_CONDITIONING * hadamard:
        S[STATUS] = SINGULAR
        return False
    _finish(F, I, S, W, x, det, kin)
    _coefficients(F, I, S, W)
    return True


@njit(cache=True, error_model="numpy", **RUNTIME)
def start_chart(model, chart, x, independent):
    """Make ``chart`` a chart of coordinate ``independent`` starting at the assembled x (n,):
    its K, L there and the sign of its det A. Returns True on success (False: singular)."""
    F, I = model
    S, W = chart
    n = I[N]
    _, start, last, kin, fields, _, _, _, _, _, guess, _, _, _ = _views(I, W)
    S[INDEPENDENT] = independent
    S[SIGN] = 0
    S[STATUS] = OK
    for j in range(n):
        guess[j] = 0.0
    guess[independent] = 1.0
    if not kinematics_at(model, chart, x, guess.copy()) or fields[CONDITIONING] < SINGULAR_CONDITIONING:
        S[STATUS] = SINGULAR
        return False
    S[SIGN] = 1 if fields[DETERMINANT] >= 0.0 else -1
    _copy(kin, last)
    _copy(kin, start)
    W[0] = x[independent]
    S[VALID] = 1
    return True


@njit(cache=True, error_model="numpy", **RUNTIME)
def mark(model, chart):
    """A copy (3, n) of the chart's last configuration (x, K, L), for :func:`rewind`."""
    last = _views(model[1], chart[1])[2]
    marked = np.empty((3, model[1][N]))
    _copy(last, marked)
    return marked


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def rewind(model, chart, marked):
    """Continue the chart's walk from the configuration :func:`mark` took. The integrators
    walk a piece's samples this way, forwards from its start in short jumps, rather than back
    from its end in one walk of hundreds of rad (halved down to :data:`LONG_JUMP`)."""
    S, W = chart
    last = _views(model[1], W)[2]
    _copy(marked, last)
    S[VALID] = 0


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def reset(model, chart):
    """Back to the chart's start configuration (a new walk along the chart)."""
    rewind(model, chart, _views(model[1], chart[1])[1])
    chart[0][STATUS] = OK


@njit(cache=True, error_model="numpy", **NO_RUNTIME)
def walk(model, chart, values, fields, kin):
    """Reset the chart and evaluate it at each of ``values`` in turn: fields (m, field_count) and
    kinematics (m, 3, n) of each. Returns the number evaluated (< m where it failed)."""
    reset(model, chart)
    views = _views(model[1], chart[1])
    for s in range(values.shape[0]):
        if not evaluate(model, chart, values[s]):
            return s
        _copy(views[4], fields[s])
        _copy(views[3], kin[s])
    return values.shape[0]


def field_count(model: Model) -> int:
    """Length of a chart's fields: N_FIELDS, then one per timed force."""
    return N_FIELDS + int(model.I[N_TIMED])


def chart_arrays(model: Model, chart: Chart) -> dict[str, np.ndarray]:
    """Named views of a chart's state (Python callers): start, last, kin, fields."""
    value, start, last, kin, fields = getattr(_views, "py_func", _views)(model.I, chart.W)[:5]
    return {"value": value, "start": start, "last": last, "kin": kin, "fields": fields}
