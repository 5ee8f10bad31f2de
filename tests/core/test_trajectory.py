"""The trajectory type: interpolation and peak location, against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from loopcheck.trajectory import Peak, Trajectory


def test_quintic_hermite_reproduces_quintic_polynomials():
    """Hermite interpolation through q, q̇, q̈ at both ends is exact for degree ≤ 5
    (round-off only: 1e-12 on values of order 10)."""
    p = np.polynomial.Polynomial([0.3, -1.0, 2.0, 0.5, -0.7, 0.2])
    t = np.array([0.0, 0.4, 1.1, 1.5, 2.3])
    tr = Trajectory(t, p(t), p.deriv()(t), p.deriv(2)(t))
    x = np.linspace(0.0, 2.3, 501)
    q, v, a = tr.interpolate(x)
    np.testing.assert_allclose(q, p(x), atol=1e-12)
    np.testing.assert_allclose(v, p.deriv()(x), atol=1e-11)
    np.testing.assert_allclose(a, p.deriv(2)(x), atol=1e-10)


def test_interpolation_converges_at_sixth_order():
    """For q = sin t the q error falls like h⁶ (ratio 64 per halving; allow 50-80)."""
    errors = []
    x = np.linspace(0.0, 3.0, 1001)
    for n in (16, 32, 64):
        t = np.linspace(0.0, 3.0, n + 1)
        q, _, _ = Trajectory(t, np.sin(t), np.cos(t), -np.sin(t)).interpolate(x)
        errors.append(np.max(np.abs(q - np.sin(x))))
    assert 50 < errors[0] / errors[1] < 80 and 50 < errors[1] / errors[2] < 80


def test_repeated_sample_times_are_handled():
    """A time may repeat (load edge, coordinate switch), even three times at the end."""
    t = np.array([0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0])
    tr = Trajectory(t, t.copy(), np.ones(7), np.zeros(7))
    q, v, _ = tr.interpolate(np.array([0.0, 0.5, 1.0, 1.5, 2.0]))
    np.testing.assert_allclose(q, [0.0, 0.5, 1.0, 1.5, 2.0])
    np.testing.assert_allclose(v, 1.0)


def test_peak_is_found_between_samples():
    """q̇ = 3 + sin(5 t) peaks at t = π/10 with 4; samples every 0.1 s miss it by up to 0.01."""
    t = np.linspace(0.0, 1.0, 11)
    tr = Trajectory(t, 3 * t - np.cos(5 * t) / 5, 3 + np.sin(5 * t), 5 * np.cos(5 * t))
    peak = tr.peak_rate()
    assert peak.time == pytest.approx(np.pi / 10, abs=1e-4)
    assert peak.omega == pytest.approx(4.0, abs=1e-6)
    assert peak.omega > np.max(tr.qdot)


def _euler_samples(h: float) -> Trajectory:
    """Semi-implicit Euler's samples of q̈ = −q (MuJoCo's Euler: q̇ advanced by h q̈ of the step's
    start, q by h q̇ of its end), from q = −1 at rest (q̇ = sin t exactly, its peak 1 at π/2):
    consistent with each other to first order only."""
    n = int(round(2.0 / h))
    q, v = np.zeros(n + 1), np.zeros(n + 1)
    q[0] = -1.0
    for k in range(n):
        v[k + 1] = v[k] - h * q[k]
        q[k + 1] = q[k] + h * v[k + 1]
    return Trajectory(np.arange(n + 1) * h, q, v, -q, refined_extrema=False)


def test_a_first_order_runs_peak_is_its_extreme_sample():
    """Samples that do not support a summit between them (``refined_extrema`` False) give the extreme
    sample, as their own peak and as another run's event (extremum_near), also on a part of the
    run (within) and resampled; the flag goes with them. The same samples taken as supporting one
    (the rule before) are raised above every sample by the quintic through them: at h = 0.1 s
    (measured) 3.6e-3 above, 4.4e-3 off the exact peak 1, where the extreme sample is 8.1e-4 off."""
    tr = _euler_samples(0.1)
    k = int(np.argmax(np.abs(tr.qdot)))
    old = Trajectory(tr.t, tr.q, tr.qdot, tr.qddot).peak_rate()
    assert old.omega > tr.qdot[k] + 1e-3  # the probe is one the interpolant raises
    assert tr.peak_rate() == Peak(float(tr.qdot[k]), float(tr.t[k]))
    assert abs(tr.peak_rate().omega - 1.0) < abs(old.omega - 1.0) / 4
    assert tr.peak_rate(sign=1).omega == tr.qdot[k]
    assert tr.extremum_near(Peak(1.0, 1.5)).omega == tr.qdot[k]
    assert not tr.within(0.05, 1.95).refined_extrema and not tr.resample(tr.t[:5]).refined_extrema
    assert tr.within(0.05, 1.95).peak_rate().omega == tr.qdot[k]


def test_refined_extrema_is_a_bool():
    t = np.linspace(0, 1, 5)
    with pytest.raises(ValueError, match="refined_extrema"):
        Trajectory(t, t, t, t, refined_extrema="no")


def test_signed_peak_picks_the_requested_side():
    t = np.linspace(0.0, 2 * np.pi, 201)
    tr = Trajectory(t, -np.cos(t), np.sin(t), np.cos(t))
    assert tr.peak_rate(sign=1).omega == pytest.approx(1.0, abs=1e-9)
    assert tr.peak_rate(sign=-1).omega == pytest.approx(-1.0, abs=1e-9)


@pytest.mark.parametrize("bad", ["nan", "decreasing", "shape"])
def test_invalid_trajectories_are_refused(bad):
    t, q = np.linspace(0, 1, 5), np.zeros(5)
    if bad == "nan":
        q = q.copy()
        q[2] = np.nan
    if bad == "decreasing":
        t = t[::-1]
    with pytest.raises(ValueError):
        Trajectory(t, q, np.zeros(4) if bad == "shape" else np.zeros(5), np.zeros(5))


def test_joint_trajectory_hermite_reproduces_cubics_and_their_rates():
    """JointTrajectory.interpolate is cubic Hermite in x and ẋ: exact for cubic polynomials, in
    value and derivative (measured 8.9e-16 and 2.2e-15 on [0, 1]; bound 1e-14), per column; a time past
    the run is clamped to its end, and a repeated last sample is taken as the later one."""
    from loopcheck.trajectory import JointTrajectory

    t = np.array([0.0, 0.13, 0.4, 0.41, 0.77, 1.0])
    cubic = np.stack([t**3 - 2 * t**2 + t, -0.5 * t**3 + 3 * t], axis=1)
    rate = np.stack([3 * t**2 - 4 * t + 1, -1.5 * t**2 + 3], axis=1)
    joints = JointTrajectory(("a", "b"), t, cubic, rate, np.zeros(len(t), int), np.zeros((len(t), 0), int))
    at = np.linspace(0.0, 1.0, 37)
    x, xdot = joints.interpolate(at)
    assert np.max(np.abs(x - np.stack([at**3 - 2 * at**2 + at, -0.5 * at**3 + 3 * at], axis=1))) < 1e-14
    assert np.max(np.abs(xdot - np.stack([3 * at**2 - 4 * at + 1, -1.5 * at**2 + 3], axis=1))) < 1e-14
    assert np.array_equal(joints.interpolate(5.0)[0][0], cubic[-1])
    repeated = JointTrajectory(("a", "b"), np.r_[t, 1.0], np.r_[cubic, [[7.0, 8.0]]], np.r_[rate, [[1.0, 2.0]]],
                               np.zeros(len(t) + 1, int), np.zeros((len(t) + 1, 0), int))
    x_end, v_end = repeated.interpolate(1.0)
    assert np.array_equal(x_end[0], [7.0, 8.0]) and np.array_equal(v_end[0], [1.0, 2.0])


def test_the_peaks_cubic_roots_are_np_roots_bit_for_bit():
    """peak_rate's roots of q̈'s cubic, all intervals' in one eigvals call, equal np.roots of each
    interval's exactly (bit for bit: the peak of a full run must not move), degenerate cubics
    (a zero leading or constant coefficient, no cubic at all) included."""
    from loopcheck.trajectory import _cubic_roots

    rng = np.random.default_rng(7)
    c2, c3, c4, c5 = rng.normal(size=(4, 400)) * 10.0 ** rng.uniform(-6, 3, size=(4, 400))
    c5[::7] = 0.0
    c2[::11] = 0.0
    c3[::13] = c4[::13] = c5[::13] = 0.0
    for k, roots in enumerate(_cubic_roots(list(zip(c2.tolist(), c3.tolist(), c4.tolist(), c5.tolist())))):
        p = [20 * c5[k], 12 * c4[k], 6 * c3[k], 2 * c2[k]]
        expected = np.roots(p) if (c5[k] or c4[k] or c3[k]) else []
        assert len(roots) == len(expected)
        assert all(a.real == b.real and a.imag == b.imag for a, b in zip(roots, expected)), k


def test_a_time_found_in_an_interval_is_located_as_interpolate_locates_it():
    """peak_rate's candidates are located in floats (Trajectory._at) without the arrays of
    _locate: the same interval, length and local coordinate, bit for bit, also for a time that
    rounds onto the interval's end (it belongs to the next interval, as interpolate says) and next
    to a repeated sample (a load edge)."""
    t = np.array([0.0, 0.1, 0.25, 0.25, 0.4, 0.7])
    tr = Trajectory(t, np.sin(t), np.cos(t), -np.sin(t))
    for j in (0, 1, 3, 4):
        for time in (t[j], t[j] + 0.3 * (t[j + 1] - t[j]), np.nextafter(t[j + 1], -1.0), t[j + 1]):
            i, h, s = tr._locate(np.array([time]))
            assert tr._at(float(time), j) == (int(i[0]), float(h[0]), float(s[0])), (j, time)
