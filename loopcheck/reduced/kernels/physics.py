"""Eksergian coefficients and the chart walk of a one-DOF planar linkage, compiled (Cython).

The one implementation of the reduced model's physics, over the linkage's compiled kinematics
(:class:`loopcheck.kernels.loops.Loops`: term tables, Φ and Φ_x, the LU, K, L and the conditioning,
which a chart holds and calls). A scene's model is two plain arrays
(:class:`Model`), and a chart (:class:`Chart`) is a compiled object holding its state in two
more and the integrators' interface (:class:`.problem.RightHandSide`), so that the integrators'
loops run without a Python object; :mod:`loopcheck.reduced.dynamics` builds the arrays from a scene and
wraps the chart for Python callers. Debug with ``LOOPCHECK_PURE_PYTHON=1``: this file then runs as
plain Python (:mod:`loopcheck.reduced.kernels`).

Term tables (:mod:`loopcheck.kernels.loops`): row k of a table is r_k(x) = offset_k + Σ_t m_t R(θ_t) w_t
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
c_j = |det J_{−j}| / Π_{l≠j} ‖Φ_x[:, l]‖ with |det J_{−j}| = |K_j| |det A|: the project's one
singular-position measure (:mod:`loopcheck.kernels.loops` evaluates it, as
:func:`loopcheck.kinematics.driving_conditioning` does through it), compared with the threshold the
chart is built with (``Chart(model, singular)``). The walk, the closed-form dyads and Eksergian's
coefficients are this module's; the term tables, Φ, Φ_x, the LU, K, L and the conditioning are
:class:`~loopcheck.kernels.loops.Loops`'s C methods, moved there with their arithmetic unchanged.

Compiled: the integer constants of the packed layout (below) are C constants declared in
``physics.pxd`` (a ``cpdef enum``: importable from Python with the same values; the block
``if not cython.compiled`` here defines them for plain Python, and
``tests/reduced/kernels/test_physics_port.py`` checks that the two agree); the numerical constants are Python
names with a C copy each (``_c_…``) that the kernels read. The arithmetic keeps the order of
every expression (the build does not contract a*b+c or reassociate), so that it gives the same
numbers as plain Python, and as the numba core it replaced: compared on every shipped scene and
the tests' timed-force and joint-element scenes, with and without dyad plans (24 624
evaluations along, back and in long jumps), not one bit differed.
"""

import math
from typing import NamedTuple

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import atan2, cos, fabs, floor, isfinite, sin, sqrt
    from cython.cimports.libc.string import memcpy
    from cython.cimports.loopcheck.kernels.loops import LOOPS, N, N_ANGLES, TABLE_ENTRIES, TABLES, Loops
    from cython.cimports.loopcheck.reduced.kernels.problem import RightHandSide
else:
    from math import atan2, cos, fabs, floor, isfinite, sin, sqrt

    from loopcheck.kernels.loops import LOOPS, N, N_ANGLES, TABLE_ENTRIES, TABLES, Loops
    from loopcheck.reduced.kernels.problem import RightHandSide

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
# tests' walks (a chart started at a fold, tests/reduced/test_long_walks.py). With the fault planted, a
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
# A joint friction's K_u within KINK_ROOT of its size (Σ |row_l K_l|) where another's kink fired is
# at its root too (its joint's rate proportional to the other's): its watch flips with it (else
# the two, at each other's roots, would fire in turn without end).
KINK_ROOT = 1e-9
# Coordinate partitioning: leave a chart when its coordinate is less than HYSTERESIS times as
# well conditioned as the best one (c_i < HYSTERESIS · max_j c_j).
HYSTERESIS = 0.5
# A clamp's mode changes where its unclamped force f_u crosses a bound by CLAMP_HYSTERESIS times the
# larger finite bound's magnitude (N·m or N): free → hi at f_u = hi + ε, hi → free at f_u = hi − ε,
# so that the mode the run then sets by value (:meth:`Chart.set_clamps`) has a margin of ~2ε at the
# root, far above the root's own error (brentq's 4 ε_mach in t, times ḟ_u), and the integrator
# restarts with every margin positive, as after a chart switch. The force is then off by at most ε
# for the ~2ε/|ḟ_u| s around the kink.
CLAMP_HYSTERESIS = 1e-9

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


# -- the packed layout -------------------------------------------------------------------
# A model is two flat arrays, F (float64) and I (int64); a chart holds two more, S (int64) and
# W (float64), and typed views of their parts (:class:`Chart`).
#
# I[0:KIN_HEADER] is the linkage's kinematics (:mod:`loopcheck.kernels.loops`: counts, the linear
# rows, the term tables, of which LOOPS is the loops'); I[KIN_HEADER:HEADER] this model's header:
# counts, then offsets of each array in F (or in I).
# Compiled, these are the C constants of physics.pxd (module docstring): keep both in step.
if not cython.compiled:
    N_DAMPERS, N_ELEMENTS, N_FORCES, HAS_GRAVITY = range(33, 37)
    (DRIVE, MASSES, INERTIAS, GRAVITY, ELEMENT_COEF, ELEMENT_REST, FORCE_DIR, SPLINE_KNOTS, SPLINE_COEF,
     SPLINE_LO, SPLINE_HI, SPLINE_PERIOD, KNOT_START, COEF_START, SPLINE_DEGREE) = range(37, 52)
    # Dyads (:func:`_dyads`): DYAD_PLAN, the offset in I of one entry per coordinate i, the first
    # step of its plan in DYAD_STEPS or −1 (no plan: Newton alone); DYAD_STEPS, the offset in I of
    # (loop, a, b) per step; DYAD_W, the offset in F of (W_a, W_b, φ_a, φ_b) per step (6 floats; φ
    # the angle of W).
    DYAD_PLAN, DYAD_STEPS, DYAD_W = 52, 53, 54
    # Joint elements (dampers, then springs, then inertias, on a joint's own coordinate u = row·x):
    # their count, the count of dampers among them, and the offsets in F of their rows (count, n),
    # coefficients and rest values (count,); N_JOINT_INERTIAS (last in the header), the count of
    # inertias, the last elements.
    N_JOINT_ELEMENTS, N_JOINT_DAMPERS, JOINT_ROWS, JOINT_COEF, JOINT_REST = range(55, 60)
    # Timed forces (F(t) along a fixed direction at a point; their points follow the point forces'
    # in the FORCE_POINTS table): their count, the offset in F of their directions (count, 2), and
    # of the loads on each piece of the run's load history (pieces, 1 + count): the input load,
    # then each timed force's value. The integrators pass a piece's index as its ``load``.
    N_TIMED, TIMED_DIR, PIECE_VALUES = range(60, 63)
    # The kinematics' term tables besides LOOPS: the centres of mass, the line elements' end
    # points, the points of the point and timed forces.
    CENTRES, ENDS, FORCE_POINTS = range(1, 4)
    N_JOINT_INERTIAS = 63
    # Actuators (loopcheck.mechanism.Actuator; header slots 64..71, 69..71 unused): their count, the
    # offset in F of their transmissions' rows (count, n: l = row·x, the tendon's Σ c_j joint rows),
    # of their parameters (count, 5: b1·gear, b2·gear, gear, force lo, force hi; ±inf unclamped) and
    # of their state-independent force on each load piece (pieces, count: gain·clamp(ctrl) + b0).
    N_ACTUATORS, ACT_ROWS, ACT_PARAMS, ACT_PIECE = range(64, 68)
    # N_CLAMPED: the count of actuators whose forcerange clamps a force that depends on the state
    # (b1 or b2 nonzero, lo < hi, a finite bound): each clamp's switching is an event (slots 69..71
    # unused).
    N_CLAMPED = 68
    # Events (:meth:`Chart.stop_margin`): joint friction (static = kinetic Coulomb friction f on a
    # joint's own coordinate u = row·x, MuJoCo's frictionloss): its count and the offsets in F of
    # its rows (count, n) and coefficients f (count,); joint ranges: their count, and the offsets
    # in F of their rows (count, n) and bounds (count, 2: lo, hi). Slots 78, 79 are reserved.
    N_FRICTION, FRICTION_ROWS, FRICTION_COEF, N_RANGES, RANGE_ROWS, RANGE_BOUNDS = range(72, 78)
    HEADER = 80

    # S: INDEPENDENT, SIGN (of det A on the chart's branch; 0 unchecked), STATUS, VALID (the memo
    # holds the chart's value), then the walk's halving budgets (DEPTH).
    INDEPENDENT, SIGN, STATUS, VALID = range(4)
    S_HEADER = 4
    # S[STATUS]: WORK_SPENT, a walk that needed more than MAX_WALK_CLOSURES closures
    OK, SINGULAR, WORK_SPENT = 0, 1, 2
    # fields: the coefficients at the memo's value, with respect to x_i
    (INERTIA, CENTRIFUGAL, POTENTIAL_GRADIENT, DAMPING, POTENTIAL, INPUT_RATE, POINT_FORCE,
     INPUT_CURVATURE, CONDITIONING, BEST_CONDITIONING, BEST, DETERMINANT) = range(12)
    # fields 12, 13 are the actuators' (reserved, 0), 14, 15 the events' (below)
    ACTUATOR_FIELD_A, ACTUATOR_FIELD_B = 12, 13
    # then one field per timed force: its generalized rate e·K_P, then two per actuator: its
    # transmission's length l and dl/dx_i (field_count)
    # FRICTION_CAPACITY: C = Σ f |K_u|, the friction's largest generalized force (N·m or N);
    # FRICTION_MODE: +1 or −1 slipping that way (friction −mode·C), STICK (q̇ = q̈ = 0), 0 (unset:
    # slipping in the sign of q̇). Set by the run (set_friction), kept by the evaluations. Fields
    # 12, 13 are reserved.
    FRICTION_CAPACITY, FRICTION_MODE = 14, 15
    N_FIELDS = 16
    STICK = 2
    # the events a stop can be (Chart.fired): the chart's coordinate worse than another, the
    # friction's slip → stick or stick → slip, a joint's range (RANGE_EVENT + 2 r + side, side 0
    # its lower bound, 1 its upper), a friction's kink (RANGE_EVENT + 2 N_RANGES + j: joint
    # friction j's K_u changes sign while slipping, where its force −f |K_u| s has a kink)
    SWITCH_EVENT, FRICTION_EVENT, RANGE_EVENT = 0, 1, 2
    # then one event per actuator a (clamped or not: an unclamped one never fires), numbered
    # RANGE_EVENT + 2 N_RANGES + N_FRICTION + a: its force's clamp switching (:meth:`Chart.clamp_event`). Each
    # clamped actuator has a mode (the chart's ``clamp``, set by the run: :meth:`Chart.set_clamps`):
    # CLAMP_FREE (f = the unclamped force f_u, between the bounds), CLAMP_HI (f = hi), CLAMP_LO
    # (f = lo), or CLAMP_AUTO (f = clamp(f_u, lo, hi) by value: the default, and every actuator's
    # force at rest, rest_force's and the stick's).
    CLAMP_FREE, CLAMP_HI, CLAMP_LO, CLAMP_AUTO = 0, 1, -1, 2
    DEPTH = MAX_HALVINGS + 2

# C copies of the numerical constants above, which the kernels read (compiled, a module's
# Python name costs a dictionary lookup and an unboxing at every use). Plain Python reads them
# too: a test that changes a bound changes the copy (tests/reduced/kernels/test_work_bounds.py).
_c_newton_tol = cython.declare(cython.double, NEWTON_TOL)
_c_newton_max_iter = cython.declare(cython.Py_ssize_t, NEWTON_MAX_ITER)
_c_newton_round_off = cython.declare(cython.double, NEWTON_ROUND_OFF)
_c_predictor_trust = cython.declare(cython.double, PREDICTOR_TRUST)
_c_trusted_correction = cython.declare(cython.double, TRUSTED_CORRECTION)
_c_max_halvings = cython.declare(cython.longlong, MAX_HALVINGS)
_c_max_walk_closures = cython.declare(cython.Py_ssize_t, MAX_WALK_CLOSURES)
_c_long_jump = cython.declare(cython.double, LONG_JUMP)
_c_far_jump = cython.declare(cython.double, FAR_JUMP)
_c_hysteresis = cython.declare(cython.double, HYSTERESIS)
_c_kink_root = cython.declare(cython.double, KINK_ROOT)
_c_clamp_hysteresis = cython.declare(cython.double, CLAMP_HYSTERESIS)
_c_dyad_round_off = cython.declare(cython.double, DYAD_ROUND_OFF)
_c_closed_form_residual = cython.declare(cython.double, CLOSED_FORM_RESIDUAL)
_c_closed_form_reach = cython.declare(cython.double, CLOSED_FORM_REACH)
_c_pi = cython.declare(cython.double, math.pi)
_c_inv_two_pi = cython.declare(cython.double, 0.5 / math.pi)
_c_nan = cython.declare(cython.double, math.nan)


class Model(NamedTuple):
    """A scene's reduced model, packed (built by :func:`loopcheck.reduced.dynamics.build_arrays`)."""

    F: np.ndarray
    I: np.ndarray


def field_count(model: Model) -> int:
    """Length of a chart's fields: N_FIELDS, then one per timed force, then two per actuator."""
    return N_FIELDS + int(model.I[N_TIMED]) + 2 * int(model.I[N_ACTUATORS])


# -- closed-form dyads ------------------------------------------------------------------

@cython.cfunc
@cython.inline
def _nearest(angle: cython.double, target: cython.double) -> cython.double:
    """angle + 2πk closest to target (rad)."""
    return target + (angle - target) - 2.0 * _c_pi * floor((angle - target) * _c_inv_two_pi + 0.5)


@cython.ccall
def _dyads(F: cython.double[::1], I: cython.longlong[::1], first: cython.Py_ssize_t, x: cython.double[::1],
           base: cython.double[::1], trig: cython.double[:, ::1], i: cython.Py_ssize_t) -> cython.bint:
    """:meth:`Chart._dyads` on the arrays of a model (F, I), from the predictor x (n,) with the
    last configuration ``base`` (n,): x and trig (2, n) are overwritten as the chart's would be.
    Returns False where the circles do not meet (no closed loop). (For tests: a chart calls its
    method, on its own views.)"""
    n: cython.Py_ssize_t = x.shape[0]
    j: cython.Py_ssize_t
    chart: Chart = Chart(Model(np.asarray(F), np.asarray(I)), 0.5)
    for j in range(n):
        chart.x[j] = x[j]
        chart.last[0, j] = base[j]
        chart.trig[0, j] = trig[0, j]
        chart.trig[1, j] = trig[1, j]
    chart._dyad_sides(first)
    closed: cython.bint = chart._dyads(first, i) == 1
    for j in range(n):
        x[j] = chart.x[j]
        trig[0, j] = chart.trig[0, j]
        trig[1, j] = chart.trig[1, j]
    return closed


# -- the chart -------------------------------------------------------------------------------

@cython.final
@cython.cclass
class Chart(RightHandSide):
    """One chart of a model: its state, q̈ in its coordinate, its walk (compiled).

    ``Chart(model)`` allocates the state for ``model`` (:class:`Model`): S (int64: INDEPENDENT,
    SIGN, STATUS, VALID, the walk's halving budgets (DEPTH)) and W (float64: value (1,), start,
    last (3, n), fields (field_count), guess (n,), base (DEPTH, 3, n), target (DEPTH,), clamp (the
    actuators' clamp modes, CLAMP_AUTO until the run sets them)), both numpy
    arrays (``chart.S[STATUS]`` says why an evaluation failed), and typed views of their parts,
    made once here (the start view is ``origin``: ``start`` is the method). The kernels below
    are methods that read and write these views and take no array argument (compiled, an array
    argument is a 200-byte view passed by value, and a view made in a call changes a reference
    count atomically: written as functions of arrays, an evaluation on the seed took 1 950 ns,
    as methods 763). Besides W, a chart owns the configuration :meth:`mark` keeps (3, n), the
    assembly of each of its dyads (``dyad_sides``, one per loop: :meth:`_dyad_sides`), the
    scratch of the B-splines (the largest degree + 1), and the linkage's kinematics (``loops``, a
    :class:`loopcheck.kernels.loops.Loops` on the model's arrays: Newton's x, trig, A, rhs, norms, rows
    and kin (3, n: x, K, L), which the chart views under the same names). A chart is empty until
    :meth:`start`.

    ``singular`` is the singular-position threshold: below this conditioning a coordinate cannot
    drive the linkage (:data:`loopcheck.kinematics.SINGULAR_CONDITIONING`, which the reduced engine
    passes in: the compiled core imports nothing of the project outside it but the kinematics' kernel).
    """

    def __init__(self, model: Model, singular: float):
        if not 0.0 < singular < 1.0:
            raise ValueError(f"Chart: the singular-position threshold is a conditioning in (0, 1), not {singular}")
        self.singular = singular
        F = np.ascontiguousarray(model.F, dtype=np.float64)
        I = np.ascontiguousarray(model.I, dtype=np.int64)
        self.model = Model(F, I)
        self.F = F
        self.I = I
        n = int(I[N])
        self.n = n
        nfields = N_FIELDS + int(I[N_TIMED]) + 2 * int(I[N_ACTUATORS])
        na = int(I[N_ACTUATORS])
        size = 1 + 9 * n + nfields + n + DEPTH * 3 * n + DEPTH + na
        self.S = np.zeros(S_HEADER + DEPTH, np.int64)
        self.W = np.zeros(size)
        self.s = self.S
        self.budget = self.S[S_HEADER:S_HEADER + DEPTH]
        views = []
        o = 0
        for shape in ((1,), (3, n), (3, n), (nfields,), (n,), (DEPTH, 3, n), (DEPTH,), (na,)):
            size = math.prod(shape)
            views.append(self.W[o:o + size].reshape(shape))
            o += size
        self.value, self.origin, self.last, self.fields, self.guess, self.base, self.target, self.clamp = views
        self.W[o - na:o] = CLAMP_AUTO
        # the linkage's kinematics, and views of its scratch under the names the methods below use
        self.loops = Loops(F, I)
        self.x, self.trig, self.A, self.rhs = self.loops.x, self.loops.trig, self.loops.A, self.loops.rhs
        self.norms, self.rows, self.kin = self.loops.norms, self.loops.rows, self.loops.kin
        self.K, self.L = self.loops.K, self.loops.L
        self.marked = np.zeros((3, n))
        # the assembly of each dyad of the chart's plan (_dyad_sides), one per loop
        self.dyad_sides = np.zeros(max(int(I[TABLES + TABLE_ENTRIES * LOOPS]), 1))
        self.kinks = np.zeros(max(int(I[N_FRICTION]), 1))
        degrees = I[I[SPLINE_DEGREE]:I[SPLINE_DEGREE] + I[N_FORCES]]
        self.spline = np.zeros(int(degrees.max()) + 1 if len(degrees) else 1)

    def arrays(self) -> dict:
        """Named numpy views of the chart's state (Python callers): value (1,), start, last,
        kin (3, n: x, K, L), fields (field_count,) and clamp (the actuators' clamp modes); they follow
        every later evaluation."""
        n = int(self.n)
        nfields = field_count(self.model)
        views = [self.W[0:1], self.W[1:1 + 3 * n].reshape(3, n), self.W[1 + 3 * n:1 + 6 * n].reshape(3, n),
                 self.W[1 + 6 * n:1 + 6 * n + nfields]]
        na = int(self.I[N_ACTUATORS])
        at = 1 + 6 * n + nfields + n + DEPTH * 3 * n + DEPTH  # the clamp modes follow target (__init__)
        return {"value": views[0], "start": views[1], "last": views[2], "kin": self.loops.B[-3 * n:].reshape(3, n),
                "fields": views[3], "clamp": self.W[at:at + na]}
    # -- one configuration ------------------------------------------------------------------

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _finish(self, det: cython.double) -> cython.int:
        """x (Newton's), K and L into kin (3, n) from the factors of A (at x, or round-off from
        it), and the conditioning of every coordinate into the fields (:meth:`Loops._finish`)."""
        self.loops._finish(det, self.s[INDEPENDENT])
        self.fields[CONDITIONING] = self.loops.own
        self.fields[BEST_CONDITIONING] = self.loops.best
        self.fields[BEST] = self.loops.best_j
        self.fields[DETERMINANT] = det
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _dyad_sides(self, first: cython.Py_ssize_t) -> cython.int:
        """The assembly of each dyad of the plan that starts at step ``first`` (:meth:`_dyads`; none
        where ``first`` < 0) in the chart's last configuration (``last``'s x), into ``dyad_sides``
        (one per loop): sin(θ_b + φ_b − θ_a − φ_a), of the sign of R(θ_a) W_a × R(θ_b) W_b, which
        cannot change along a chart. Set once, where the chart starts (:meth:`start`), as the sign
        of its det A is, rather than at every closure from the walk's base: the same signs
        (checked on every closure of the reduced tests and of benchmarks/same_results.py), a sine
        saved at each closure (3 % of an evaluation's instructions on the seed)."""
        n_loops: cython.Py_ssize_t = self.I[TABLES + TABLE_ENTRIES * LOOPS]
        step: cython.Py_ssize_t
        a: cython.Py_ssize_t
        b: cython.Py_ssize_t
        w: cython.Py_ssize_t
        if first < 0:
            return 0
        for step in range(first, first + n_loops):
            a = self.I[self.I[DYAD_STEPS] + 3 * step + 1]
            b = self.I[self.I[DYAD_STEPS] + 3 * step + 2]
            w = self.I[DYAD_W] + 6 * step
            self.dyad_sides[step - first] = sin(self.last[0, b] + self.F[w + 5] - self.last[0, a] - self.F[w + 4])
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _dyads(self, first: cython.Py_ssize_t, i: cython.Py_ssize_t) -> cython.int:
        """The dependent angles of the chart's x (the predictor) by closed form, loop after loop
        of the plan that starts at step ``first`` (:data:`DYAD_PLAN`): each loop k with two unknown
        angles a, b (the others known: the chart's coordinate or solved by an earlier step) and
        only fixed-length terms reads

            R(θ_a) W_a + R(θ_b) W_b = d,   d = −(offset_k + Σ_known R(θ_t) w_t),

        two circles: the angle ψ of R(θ_a) W_a from d satisfies cos ψ = (|d|² + |W_a|² − |W_b|²) /
        (2 |d| |W_a|). Of the two assemblies (±ψ) the chart's is taken (``dyad_sides``, set where it
        starts: :meth:`_dyad_sides`): the sign of R(θ_a) W_a × R(θ_b) W_b, which cannot change
        along a chart (the dyad's 2×2 block of Φ_x would be singular, and so [Φ_x; e_i]); θ_b
        follows from R(θ_b) W_b = d − R(θ_a) W_a; both angles are the 2π-turns nearest x's (the
        predictor's). The cos and sin of every angle
        (the chart's coordinate i and the solved ones: with a plan, all) go into trig (2, n) as
        they are computed, as :func:`angle_trig` would compute them. Returns 0 where the circles
        do not meet (no closed loop), else 1. A method on the chart's own views: as a function of
        the arrays (:func:`_dyads`), five views were copied by value at every closure (2 % of a
        seed variant's instructions)."""
        tb: cython.Py_ssize_t = TABLES + TABLE_ENTRIES * LOOPS
        n_loops: cython.Py_ssize_t = self.I[tb]
        step: cython.Py_ssize_t
        k: cython.Py_ssize_t
        a: cython.Py_ssize_t
        b: cython.Py_ssize_t
        w: cython.Py_ssize_t
        t: cython.Py_ssize_t
        g: cython.Py_ssize_t
        wax: cython.double
        way: cython.double
        wbx: cython.double
        wby: cython.double
        phi_a: cython.double
        phi_b: cython.double
        dx: cython.double
        dy: cython.double
        ux: cython.double
        uy: cython.double
        c: cython.double
        sn: cython.double
        d2: cython.double
        ra2: cython.double
        cos_psi: cython.double
        sin_psi: cython.double
        side: cython.double
        norm: cython.double
        ra: cython.double
        qx: cython.double
        qy: cython.double
        rq: cython.double
        self.trig[0, i] = cos(self.x[i])
        self.trig[1, i] = sin(self.x[i])
        for step in range(first, first + n_loops):
            k = self.I[self.I[DYAD_STEPS] + 3 * step]
            a = self.I[self.I[DYAD_STEPS] + 3 * step + 1]
            b = self.I[self.I[DYAD_STEPS] + 3 * step + 2]
            w = self.I[DYAD_W] + 6 * step
            wax, way, wbx, wby = self.F[w], self.F[w + 1], self.F[w + 2], self.F[w + 3]
            phi_a, phi_b = self.F[w + 4], self.F[w + 5]
            dx = -self.F[self.I[tb + 2] + 2 * k]
            dy = -self.F[self.I[tb + 2] + 2 * k + 1]
            for t in range(self.I[tb + 1]):
                g = self.I[self.I[tb + 6] + t]
                if self.I[self.I[tb + 4] + t] != k or g == a or g == b:
                    continue
                ux = self.F[self.I[tb + 3] + 2 * t]
                uy = self.F[self.I[tb + 3] + 2 * t + 1]
                if g >= 0:  # a known angle: i's or solved by an earlier step
                    c = self.trig[0, g]
                    sn = self.trig[1, g]
                    ux, uy = ux * c - uy * sn, ux * sn + uy * c
                dx -= ux
                dy -= uy
            d2 = dx * dx + dy * dy
            ra2 = wax * wax + way * way
            cos_psi = (d2 + ra2 - (wbx * wbx + wby * wby)) / (2.0 * sqrt(d2 * ra2))
            if not fabs(cos_psi) <= 1.0 + _c_dyad_round_off:
                return 0
            # R(θ_a) W_a × (d − R(θ_a) W_a) = −|W_a| |d| sin(±ψ): the +ψ assembly has a negative cross
            # product; the chart's, sin(θ_b + φ_b − θ_a − φ_a) (_dyad_sides)
            side = self.dyad_sides[step - first]
            cos_psi = min(max(cos_psi, -1.0), 1.0)  # a flat dyad, to round-off: Newton polishes it
            sin_psi = sqrt(1.0 - cos_psi * cos_psi) if side < 0.0 else -sqrt(1.0 - cos_psi * cos_psi)
            # the direction of R(θ_a) W_a, at θ_a + φ_a: d's turned by ±ψ; cos θ_a, sin θ_a turned back by φ_a
            norm = sqrt(d2)
            ux, uy = (dx * cos_psi - dy * sin_psi) / norm, (dy * cos_psi + dx * sin_psi) / norm
            ra = sqrt(ra2)
            c, sn = (ux * wax + uy * way) / ra, (uy * wax - ux * way) / ra
            self.x[a] = _nearest(atan2(uy, ux) - phi_a, self.x[a])
            self.trig[0, a] = c
            self.trig[1, a] = sn
            qx, qy = dx - (wax * c - way * sn), dy - (wax * sn + way * c)  # R(θ_b) W_b
            self.x[b] = _nearest(atan2(qy, qx) - phi_b, self.x[b])
            rq = sqrt(qx * qx + qy * qy) * sqrt(wbx * wbx + wby * wby)
            if rq > 0.0:
                self.trig[0, b] = (qx * wbx + qy * wby) / rq
                self.trig[1, b] = (qy * wbx - qx * wby) / rq
            else:
                self.trig[0, b] = cos(self.x[b])
                self.trig[1, b] = sin(self.x[b])
        return 1

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _close(self, depth: cython.Py_ssize_t, value: cython.double, reach: cython.double) -> cython.int:
        """Newton from the predictor of base[depth] (rows x, K, L) to x_i = value, whose predicted
        motion max_j |K_j Δ| + ½ |L_j| Δ² is ``reach``; x, K, L into kin (3, n).

        Returns 0 (closed, on the chart's branch, not singular) or 1 (failed: no convergence,
        singular, or another branch). Leaves the conditioning and det in the fields.
        """
        n: cython.Py_ssize_t = self.n
        i: cython.Py_ssize_t = self.s[INDEPENDENT]
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        c: cython.Py_ssize_t
        it: cython.Py_ssize_t
        v: cython.double
        scale: cython.double
        largest: cython.double
        delta: cython.double = value - self.base[depth, 0, i]
        far: cython.bint = reach > _c_far_jump  # from the base's configuration (FAR_JUMP)
        for j in range(n):  # the predictor, and a copy of it in guess (_walk's trust in it)
            v = value if j == i else (self.base[depth, 0, j] if far else (
                self.base[depth, 0, j] + self.base[depth, 1, j] * delta + 0.5 * self.base[depth, 2, j] * delta * delta))
            self.x[j] = v
            self.guess[j] = v
        det: cython.double = 0.0
        converged: cython.bint = False
        factored: cython.bint = False  # at the polished x
        plan: cython.Py_ssize_t = self.I[self.I[DYAD_PLAN] + i]
        # x by closed form: taken as it is if it closes the loops
        closed: cython.bint = plan >= 0 and (reach <= _c_closed_form_reach or far)
        if closed and not self._dyads(plan, i):
            return 1
        for it in range(_c_newton_max_iter + 1):
            if not closed:  # the closed form left trig at x
                self.loops._angle_trig()
            scale = self.loops._constraints()
            largest = 0.0
            for r in range(n - 1):
                if not isfinite(self.rhs[r]):
                    return 1
                largest = max(largest, fabs(self.rhs[r]))
            for c in range(n):
                v = 0.0
                for r in range(n - 1):
                    v += self.A[r, c] * self.A[r, c]
                self.norms[c] = sqrt(v)
                self.A[n - 1, c] = 0.0
            self.A[n - 1, i] = 1.0
            self.rhs[n - 1] = 0.0
            det = self.loops._lu_factor()
            if det == 0.0 or not isfinite(det):
                return 1
            if converged or (closed and largest <= _c_closed_form_residual * scale):
                factored = True
                break
            closed = False  # not closed to round-off: Newton from there
            self.loops._lu_solve(self.loops.rhs_at)
            for j in range(n):
                self.x[j] -= self.rhs[j]
            # converged: the step just taken polishes to round-off
            converged = largest <= max(_c_newton_tol, _c_newton_round_off * self.loops.spread)
        if not factored:
            return 1
        for j in range(n):
            if not isfinite(self.x[j]):
                return 1
        self._finish(det)
        if self.fields[CONDITIONING] < self.singular:
            return 1
        if self.s[SIGN] != 0 and (1 if det >= 0.0 else -1) != self.s[SIGN]:
            return 1
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _walk(self, value: cython.double) -> cython.int:
        """Continue the chart from its last configuration to x_i = value, halving untrusted
        jumps; the result in kin and last. Returns OK, SINGULAR (no closure within the halvings)
        or WORK_SPENT (more than MAX_WALK_CLOSURES closures)."""
        n: cython.Py_ssize_t = self.n
        i: cython.Py_ssize_t = self.s[INDEPENDENT]
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        delta: cython.double
        predicted: cython.double
        moved: cython.double
        failed: cython.bint
        trusted: cython.bint
        if cython.compiled:  # base[0] and last: C-contiguous (3, n) blocks of W, one copy
            memcpy(cython.address(self.base[0, 0, 0]), cython.address(self.last[0, 0]),
                   3 * n * cython.sizeof(cython.double))
        else:
            for r in range(3):
                for j in range(n):
                    self.base[0, r, j] = self.last[r, j]
        self.target[0] = value
        self.budget[0] = _c_max_halvings
        depth: cython.Py_ssize_t = 0  # base[d] is the configuration from which target[d] is sought
        closures: cython.Py_ssize_t = 0
        while True:
            delta = self.target[depth] - self.base[depth, 0, i]
            predicted = 0.0  # the jump's predicted motion, max_j |K_j Δ| + ½ |L_j| Δ²
            for j in range(n):
                predicted = max(predicted, fabs(self.base[depth, 1, j] * delta)
                                + 0.5 * fabs(self.base[depth, 2, j]) * delta * delta)
            failed = False  # a jump beyond LONG_JUMP (up to FAR_JUMP) is halved untried
            trusted = False
            if predicted <= _c_long_jump or predicted > _c_far_jump or self.budget[depth] <= 0:
                if closures == _c_max_walk_closures:
                    return WORK_SPENT
                closures += 1
                failed = self._close(depth, self.target[depth], predicted) != 0
                if not failed:
                    moved = 0.0
                    for j in range(n):
                        moved = max(moved, fabs(self.kin[0, j] - self.guess[j]))
                    trusted = moved <= _c_predictor_trust * predicted + _c_trusted_correction
            if failed and self.budget[depth] <= 0:
                return SINGULAR
            if trusted or self.budget[depth] <= 0:
                if predicted > _c_long_jump:  # closed at once: the turns nearest the base's
                    for j in range(self.I[N_ANGLES]):
                        if j != i:
                            self.kin[0, j] = _nearest(self.kin[0, j], self.base[depth, 0, j])
                if depth == 0:
                    break
                # the midpoint is reached: it is the base of the second half, one level down
                depth -= 1
                for r in range(3):
                    for j in range(n):
                        self.base[depth, r, j] = self.kin[r, j]
                self.budget[depth] -= 1
                continue
            # halve: seek the midpoint first, then the target from there
            for r in range(3):
                for j in range(n):
                    self.base[depth + 1, r, j] = self.base[depth, r, j]
            self.target[depth + 1] = self.base[depth, 0, i] + 0.5 * (self.target[depth] - self.base[depth, 0, i])
            self.budget[depth + 1] = self.budget[depth] - 1
            depth += 1
        if cython.compiled:  # kin (the kinematics' B) and last: C-contiguous (3, n) blocks, one copy
            memcpy(cython.address(self.last[0, 0]), cython.address(self.kin[0, 0]),
                   3 * n * cython.sizeof(cython.double))
        else:
            for r in range(3):
                for j in range(n):
                    self.last[r, j] = self.kin[r, j]
        return OK

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _point_force(self, p: cython.Py_ssize_t, q: cython.double) -> cython.double:
        """F_p(q) (N): the B-spline of point force p at the input coordinate q (de Boor, in the
        chart's spline scratch)."""
        lo: cython.double = self.F[self.I[SPLINE_LO] + p]
        hi: cython.double = self.F[self.I[SPLINE_HI] + p]
        period: cython.double = self.F[self.I[SPLINE_PERIOD] + p]
        if period > 0.0:
            q = lo + (q - lo) - period * floor((q - lo) / period)
        else:
            q = min(max(q, lo), hi)
        t0: cython.Py_ssize_t = self.I[SPLINE_KNOTS] + self.I[self.I[KNOT_START] + p]
        c0: cython.Py_ssize_t = self.I[SPLINE_COEF] + self.I[self.I[COEF_START] + p]
        nc: cython.Py_ssize_t = self.I[self.I[COEF_START] + p + 1] - self.I[self.I[COEF_START] + p]
        k: cython.Py_ssize_t = self.I[self.I[SPLINE_DEGREE] + p]
        l: cython.Py_ssize_t = k
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        left: cython.double
        alpha: cython.double
        while l < nc - 1 and self.F[t0 + l + 1] <= q:
            l += 1
        for j in range(k + 1):
            self.spline[j] = self.F[c0 + l - k + j]
        for r in range(1, k + 1):
            for j in range(k, r - 1, -1):
                left = self.F[t0 + j + l - k]
                alpha = (q - left) / (self.F[t0 + j + 1 + l - r] - left)
                self.spline[j] = (1.0 - alpha) * self.spline[j - 1] + alpha * self.spline[j]
        return self.spline[k]

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _coefficients(self) -> cython.int:
        """Eksergian's coefficients at the chart's kin into its fields (loopcheck.reduced.dynamics documents
        them). Uses the trig of the last Newton iteration (round-off from kin's x)."""
        nb: cython.Py_ssize_t = self.I[N_ANGLES]
        ms: cython.Py_ssize_t = self.I[MASSES]
        ins: cython.Py_ssize_t = self.I[INERTIAS]
        b: cython.Py_ssize_t
        e: cython.Py_ssize_t
        j: cython.Py_ssize_t
        p: cython.Py_ssize_t
        m: cython.double
        inertia: cython.double
        gx: cython.double
        gy: cython.double
        dx: cython.double
        dy: cython.double
        length: cython.double
        k_d: cython.double
        c: cython.double
        stretch: cython.double
        u: cython.double
        k_u: cython.double
        r: cython.double
        d: cython.double
        along: cython.double
        self.loops._table_rates(CENTRES, True)
        J: cython.double = 0.0
        zeta: cython.double = 0.0
        for b in range(nb):
            m = self.F[ms + b]
            inertia = self.F[ins + b]
            J += m * (self.rows[b, 0] * self.rows[b, 0] + self.rows[b, 1] * self.rows[b, 1]) + inertia * self.K[b] * self.K[b]
            zeta += m * (self.rows[b, 0] * self.rows[b, 2] + self.rows[b, 1] * self.rows[b, 3]) + inertia * self.K[b] * self.L[b]
        dV: cython.double = 0.0
        V: cython.double = 0.0
        damping: cython.double = 0.0
        force: cython.double = 0.0
        if self.I[HAS_GRAVITY]:  # each body's own gravity (the scene's, times 1 − its gravcomp)
            for b in range(nb):
                gx = self.F[self.I[GRAVITY] + 2 * b]
                gy = self.F[self.I[GRAVITY] + 2 * b + 1]
                dV -= self.F[ms + b] * (gx * self.rows[b, 0] + gy * self.rows[b, 1])
            self.loops._table_positions(CENTRES)
            for b in range(nb):
                gx = self.F[self.I[GRAVITY] + 2 * b]
                gy = self.F[self.I[GRAVITY] + 2 * b + 1]
                V -= self.F[ms + b] * (gx * self.rows[b, 0] + gy * self.rows[b, 1])
        ne: cython.Py_ssize_t = self.I[N_ELEMENTS]
        if ne:
            self.loops._table_points(ENDS, True)  # the ends' positions and K_r, one walk of the table
            for e in range(ne):
                dx = self.rows[2 * e, 0] - self.rows[2 * e + 1, 0]
                dy = self.rows[2 * e, 1] - self.rows[2 * e + 1, 1]
                length = sqrt(dx * dx + dy * dy)
                k_d = (dx * (self.rows[2 * e, 2] - self.rows[2 * e + 1, 2])  # K_D = dD/dx_i, K_a − K_b
                       + dy * (self.rows[2 * e, 3] - self.rows[2 * e + 1, 3])) / length
                c = self.F[self.I[ELEMENT_COEF] + e]
                if e < self.I[N_DAMPERS]:
                    damping += c * k_d * k_d
                else:
                    stretch = length - self.F[self.I[ELEMENT_REST] + e]
                    dV += c * stretch * k_d
                    V += 0.5 * c * stretch * stretch
        nj: cython.Py_ssize_t = self.I[N_JOINT_ELEMENTS]
        n: cython.Py_ssize_t = self.n
        rows_at: cython.Py_ssize_t
        first_inertia: cython.Py_ssize_t = nj - self.I[N_JOINT_INERTIAS]
        l_u: cython.double
        if nj:
            rows_at = self.I[JOINT_ROWS]
            for e in range(nj):  # u = row·x, K_u = du/dx_i = row·K, L_u = row·L
                u = 0.0
                k_u = 0.0
                l_u = 0.0
                for j in range(n):
                    r = self.F[rows_at + e * n + j]
                    u += r * self.kin[0, j]
                    k_u += r * self.K[j]
                    l_u += r * self.L[j]
                c = self.F[self.I[JOINT_COEF] + e]
                if e < self.I[N_JOINT_DAMPERS]:
                    damping += c * k_u * k_u
                elif e >= first_inertia:  # T = ½ c u̇² = ½ c K_u² q̇²: adds c K_u² to 𝔍 and c K_u L_u to ζ
                    J += c * k_u * k_u
                    zeta += c * k_u * l_u
                else:
                    stretch = u - self.F[self.I[JOINT_REST] + e]
                    dV += c * stretch * k_u
                    V += 0.5 * c * stretch * stretch
        rate: cython.double = 0.0
        curvature: cython.double = 0.0
        q: cython.double = 0.0
        for j in range(n):
            d = self.F[self.I[DRIVE] + j]
            rate += d * self.K[j]
            curvature += d * self.L[j]
            q += d * self.kin[0, j]
        nf: cython.Py_ssize_t = self.I[N_FORCES]
        nt: cython.Py_ssize_t = self.I[N_TIMED]
        fd: cython.Py_ssize_t
        td: cython.Py_ssize_t
        if nf or nt:
            self.loops._table_rates(FORCE_POINTS, False)
            fd = self.I[FORCE_DIR]
            for p in range(nf):
                along = self.rows[p, 0] * self.F[fd + 2 * p] + self.rows[p, 1] * self.F[fd + 2 * p + 1]
                force += self._point_force(p, q) * along
            td = self.I[TIMED_DIR]
            for p in range(nt):  # the generalized rate of timed force p: its force is F_p(t) times this
                self.fields[N_FIELDS + p] = self.rows[nf + p, 0] * self.F[td + 2 * p] + self.rows[nf + p, 1] * self.F[td + 2 * p + 1]
        na: cython.Py_ssize_t = self.I[N_ACTUATORS]
        a: cython.Py_ssize_t
        if na:
            rows_at = self.I[ACT_ROWS]
            for a in range(na):  # l = row·x, dl/dx_i = row·K
                u = 0.0
                k_u = 0.0
                for j in range(n):
                    r = self.F[rows_at + a * n + j]
                    u += r * self.kin[0, j]
                    k_u += r * self.K[j]
                self.fields[N_FIELDS + nt + 2 * a] = u
                self.fields[N_FIELDS + nt + 2 * a + 1] = k_u
        capacity: cython.double = 0.0
        nfr: cython.Py_ssize_t = self.I[N_FRICTION]
        if nfr:  # C = Σ f |K_u|, K_u = row·K: the friction's generalized force while slipping
            rows_at = self.I[FRICTION_ROWS]
            for e in range(nfr):
                k_u = 0.0
                for j in range(n):
                    k_u += self.F[rows_at + e * n + j] * self.K[j]
                capacity += self.F[self.I[FRICTION_COEF] + e] * fabs(k_u)
        self.fields[FRICTION_CAPACITY] = capacity
        self.fields[INERTIA] = J
        self.fields[CENTRIFUGAL] = zeta
        self.fields[POTENTIAL_GRADIENT] = dV
        self.fields[DAMPING] = damping
        self.fields[POTENTIAL] = V
        self.fields[INPUT_RATE] = rate
        self.fields[POINT_FORCE] = force
        self.fields[INPUT_CURVATURE] = curvature
        return 0

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _applied(self, piece: cython.Py_ssize_t) -> cython.double:
        """The generalized force of the loads (N·m or N) at the fields on load piece ``piece``
        (its index): T·dq/dx_i + Σ F_p(q) e·K_P + Σ F_p(t) e·K_P, the loads over time those of
        the piece (PIECE_VALUES)."""
        nt: cython.Py_ssize_t = self.I[N_TIMED]
        row: cython.Py_ssize_t = self.I[PIECE_VALUES] + piece * (1 + nt)
        p: cython.Py_ssize_t
        g: cython.double = self.F[row] * self.fields[INPUT_RATE] + self.fields[POINT_FORCE]
        for p in range(nt):
            g += self.F[row + 1 + p] * self.fields[N_FIELDS + p]
        return g

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _unclamped(self, a: cython.Py_ssize_t, piece: cython.Py_ssize_t, v: cython.double) -> cython.double:
        """Actuator a's force before its forcerange clamp, f_u = c + b1·gear·l + b2·gear·l̇ (N or
        N·m), at the fields, ẋ_i = v, on load piece ``piece``."""
        na: cython.Py_ssize_t = self.I[N_ACTUATORS]
        at: cython.Py_ssize_t = N_FIELDS + self.I[N_TIMED] + 2 * a
        prm: cython.Py_ssize_t = self.I[ACT_PARAMS] + 5 * a
        return (self.F[self.I[ACT_PIECE] + piece * na + a] + self.F[prm] * self.fields[at]
                + self.F[prm + 1] * (self.fields[at + 1] * v))

    @cython.cfunc
    @cython.exceptval(-1, check=False)
    def _clamped(self, a: cython.Py_ssize_t) -> cython.bint:
        """Whether actuator a's clamp switches with the state (an event): b1 or b2 nonzero, lo < hi,
        a finite bound."""
        prm: cython.Py_ssize_t = self.I[ACT_PARAMS] + 5 * a
        lo: cython.double = self.F[prm + 3]
        hi: cython.double = self.F[prm + 4]
        return (self.F[prm] != 0.0 or self.F[prm + 1] != 0.0) and lo < hi and (isfinite(lo) or isfinite(hi))

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _actuated(self, piece: cython.Py_ssize_t, v: cython.double, modes: cython.bint) -> cython.double:
        """The actuators' generalized force (N·m or N) at the fields, ẋ_i = v, on load piece
        ``piece``: Σ gear·f·dl/dx_i with f = clamp(c + b1·gear·l + b2·gear·l̇, lo, hi), c the
        piece's gain·clamp(ctrl) + b0 (ACT_PIECE), l̇ = (dl/dx_i) v; with ``modes``, a clamped
        actuator's f is its mode's (CLAMP_FREE: unclamped, CLAMP_HI: hi, CLAMP_LO: lo), so that q̈
        is smooth between the clamp's events; CLAMP_AUTO (and without ``modes``) clamps by value."""
        na: cython.Py_ssize_t = self.I[N_ACTUATORS]
        if na == 0:
            return 0.0
        nt: cython.Py_ssize_t = self.I[N_TIMED]
        prm: cython.Py_ssize_t = self.I[ACT_PARAMS]
        a: cython.Py_ssize_t
        k: cython.double
        f: cython.double
        mode: cython.double
        g: cython.double = 0.0
        for a in range(na):
            k = self.fields[N_FIELDS + nt + 2 * a + 1]
            f = self._unclamped(a, piece, v)
            mode = self.clamp[a] if modes else CLAMP_AUTO
            if mode == CLAMP_HI:
                f = self.F[prm + 5 * a + 4]
            elif mode == CLAMP_LO:
                f = self.F[prm + 5 * a + 3]
            elif mode != CLAMP_FREE:
                f = min(max(f, self.F[prm + 5 * a + 3]), self.F[prm + 5 * a + 4])
            g += self.F[prm + 5 * a + 2] * f * k
        return g

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _clamp_margin(self, a: cython.Py_ssize_t, v: cython.double) -> cython.double:
        """Actuator a's clamp margin at the fields, ẋ_i = v, on the latest acceleration's piece: > 0
        while its mode holds (CLAMP_FREE: min(hi − f_u, f_u − lo) + ε; CLAMP_HI: f_u − hi + ε;
        CLAMP_LO: lo − f_u + ε; ε = CLAMP_HYSTERESIS × the larger finite bound's magnitude); 1 for
        an actuator without a clamp event or in CLAMP_AUTO."""
        if not self._clamped(a):
            return 1.0
        mode: cython.double = self.clamp[a]
        prm: cython.Py_ssize_t = self.I[ACT_PARAMS] + 5 * a
        lo: cython.double = self.F[prm + 3]
        hi: cython.double = self.F[prm + 4]
        scale: cython.double = 0.0
        if isfinite(lo):
            scale = fabs(lo)
        if isfinite(hi):
            scale = max(scale, fabs(hi))
        eps: cython.double = _c_clamp_hysteresis * scale
        f: cython.double = self._unclamped(a, self.piece, v)
        if mode == CLAMP_HI:
            return f - hi + eps
        if mode == CLAMP_LO:
            return lo - f + eps
        if mode == CLAMP_FREE:
            return min(hi - f, f - lo) + eps
        return 1.0

    # -- the chart interface ----------------------------------------------------------------

    @cython.ccall
    @cython.exceptval(-1, check=False)
    def evaluate(self, value: cython.double) -> cython.bint:
        """The chart's configuration and coefficients at x_i = value (memoized): True on success,
        else S[STATUS] = SINGULAR (no closed loop, a singular position or another branch within
        reach of the walk) or WORK_SPENT (the walk needed more than MAX_WALK_CLOSURES closures)."""
        if self.s[VALID] == 1 and self.value[0] == value:
            return True
        if self.s[INDEPENDENT] < 0:
            raise ValueError("a chart without a coordinate (kinematics_at's) cannot be evaluated: start() it first")
        self.s[VALID] = 0
        status: cython.int = self._walk(value)
        if status != OK:
            self.s[STATUS] = status
            return False
        self._coefficients()
        self.value[0] = value
        self.s[VALID] = 1
        return True

    @cython.cfunc
    @cython.exceptval(-2, check=True)
    def _friction_sign(self, v: cython.double) -> cython.double:
        """The sign s of the slip (friction −s·C), 0 when sticking or without friction."""
        if not self.I[N_FRICTION]:
            return 0.0
        mode: cython.double = self.fields[FRICTION_MODE]
        if mode == STICK:
            return 0.0
        if mode != 0.0:
            return mode
        return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)

    @cython.ccall
    def acceleration(self, load: cython.Py_ssize_t, t: cython.double, q: cython.double,
                     v: cython.double) -> cython.double:
        """ẍ_i at x_i = q, ẋ_i = v from Eksergian's equation on load piece ``load`` (its index:
        the loads over time are constant on it, :meth:`_applied`): (Q_applied − b ẋ_i − ζ ẋ_i² −
        dV/dx_i − s C) / 𝔍, s C the joint friction while slipping (FRICTION_MODE); 0 while it
        sticks. NaN when the configuration cannot be found (S[STATUS] says why)."""
        self.piece = load
        if not self.evaluate(q):
            return _c_nan
        if self.I[N_FRICTION] and self.fields[FRICTION_MODE] == STICK:
            return 0.0
        Q: cython.double = self._applied(load) + self._actuated(load, v, True) - self.fields[DAMPING] * v
        Q -= self._friction_sign(v) * self.fields[FRICTION_CAPACITY]
        return (Q - self.fields[CENTRIFUGAL] * v * v - self.fields[POTENTIAL_GRADIENT]) / self.fields[INERTIA]

    @cython.ccall
    def power(self, load: cython.Py_ssize_t, v: cython.double) -> cython.double:
        """P = Q_applied ẋ_i (W) at the configuration last evaluated, right after its
        :meth:`acceleration`: the power of the input load, of the point forces over q and t and
        of the actuators on load piece ``load``; the energy audit integrates it."""
        return (self._applied(load) + self._actuated(load, v, True)) * v

    @cython.ccall
    def dissipation(self, v: cython.double) -> cython.double:
        """D = Σ b K_D² ẋ_i² + s C ẋ_i (W), the dampers' and the joint friction's dissipation
        rate at the configuration last evaluated, right after its :meth:`acceleration`."""
        return self.fields[DAMPING] * v * v + self._friction_sign(v) * self.fields[FRICTION_CAPACITY] * v

    @cython.ccall
    def rest_force(self, load: cython.Py_ssize_t, q: cython.double) -> cython.double:
        """Q_rest at x_i = q, ẋ_i = 0 on load piece ``load``: every generalized force but the
        friction's (Q_applied + the actuators' − dV/dx_i); NaN where the configuration fails. Leaves the
        friction's capacity C in the fields."""
        if not self.evaluate(q):
            return _c_nan
        return self._applied(load) + self._actuated(load, 0.0, False) - self.fields[POTENTIAL_GRADIENT]

    @cython.ccall
    def set_friction(self, mode: cython.double):
        """Set the friction's mode (FRICTION_MODE: +1, −1, STICK or 0)."""
        if not (mode == 1.0 or mode == -1.0 or mode == 0.0 or mode == STICK):
            raise ValueError(f"set_friction: a mode of +1, -1, 0 or STICK ({STICK}), not {mode}")
        self.fields[FRICTION_MODE] = mode

    @cython.ccall
    def set_kinks(self, flipped: cython.Py_ssize_t):
        """Watch each joint friction's kink from the configuration last evaluated: σ_j = the sign of
        its K_u = row·K there (0, not watched, where K_u = 0). With ``flipped`` ≥ 0 (the kink
        that just fired, its K_u at its root), that friction and every other at its root with it
        (|K_u| ≤ KINK_ROOT × Σ |row_l K_l|: a joint whose rate is proportional to its rate) take
        the opposite of their σ before: the sign of a K_u at its root is round-off's."""
        n: cython.Py_ssize_t = self.n
        e: cython.Py_ssize_t
        j: cython.Py_ssize_t
        k_u: cython.double
        size: cython.double
        for e in range(self.I[N_FRICTION]):
            k_u = 0.0
            size = 0.0
            for j in range(n):
                k_u += self.F[self.I[FRICTION_ROWS] + e * n + j] * self.K[j]
                size += fabs(self.F[self.I[FRICTION_ROWS] + e * n + j] * self.K[j])
            if e == flipped or (flipped >= 0 and self.kinks[e] != 0.0 and fabs(k_u) <= _c_kink_root * size):
                self.kinks[e] = -self.kinks[e]
            else:
                self.kinks[e] = 1.0 if k_u > 0.0 else (-1.0 if k_u < 0.0 else 0.0)

    @cython.cfunc
    @cython.exceptval(-1, check=True)
    def _event_margin(self, event: cython.Py_ssize_t, v: cython.double) -> cython.double:
        """The margin of ``event`` (:meth:`fired`'s numbering) at the configuration last
        evaluated and rate v: > 0 while it has not happened."""
        n: cython.Py_ssize_t = self.n
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        u: cython.double
        mode: cython.double
        rest: cython.double
        if event == SWITCH_EVENT:
            return self.fields[CONDITIONING] - _c_hysteresis * self.fields[BEST_CONDITIONING]
        if event == FRICTION_EVENT:
            mode = self.fields[FRICTION_MODE]
            if mode == STICK:  # constant on a load piece: < 0 from its start when the load breaks it loose
                rest = self._applied(self.piece) + self._actuated(self.piece, 0.0, False) - self.fields[POTENTIAL_GRADIENT]
                return 1.0 if fabs(rest) <= self.fields[FRICTION_CAPACITY] else -1.0
            return mode * v if mode != 0.0 else 1.0  # slipping: until q̇ reaches 0
        if event >= RANGE_EVENT + 2 * self.I[N_RANGES] + self.I[N_FRICTION]:  # a clamp
            return self._clamp_margin(event - RANGE_EVENT - 2 * self.I[N_RANGES] - self.I[N_FRICTION], v)
        if event >= RANGE_EVENT + 2 * self.I[N_RANGES]:  # a kink: σ_j K_u while slipping
            r = event - RANGE_EVENT - 2 * self.I[N_RANGES]
            mode = self.fields[FRICTION_MODE]
            if self.kinks[r] == 0.0 or not (mode == 1.0 or mode == -1.0):
                return 1.0
            u = 0.0
            for j in range(n):
                u += self.F[self.I[FRICTION_ROWS] + r * n + j] * self.K[j]
            return self.kinks[r] * u
        r = (event - RANGE_EVENT) // 2
        u = 0.0
        for j in range(n):
            u += self.F[self.I[RANGE_ROWS] + r * n + j] * self.kin[0, j]
        if (event - RANGE_EVENT) % 2 == 0:
            return u - self.F[self.I[RANGE_BOUNDS] + 2 * r]
        return self.F[self.I[RANGE_BOUNDS] + 2 * r + 1] - u

    @cython.ccall
    def stop_margin(self, t: cython.double, q: cython.double, v: cython.double) -> cython.double:
        """> 0 while no event has happened, the least of the events' margins: the chart's
        coordinate good enough (≤ 0 when another is better by more than the hysteresis:
        c_i < HYSTERESIS · max_j c_j); the friction slipping with q̇ ≠ 0, or sticking with the
        loads of the latest acceleration's piece within its capacity; every joint inside its
        range; each joint friction's K_u keeping its sign while slipping (the kinks).
        every clamped actuator's force in its mode (:meth:`_clamp_margin`). −1 where the
        configuration fails."""
        if not self.evaluate(q):
            return -1.0
        g: cython.double = self._event_margin(SWITCH_EVENT, v)
        e: cython.Py_ssize_t
        if self.I[N_FRICTION]:
            g = min(g, self._event_margin(FRICTION_EVENT, v))
        for e in range(RANGE_EVENT, RANGE_EVENT + 2 * self.I[N_RANGES] + self.I[N_FRICTION]):
            g = min(g, self._event_margin(e, v))
        if self.I[N_CLAMPED]:
            for e in range(self.I[N_ACTUATORS]):
                g = min(g, self._clamp_margin(e, v))
        return g

    @cython.ccall
    def locate(self, t: cython.double, q: cython.double, v: cython.double) -> cython.bint:
        """A friction's change of mode, a range reached or a clamp's switching is located at its
        root (the time of a stick, of a reversal, of the bound, of the force's kink); a chart switch
        may happen anywhere near its own."""
        return self.fired(t, q, v) >= FRICTION_EVENT

    @cython.ccall
    def stop_at_start(self, t: cython.double, q: cython.double, v: cython.double) -> cython.bint:
        """True at a load piece's start where the friction sticks and the piece's loads (those
        of the latest acceleration) exceed its capacity: it breaks loose there; or where a clamped
        actuator's force leaves its mode (a control step past a bound, or back inside)."""
        e: cython.Py_ssize_t
        if self.I[N_FRICTION] and self.fields[FRICTION_MODE] == STICK:
            if not self.evaluate(q) or self._event_margin(FRICTION_EVENT, v) < 0.0:
                return True
        if self.I[N_CLAMPED]:
            if not self.evaluate(q):
                return True
            for e in range(self.I[N_ACTUATORS]):
                if self._clamp_margin(e, v) < 0.0:
                    return True
        return False

    @cython.ccall
    def set_clamps(self, load: cython.Py_ssize_t, q: cython.double, v: cython.double) -> cython.Py_ssize_t:
        """Set each clamped actuator's mode by its unclamped force f_u at x_i = q, ẋ_i = v on load
        piece ``load``: CLAMP_HI above hi, CLAMP_LO below lo, else CLAMP_FREE (the mode whose margin
        is then the largest, ≥ ε). Returns the count of modes changed, −1 where the configuration
        fails."""
        if not self.evaluate(q):
            return -1
        self.piece = load
        changed: cython.Py_ssize_t = 0
        a: cython.Py_ssize_t
        f: cython.double
        mode: cython.double
        prm: cython.Py_ssize_t
        for a in range(self.I[N_ACTUATORS]):
            if not self._clamped(a):
                continue
            prm = self.I[ACT_PARAMS] + 5 * a
            f = self._unclamped(a, load, v)
            mode = CLAMP_HI if f > self.F[prm + 4] else (CLAMP_LO if f < self.F[prm + 3] else CLAMP_FREE)
            if mode != self.clamp[a]:
                changed += 1
                self.clamp[a] = mode
        return changed

    @cython.ccall
    def clamp_event(self, event: cython.Py_ssize_t) -> cython.Py_ssize_t:
        """The actuator whose clamp ``event`` (:meth:`fired`'s numbering) is, −1 if it is no clamp's."""
        base: cython.Py_ssize_t = RANGE_EVENT + 2 * self.I[N_RANGES] + self.I[N_FRICTION]
        if base <= event < base + self.I[N_ACTUATORS]:
            return event - base
        return -1

    @cython.ccall
    def fired(self, t: cython.double, q: cython.double, v: cython.double) -> cython.Py_ssize_t:
        """Which event a stop at (t, q, v) is: the one of least margin (SWITCH_EVENT,
        FRICTION_EVENT, RANGE_EVENT + 2 r + side: joint range r's lower (side 0) or upper (1)
        bound, RANGE_EVENT + 2 N_RANGES + j: joint friction j's kink, or RANGE_EVENT + 2 N_RANGES +
        N_FRICTION + a: actuator a's clamp); −1 where the
        configuration fails."""
        if not self.evaluate(q):
            return -1
        best: cython.Py_ssize_t = SWITCH_EVENT
        least: cython.double = self._event_margin(SWITCH_EVENT, v)
        g: cython.double
        e: cython.Py_ssize_t
        if self.I[N_FRICTION]:
            g = self._event_margin(FRICTION_EVENT, v)
            if g < least:
                best, least = FRICTION_EVENT, g
        for e in range(RANGE_EVENT, RANGE_EVENT + 2 * self.I[N_RANGES] + self.I[N_FRICTION]):
            g = self._event_margin(e, v)
            if g < least:
                best, least = e, g
        if self.I[N_CLAMPED]:
            for e in range(self.I[N_ACTUATORS]):
                g = self._clamp_margin(e, v)
                if g < least:
                    best, least = RANGE_EVENT + 2 * self.I[N_RANGES] + self.I[N_FRICTION] + e, g
        return best

    @cython.ccall
    def observation_size(self) -> cython.Py_ssize_t:
        """Length of :meth:`observe`'s row: the fields, then x, K and L (field_count + 3 n)."""
        return N_FIELDS + self.I[N_TIMED] + 2 * self.I[N_ACTUATORS] + 3 * self.n

    @cython.ccall
    def observe(self, out: cython.double[:, ::1], row: cython.Py_ssize_t):
        """The configuration last evaluated, into out[row, :observation_size()]: its coefficient
        fields, then x, K and L (n each) — what the outputs and the energy audit need at a
        sample, recorded where the integrator evaluated it instead of walked to again."""
        n: cython.Py_ssize_t = self.n
        nf: cython.Py_ssize_t = N_FIELDS + self.I[N_TIMED] + 2 * self.I[N_ACTUATORS]
        k: cython.Py_ssize_t
        r: cython.Py_ssize_t
        j: cython.Py_ssize_t
        if not (0 <= row < out.shape[0] and out.shape[1] >= nf + 3 * n):
            raise IndexError(f"observe: row {row} of an array of shape ({out.shape[0]}, {out.shape[1]}) "
                             f"(rows of {nf + 3 * n} values)")
        for k in range(nf):
            out[row, k] = self.fields[k]
        for r in range(3):
            for j in range(n):
                out[row, nf + r * n + j] = self.kin[r, j]

    @cython.ccall
    def mark(self):
        """Keep the chart's last configuration (x, K, L) for :meth:`rewind`."""
        r: cython.Py_ssize_t
        j: cython.Py_ssize_t
        for r in range(3):
            for j in range(self.n):
                self.marked[r, j] = self.last[r, j]

    @cython.ccall
    def rewind(self):
        """Continue the chart's walk from the configuration :meth:`mark` kept. The integrators
        walk a piece's samples this way, forwards from its start in short jumps, rather than back
        from its end in one walk of hundreds of rad (halved down to :data:`LONG_JUMP`)."""
        r: cython.Py_ssize_t
        j: cython.Py_ssize_t
        for r in range(3):
            for j in range(self.n):
                self.last[r, j] = self.marked[r, j]
        self.s[VALID] = 0

    @cython.ccall
    def reset(self):
        """Back to the chart's start configuration (a new walk along the chart)."""
        r: cython.Py_ssize_t
        j: cython.Py_ssize_t
        for r in range(3):
            for j in range(self.n):
                self.last[r, j] = self.origin[r, j]
        self.s[VALID] = 0
        self.s[STATUS] = OK

    @cython.ccall
    def kinematics_at(self, x: cython.double[::1], row: cython.double[::1]) -> cython.bint:
        """K = dx/dp, L = d²x/dp² and the coefficients at an assembled x (n,) for the coordinate
        p = row·x (the input's drive row, or e_i), into the chart's kin and fields. Returns False
        where p cannot drive the linkage: its conditioning below the chart's threshold, the
        Hadamard ratio of the dependent Jacobian (:func:`loopcheck.kinematics.dependent_jacobian`:
        with i the row's largest |entry|, columns Φ_x[:, l] − (row_l / row_i) Φ_x[:, i], l ≠ i),
        |det A| / (|row_i| Π_{l≠i} ‖column l‖) with A = [Φ_x; row]; for row = e_i that is c_i.
        S[INDEPENDENT] should be −1 unless row is e_i.
        x is copied first (into Newton's x): it may be one of the chart's own buffers."""
        n: cython.Py_ssize_t = self.n
        c: cython.Py_ssize_t
        if x.shape[0] != n or row.shape[0] != n:
            raise ValueError(f"kinematics_at: x and row of {n} coordinates, not {x.shape[0]} and {row.shape[0]}")
        for c in range(n):
            self.x[c] = x[c]
        self.loops._angle_trig()
        self.loops._constraints()
        det: cython.double = self.loops._factor_row(row)
        self.s[VALID] = 0  # not a chart value: the memo is not valid for evaluate()
        if det == 0.0 or not isfinite(det) or fabs(det) < self.singular * self.loops.hadamard:
            self.s[STATUS] = SINGULAR
            return False
        self._finish(det)
        self._coefficients()
        return True

    @cython.ccall
    def start(self, x: cython.double[::1], independent: cython.Py_ssize_t) -> cython.bint:
        """Make this a chart of coordinate ``independent`` starting at the assembled x (n,): its
        K, L there, the sign of its det A and its dyads' assemblies (:meth:`_dyad_sides`), which
        its walks keep. Returns True on success (False: singular). x may
        be one of the chart's own buffers (its kin[0], at a switch): :meth:`kinematics_at`
        copies it first."""
        n: cython.Py_ssize_t = self.n
        j: cython.Py_ssize_t
        r: cython.Py_ssize_t
        if x.shape[0] != n or not 0 <= independent < n:
            raise ValueError(f"start: x of {n} coordinates (not {x.shape[0]}) and a coordinate in [0, {n}), "
                             f"not {independent}")
        self.s[INDEPENDENT] = independent
        self.s[SIGN] = 0
        self.s[STATUS] = OK
        for j in range(n):
            self.guess[j] = 0.0
        self.guess[independent] = 1.0
        if not self.kinematics_at(x, self.guess):  # its conditioning is c_i: row e_i
            self.s[STATUS] = SINGULAR
            return False
        self.s[SIGN] = 1 if self.fields[DETERMINANT] >= 0.0 else -1
        for r in range(3):
            for j in range(n):
                self.last[r, j] = self.kin[r, j]
                self.origin[r, j] = self.kin[r, j]
        self._dyad_sides(self.I[self.I[DYAD_PLAN] + independent])
        self.value[0] = self.x[independent]  # x's, copied by kinematics_at
        self.s[VALID] = 1
        return True

    @cython.ccall
    def walk(self, values: cython.double[::1], fields: cython.double[:, ::1],
             kin: cython.double[:, :, ::1]) -> cython.Py_ssize_t:
        """Reset the chart and evaluate it at each of ``values`` in turn: fields (m, field_count)
        and kinematics (m, 3, n) of each. Returns the number evaluated (< m where it failed)."""
        s: cython.Py_ssize_t
        k: cython.Py_ssize_t
        r: cython.Py_ssize_t
        j: cython.Py_ssize_t
        nf: cython.Py_ssize_t = N_FIELDS + self.I[N_TIMED] + 2 * self.I[N_ACTUATORS]
        m: cython.Py_ssize_t = values.shape[0]
        if not (fields.shape[0] >= m and fields.shape[1] >= nf and kin.shape[0] >= m and kin.shape[1] == 3
                and kin.shape[2] == self.n):
            raise ValueError(f"walk: fields ({m}, ≥{nf}) and kin ({m}, 3, {self.n}) for {m} values")
        self.reset()
        for s in range(values.shape[0]):
            if not self.evaluate(values[s]):
                return s
            for k in range(nf):
                fields[s, k] = self.fields[k]
            for r in range(3):
                for j in range(self.n):
                    kin[s, r, j] = self.kin[r, j]
        return values.shape[0]
