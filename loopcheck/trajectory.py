"""The one trajectory type every engine returns, with its interpolant and peak finder.

Samples are (t, q, q̇, q̈) of the input link. Times are non-decreasing; a time may
appear twice where q̈ jumps (a load edge): q and q̇ agree there, q̈ holds the values on
either side. Between samples the trajectory is the quintic Hermite polynomial through
q, q̇, q̈ at both ends: O(h⁶) in q and O(h⁵) in q̇ for a smooth motion, so it adds less
error than a fourth-order integrator at the same spacing.

That holds when the samples' q̈ is consistent with their q and q̇ to high order: a dense output
(the reduced engine, Pinocchio's) or a fourth-order method's steps (MuJoCo's RK4). A first-order
integrator's samples (MuJoCo's Euler, implicit, implicitfast) are consistent to O(h) only (the
step advances q̇ by h times the step's start acceleration, damping taken implicitly, q by h q̇ at
the step's end), so the polynomial through them swings by O(h q̈) between samples. Such a
trajectory says so (``refined_extrema=False``) and its peak is the extreme sample
(:meth:`Trajectory.peak_rate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


PEAK_CANDIDATE_BAND = 0.01  # local maxima of |q̇| samples within 1 % of the largest are refined


def freeze_arrays(value, names: tuple[str, ...], dtype=None) -> None:
    """Set each named field of the frozen dataclass ``value`` to a read-only copy of its array
    (results are read-only: a caller's array is neither kept nor frozen)."""
    for name in names:
        a = np.array(getattr(value, name), dtype=dtype, copy=True)
        a.setflags(write=False)
        object.__setattr__(value, name, a)


@dataclass(frozen=True)
class Peak:
    """The peak of a run's input rate, one event: q̇ (signed; rad/s, or m/s for a prismatic
    input) at time t (s).

    ``still_rising`` is True when the event is the run's last sample and |q̇| is still rising
    there (sign(q̇)·q̈ > 0): the horizon ends before the speed peaks, so the "peak" is only the
    speed at the end. Defined by :meth:`Trajectory.peak_rate` (a run's own peak)
    and :meth:`Trajectory.extremum_near` (the same event in another run): every output that
    shows a peak takes it from these two.
    """

    omega: float
    time: float
    still_rising: bool = False


def _cubic_roots(cubics: list[tuple[float, float, float, float]]) -> list:
    """Per interval, the roots of 20 c5 s³ + 12 c4 s² + 6 c3 s + 2 c2 (``cubics``: each interval's
    (c2, c3, c4, c5), floats) exactly as ``np.roots([20 c5, 12 c4, 6 c3, 2 c2])`` gives them (none
    where c3 = c4 = c5 = 0): the eigenvalues of its companion matrix, those of every full cubic
    (c5 ≠ 0, c2 ≠ 0) from one batched call of ``np.linalg.eigvals`` (the matrix's first row
    −p[1:] / p[0] as np.roots makes it), the others by ``np.roots`` itself."""
    polys = [(20 * c5, 12 * c4, 6 * c3, 2 * c2) for c2, c3, c4, c5 in cubics]
    full = [k for k, p in enumerate(polys) if p[0] != 0 and p[3] != 0]
    out: list = [None] * len(polys)
    if full:
        A = np.zeros((len(full), 3, 3))
        A[:, 1, 0] = A[:, 2, 1] = 1.0
        A[:, 0, :] = [[-p[1] / p[0], -p[2] / p[0], -p[3] / p[0]] for p in (polys[k] for k in full)]
        for k, w in zip(full, np.linalg.eigvals(A)):
            out[k] = w
    for k, p in enumerate(polys):
        if out[k] is None:
            out[k] = np.roots(p) if (p[0] or p[1] or p[2]) else []
    return out


def _quintic(c: tuple, s, h) -> tuple:
    """q, q̇, q̈ of the quintic with coefficients ``c`` (c0..c5 in s = (t − t_i)/h) at s, on intervals
    of length h: arrays or floats alike (the same operations in the same order: the same bits)."""
    c0, c1, c2, c3, c4, c5 = c
    q = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
    v = (c1 + s * (2 * c2 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)))) / h
    a = (2 * c2 + s * (6 * c3 + s * (12 * c4 + s * 20 * c5))) / (h * h)
    return q, v, a


@dataclass(frozen=True)
class Trajectory:
    """Samples of the input link: times (s), q (rad), q̇ (rad/s), q̈ (rad/s²), each shape (n,).

    ``refined_extrema``: whether the samples support an extremum located between them (module
    docstring): True for a dense output or a fourth-order method's steps, False for a first-order
    integrator's samples, whose peak is then the extreme sample.
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    qddot: np.ndarray
    refined_extrema: bool = True

    def __post_init__(self) -> None:
        arrays = {name: np.asarray(getattr(self, name), dtype=float)
                  for name in ("t", "q", "qdot", "qddot")}
        n = arrays["t"].shape
        for name, a in arrays.items():
            if a.ndim != 1 or a.shape != n:
                raise ValueError(f"Trajectory.{name} must have shape {n}, got {a.shape}")
            if not np.isfinite(a).all():
                raise ValueError(f"Trajectory.{name} contains NaN or inf")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if n[0] < 2:
            raise ValueError("a trajectory needs at least two samples")
        t = arrays["t"]
        if (t[1:] < t[:-1]).any():
            raise ValueError("Trajectory.t must be non-decreasing")
        if not isinstance(self.refined_extrema, (bool, np.bool_)):
            raise ValueError(f"Trajectory.refined_extrema must be True or False, got {self.refined_extrema!r}")
        object.__setattr__(self, "refined_extrema", bool(self.refined_extrema))

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def _coefficients(self, i, h) -> tuple:
        """Polynomial coefficients c0..c5 in s = (t − t_i)/h on intervals i (an array, or one index
        and its length h as floats)."""
        q0, v0, a0 = self.q[i], self.qdot[i], self.qddot[i]
        q1, v1, a1 = self.q[i + 1], self.qdot[i + 1], self.qddot[i + 1]
        c0, c1, c2 = q0, h * v0, 0.5 * h * h * a0
        r0 = q1 - c0 - c1 - c2
        r1 = h * v1 - c1 - 2.0 * c2
        r2 = h * h * a1 - 2.0 * c2
        c3 = 10.0 * r0 - 4.0 * r1 + 0.5 * r2
        c4 = -15.0 * r0 + 7.0 * r1 - r2
        c5 = 6.0 * r0 - 3.0 * r1 + 0.5 * r2
        return c0, c1, c2, c3, c4, c5

    def _locate(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Interval index i, its length h and the local coordinate s = (t − t_i)/h.

        Only intervals of positive length are used: a time on a repeated sample (a load edge
        or a coordinate switch) goes to the next such interval, or the last one at the end.
        """
        live = np.flatnonzero(np.diff(self.t) > 0.0)
        i = np.searchsorted(self.t, times, side="right") - 1
        k = np.minimum(np.searchsorted(live, i), len(live) - 1)
        i = live[k]
        h = self.t[i + 1] - self.t[i]
        return i, h, (times - self.t[i]) / h

    def _at(self, time: float, j: int) -> tuple[int, float, float]:
        """:meth:`_locate` of one time found inside interval j (whose length is positive): (i, h, s)
        in floats, the same numbers; a time that rounds onto t[j + 1] goes to :meth:`_locate`."""
        if self.t[j] <= time < self.t[j + 1]:
            h = self.t[j + 1] - self.t[j]
            return j, h, (time - self.t[j]) / h
        i, h, s = self._locate(np.array([time]))
        return int(i[0]), float(h[0]), float(s[0])

    def interpolate(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, q̇, q̈ at ``times`` (within [t0, tf]); each the shape of ``times``."""
        times = np.asarray(times, dtype=float)
        if np.any(times < self.t[0] - 1e-12) or np.any(times > self.t[-1] + 1e-12):
            raise ValueError("interpolation outside the trajectory's time span")
        i, h, s = self._locate(times)
        return _quintic(self._coefficients(i, h), s, h)

    def peak_rate(self, sign: int | None = None) -> Peak:
        """The largest |q̇| over the run (rad/s, or m/s for a prismatic input), located between
        samples where q̈ = 0 when the samples support it (``refined_extrema``), else the extreme
        sample.

        Candidates are every sample (a maximum may sit on a load edge where q̈ jumps)
        and every root of the interpolant's q̈ (a cubic in s) inside the intervals next
        to the largest sample; the best candidate is returned with its sign. With
        ``sign`` = +1 (−1) only the largest positive (most negative) q̇ is sought, so that
        two runs of a swinging motion are compared on the same side.

        The rule: a first-order integrator's samples (``refined_extrema`` False) give the extreme
        sample. The polynomial through them is off by O(h q̈) between samples (module docstring),
        so its summit is an artefact of the interpolant, not of the run: on a driven four-bar
        swinging under gravity, by MuJoCo's Euler at 2 ms, it stood 4.0e-4 rad/s above every
        sample, 5.2e-4 off the exact peak where the extreme sample is 1.1e-4 off
        (tests/reference_models/test_mujoco_sampled_peak.py). The extreme sample's error is the run's own plus the sampling
        shortfall, at most ~h²|q⃛|/8, second order in h, below a first-order run's own error.
        """
        objective = np.abs(self.qdot) if sign is None else sign * self.qdot
        k = int(np.argmax(objective))
        best = Peak(float(self.qdot[k]), float(self.t[k]))
        if not self.refined_extrema:
            return self._flagged(best)
        # The summit between samples of one extremum can exceed the largest sample, which may
        # belong to another: refine around every local maximum of the samples within
        # PEAK_CANDIDATE_BAND of the largest (a summit exceeds its samples by ~h²|q⃛|/8, far less).
        rises = (objective[1:-1] > objective[:-2]) & (objective[1:-1] >= objective[2:])
        near = objective[1:-1] >= objective[k] - PEAK_CANDIDATE_BAND * abs(objective[k])
        maxima = np.flatnonzero(rises & near) + 1
        around = sorted({i for m in (k, *maxima.tolist()) for i in (m - 2, m - 1, m, m + 1)})
        around = [i for i in around if 0 <= i and i + 1 < len(self.t) and self.t[i + 1] != self.t[i]]
        if not around:
            return self._flagged(best)
        h = [self.t[j + 1] - self.t[j] for j in around]
        # q̈ ∝ 2 c2 + 6 c3 s + 12 c4 s² + 20 c5 s³: its roots in (0, 1), interval by interval in
        # time order (a tie keeps the earlier), as np.roots finds them, the eigenvalues of the
        # companion matrix, here of all the (few) intervals' in one call, their coefficients in floats
        cubics = [self._coefficients(j, hj)[2:] for j, hj in zip(around, h)]
        found = [(self.t[j] + r.real * hj, j) for j, hj, roots in zip(around, h, _cubic_roots(cubics))
                 for r in roots if abs(r.imag) < 1e-12 and 0.0 < r.real < 1.0]
        if found:  # q̇ there as interpolate gives it, each (a few) in floats: ~1 µs, not ~50 of arrays
            times = [t for t, _ in found]
            v = [_quintic(self._coefficients(i, h), s, h)[1] for i, h, s in (self._at(t, j) for t, j in found)]
            for t, vt in zip(times, v):
                better = abs(vt) > abs(best.omega) if sign is None else sign * vt > sign * best.omega
                if better:
                    best = Peak(float(vt), float(t))
        return self._flagged(best)

    def _flagged(self, peak: Peak) -> Peak:
        """``peak`` with ``still_rising`` set when it is the last sample and |q̇| rises there."""
        rising = peak.time == self.t[-1] and float(np.sign(peak.omega) * self.qddot[-1]) > 0.0
        return Peak(peak.omega, peak.time, still_rising=bool(rising))

    def extremum_near(self, peak: Peak) -> Peak:
        """The same event as ``peak`` (another run's peak) in this trajectory: the local
        extremum of q̇ of the same sign as ``peak.omega`` nearest in time to ``peak.time``
        (a local maximum of q̇ for a positive peak, a local minimum for a negative one).

        Candidates are the samples where sign·q̇ > 0 stops rising, each end included where
        sign·q̇ does not rise into the run from it; each is refined between samples by
        :meth:`peak_rate` (with the sign) on its two neighbouring intervals (so not between
        samples of a first-order integrator: the candidate sample itself). Of
        candidates equally near, the larger sign·q̇ wins. When q̇ never takes that sign, there
        is no such event: the value at ``peak.time`` is returned (so the difference of the two
        shows how far apart the runs are, and a gate on it fails).
        """
        sign = 1.0 if peak.omega >= 0.0 else -1.0
        w = sign * self.qdot
        rising_in = np.r_[True, w[1:] > w[:-1]]
        falling_out = np.r_[w[:-1] >= w[1:], True]
        candidates = np.flatnonzero(rising_in & falling_out & (w > 0.0))
        found: list[Peak] = []
        n = len(self.t)
        for k in candidates:
            a, b = max(k - 1, 0), min(k + 2, n)  # the two intervals beside sample k
            if b - a < 2 or not np.any(np.diff(self.t[a:b]) > 0.0):
                found.append(Peak(float(self.qdot[k]), float(self.t[k])))
                continue
            part = Trajectory(self.t[a:b], self.q[a:b], self.qdot[a:b], self.qddot[a:b], self.refined_extrema)
            found.append(part.peak_rate(sign=int(sign)))
        if not found:
            time = float(np.clip(peak.time, self.t[0], self.t[-1]))
            return Peak(float(self.interpolate(np.array([time]))[1][0]), time)
        best = min(found, key=lambda p: (abs(p.time - peak.time), -sign * p.omega))
        return self._flagged(Peak(best.omega, best.time))

    def within(self, start: float, end: float) -> "Trajectory":
        """The trajectory on [start, end] (s, inside its span): itself when that is its whole
        span, else its samples inside with the ends interpolated."""
        if start <= self.t[0] and end >= self.t[-1]:
            return self
        start, end = max(float(start), float(self.t[0])), min(float(end), float(self.t[-1]))
        inside = (self.t > start) & (self.t < end)
        q, v, a = self.interpolate(np.array([start, end]))
        return Trajectory(np.r_[start, self.t[inside], end], np.r_[q[0], self.q[inside], q[1]],
                          np.r_[v[0], self.qdot[inside], v[1]], np.r_[a[0], self.qddot[inside], a[1]],
                          self.refined_extrema)

    def resample(self, times: np.ndarray) -> "Trajectory":
        """The trajectory at new sample times (interpolated)."""
        q, v, a = self.interpolate(times)
        return Trajectory(np.asarray(times, dtype=float), q, v, a, self.refined_extrema)


@dataclass(frozen=True)
class JointTrajectory:
    """Every joint coordinate along a run, in the coordinates of :class:`loopcheck.kinematics.LoopSystem`.

    names (m,) its coordinate names; t (n,) s; x (n, m) rad or m (angles unwrapped);
    xdot (n, m) rad/s or m/s; coordinate (n,) index of the independent coordinate used at
    each sample (−1 for an engine without charts, MuJoCo); mode (n, loops) int, the
    assembly mode (:func:`loopcheck.kinematics.assembly_modes`) at each sample.
    """

    names: tuple[str, ...]
    t: np.ndarray
    x: np.ndarray
    xdot: np.ndarray
    coordinate: np.ndarray
    mode: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(self.names))
        freeze_arrays(self, ("t", "x", "xdot", "coordinate", "mode"))

    def interpolate(self, times) -> tuple[np.ndarray, np.ndarray]:
        """x and ẋ at ``times`` (s, clamped to the run's span), shapes (len(times), m): the cubic
        Hermite interpolant of the samples' x and ẋ on the interval holding each time (O(h⁴)) and
        its derivative. At a repeated time (a coordinate switch, a load edge) the later sample
        is used."""
        T = np.asarray(self.t, dtype=float)
        X, V = np.asarray(self.x, dtype=float), np.asarray(self.xdot, dtype=float)
        times = np.clip(np.atleast_1d(np.asarray(times, dtype=float)), T[0], T[-1])
        if len(T) == 1:
            return np.repeat(X, len(times), axis=0), np.repeat(V, len(times), axis=0)
        k = np.clip(np.searchsorted(T, times, side="right") - 1, 0, len(T) - 2)
        h = T[k + 1] - T[k]
        flat = h <= 0.0  # the last two samples at one time: the later one
        h = np.where(flat, 1.0, h)[:, None]
        s = np.where(flat, 1.0, (times - T[k]) / h[:, 0])[:, None]
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, 6 * s - 6 * s**2, 3 * s**2 - 2 * s
        x = h00 * X[k] + h10 * h * V[k] + h01 * X[k + 1] + h11 * h * V[k + 1]
        xdot = np.where(flat[:, None], V[k + 1], (d00 * X[k] + d01 * X[k + 1]) / h + d10 * V[k] + d11 * V[k + 1])
        return x, xdot
