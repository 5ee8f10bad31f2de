"""The compiled core's Python-facing entry points refuse arguments of the wrong shape.

The kernels are built without bounds checks (setup.py; CI runs the kernels' tests once on a
checked build): an index past a buffer would read or write other memory silently. Each entry
point therefore checks, once per call, what its loops then trust: the integrators their load
pieces and settings, a chart its configuration's size, its coordinate and the arrays it writes.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers import ClosedForm, run_dop853, run_rkn
from loopcheck.reduced import MechanismModel
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path
from loopcheck.reduced.kernels import physics


@pytest.fixture(scope="module")
def model():
    return MechanismModel(load_scene(default_scene_path()))


def oscillator():
    return ClosedForm(lambda t, q, v, u: -q, [0.0])


@pytest.mark.parametrize("run", [run_rkn, run_dop853], ids=["rkn", "dop853"])
def test_an_integrator_refuses_loads_that_do_not_match_its_pieces(run):
    extra = {"step": 0.01} if run is run_rkn else {}
    with pytest.raises(ValueError, match="one more edge than pieces"):
        run(oscillator(), [0.0, 1.0], 1.0, 0.0, loads=[0, 0], **extra)
    with pytest.raises(ValueError, match="one more edge than pieces"):
        run(oscillator(), [0.0], 1.0, 0.0, loads=[], **extra)


def test_the_integrators_refuse_settings_their_loops_cannot_take():
    with pytest.raises(ValueError, match="step"):
        run_rkn(oscillator(), [0.0, 1.0], 1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="rtol"):
        run_dop853(oscillator(), [0.0, 1.0], 1.0, 0.0, rtol=0.0)
    with pytest.raises(ValueError, match="per_step"):
        run_dop853(oscillator(), [0.0, 1.0], 1.0, 0.0, per_step=0)


def test_a_chart_refuses_a_configuration_or_coordinate_out_of_range(model):
    chart = model.new_chart()
    x0 = np.ascontiguousarray(model.x0)
    n = len(x0)
    with pytest.raises(ValueError, match="coordinate"):
        chart.start(x0, n)
    with pytest.raises(ValueError, match="coordinate"):
        chart.start(x0, -1)
    with pytest.raises(ValueError, match="coordinates"):
        chart.start(np.zeros(n + 1), 0)
    with pytest.raises(ValueError, match="coordinates"):
        chart.kinematics_at(x0, np.zeros(n - 1))
    assert chart.start(x0, 0)  # and the right ones are taken


def test_a_chart_refuses_arrays_too_small_for_what_it_writes(model):
    chart = model.new_chart()
    assert chart.start(np.ascontiguousarray(model.x0), 0)
    width = chart.observation_size()
    with pytest.raises(IndexError, match="row 3"):
        chart.observe(np.zeros((3, width)), 3)
    with pytest.raises(IndexError):
        chart.observe(np.zeros((3, width - 1)), 0)
    values = np.array([0.1, 0.2])
    with pytest.raises(ValueError, match="walk"):
        chart.walk(values, np.zeros((1, physics.field_count(model.arrays))), np.zeros((2, 3, len(model.x0))))
    chart.observe(np.zeros((3, width)), 2)  # and the right ones are taken


def test_a_chart_without_a_coordinate_is_not_evaluated(model):
    chart = model.new_chart()
    row = np.zeros(len(model.x0))
    row[0] = 1.0
    chart.S[physics.INDEPENDENT] = -1  # as MechanismModel.kinematics_at leaves a chart
    assert chart.kinematics_at(np.ascontiguousarray(model.x0), row)
    with pytest.raises(ValueError, match="start"):
        chart.evaluate(0.3)
