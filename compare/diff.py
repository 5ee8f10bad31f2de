"""Differences between two trajectories of the input link, and the agreement gate.

Common time grid: the compared trajectory's own sample times. The reference is evaluated
there through its quintic Hermite interpolant (O(h⁶) in q, O(h⁵) in q̇ at its ≤ 1 ms
sample spacing: below 1e-10 rad on the seed scene), so the compared engine's samples
are used as they are and the interpolation adds less error than either engine makes.

Over configuration: for each compared sample (q_k, q̇_k) the reference time t* with
q_ref(t*) = q_k is found by Newton's method on the interpolant (from t_k), and
Δω(q) = q̇_k − q̇_ref(t*). A pure timing (phase) error then gives Δω(q) ≈ 0 while
|Δq̇(t)| can be large. Samples where the reference moves slowly
(|q̇_ref| < 1 % of its largest value) are left out: there q does not fix the time; so
are samples whose angle the reference never reaches within its time span.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from reduced.scene import Tolerances
from reduced.trajectory import Trajectory

SLOW_FRACTION = 0.01
ANGLE_MATCH = 1e-9  # rad per rad: Newton's residual below which q_ref(t*) = q_k is accepted


@dataclass(frozen=True)
class Difference:
    """How far ``other`` is from ``reference`` (units: rad, rad/s, s)."""

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

    def figures(self) -> dict[str, float]:
        """The scalar figures, for reports."""
        return {k: getattr(self, k) for k in (
            "peak_omega_abs", "peak_omega_rel", "t_peak_abs", "q_max_abs", "q_rms",
            "omega_max_abs", "omega_rms", "omega_vs_q_max_abs")}


def _time_at_angle(reference: Trajectory, q_target: np.ndarray, t_guess: np.ndarray,
                   iterations: int = 8) -> np.ndarray:
    """Solve q_ref(t) = q_target near t_guess by Newton's method (vectorized)."""
    t = t_guess.copy()
    lo, hi = reference.t[0], reference.t[-1]
    for _ in range(iterations):
        q, v, _ = reference.interpolate(t)
        t = np.clip(t - (q - q_target) / v, lo, hi)
    return t


def compare_trajectories(reference: Trajectory, other: Trajectory) -> Difference:
    """Differences of ``other`` from ``reference`` on ``other``'s sample times."""
    end = min(reference.t[-1], other.t[-1])
    keep = other.t <= end + 1e-12
    times = other.t[keep]
    q_ref, v_ref, _ = reference.interpolate(np.minimum(times, reference.t[-1]))
    dq = other.q[keep] - q_ref
    domega = other.qdot[keep] - v_ref

    # The reference's largest |ω|, and the other's extremum on the same side (a swinging
    # motion has two near-equal extremes of opposite sign).
    p_ref = reference.peak_angular_velocity()
    p_other = other.peak_angular_velocity(sign=1 if p_ref.omega >= 0 else -1)
    fast = np.abs(v_ref) >= SLOW_FRACTION * np.max(np.abs(reference.qdot))
    q_fast = other.q[keep][fast]
    t_star = _time_at_angle(reference, q_fast, times[fast])
    q_star, v_star, _ = reference.interpolate(t_star)
    matched = np.abs(q_star - q_fast) <= ANGLE_MATCH * (1.0 + np.abs(q_fast))
    domega_q = (other.qdot[keep][fast] - v_star)[matched]

    def rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(a * a))) if a.size else 0.0

    return Difference(
        peak_omega_abs=abs(p_other.omega - p_ref.omega),
        peak_omega_rel=abs(p_other.omega - p_ref.omega) / max(abs(p_ref.omega), 1e-300),
        t_peak_abs=abs(p_other.time - p_ref.time),
        q_max_abs=float(np.max(np.abs(dq))), q_rms=rms(dq),
        omega_max_abs=float(np.max(np.abs(domega))), omega_rms=rms(domega),
        omega_vs_q_max_abs=float(np.max(np.abs(domega_q))) if domega_q.size else 0.0,
        times=times, dq=dq, domega=domega, q_samples=q_fast[matched], domega_vs_q=domega_q)


@dataclass(frozen=True)
class BranchCheck:
    """Samples where the compared engine sits on the other assembly branch."""

    mismatches: int
    first_time: float | None  # s


def compare_branches(reference, other, window: float | None = None) -> BranchCheck:
    """Count ``other``'s samples whose assembly branch differs from the reference's.

    Both are :class:`~reduced.partition.JointTrajectory`. The reference branch changes
    legitimately at the input link's limit positions; samples within ``window`` seconds of
    such a change (default: twice the coarser sample spacing) are not judged.
    """
    t_ref, b_ref = reference.t, reference.branch
    spacing = max(float(np.max(np.diff(t_ref))), float(np.max(np.diff(other.t))))
    window = 2.0 * spacing if window is None else window
    k = np.clip(np.searchsorted(t_ref, other.t), 0, len(t_ref) - 1)
    changes = t_ref[1:][b_ref[1:] != b_ref[:-1]]
    near_change = np.zeros(len(other.t), dtype=bool)
    for tc in changes:
        near_change |= np.abs(other.t - tc) <= window
    wrong = (other.branch != b_ref[k]) & ~near_change
    return BranchCheck(int(np.sum(wrong)), float(other.t[np.argmax(wrong)]) if wrong.any() else None)


@dataclass(frozen=True)
class GateResult:
    """Whether two engines agree within the tolerances."""

    passed: bool
    failures: tuple[str, ...]
    tolerances: Tolerances


def gate(diff: Difference, tolerances: Tolerances, branches: BranchCheck | None = None) -> GateResult:
    """Check the peak-ω relative difference, max |Δq|, max |Δq̇| (and, when the tolerances
    set it, max |Δω| at equal q) against tolerances, and that no sample is on the other branch."""
    checks = [("peak_omega_rel", diff.peak_omega_rel, tolerances.peak_omega_rtol, ""),
              ("q_max_abs", diff.q_max_abs, tolerances.q_atol, " rad"),
              ("omega_max_abs", diff.omega_max_abs, tolerances.omega_atol, " rad/s")]
    if tolerances.omega_vs_q_atol is not None:
        checks.append(("omega_vs_q_max_abs", diff.omega_vs_q_max_abs, tolerances.omega_vs_q_atol, " rad/s"))
    failures = [f"{name} = {value:.3e}{unit} > tolerance {tol:.3e}{unit}"
                for name, value, tol, unit in checks if not value <= tol]
    if branches is not None and branches.mismatches:
        failures.append(f"assembly branch differs at {branches.mismatches} sample(s), first at "
                        f"t = {branches.first_time:.6g} s: the loop constraint jumped to the other branch")
    return GateResult(passed=not failures, failures=tuple(failures), tolerances=tolerances)
