"""Torque profiles: the vectorized sampling (fast path) equals the scalar definition."""

from __future__ import annotations

import numpy as np
import pytest

from reduced.loads import ConstantTorque, PiecewiseConstantTorque, PulseTorque

PROFILES = [ConstantTorque(3.0), PulseTorque(250.0, 0.5, 1.0),
            PiecewiseConstantTorque((0.0, 1.0, 2.0), (1.0, -2.0, 5.0))]


@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: type(p).__name__)
def test_sample_equals_pointwise_values(profile):
    times = np.concatenate([np.linspace(-1.0, 3.0, 4001), np.array(profile.edges)])
    np.testing.assert_array_equal(profile.sample(times), [profile(t) for t in times])


@pytest.mark.parametrize("profile", PROFILES[1:], ids=lambda p: type(p).__name__)
def test_a_piece_sees_one_side_of_each_edge(profile):
    edges = profile.edges
    for a, b in zip(edges, edges[1:]):
        inside = profile(0.5 * (a + b))
        f = profile.on_piece(a, b)
        assert f(a) == inside and f(b) == inside  # both ends take the value of the open interval


@pytest.mark.parametrize("make, field", [
    (lambda: ConstantTorque(float("nan")), "ConstantTorque.amplitude"),
    (lambda: PulseTorque(1.0, -0.5, 1.0), "PulseTorque.start"),
    (lambda: PulseTorque(1.0, 0.0, -1.0), "PulseTorque.duration"),
    (lambda: PulseTorque(float("inf"), 0.0, 1.0), "PulseTorque.amplitude"),
    (lambda: PiecewiseConstantTorque((0.0, 1.0), (1.0,)), "PiecewiseConstantTorque.times and .values"),
    (lambda: PiecewiseConstantTorque((), ()), "PiecewiseConstantTorque.times and .values"),
    (lambda: PiecewiseConstantTorque((0.0, 0.0), (1.0, 2.0)), "PiecewiseConstantTorque.times must be strictly"),
    (lambda: PiecewiseConstantTorque((0.0, 1.0), (1.0, float("nan"))), "PiecewiseConstantTorque.values[1]"),
], ids=["nan", "neg_start", "neg_duration", "inf", "lengths", "empty", "not_increasing", "nan_value"])
def test_profiles_validate_their_fields(make, field):
    """Built directly (not from a scene), a profile still refuses what it cannot represent."""
    with pytest.raises(ValueError) as info:
        make()
    assert str(info.value).startswith(field)
