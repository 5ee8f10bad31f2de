"""The peak is one event, the same in every output: a run's largest |q̇| with its sign and
time; in a comparison, the reduced run's, and MuJoCo's local extremum of q̇ of the same sign
nearest in time to it (loopcheck/trajectory.py). A peak that is the last sample with the speed
still rising is said to be so in the tables, report.json and the plots.

Synthetic trajectories have closed forms (oracles written here); the catalogue's driven
slider and a seed variant driven from rest run through both engines.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from loopcheck.compare.diff import compare_trajectories
from loopcheck.compare.report import report_dict
from loopcheck.compare.run import compare_engines
from loopcheck.compare.text import STILL_RISING, comparison_lines, result_lines
from loopcheck.trajectory import Trajectory

from helpers import variant

T = np.linspace(0.0, 2.0, 2001)  # 1 ms samples
W = 0.01  # s², width² of the Gaussian bumps below


def bumped(bumps: list[tuple[float, float]]) -> Trajectory:
    """q̇ = cos(πt) + Σ a·exp(−(t − c)²/W) for bumps (a, c), with q and q̈ in closed form."""
    q, v, acc = np.sin(np.pi * T) / np.pi, np.cos(np.pi * T), -np.pi * np.sin(np.pi * T)
    for a, c in bumps:
        g = np.exp(-(T - c) ** 2 / W)
        q = q + a * math.sqrt(math.pi * W) / 2 * (erf((T - c) / math.sqrt(W)) - erf(-c / math.sqrt(W)))
        v = v + a * g
        acc = acc - a * 2 * (T - c) / W * g
    return Trajectory(T, q, v, acc)


def test_the_other_run_s_event_is_the_same_sign_nearest_in_time():
    """Reference: q̇ = cos(πt) − 0.01 bump at t = 1, so its largest |q̇| is −1.01 at t = 1. The
    other run adds a +0.05 bump at t = 0: its own largest |q̇| is +1.05 at t = 0, another
    event of the other sign (the rule before this one paired it: its tie band held only that
    maximum). The bump at 0 is 0.05·e⁻¹⁰⁰ ≈ 2e-45 near t = 1, below a double's resolution of
    q̇ there, so the other run's samples around t = 1 are the reference's: the same event is
    found exactly, with the same sign and time."""
    reference = bumped([(-0.01, 1.0)])
    other = bumped([(-0.01, 1.0), (0.05, 0.0)])
    own = other.peak_rate()
    assert own.omega == pytest.approx(1.05, abs=1e-9) and own.time == 0.0  # the other run's own largest
    d = compare_trajectories(reference, other)
    assert d.peak_omega_reference == pytest.approx(-1.01, abs=1e-9) and d.t_peak_reference == pytest.approx(1.0)
    assert d.peak_omega_other == d.peak_omega_reference and d.t_peak_other == d.t_peak_reference
    assert d.peak_omega_abs == 0.0 and d.t_peak_abs == 0.0


def test_an_extremum_of_the_other_sign_nearer_in_time_is_not_the_event():
    """Reference peak −1.01 at t = 1; the other run is cos(π(t − 0.6)) (no bump): its nearest
    extremum to t = 1 is +1 at t = 0.6, the nearest of the same sign −1 at t = 1.6."""
    reference = bumped([(-0.01, 1.0)])
    s = 0.6
    other = Trajectory(T, np.sin(np.pi * (T - s)) / np.pi, np.cos(np.pi * (T - s)), -np.pi * np.sin(np.pi * (T - s)))
    event = other.extremum_near(reference.peak_rate())
    # Refined between 1 ms samples by the quintic interpolant: measured within 1e-12 s and
    # 1e-15 of the closed form; bounds 1e-9 (time) and 1e-12 (value).
    assert event.time == pytest.approx(1.6, abs=1e-9) and event.omega == pytest.approx(-1.0, abs=1e-12)


def test_a_speed_rising_to_the_end_is_flagged_and_a_turning_one_is_not():
    """q̇ = 20 t rises to the end: its peak is the last sample, still rising, in both runs;
    q̇ = cos(πt) on [0, 2] ends on a maximum (q̈ = 0 there): not rising."""
    rising = Trajectory(T, 10 * T**2, 20 * T, np.full_like(T, 20.0))
    peak = rising.peak_rate()
    assert peak.time == 2.0 and peak.omega == 40.0 and peak.still_rising
    assert rising.extremum_near(peak).still_rising
    turning = bumped([])
    assert not turning.peak_rate().still_rising


def test_a_negative_speed_rising_in_magnitude_to_the_end_is_flagged():
    """The flag is about |q̇|: q̇ = −20 t (q̈ = −20 < 0) grows in magnitude to the end, its peak
    −40 at t = 2 is still rising; q̇ = −20 t + 5 t² ends at −20 with q̈ = 0, and q̇ = −(1 + t)
    then eased back (q̇ = −t(4 − t), q̈ = 2t − 4 = 0 at t = 2) peaks at the end without rising.
    (Planted: q̈ > 0 without the peak's sign flags none of the rising negative ones.)"""
    falling = Trajectory(T, -10 * T**2, -20 * T, np.full_like(T, -20.0))
    peak = falling.peak_rate()
    assert peak.time == 2.0 and peak.omega == -40.0 and peak.still_rising
    assert falling.extremum_near(peak).still_rising
    rising_back = Trajectory(T, -10 * T**2 + T**3, -20 * T + 3 * T**2, -20 + 6 * T)  # q̈(2) = −8: rising
    assert rising_back.peak_rate().still_rising
    easing = Trajectory(T, -2 * T**2 + T**3 / 3, -T * (4 - T), 2 * T - 4)  # q̈(2) = 0: at its extremum
    end = easing.peak_rate()
    assert end.omega == pytest.approx(-4.0, abs=1e-9) and not end.still_rising
    slowing = Trajectory(T, -10 * T**2 + 2 * T**3, -20 * T + 6 * T**2, -20 + 12 * T)  # |q̇| falls after t = 5/3
    assert not slowing.peak_rate().still_rising


def dots(figure) -> list[tuple[float, float]]:
    """The single-point 'o' markers of a figure's axes: (t, q̇) of each."""
    return [tuple(line.get_xydata()[0]) for ax in figure.axes for line in ax.lines
            if line.get_marker() == "o" and len(line.get_xydata()) == 1]


def saved(monkeypatch) -> list:
    import loopcheck.compare.plots

    kept = []
    monkeypatch.setattr(loopcheck.compare.plots, "_save", lambda fig, path: kept.append(fig))
    return kept


def test_the_driven_slider_s_peak_is_one_event_in_every_output(slider_driven_comparison, monkeypatch, tmp_path):
    """slider_crank_driven_slider's cycles peak within 3e-5 of each other: MuJoCo's own
    largest |q̇| is the first cycle's (t = 0.0189 s), the reduced run's the sixth (0.166 s).
    The comparison pairs the sixth in both, and report.json and the plot's dots say the same
    event (they once gave MuJoCo's own). Measured time difference of the pair 9.9e-6 s (MuJoCo
    at 0.25 ms steps); bound 5e-5 s, against 0.03 s between cycles."""
    from loopcheck.compare.plots import plot_trajectories

    c = slider_driven_comparison
    d = c.diff
    assert abs(c.other.peak.time - d.t_peak_reference) > 0.1  # the case this is about
    assert d.t_peak_abs < 5e-5 and np.sign(d.peak_omega_other) == np.sign(d.peak_omega_reference)
    report = report_dict(c)
    for engine, peak in (("reduced", d.peak_reference), ("mujoco", d.peak_other)):
        assert (report[engine]["peak_omega"], report[engine]["t_peak"]) == (peak.omega, peak.time)
        assert report[engine]["peak_still_rising"] is False
    assert (report["diff"]["peak_omega_other"], report["diff"]["t_peak_other"]) == (d.peak_omega_other, d.t_peak_other)
    kept = saved(monkeypatch)
    plot_trajectories(c, tmp_path / "t.png")
    assert dots(kept[0]) == [(d.t_peak_reference, d.peak_omega_reference), (d.t_peak_other, d.peak_omega_other)]


def test_every_table_prints_the_peak_signed_under_one_label(slider_driven_comparison):
    """loopcheck reduced, loopcheck mujoco and loopcheck run print the peak signed, under 'peak qdot'."""
    c = slider_driven_comparison
    d = c.diff
    rows = {line.split("  ")[0]: line.split() for line in comparison_lines(c)}
    peak = rows["peak qdot (m/s)"]
    assert float(peak[3]) == pytest.approx(d.peak_omega_reference, rel=1e-9)
    assert float(peak[4]) == pytest.approx(d.peak_omega_other, rel=1e-9)
    for lines, result in ((result_lines(c.scene, c.reference), c.reference), (result_lines(c.scene, c.other), c.other)):
        (line,) = [line for line in lines if line.startswith("peak qdot")]
        assert line.split()[2] == f"{result.peak.omega:+.10g}" and "(largest |qdot|)" in line


@pytest.fixture(scope="module")
def from_rest():
    """The seed linkage from rest, its torque a constant 50 N·m, over 0.05 s: the crank
    speeds up all the way to the horizon."""
    return compare_engines(variant(initial={"q": 0.2, "qdot": 0.0}, simulation={"horizon": 0.05},
                                   torque={"type": "constant", "value": 50.0}))


def test_a_speed_still_rising_at_the_horizon_says_so_everywhere(from_rest, monkeypatch, tmp_path):
    from loopcheck.compare.draw import plot_mechanism_strip
    from loopcheck.compare.plots import plot_trajectories

    c = from_rest
    d = c.diff
    assert d.t_peak_reference == pytest.approx(0.05) and d.peak_still_rising and d.peak_other.still_rising
    assert any(line.startswith(f"peak: {STILL_RISING} (reduced and MuJoCo)") for line in comparison_lines(c))
    assert any(STILL_RISING in line for line in result_lines(c.scene, c.reference))
    assert any(STILL_RISING in line for line in result_lines(c.scene, c.other))
    report = report_dict(c)
    assert report["reduced"]["peak_still_rising"] is True and report["mujoco"]["peak_still_rising"] is True
    kept = saved(monkeypatch)
    plot_trajectories(c, tmp_path / "t.png")
    plot_mechanism_strip(c, tmp_path / "m.png")
    assert STILL_RISING in kept[0].axes[0].get_title()
    assert any(STILL_RISING in ax.get_title() for ax in kept[1].axes)


def test_the_seed_s_peak_is_not_flagged(seed_comparison, monkeypatch, tmp_path):
    from loopcheck.compare.plots import plot_trajectories

    c = seed_comparison
    assert not c.diff.peak_still_rising and not c.diff.peak_other.still_rising
    assert not any(STILL_RISING in line for line in comparison_lines(c) + result_lines(c.scene, c.reference))
    assert report_dict(c)["reduced"]["peak_still_rising"] is False
    kept = saved(monkeypatch)
    plot_trajectories(c, tmp_path / "t.png")
    assert STILL_RISING not in kept[0].axes[0].get_title()
