"""The comparison and the gate against closed-form differences and real engine runs.

Synthetic pairs are sampled at the same times, so the reference's interpolant returns its
own samples (q exactly, q̇ to round-off ~1e-14) and each figure is a known closed form.
"""

from __future__ import annotations

import math
from dataclasses import replace
from decimal import Decimal

import numpy as np
import pytest

from loopcheck.compare.diff import compare_trajectories, gate
from loopcheck.compare.run import compare_engines, judge
from loopcheck.compare.text import comparison_lines
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.trajectory import Trajectory
from loopcheck.scene import Tolerances
from loopcheck.reference_models import MujocoSettings, simulate_mujoco

from helpers import variant

LOOSE = Tolerances(peak_omega_rtol=1.0, q_atol=10.0, omega_atol=100.0)
T = np.linspace(0.0, 2.0, 2001)  # 1 ms samples


def parabola() -> Trajectory:
    """q = 10 t²: ω = 20 t rises to its peak 40 rad/s at the end, t = 2 s."""
    return Trajectory(T, 10 * T**2, 20 * T, np.full_like(T, 20.0))


def bump(t: np.ndarray, amplitude: float, start: float = 1.2, width: float = 0.4):
    """δ = A sin²(π (t − start)/width) on [start, start + width], zero elsewhere: δ, δ', δ''."""
    x = np.clip((t - start) / width, 0.0, 1.0)
    k = np.pi / width
    inside = (x > 0) & (x < 1)
    d = amplitude * np.sin(np.pi * x) ** 2
    d1 = np.where(inside, amplitude * k * np.sin(2 * np.pi * x), 0.0)
    d2 = np.where(inside, 2 * amplitude * k * k * np.cos(2 * np.pi * x), 0.0)
    return d, d1, d2


def test_a_difference_in_the_second_half_is_measured_exactly():
    """A bump of height A = 1e-3 rad on [1.2, 1.6] s (second half only): max |Δq| = A at
    t = 1.4 s, max |Δω| = A π / 0.4 at t = 1.3 s, rms Δq² = A²·(3/8)·(0.4/2); at equal angle
    Δω(q) = 20 t + δ' − 20 √(t² + δ/10) (the reference's speed where q = 10 t² + δ)."""
    a = 1e-3
    d, d1, d2 = bump(T, a)
    ref = parabola()
    other = Trajectory(T, ref.q + d, ref.qdot + d1, ref.qddot + d2)
    diff = compare_trajectories(ref, other)
    assert diff.span_start == 0.0 and diff.span_end == 2.0 and diff.covers_horizon
    assert diff.q_max_abs == pytest.approx(a, rel=1e-12)
    assert diff.omega_max_abs == pytest.approx(a * np.pi / 0.4, rel=1e-9)
    # Sum over 1 ms samples against the integral: the bump is smooth, so the two agree to
    # far better than 1e-3.
    assert diff.q_rms == pytest.approx(a * np.sqrt(3 / 8 * 0.4 / 2), rel=1e-3)
    expected_vs_q = 20 * T + d1 - 20 * np.sqrt(T**2 + d / 10)
    assert diff.omega_vs_q_max_abs == pytest.approx(np.max(np.abs(expected_vs_q[T >= 0.02])), rel=1e-6)
    assert diff.peak_omega_abs == 0.0 and diff.t_peak_reference == 2.0  # the bump is before the peak


def test_a_known_phase_shift_gives_its_closed_form_everywhere():
    """The reference delayed by s = 2 ms: Δq(t) = q(t − s) − q(t), Δω likewise, both
    evaluated in closed form on every sample (q = 20 t + 0.3 sin 8t, sped up over time
    by 0.5 t² so the largest difference is at the end)."""
    def motion(t):
        return (20 * t + 0.3 * np.sin(8 * t) + 0.5 * t**2, 20 + 2.4 * np.cos(8 * t) + t,
                -19.2 * np.sin(8 * t) + 1.0)

    s = 2e-3
    ref = Trajectory(T, *motion(T))
    late = Trajectory(T, *motion(T - s))
    diff = compare_trajectories(ref, late)
    dq = motion(T - s)[0] - motion(T)[0]
    dw = motion(T - s)[1] - motion(T)[1]
    assert diff.q_max_abs == pytest.approx(np.max(np.abs(dq)), rel=1e-12)
    assert diff.omega_max_abs == pytest.approx(np.max(np.abs(dw)), rel=1e-9)
    assert np.argmax(np.abs(diff.dq)) > len(T) // 2  # the largest lies in the second half
    assert diff.omega_vs_q_max_abs < 1e-6  # a pure delay: same speed at the same angle
    assert diff.t_peak_abs == pytest.approx(s, abs=1e-7)


def test_gate_applies_omega_vs_q_atol():
    """Uniform rotation q = 5 t against q = 5 t + b sin(c t): at equal angle the speeds
    differ by b c cos(c t) exactly, largest b c = 0.01 rad/s (at t = 0, on a sample)."""
    b, c = 1e-3, 10.0
    ref = Trajectory(T, 5 * T, np.full_like(T, 5.0), np.zeros_like(T))
    other = Trajectory(T, 5 * T + b * np.sin(c * T), 5 + b * c * np.cos(c * T), -b * c * c * np.sin(c * T))
    diff = compare_trajectories(ref, other)
    assert diff.omega_vs_q_max_abs == pytest.approx(b * c, rel=1e-9)
    assert gate(diff, LOOSE).passed  # not asked for: not checked
    assert gate(diff, replace(LOOSE, omega_vs_q_atol=3 * b * c)).passed
    tight = gate(diff, replace(LOOSE, omega_vs_q_atol=b * c / 3))
    assert not tight.passed and len(tight.failures) == 1 and "omega_vs_q_max_abs" in tight.failures[0]


def test_gate_fails_each_figure_just_above_its_tolerance():
    b, c = 1e-3, 10.0
    ref = Trajectory(T, 5 * T, np.full_like(T, 5.0), np.zeros_like(T))
    other = Trajectory(T, 5 * T + b * np.sin(c * T), 5 + b * c * np.cos(c * T), -b * c * c * np.sin(c * T))
    diff = compare_trajectories(ref, other)
    for name, field in (("q_atol", "q_max_abs"), ("omega_atol", "omega_max_abs")):
        value = getattr(diff, field)
        assert gate(diff, replace(LOOSE, **{name: value * 1.01})).passed
        failed = gate(diff, replace(LOOSE, **{name: value * 0.99}))
        assert not failed.passed and failed.failures[0].startswith(field)


def test_tied_extremes_are_matched_by_event():
    """ω = cos(π t) has |ω| = 1 at t = 0, 1, 2 (signs +, −, +): a tie. The other run's
    ω = cos(π t)(1 + ε t) with ε = 1e-7 is largest at t = 2, but the compared peak is the
    same event as the reference's (its extremum of the same sign nearest in time): same
    time, and a difference of exactly ε·t_ref (the reference's own choice among equal
    extremes is its business)."""
    eps = 1e-7
    w = np.pi
    ref = Trajectory(T, np.sin(w * T) / w, np.cos(w * T), -w * np.sin(w * T))
    g = 1 + eps * T
    other = Trajectory(T, ref.q * g, np.cos(w * T) * g + eps * np.sin(w * T) / w,
                       -w * np.sin(w * T) * g + 2 * eps * np.cos(w * T))
    diff = compare_trajectories(ref, other)
    assert diff.peak_omega_reference == pytest.approx(1.0, abs=1e-12)
    assert diff.t_peak_abs < 1e-6
    assert diff.peak_omega_abs == pytest.approx(eps * diff.t_peak_reference, abs=1e-12)
    assert diff.t_peak_other == pytest.approx(diff.t_peak_reference, abs=1e-6)


# ---------------------------------------------------------------------------
# Real engine runs
# ---------------------------------------------------------------------------

SETTINGS = dict(reduced=ReducedSettings(), mujoco=MujocoSettings(integrator="rk4", timestep=1e-3))


@pytest.fixture(scope="module")
def seed_runs():
    scene = variant()
    return scene, simulate(scene, SETTINGS["reduced"]), simulate_mujoco(scene, SETTINGS["mujoco"])


def cut(trajectory: Trajectory, t_end: float) -> Trajectory:
    """The trajectory as if its run had stopped at t_end: its samples before, and its state there."""
    k = int(np.searchsorted(trajectory.t, t_end, side="left"))
    end = trajectory.interpolate(np.array([t_end]))
    return Trajectory(*(np.append(a[:k], e) for a, e in zip(
        (trajectory.t, trajectory.q, trajectory.qdot, trajectory.qddot), (np.array([t_end]), *end))))


@pytest.mark.parametrize("which", ["mujoco", "reduced"])
def test_a_truncated_engine_trajectory_fails_the_gate(seed_runs, which):
    """A real run stopped at t = 0.8 s of the seed's 2 s: over the overlap the two agree
    (the gate would pass on it), but the comparison states its span and the gate fails."""
    scene, reduced, mujoco = seed_runs
    whole = judge(scene, reduced, mujoco, scene.tolerances)
    assert whole.gate.passed and whole.diff.span_end == pytest.approx(2.0)
    runs = {"reduced": reduced, "mujoco": mujoco}
    runs[which] = replace(runs[which], trajectory=cut(runs[which].trajectory, 0.8))
    c = judge(scene, runs["reduced"], runs["mujoco"], scene.tolerances)
    assert c.diff.span_end == pytest.approx(0.8) and c.diff.horizon == 2.0 and not c.diff.covers_horizon
    assert not c.gate.passed and len(c.gate.failures) == 1
    assert "stops short of the horizon 2 s" in c.gate.failures[0] and "0.8" in c.gate.failures[0]
    assert ("reference" if which == "reduced" else "compared run") in c.gate.failures[0]
    assert any("0 to 0.8 (horizon 2)" in line for line in comparison_lines(c))


def test_nothing_moving_is_judged_on_its_absolute_difference():
    """A pulse of zero duration: nothing moves. The engines agree to ~1e-13 rad/s; the
    relative peak figure is taken of the floor peak_omega_atol/peak_omega_rtol = 1e-5 rad/s,
    never of the round-off peak, and the gate passes."""
    scene = variant(torque={"type": "pulse", "value": 250.0, "start": 0.0, "duration": 0.0})
    c = compare_engines(scene, **SETTINGS)
    d = c.diff
    assert d.peak_omega_reference < 1e-12 and d.peak_omega_abs < 1e-12
    assert d.peak_floor == pytest.approx(1e-5)
    assert d.peak_omega_rel == pytest.approx(d.peak_omega_abs / 1e-5)
    assert c.gate.passed, c.gate.failures


def test_peak_gate_is_rtol_times_peak_plus_atol(seed_runs):
    """The seed's peak difference judged against bounds just above and below it: the gate
    passes when |Δ| ≤ rtol·|peak| + atol, with the absolute floor counted."""
    scene, reduced, mujoco = seed_runs
    d = judge(scene, reduced, mujoco, scene.tolerances).diff
    rtol = d.peak_omega_abs / d.peak_omega_reference
    both = Tolerances(peak_omega_rtol=rtol / 2, peak_omega_atol=d.peak_omega_abs * 0.51, q_atol=1, omega_atol=1)
    assert gate(d, both).passed  # rtol·peak alone is short by half: atol makes it up
    short = gate(d, replace(both, peak_omega_atol=d.peak_omega_abs * 0.49))
    assert not short.passed and "peak_omega_abs" in short.failures[0] and "peak_omega_rel" in short.failures[0]


def test_swing_peak_is_one_event_in_both_engines_and_the_table_subtracts():
    """A conservative swing (seed linkage, a 200 N/m spring on the crank, from rest): its
    extremes of ω are ±2.71842 rad/s, equal to round-off, so each engine's own largest |ω|
    falls at a different time and sign (measured: reduced +2.71842 at 0.41 s, MuJoCo
    −2.71843 at 2.78 s). The compared peak is one event in both (measured time difference
    4.6e-4 s at 1 ms against a half-period of ~1.2 s; bound 10x), its difference is no
    more than the largest |Δω| there is, and the table's printed difference is the
    difference of the printed values."""
    scene = variant(drop=("torque", "dampers", "tolerances"), initial={"q": 0.2, "qdot": 0.0},
                    simulation={"horizon": 3.0},
                    springs=[{"stiffness": 200.0, "rest_length": 0.1, "ground_point": [0.0, 0.6],
                              "body": "crank", "body_point": [0.5, 0.0]}])
    c = compare_engines(scene, **SETTINGS)
    d = c.diff
    assert np.sign(c.reference.peak.omega) != np.sign(c.other.peak.omega)  # the case this is about
    assert d.t_peak_abs < 5e-3
    assert d.peak_omega_abs <= d.omega_max_abs + 1e-9
    rows = {line.split("  ")[0]: line.split() for line in comparison_lines(c)}
    peak = rows["peak qdot (rad/s)"]
    assert Decimal(peak[4]) - Decimal(peak[3]) == Decimal(peak[5])
    assert float(peak[3]) == pytest.approx(d.peak_omega_reference, rel=1e-9)
    assert float(peak[4]) == pytest.approx(d.peak_omega_other, rel=1e-9)
    assert np.sign(float(peak[4])) == np.sign(float(peak[3]))  # one event: the same sign
    when = rows["time of peak (s)"]
    assert Decimal(when[5]) - Decimal(when[4]) == Decimal(when[6])
    assert abs(float(when[6])) == pytest.approx(d.t_peak_abs, rel=0.01)


def test_trajectories_that_never_overlap_are_a_numerical_failure():
    from loopcheck.errors import NumericalFailure
    from loopcheck.errors import FailureReason

    early = parabola()
    late = Trajectory(T + 3.0, early.q, early.qdot, early.qddot)
    with pytest.raises(NumericalFailure) as caught:
        compare_trajectories(early, late)
    assert caught.value.reason == FailureReason.INCOMPLETE and "nothing to compare" in str(caught.value)


def test_a_span_shorter_than_the_reference_spacing_is_still_compared():
    """The other run stops after 0.4 ms, before the reference's second 1 ms sample: the
    comparison says so instead of failing to find a peak."""
    ref = parabola()
    t = np.linspace(0.0, 4e-4, 5)
    short = Trajectory(t, 10 * t**2, 20 * t, np.full_like(t, 20.0))
    diff = compare_trajectories(ref, short)
    assert diff.span_end == pytest.approx(4e-4) and not diff.covers_horizon
    assert diff.peak_omega_reference == pytest.approx(8e-3) and diff.peak_omega_abs < 1e-12
    assert not gate(diff, LOOSE).passed


def test_an_untied_peak_is_each_engines_own_refined_peak(seed_runs):
    """The seed's peak is single (during the pulse): the compared peaks are each engine's own
    largest |ω|, located between samples (not the largest sample, which is up to
    |ω̈| h²/8 ≈ 1e-4 rad/s lower at 1 ms spacing)."""
    scene, reduced, mujoco = seed_runs
    d = judge(scene, reduced, mujoco, scene.tolerances).diff
    for compared, when, own in ((d.peak_omega_reference, d.t_peak_reference, reduced),
                                (d.peak_omega_other, d.t_peak_other, mujoco)):
        assert compared == pytest.approx(own.peak.omega, rel=1e-14) and when == pytest.approx(own.peak.time)
        assert abs(compared) > np.max(np.abs(own.trajectory.qdot))


def test_omega_vs_q_with_no_matching_angle_fails_instead_of_reading_zero():
    """A compared run that never reaches the reference's angles (here shifted by a whole turn,
    as a reduced run once reported q0 − 2π) gives no sample to compare at equal q: the figure is
    NaN and the gate fails saying why, instead of a max |Δω| of 0 that passes."""
    t = np.linspace(0.0, 1.0, 201)
    reference = Trajectory(t, 2.0 * t, np.full_like(t, 2.0), np.zeros_like(t))
    shifted = Trajectory(t, 2.0 * t - 2 * np.pi, np.full_like(t, 2.0), np.zeros_like(t))
    d = compare_trajectories(reference, shifted)
    assert math.isnan(d.omega_vs_q_max_abs)
    verdict = gate(d, Tolerances(q_atol=10.0, omega_atol=1.0, omega_vs_q_atol=1.0))
    assert not verdict.passed and "cannot be compared" in " ".join(verdict.failures)
    same = compare_trajectories(reference, reference)
    assert same.omega_vs_q_max_abs == 0.0
