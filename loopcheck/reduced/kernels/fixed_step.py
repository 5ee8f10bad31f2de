"""Fixed-step Runge-Kutta-Nyström methods (RKN4), compiled; they know only :mod:`.problem`.

An explicit RKN method for q̈ = f(t, q, q̇) is its tableau (:class:`RKNTableau`):

    stage i:  Q_i = q + c_i h q̇ + h² Σ_j abar_ij k_j,   V_i = q̇ + h Σ_j a_ij k_j,
              k_i = f(t + c_i h, Q_i, V_i)
    update:   q⁺ = q + h q̇ + h² Σ_i bbar_i k_i,        q̇⁺ = q̇ + h Σ_i b_i k_i

RKN4 (:data:`RKN4`: Abramowitz & Stegun 25.5.20, the seed's method with errata 1 and 2
corrected) is

    k1 = f(t, q, v)
    k2 = f(t + h/2, q + h v/2 + h² k1/8, v + h k1/2)
    k3 = f(t + h/2, q + h v/2 + h² k1/8, v + h k2/2)
    k4 = f(t + h,   q + h v + h² k3/2,   v + h k3)
    q⁺ = q + h v + h² (k1 + k2 + k3)/6,   v⁺ = v + h (k1 + 2 k2 + 2 k3 + k4)/6

and :data:`RKN4_AS_PRINTED` the seed's printed variant (a third-order erratum), which runs
through the same kernel (:func:`rkn_chart`). The kernel evaluates a tableau in the order the
formulas above are written for RKN4, so that RKN4 through it is bit for bit the hand-written
method: a stage sums only its nonzero entries, left to right (h² (abar k) equals (h² k)/8
exactly: the entries are powers of two); b and bbar are integer numerators over a common
denominator (k1 + 2 k2 + 2 k3 + k4 summed as written, then ``h * sum / 6.0``: k1/6 + k2/3 …
would round otherwise).

f is constant-load on each piece of the load history; every piece gets a whole number of equal
steps (⌈ℓ/step⌉), so every load edge is a step boundary (seed-notes erratum 5).

The energy flows of :class:`.problem.RightHandSide` (the work done on the system W and the
dissipated energy E, with rates P and D at each stage) are integrated with the velocity's
weights, W⁺ = W + h (P1 + 2 P2 + 2 P3 + P4)/6 and likewise E: the quadrature of a function of
(t, q, q̇) that the update of q̇ is for f, so of the same order 4.

Every ``STABILITY_CHECK_EVERY`` steps the step is checked against the stability region of the
locally linearized problem (:func:`check_stability`, below with its constants).

A stop (the problem's ``stop_margin`` ≤ 0 after a step) ends the run after that step, unless the
problem asks for it to be located (``locate``): then the step is taken again from its start, to
the margin's root on the step's cubic Hermite interpolants (q from q and q̇ at its ends, q̇ from
q̇ and q̈: fourth order, as the method), and its sample replaced by the one there.
"""

import cython
import numpy as np

if cython.compiled:
    from cython.cimports.libc.math import atan2, ceil, cos, exp, fabs, hypot, isfinite, pow, sin
    from cython.cimports.loopcheck.reduced.kernels.output import Outcome, Samples, check_run
    from cython.cimports.loopcheck.reduced.kernels.problem import RightHandSide
else:
    from math import atan2, ceil, cos, exp, fabs, hypot, isfinite, pow, sin

    from loopcheck.reduced.kernels.output import Outcome, Samples, check_run
    from loopcheck.reduced.kernels.problem import RightHandSide

from loopcheck.reduced.kernels import output as _output

# the statuses (loopcheck.reduced.kernels.output) as C constants
OK = cython.declare(cython.int, _output.OK)
NONFINITE = cython.declare(cython.int, _output.NONFINITE)
SPEED = cython.declare(cython.int, _output.SPEED)
UNSTABLE = cython.declare(cython.int, _output.UNSTABLE)
FAILED = cython.declare(cython.int, _output.FAILED)

# RKN4 applied to y'' = λ_1,2-mode of the linearized problem has the stability function of
# classical RK4, R(z) = 1 + z + z²/2 + z³/6 + z⁴/24; a decaying mode needs |R(hλ)| ≤ 1.
STABILITY_CHECK_EVERY = 50  # steps between linearized stability checks
# Growth per step beyond the exact one that is refused. Round-off in the differenced
# Jacobian puts an undamped mode at Re(hλ) ~ 1e-10 on the seed; RK4 just outside its
# imaginary interval (|hω| = 2√2 (1 + 1e-4)) already amplifies by 1 + 2e-4.
STABILITY_MARGIN = 1e-6
# A mode with Re(hλ) above GROWING (relative to |hλ|; round-off gives ~1e-10) grows in the
# problem itself; RK4 reproduces |e^{hλ}| only to O(|hλ|⁵) (on the seed at h = 4 ms a local mode
# hλ = 0.169 + 0.224j has |R| above e^{0.169} by ~1e-5), so such a mode is refused only when the
# method grows it GROWTH_EXCESS (10 %) per step faster than the problem does.
GROWING = 1e-6
GROWTH_EXCESS = 0.1
_CHECK_EVERY = cython.declare(cython.Py_ssize_t, STABILITY_CHECK_EVERY)  # C copies for the kernel
_STABILITY_MARGIN = cython.declare(cython.double, STABILITY_MARGIN)
_GROWING = cython.declare(cython.double, GROWING)
_GROWTH_EXCESS = cython.declare(cython.double, GROWTH_EXCESS)


@cython.cclass
class RKNTableau:
    """An explicit Runge-Kutta-Nyström method for q̈ = f(t, q, q̇) (module docstring).

    Parameters
    ----------
    name : str
    order : int, the order it is declared to have
    c : (s,) stage times (fractions of h); c[0] must be 0 (the kernel reuses f at a step's end
        as the next step's first stage)
    abar, a : (s, s) strictly lower triangular: the stages' position and velocity weights
    bbar, b : (s,) the update's position and velocity weights as numerators over
    denominator : float, the common denominator of bbar and b (exact weights are
        bbar/denominator and b/denominator)
    """

    def __init__(self, name: str, order: int, c, abar, a, bbar, b, denominator: float):
        s = len(c)
        self.name = name
        self.order = order
        self.stages = s
        self.c = np.array(c, dtype=np.float64)
        self.abar = np.zeros((s, s))
        self.a = np.zeros((s, s))
        for i in range(s):
            for j in range(len(abar[i])):
                self.abar[i, j] = abar[i][j]
            for j in range(len(a[i])):
                self.a[i, j] = a[i][j]
        self.bbar = np.array(bbar, dtype=np.float64)
        self.b = np.array(b, dtype=np.float64)
        self.denominator = denominator
        if s < 1 or self.c[0] != 0.0:
            raise ValueError(f"{name}: c[0] must be 0 (the kernel reuses f at a step's end as the next first stage)")
        if len(bbar) != s or len(b) != s or len(abar) != s or len(a) != s:
            raise ValueError(f"{name}: c, abar, a, bbar and b must have one entry per stage")
        if np.any(np.triu(np.asarray(self.abar)) != 0.0) or np.any(np.triu(np.asarray(self.a)) != 0.0):
            raise ValueError(f"{name}: abar and a must be strictly lower triangular (an explicit method)")
        if not denominator > 0.0:
            raise ValueError(f"{name}: the denominator of b and bbar must be positive")

    def __repr__(self):
        return f"RKNTableau({self.name!r}, order={self.order}, stages={self.stages})"

    def __reduce__(self):
        """Pickled as its constructor's arguments (a sweep's workers receive the settings)."""
        a, abar = np.asarray(self.a), np.asarray(self.abar)
        return (RKNTableau, (self.name, self.order, tuple(np.asarray(self.c)),
                             tuple(tuple(abar[i, :i]) for i in range(self.stages)),
                             tuple(tuple(a[i, :i]) for i in range(self.stages)),
                             tuple(np.asarray(self.bbar)), tuple(np.asarray(self.b)), self.denominator))

    def weights(self):
        """The update's weights as floats: (bbar, b), each (s,) (numerators / denominator)."""
        return np.asarray(self.bbar) / self.denominator, np.asarray(self.b) / self.denominator

    def order_condition_residuals(self) -> dict:
        """Residuals of the quadrature conditions up to order 4 (zero for a sound table)."""
        c = np.asarray(self.c)
        bb, b = self.weights()
        a, abar = np.asarray(self.a), np.asarray(self.abar)
        return {
            "sum b = 1": b.sum() - 1.0,
            "b·c = 1/2": b @ c - 0.5,
            "b·c² = 1/3": b @ c**2 - 1.0 / 3,
            "b·c³ = 1/4": b @ c**3 - 0.25,
            "sum bbar = 1/2": bb.sum() - 0.5,
            "bbar·c = 1/6": bb @ c - 1.0 / 6,
            "bbar·c² = 1/12": bb @ c**2 - 1.0 / 12,
            "rows of a sum to c": float(np.max(np.abs(a.sum(axis=1) - c))),
            "rows of abar sum to c²/2": float(np.max(np.abs(abar.sum(axis=1) - c * c / 2))),
        }


# The seed's method with errata 1 and 2 corrected: Abramowitz & Stegun 25.5.20.
RKN4 = RKNTableau(
    "RKN4 (Abramowitz & Stegun 25.5.20)", 4,
    c=(0.0, 0.5, 0.5, 1.0),
    abar=((), (1.0 / 8,), (1.0 / 8, 0.0), (0.0, 0.0, 1.0 / 2)),
    a=((), (1.0 / 2,), (0.0, 1.0 / 2), (0.0, 0.0, 1.0)),
    bbar=(1.0, 1.0, 1.0, 0.0), b=(1.0, 2.0, 2.0, 1.0), denominator=6.0,
)

# The third stage as printed in the seed (m2 in the position argument): third order
# whenever f depends on q. Kept to show the erratum in a test, never used by default.
RKN4_AS_PRINTED = RKNTableau(
    "RKN as printed in the seed", 3,
    c=(0.0, 0.5, 0.5, 1.0),
    abar=((), (1.0 / 8,), (0.0, 1.0 / 8), (0.0, 0.0, 1.0 / 2)),
    a=((), (1.0 / 2,), (0.0, 1.0 / 2), (0.0, 0.0, 1.0)),
    bbar=(1.0, 1.0, 1.0, 0.0), b=(1.0, 2.0, 2.0, 1.0), denominator=6.0,
)

for _name, _residual in RKN4.order_condition_residuals().items():
    assert abs(_residual) < 1e-15, f"RKN4 violates {_name}"


@cython.ccall
def rk4_amplification(zr: cython.double, zi: cython.double) -> cython.double:
    """|R(z)| of classical RK4 (and of RKN4 on a linear problem), z = zr + i zi: the terms
    1 + z + z²/2 + z³/6 + z⁴/24 summed in that order, each power a product from the left
    ((a + ib)(c + id) = (ac − bd) + i(ad + bc), as Python and numba multiply)."""
    z2r: cython.double = zr * zr - zi * zi
    z2i: cython.double = zr * zi + zi * zr
    z3r: cython.double = z2r * zr - z2i * zi
    z3i: cython.double = z2r * zi + z2i * zr
    z4r: cython.double = z3r * zr - z3i * zi
    z4i: cython.double = z3r * zi + z3i * zr
    re: cython.double = 1.0 + zr + z2r / 2.0 + z3r / 6.0 + z4r / 24.0
    im: cython.double = zi + z2i / 2.0 + z3i / 6.0 + z4i / 24.0
    return hypot(re, im)


@cython.ccall
def amplification_limit(zr: cython.double, zi: cython.double) -> cython.double:
    """The largest |R(z)| allowed for the mode z = zr + i zi = hλ: 1 + STABILITY_MARGIN where
    the mode does not grow in the problem, |e^z| (1 + GROWTH_EXCESS) where it does
    (Re z > GROWING |z|)."""
    if zr > _GROWING * hypot(zr, zi):
        return exp(min(zr, 700.0)) * (1.0 + _GROWTH_EXCESS)
    return 1.0 + _STABILITY_MARGIN


@cython.ccall
def check_stability(rhs: RightHandSide, load: cython.Py_ssize_t, t: cython.double, q: cython.double,
                    v: cython.double, h: cython.double, outcome: Outcome) -> cython.int:
    """OK if every mode of the linearization at (q, v) is inside RK4's stability region (or
    grows no faster in the method than in the problem); else UNSTABLE with outcome.detail =
    (Re hλ, Im hλ, |R|, limit), or FAILED when f cannot be evaluated. Uses 3 evaluations.

    The Jacobian of (q, q̇) ↦ (q̇, f) is [[0, 1], [f_q, f_q̇]] (one-sided differences); its
    modes solve λ² − f_q̇ λ − f_q = 0: λ = (f_q̇ ± √disc)/2 with the root of the real
    discriminant taken as Python's ``complex(disc) ** 0.5`` takes it (|disc|^½ (cos φ/2, sin φ/2),
    φ = atan2(0, disc)), so that the verdict and the detail are the numba core's to the bit.
    """
    f0: cython.double = rhs.acceleration(load, t, q, v)
    dq: cython.double = 1e-7 * max(1.0, fabs(q))
    dv: cython.double = 1e-7 * max(1.0, fabs(v))
    fq: cython.double = rhs.acceleration(load, t, q + dq, v)
    fv: cython.double = rhs.acceleration(load, t, q, v + dv)
    if not (isfinite(f0) and isfinite(fq) and isfinite(fv)):
        return FAILED
    f_q: cython.double = (fq - f0) / dq
    f_v: cython.double = (fv - f0) / dv
    disc: cython.double = f_v * f_v + 4.0 * f_q
    root_r: cython.double = 0.0
    root_i: cython.double = 0.0
    if disc != 0.0:  # CPython's _Py_c_pow (numba's too) for complex(disc) ** 0.5
        length: cython.double = pow(fabs(disc), 0.5)  # hypot(disc, 0) = |disc|
        phase: cython.double = atan2(0.0, disc) * 0.5
        root_r = length * cos(phase)
        root_i = length * sin(phase)
    sign: cython.int
    for sign in range(2):
        lr: cython.double = 0.5 * (f_v + root_r) if sign == 0 else 0.5 * (f_v - root_r)
        li: cython.double = 0.5 * root_i if sign == 0 else 0.5 * (0.0 - root_i)
        zr: cython.double = h * lr
        zi: cython.double = h * li
        amplification: cython.double = rk4_amplification(zr, zi)
        limit: cython.double = amplification_limit(zr, zi)
        if amplification > limit:
            outcome.detail[0] = zr
            outcome.detail[1] = zi
            outcome.detail[2] = amplification
            outcome.detail[3] = limit
            return UNSTABLE
    return OK


@cython.cfunc
@cython.inline
def _sample(rhs: RightHandSide, out: Samples, t: cython.double, q: cython.double, v: cython.double,
            accel: cython.double, work: cython.double, dissipated: cython.double) -> cython.void:
    """Append one sample (q̈ = accel just evaluated at it, so observe() records it)."""
    i: cython.Py_ssize_t = out.n
    out.t[i] = t
    out.q[i] = q
    out.v[i] = v
    out.a[i] = accel
    rhs.observe(out.observed, i)
    out.energy[i, 0] = work
    out.energy[i, 1] = dissipated
    out.n = i + 1


@cython.cfunc
def _step(rhs: RightHandSide, load: cython.Py_ssize_t, t: cython.double, q: cython.double, v: cython.double,
          h: cython.double, c: cython.double[::1], a: cython.double[:, ::1], abar: cython.double[:, ::1],
          b: cython.double[::1], bbar: cython.double[::1], den: cython.double, kk: cython.double[::1],
          pp: cython.double[::1], dd: cython.double[::1], res: cython.double[::1]) -> cython.bint:
    """One step of h from (t, q, v), its first stage's f, P, D in kk[0], pp[0], dd[0]: q⁺, q̇⁺
    and the increments of the work done and of the energy dissipated into res[0:4]. False
    where a stage's f is not finite."""
    s: cython.Py_ssize_t = kk.shape[0]
    i: cython.Py_ssize_t
    j: cython.Py_ssize_t
    started: cython.bint
    sq: cython.double
    sv: cython.double
    sp: cython.double
    sd: cython.double
    Q: cython.double
    V: cython.double
    finite: cython.bint = True
    for i in range(1, s):
        # nonzero entries only, left to right (module docstring: RKN4 to the bit)
        started = False
        sq = 0.0
        sv = 0.0
        for j in range(i):
            if abar[i, j] != 0.0:
                sq = sq + abar[i, j] * kk[j] if started else abar[i, j] * kk[j]
                started = True
        Q = q + c[i] * h * v
        if started:
            Q = Q + h * h * sq
        started = False
        for j in range(i):
            if a[i, j] != 0.0:
                sv = sv + a[i, j] * kk[j] if started else a[i, j] * kk[j]
                started = True
        V = v
        if started:
            V = V + h * sv
        kk[i] = rhs.acceleration(load, t + c[i] * h, Q, V)
        pp[i] = rhs.power(load, V)
        dd[i] = rhs.dissipation(V)
        finite = finite and isfinite(kk[i])
    if not finite:
        return False
    sq = 0.0
    sv = 0.0
    sp = 0.0
    sd = 0.0
    started = False
    for i in range(s):
        if bbar[i] != 0.0:
            sq = sq + bbar[i] * kk[i] if started else bbar[i] * kk[i]
            started = True
    started = False
    for i in range(s):
        if b[i] != 0.0:
            if started:
                sv = sv + b[i] * kk[i]
                sp = sp + b[i] * pp[i]
                sd = sd + b[i] * dd[i]
            else:
                sv = b[i] * kk[i]
                sp = b[i] * pp[i]
                sd = b[i] * dd[i]
            started = True
    res[0] = q + h * v + h * h * sq / den
    res[1] = v + h * sv / den
    res[2] = h * sp / den
    res[3] = h * sd / den
    return True


@cython.cfunc
def _root(rhs: RightHandSide, t: cython.double, q0: cython.double, v0: cython.double, a0: cython.double,
          q1: cython.double, v1: cython.double, a1: cython.double, h: cython.double) -> cython.double:
    """The part of the step [t, t + h] to the stop margin's root: bisection (to the spacing of
    the floats) of the margin on the step's cubic Hermite interpolants, q from (q, q̇) and q̇ from
    (q̇, q̈) at its ends (fourth order in h, as the method); the margin is > 0 at its start and
    ≤ 0 at its end."""
    lo: cython.double = 0.0
    hi: cython.double = 1.0
    x: cython.double
    x2: cython.double
    x3: cython.double
    it: cython.int
    for it in range(60):
        x = 0.5 * (lo + hi)
        if x <= lo or x >= hi:
            break
        x2 = x * x
        x3 = x2 * x
        if rhs.stop_margin(t + x * h,
                           (2 * x3 - 3 * x2 + 1) * q0 + (x3 - 2 * x2 + x) * h * v0 + (3 * x2 - 2 * x3) * q1 + (x3 - x2) * h * v1,
                           (2 * x3 - 3 * x2 + 1) * v0 + (x3 - 2 * x2 + x) * h * a0 + (3 * x2 - 2 * x3) * v1 + (x3 - x2) * h * a1
                           ) > 0.0:
            lo = x
        else:
            hi = x
    return hi * h


@cython.ccall
def rkn_chart(rhs: RightHandSide, tableau: RKNTableau, edges: cython.double[::1],
              loads: cython.Py_ssize_t[::1], t0: cython.double, q0: cython.double, v0: cython.double,
              step: cython.double, speed_limit: cython.double, stability: cython.bint, use_stop: cython.bint,
              out: Samples) -> Outcome:
    """Integrate q̈ = rhs.acceleration(load, t, q, q̇) with ``tableau`` from t0 to edges[-1];
    the load history is loads[k] on [edges[k], edges[k+1]] (pieces before t0 are skipped, the
    one holding t0 starts there).

    Parameters
    ----------
    rhs : the problem; tableau : the method (c[0] = 0)
    edges : (p+1,) s, increasing; loads : (p,) the load index of each piece
    t0, q0, v0 : the start (s) and the state there
    step : the largest step (s): a piece of length ℓ gets ⌈ℓ/step − 1e-9⌉ equal steps
    speed_limit : |q̇| beyond which the run ends with SPEED
    stability : check the step every STABILITY_CHECK_EVERY steps (:func:`check_stability`)
    use_stop : end the run after the first step where rhs.stop_margin ≤ 0 (outcome.stopped), or
        at a piece's first sample where rhs.stop_at_start; where rhs.locate says so, that step is
        taken again from its start, to the margin's root on the step's interpolant (:func:`_root`)
    out : the samples are appended to it (its width must be rhs.observation_size()): one at
        every step, and at each piece's start one repeating the previous piece's last time
        with q̈ on the new side; with each, what rhs.observe records and the work done and the
        energy dissipated since t0 (J, the quadrature of the module docstring)

    Returns
    -------
    Outcome: status OK, NONFINITE (fail_time), SPEED (fail_time, fail_value = q̇), UNSTABLE
    (fail_time, detail) or FAILED (fail_time: f not finite there); t_reached, the last sample's
    time; n_evaluations counts every evaluation of f (the stability checks' too). On a failure
    the samples before it stay appended.
    """
    outcome: Outcome = Outcome()
    check_run(out, rhs.observation_size(), edges.shape[0], loads.shape[0])
    if tableau.c[0] != 0.0:
        raise ValueError("the kernel reuses f at a step's end as the next first stage: c[0] must be 0")
    if not step > 0.0:
        raise ValueError(f"step {step}: positive and finite")
    npieces: cython.Py_ssize_t = loads.shape[0]
    s: cython.Py_ssize_t = tableau.stages
    first: cython.Py_ssize_t = 0
    while first < npieces - 1 and edges[first + 1] <= t0:
        first += 1
    total: cython.Py_ssize_t = 0
    k: cython.Py_ssize_t
    start: cython.double
    end: cython.double
    for k in range(first, npieces):
        start = max(edges[k], t0)
        if edges[k + 1] > start:
            total += 1 + max(1, cython.cast(cython.Py_ssize_t, ceil((edges[k + 1] - start) / step - 1e-9)))
    out.reserve(total)
    kk_array = np.empty(s)
    pp_array = np.empty(s)
    dd_array = np.empty(s)
    kk: cython.double[::1] = kk_array  # the stages' f, P and D
    pp: cython.double[::1] = pp_array
    dd: cython.double[::1] = dd_array
    c: cython.double[::1] = tableau.c
    a: cython.double[:, ::1] = tableau.a
    abar: cython.double[:, ::1] = tableau.abar
    b: cython.double[::1] = tableau.b
    bbar: cython.double[::1] = tableau.bbar
    den: cython.double = tableau.denominator
    work: cython.double = 0.0
    dissipated: cython.double = 0.0
    n_steps: cython.Py_ssize_t = 0
    n_eval: cython.Py_ssize_t = 0
    q: cython.double = q0
    v: cython.double = v0
    t: cython.double
    t_next: cython.double
    h: cython.double
    accel: cython.double
    load: cython.Py_ssize_t
    n: cython.Py_ssize_t
    m: cython.Py_ssize_t
    i: cython.Py_ssize_t
    status: cython.int
    q_prev: cython.double = q0
    v_prev: cython.double = v0
    hs: cython.double
    res_array = np.empty(4)
    res: cython.double[::1] = res_array  # a step's q⁺, q̇⁺ and the energy flows' increments
    outcome.t_reached = t0
    if not (isfinite(q) and isfinite(v)):
        outcome.status = NONFINITE
        outcome.fail_time = t0
        return outcome
    if fabs(v) > speed_limit:
        outcome.status = SPEED
        outcome.fail_time = t0
        outcome.fail_value = v
        return outcome
    for k in range(first, npieces):
        start = max(edges[k], t0)
        end = edges[k + 1]
        if end <= start:
            continue
        load = loads[k]
        n = max(1, cython.cast(cython.Py_ssize_t, ceil((end - start) / step - 1e-9)))
        h = (end - start) / n
        accel = rhs.acceleration(load, start, q, v)
        pp[0] = rhs.power(load, v)
        dd[0] = rhs.dissipation(v)
        n_eval += 1
        if not isfinite(accel):
            outcome.status = FAILED
            outcome.fail_time = start
            break
        _sample(rhs, out, start, q, v, accel, work, dissipated)
        outcome.t_reached = start
        if use_stop and rhs.stop_at_start(start, q, v):  # an event at the piece's start (a load edge)
            outcome.stopped = True
            break
        for m in range(n):
            t = start + m * h
            if stability and n_steps % _CHECK_EVERY == 0:
                status = check_stability(rhs, load, t, q, v, h, outcome)
                n_eval += 3
                if status != OK:
                    outcome.status = status
                    outcome.fail_time = t
                    break
            kk[0] = accel
            q_prev = q
            v_prev = v
            if not _step(rhs, load, t, q, v, h, c, a, abar, b, bbar, den, kk, pp, dd, res):
                outcome.status = FAILED
                outcome.fail_time = t
                break
            q = res[0]
            v = res[1]
            work += res[2]
            dissipated += res[3]
            t_next = end if m + 1 == n else start + (m + 1) * h
            if not (isfinite(q) and isfinite(v)):
                outcome.status = NONFINITE
                outcome.fail_time = t_next
                break
            if fabs(v) > speed_limit:
                outcome.status = SPEED
                outcome.fail_time = t_next
                outcome.fail_value = v
                break
            accel = rhs.acceleration(load, t_next, q, v)  # also the next step's k1
            pp[0] = rhs.power(load, v)
            dd[0] = rhs.dissipation(v)
            n_eval += s
            n_steps += 1
            if not isfinite(accel):
                outcome.status = FAILED
                outcome.fail_time = t_next
                break
            _sample(rhs, out, t_next, q, v, accel, work, dissipated)
            outcome.t_reached = t_next
            if use_stop and rhs.stop_margin(t_next, q, v) <= 0.0:
                outcome.stopped = True
                if rhs.locate(t_next, q, v):  # the step again, to the event's root (module docstring)
                    hs = _root(rhs, t, q_prev, v_prev, kk[0], q, v, accel, t_next - t)
                    kk[0] = rhs.acceleration(load, t, q_prev, v_prev)
                    pp[0] = rhs.power(load, v_prev)
                    dd[0] = rhs.dissipation(v_prev)
                    work -= res[2]
                    dissipated -= res[3]
                    if not _step(rhs, load, t, q_prev, v_prev, hs, c, a, abar, b, bbar, den, kk, pp, dd, res):
                        outcome.status = FAILED
                        outcome.fail_time = t
                        break
                    q = res[0]
                    v = res[1]
                    work += res[2]
                    dissipated += res[3]
                    accel = rhs.acceleration(load, t + hs, q, v)
                    n_eval += s + 1
                    out.n -= 1
                    _sample(rhs, out, t + hs, q, v, accel, work, dissipated)
                    outcome.t_reached = t + hs
                break
        if outcome.status != OK or outcome.stopped:
            break
    outcome.n_steps = n_steps
    outcome.n_evaluations = n_eval
    return outcome
