"""Walks of a chart over hundreds of radians, as a piece's samples are walked to from its end.

Not in test_reduced_kinematics.py, which test_no_jit runs as plain Python: these walks and runs
take minutes there."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reduced import MechanismModel, load_scene
from reduced.partition import Chart

from helpers import SEED_SCENE


LONG_CONSERVATIVE = SEED_SCENE.parent / "hard" / "long_conservative.toml"


@pytest.mark.parametrize("far", [200.2, 1350.2, 5000.2])
def test_a_walk_of_hundreds_of_rad_keeps_the_dependent_angles_turns(far):
    """A chart walked far and back (as the samples of a piece are walked to from its end): the
    crank-rocker's coupler and rocker never turn, so they stay within a turn of their start, and
    the walk back returns to the start configuration. Before the dependent angles took the
    nearest turn after a long jump they stood at thousands of rad (14 678 and 41 063 rad after
    200.2 and back), where the loops could not close to Newton's tolerance: the walk back failed.
    Measured: back to the start within 3.1e-12 rad; bound 1e-10 (the walk's Newton tolerance, 1e-12,
    times the loop's conditioning)."""
    from reduced.partition import _start

    model = MechanismModel(load_scene(LONG_CONSERVATIVE))
    x0, i, _ = _start(model)
    chart = Chart(model, i, x0)
    there = chart.kinematics(far).x
    back = chart.kinematics(float(x0[i])).x
    dependent = [j for j in range(len(x0)) if j != i]
    assert np.all(np.abs(there[dependent]) < 2 * math.pi)
    assert np.max(np.abs(back - x0)) <= 1e-10


@pytest.mark.parametrize("method, rtol", [("dop853", 1e-9), ("dop853", 1e-6), ("scipy-dop853", 1e-7)])
def test_long_runs_at_loose_tolerances_sample_their_pieces(method, rtol):
    """45 s of a crank coasting at 30 rad/s (about 1 350 rad): the samples are walked to from
    the piece's end back to its start. These runs failed ("Newton's method did not close the
    loops … crank.angle = 0.2") until the walk kept the dependent angles' turns."""
    from reduced import ReducedSettings, simulate

    result = simulate(load_scene(LONG_CONSERVATIVE), ReducedSettings(method=method, rtol=rtol, check_error=False))
    assert result.trajectory.t[-1] == pytest.approx(45.0)
