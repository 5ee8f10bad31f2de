"""Differences between two trajectories of the input joint, and the agreement gate (over every
input of a scene of several degrees of freedom: :func:`gate_inputs`, one :class:`Difference` per input).

q is the input coordinate: an angle (rad) or a slider displacement (m); "ω" in names and
keys is its rate q̇ (rad/s or m/s). Figures below quoted in rad hold for a revolute input.

Span: the comparison covers the times both trajectories reach, [max of the starts, min of
the ends], and records it (``span_start``, ``span_end``) beside the span it was asked to
cover (``horizon``: the scene's, or by default the reference's end). The gate fails when a
trajectory stops short of the horizon, so a truncated run is never judged on its overlap.

Common time grid: the compared trajectory's own sample times inside the span. The reference
is evaluated there through its quintic Hermite interpolant (O(h⁶) in q, O(h⁵) in q̇ at its
≤ 1 ms sample spacing: below 1e-10 rad on the seed scene), so the compared engine's samples
are used as they are and the interpolation adds less error than either engine makes.

The compared peak, one event in both runs (:class:`loopcheck.trajectory.Peak`, defined once in
:mod:`loopcheck.trajectory`): the reference's largest |ω| within the span, with its sign and
time (:meth:`~loopcheck.trajectory.Trajectory.peak_rate`), and the other engine's
local extremum of ω of the same sign nearest in time to it
(:meth:`~loopcheck.trajectory.Trajectory.extremum_near`). A conservative swing has several
extremes of |ω| equal to round-off, of both signs; pairing by sign and time keeps both engines
on the same one, so the peak-time difference is the difference of the two reported times. A
peak flagged ``still_rising`` is the span's last sample with |ω| still rising: the horizon
ends before the speed peaks.

Relative peak figure: |Δ peak| / max(|peak_ref|, ``peak_floor``), with ``peak_floor`` =
peak_omega_atol / peak_omega_rtol of the tolerances (1e-5 rad/s by default): a motion that
barely moves is judged on its absolute difference, never on a ratio of round-off.

Over configuration: for each compared sample (q_k, q̇_k) the reference time t* with
q_ref(t*) = q_k is found by Newton's method on the interpolant (from t_k), and
Δω(q) = q̇_k − q̇_ref(t*). A pure timing (phase) error then gives Δω(q) ≈ 0 while
|Δq̇(t)| can be large. Samples where the reference moves slowly
(|q̇_ref| < 1 % of its largest value) are left out: there q does not fix the time; so
are samples whose angle the reference never reaches within its time span.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.scene import Tolerances
from loopcheck.trajectory import Peak, Trajectory

SLOW_FRACTION = 0.01
ANGLE_MATCH = 1e-9  # per unit of q (rad or m): Newton's residual below which q_ref(t*) = q_k is accepted
DEFAULT_PEAK_FLOOR = Tolerances().peak_omega_atol / Tolerances().peak_omega_rtol  # rad/s
SPAN_SLACK = 1e-9  # relative: a trajectory ending this close to the horizon covers it


@dataclass(frozen=True)
class Difference:
    """How far ``other`` is from ``reference`` in the input coordinate q (units: rad and
    rad/s for a revolute input, m and m/s for a prismatic one, and s; "ω" is q̇ either way).

    ``peak_reference``/``peak_other`` are the compared peak, one event in both runs (module
    docstring); ``peak_omega_reference``/``peak_omega_other`` their signed ω (rad/s) at
    ``t_peak_reference``/``t_peak_other`` (s); ``peak_omega_abs`` and ``t_peak_abs`` are
    their differences, ``peak_omega_rel`` = peak_omega_abs / max(|peak_omega_reference|,
    ``peak_floor``). ``span_start``/``span_end`` (s) is the time span compared;
    ``horizon`` (s) the end it had to reach; ``reference_end``/``other_end`` where each
    trajectory stops.
    """

    peak_omega_abs: float
    peak_omega_rel: float
    t_peak_abs: float
    q_max_abs: float
    q_rms: float
    omega_max_abs: float
    omega_rms: float
    omega_vs_q_max_abs: float
    times: np.ndarray = field(repr=False)
    dq: np.ndarray = field(repr=False)
    domega: np.ndarray = field(repr=False)
    q_samples: np.ndarray = field(repr=False)  # q_k of the compared samples used for Δω(q)
    domega_vs_q: np.ndarray = field(repr=False)
    peak_reference: Peak
    peak_other: Peak
    peak_floor: float
    span_start: float
    span_end: float
    horizon: float
    reference_end: float
    other_end: float

    @property
    def peak_omega_reference(self) -> float:
        return self.peak_reference.omega

    @property
    def peak_omega_other(self) -> float:
        return self.peak_other.omega

    @property
    def t_peak_reference(self) -> float:
        return self.peak_reference.time

    @property
    def t_peak_other(self) -> float:
        return self.peak_other.time

    @property
    def peak_still_rising(self) -> bool:
        """Whether the reference's peak is the span's end with |ω| still rising."""
        return self.peak_reference.still_rising

    @property
    def covers_horizon(self) -> bool:
        """Whether the compared span reaches the horizon (to ``SPAN_SLACK`` relative)."""
        return self.span_end >= self.horizon - SPAN_SLACK * max(abs(self.horizon), 1.0)

    def figures(self) -> dict[str, float]:
        """The scalar figures, for reports."""
        return {k: getattr(self, k) for k in (
            "peak_omega_abs", "peak_omega_rel", "t_peak_abs", "q_max_abs", "q_rms",
            "omega_max_abs", "omega_rms", "omega_vs_q_max_abs", "peak_omega_reference",
            "peak_omega_other", "t_peak_reference", "t_peak_other", "span_start", "span_end",
            "horizon")}


def _time_at_angle(reference: Trajectory, q_target: np.ndarray, t_guess: np.ndarray,
                   iterations: int = 8) -> np.ndarray:
    """Solve q_ref(t) = q_target near t_guess by Newton's method (vectorized). An iterate that
    lands where q̇_ref = 0 (a turning point the guess was near) stays there; the caller keeps
    only the matches that solve the equation."""
    t = t_guess.copy()
    lo, hi = reference.t[0], reference.t[-1]
    for _ in range(iterations):
        q, v, _ = reference.interpolate(t)
        moving = v != 0.0
        step = np.zeros_like(t)
        step[moving] = (q[moving] - q_target[moving]) / v[moving]
        t = np.clip(t - step, lo, hi)
    return t


def compared_peaks(reference: Trajectory, other: Trajectory, start: float, end: float) -> tuple[Peak, Peak]:
    """The compared peak on [start, end] (s), one event in both runs (module docstring): the
    reference's largest |ω| with its sign and time, and ``other``'s local extremum of ω of
    the same sign nearest in time to it."""
    peak = reference.within(start, end).peak_rate()
    return peak, other.within(start, end).extremum_near(peak)


def peak_floor_of(tolerances: Tolerances) -> float:
    """peak_omega_atol / peak_omega_rtol (rad/s): below this |peak| a relative figure is
    taken of the floor instead, so that rel ≤ rtol implies the gate's absolute test."""
    if tolerances.peak_omega_rtol <= 0.0:
        return np.inf
    return tolerances.peak_omega_atol / tolerances.peak_omega_rtol


def compare_trajectories(reference: Trajectory, other: Trajectory, *, horizon: float | None = None,
                         peak_floor: float = DEFAULT_PEAK_FLOOR) -> Difference:
    """Differences of ``other`` from ``reference`` on ``other``'s sample times.

    Parameters
    ----------
    horizon : the time (s) both must reach; default the reference's end. Recorded in the
        result; :func:`gate` fails when the compared span stops short of it.
    peak_floor : the smallest |peak| (rad/s) a relative peak difference is taken of:
        ``peak_omega_rel`` = |Δ peak| / max(|peak_ref|, peak_floor). Pass
        peak_omega_atol / peak_omega_rtol of the tolerances in use.

    Raises
    ------
    NumericalFailure
        (INCOMPLETE) when the two trajectories share no sample time at all.
    """
    if not peak_floor >= 0.0:
        raise ValueError(f"peak_floor must be non-negative, got {peak_floor}")
    start = max(reference.t[0], other.t[0])
    end = min(reference.t[-1], other.t[-1])
    keep = (other.t >= start - 1e-12) & (other.t <= end + 1e-12)
    if not np.any(keep) or end < start:
        raise NumericalFailure(FailureReason.INCOMPLETE, (
            f"nothing to compare: the reference spans [{reference.t[0]:g}, {reference.t[-1]:g}] s, "
            f"the other trajectory [{other.t[0]:g}, {other.t[-1]:g}] s"))
    times = other.t[keep]
    q_ref, v_ref, _ = reference.interpolate(np.clip(times, reference.t[0], reference.t[-1]))
    dq = other.q[keep] - q_ref
    domega = other.qdot[keep] - v_ref

    peak_ref, peak_other = compared_peaks(reference, other, start, end)
    fast = (np.abs(v_ref) >= SLOW_FRACTION * np.max(np.abs(reference.qdot))) & (v_ref != 0.0)
    q_fast = other.q[keep][fast]
    t_star = _time_at_angle(reference, q_fast, times[fast])
    q_star, v_star, _ = reference.interpolate(t_star)
    matched = np.abs(q_star - q_fast) <= ANGLE_MATCH * (1.0 + np.abs(q_fast))
    domega_q = (other.qdot[keep][fast] - v_star)[matched]

    def rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(a * a))) if a.size else 0.0

    peak_abs = abs(peak_other.omega - peak_ref.omega)
    scale = max(abs(peak_ref.omega), peak_floor)
    return Difference(
        peak_omega_abs=peak_abs,
        peak_omega_rel=(peak_abs / scale if scale > 0.0 else np.inf) if peak_abs else 0.0,
        t_peak_abs=abs(peak_other.time - peak_ref.time),
        q_max_abs=float(np.max(np.abs(dq))), q_rms=rms(dq),
        omega_max_abs=float(np.max(np.abs(domega))), omega_rms=rms(domega),
        # No fast sample: nothing to compare (0). Fast samples but none at an angle the reference
        # reaches: the engines are not in the same configuration at all — NaN, which fails the gate.
        omega_vs_q_max_abs=(float(np.max(np.abs(domega_q))) if domega_q.size
                            else math.nan if fast.any() else 0.0),
        times=times, dq=dq, domega=domega, q_samples=q_fast[matched], domega_vs_q=domega_q,
        peak_reference=peak_ref, peak_other=peak_other, peak_floor=peak_floor, span_start=float(start), span_end=float(end),
        horizon=float(reference.t[-1] if horizon is None else horizon),
        reference_end=float(reference.t[-1]), other_end=float(other.t[-1]))


@dataclass(frozen=True)
class ModeCheck:
    """Samples where the compared engine sits in another assembly mode, loop by loop.

    ``mismatches[k]`` counts the judged samples whose sign of loop k differs from the
    reference's; ``first_times[k]`` (s) is the first of them, or None.
    """

    mismatches: tuple[int, ...]
    first_times: tuple[float | None, ...]

    @property
    def total(self) -> int:
        """Samples with any loop in another mode, summed over the loops."""
        return int(sum(self.mismatches))

    def lines(self) -> list[str]:
        """One phrase per loop that differs: ``loop 2: 41 sample(s) from t = 0.6 s``."""
        return [f"loop {k + 1}: {n} sample(s) from t = {t:.6g} s"
                for k, (n, t) in enumerate(zip(self.mismatches, self.first_times)) if n]


def compare_modes(reference, other, window: float | None = None) -> ModeCheck:
    """Count, per loop, ``other``'s samples whose assembly mode differs from the reference's.

    Both are :class:`~loopcheck.reduced.charts.JointTrajectory`, whose ``mode`` has shape
    (samples, loops) (one sign ±1 per loop, 0 where the loop's dyad is degenerate). A loop's
    mode changes legitimately where its dyad passes a limit position; samples within
    ``window`` seconds of a change of that loop's reference mode (default: twice the coarser
    sample spacing) are not judged, nor are samples where either sign is 0. The reference is
    read at its sample at or after each compared time.

    Raises
    ------
    ValueError
        When the two trajectories do not have the same number of loops.
    """
    m_ref = np.asarray(reference.mode, dtype=int).reshape(len(reference.t), -1)
    m_oth = np.asarray(other.mode, dtype=int).reshape(len(other.t), -1)
    if m_ref.shape[1] != m_oth.shape[1]:
        raise ValueError(f"the reference has {m_ref.shape[1]} loop(s), the compared run "
                         f"{m_oth.shape[1]}: their modes cannot be compared")
    t_ref, t_oth = np.asarray(reference.t), np.asarray(other.t)
    spacing = max(float(np.max(np.diff(t_ref), initial=0.0)), float(np.max(np.diff(t_oth), initial=0.0)))
    window = 2.0 * spacing if window is None else window
    k = np.clip(np.searchsorted(t_ref, t_oth), 0, len(t_ref) - 1)
    mismatches, firsts = [], []
    for loop in range(m_ref.shape[1]):
        ref = m_ref[:, loop]
        changes = t_ref[1:][ref[1:] != ref[:-1]]
        near_change = np.zeros(len(t_oth), dtype=bool)
        for tc in changes:
            near_change |= np.abs(t_oth - tc) <= window
        judged = ~near_change & (ref[k] != 0) & (m_oth[:, loop] != 0)
        wrong = (m_oth[:, loop] != ref[k]) & judged
        mismatches.append(int(np.sum(wrong)))
        firsts.append(float(t_oth[np.argmax(wrong)]) if wrong.any() else None)
    return ModeCheck(tuple(mismatches), tuple(firsts))


@dataclass(frozen=True)
class GateResult:
    """Whether two engines agree within the tolerances."""

    passed: bool
    failures: tuple[str, ...]
    tolerances: Tolerances


def gate(diff: Difference, tolerances: Tolerances, modes: ModeCheck | None = None, *,
         unit: str = "rad") -> GateResult:
    """Judge a comparison against tolerances.

    It fails when the compared span stops short of ``diff.horizon``; when the peaks of |ω|
    differ by more than peak_omega_rtol·|peak_ref| + peak_omega_atol (rad/s); when max |Δq|
    exceeds q_atol (rad) or max |Δq̇| exceeds omega_atol (rad/s); when the tolerances set
    omega_vs_q_atol and max |Δω| at equal q exceeds it (rad/s); and when a sample sits in
    another assembly mode (any loop). ``unit`` is the input coordinate's ("rad" or "m",
    ``scene.input_unit``): the messages give q in it and its rate in it per s.
    """
    failures = [*_span_failures(diff), *_input_failures(diff, tolerances, unit), *_mode_failures(modes)]
    return GateResult(passed=not failures, failures=tuple(failures), tolerances=tolerances)


def gate_inputs(diffs: tuple[Difference, ...], tolerances: Tolerances, modes: ModeCheck | None = None, *,
                units: tuple[str, ...], names: tuple[str, ...]) -> GateResult:
    """The gate over every input of a scene of several degrees of freedom: ``diffs`` one
    :class:`Difference` per input (in the scene's inputs order, ``names``, each in its ``units``
    entry, "rad" or "m"). Each input is judged as :func:`gate` judges the one input, against the
    same tolerances read in that input's own unit (q_atol is rad for an angle and m for a
    displacement, as for one input); each failure names its input (``O5: q_max_abs = …``). The
    span (the runs' common times) and the assembly modes (of the whole linkage) are judged once.
    With one input it is :func:`gate` exactly."""
    if not (len(diffs) == len(units) == len(names)) or not diffs:
        raise ValueError(f"{len(diffs)} differences for {len(names)} inputs and {len(units)} units")
    if len(diffs) == 1:
        return gate(diffs[0], tolerances, modes, unit=units[0])
    failures = [*_span_failures(diffs[0])]
    for diff, unit, name in zip(diffs, units, names):
        failures += [f"{name}: {failure}" for failure in _input_failures(diff, tolerances, unit)]
    failures += _mode_failures(modes)
    return GateResult(passed=not failures, failures=tuple(failures), tolerances=tolerances)


def _span_failures(diff: Difference) -> list[str]:
    if diff.covers_horizon:
        return []
    short = [f"{name} stops at t = {end:.6g} s" for name, end in
             (("the reference", diff.reference_end), ("the compared run", diff.other_end))
             if end < diff.span_end + 1e-12]
    return [f"compared span [{diff.span_start:.6g}, {diff.span_end:.6g}] s stops short of the "
            f"horizon {diff.horizon:.6g} s: {' and '.join(short)}"]


def _input_failures(diff: Difference, tolerances: Tolerances, unit: str) -> list[str]:
    rate = f"{unit}/s"
    failures = []
    bound = tolerances.peak_bound(abs(diff.peak_omega_reference))
    if not diff.peak_omega_abs <= bound:
        failures.append(f"peak_omega_abs = {diff.peak_omega_abs:.3e} {rate} > tolerance peak_omega_rtol·|peak| + "
                        f"peak_omega_atol = {bound:.3e} {rate} (peak_omega_rel = {diff.peak_omega_rel:.3e} "
                        f"> tolerance {tolerances.peak_omega_rtol:.3e})")
    checks = [("q_max_abs", diff.q_max_abs, tolerances.q_atol, f" {unit}"),
              ("omega_max_abs", diff.omega_max_abs, tolerances.omega_atol, f" {rate}")]
    if tolerances.omega_vs_q_atol is not None:
        checks.append(("omega_vs_q_max_abs", diff.omega_vs_q_max_abs, tolerances.omega_vs_q_atol, f" {rate}"))
    failures += [f"{name} = {value:.3e}{unit} > tolerance {tol:.3e}{unit}" if not math.isnan(value) else
                 f"{name}: no sample of the compared run is at an input position the reference reaches, so ω at equal "
                 "q cannot be compared (the engines are not in the same configuration)"
                 for name, value, tol, unit in checks if not value <= tol]
    return failures


def _mode_failures(modes: ModeCheck | None) -> list[str]:
    if modes is not None and modes.total:
        return [f"assembly mode differs ({'; '.join(modes.lines())}): a loop closed in its other assembly"]
    return []


ERROR_FIGURES = ("peak_omega_abs", "peak_omega_rel", "t_peak_abs", "q_max_abs", "q_rms", "omega_max_abs", "omega_rms",
                 "omega_vs_q_max_abs")  # a Difference's figures that measure an error (larger is worse)


def worst_figures(diffs: tuple[Difference, ...]) -> dict[str, float]:
    """Each error figure (:data:`ERROR_FIGURES`) of ``diffs`` (one :class:`Difference` per input of
    a scene, in its inputs order) at its largest over the inputs, each in its input's unit (rad or
    m, per s): what a study of a scene of several degrees of freedom judges, so that what it says
    holds for every input. NaN where any input's figure is NaN (ω at equal q not comparable there).
    With one input, that input's figures exactly."""
    if not diffs:
        raise ValueError("worst_figures needs one difference per input, got none")
    out = {}
    for key in ERROR_FIGURES:
        values = [getattr(d, key) for d in diffs]
        out[key] = math.nan if any(math.isnan(v) for v in values) else max(values)
    return out
