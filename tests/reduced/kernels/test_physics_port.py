"""The compiled physics (loopcheck/reduced/kernels/physics.py, Cython) and its plain-Python source agree.

physics.py is compiled by the package's build and runs as plain Python under
``LOOPCHECK_PURE_PYTHON=1`` (the debug path). Its integer layout constants live twice: C constants in
physics.pxd (a ``cpdef enum``) and, for plain Python, the ``if not cython.compiled`` block of
physics.py; a value changed in one and not the other would index the packed arrays differently
in the two modes. Here the source is loaded as a second, uncompiled module beside the compiled
one, and both are compared: the constants exactly, and a chart's results bit for bit (the
build does not contract or reassociate, and libm is the same: measured 0 differing bits over
21 168 values on three scenes). The physics itself is checked against independent oracles
elsewhere (closed forms: test_reduced_kinematics.py, test_dyads.py; long walks:
test_long_walks.py).
"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from loopcheck.reduced import MechanismModel
from loopcheck.kinematics import SINGULAR_CONDITIONING
from loopcheck.scenefile import load_scene
from loopcheck.reduced.kernels import compiled, physics

from helpers import ROOT

needs_compiled = pytest.mark.skipif(not compiled(), reason="the kernels run as plain Python: nothing to compare")


def _load_source(name: str, path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def loops_source():
    """loopcheck/kernels/loops.py loaded from its source as plain Python (a module of another name)."""
    return _load_source("loops_source", ROOT / "loopcheck" / "kernels" / "loops.py")


def source_module():
    """physics.py loaded from its source as plain Python (a module of another name), over the
    kinematics' source (loopcheck/kernels/loops.py, also plain Python: the compiled Loops's C methods
    cannot be called from Python)."""
    compiled_loops = sys.modules["loopcheck.kernels.loops"]
    sys.modules["loopcheck.kernels.loops"] = loops_source()
    try:
        return _load_source("physics_source", ROOT / "loopcheck" / "reduced" / "kernels" / "physics.py")
    finally:
        sys.modules["loopcheck.kernels.loops"] = compiled_loops


@needs_compiled
def test_the_layout_constants_are_the_same_compiled_and_as_python():
    source, kinematics = source_module(), loops_source()
    names = [name for name in dir(source) if name.isupper() and isinstance(getattr(source, name), (int, float))]
    assert len(names) > 60  # every constant of the layout and the numerical ones
    own = [name for name in names if not hasattr(kinematics, name)]
    for name in own:
        assert getattr(physics, name) == getattr(source, name), name
    # the kinematics' header comes first, this model's after it
    assert min(getattr(source, name) for name in ("N_DAMPERS", "DRIVE", "PIECE_VALUES")) == kinematics.KIN_HEADER


def _evaluations(module, scene_path: str) -> np.ndarray:
    """q̈, the stop margin, P and D, then the observed row, along the input's chart of a scene:
    forwards, back, and jumps long enough to be halved."""
    model = MechanismModel(load_scene(scene_path))
    x0 = np.ascontiguousarray(model.assemble(model.scene.q0))
    chart = module.Chart(model.arrays, SINGULAR_CONDITIONING)
    assert chart.start(x0, 0)
    v0 = float(x0[0])
    values = [v0 + 0.05 * k for k in range(30)] + [v0 + 1.5 - 0.07 * k for k in range(30)] + [v0 + 7.5, v0 - 20.0]
    observed = np.zeros((3, chart.observation_size()))
    rows = []
    for value in values:
        a = chart.acceleration(0, 0.0, value, 2.0)
        chart.observe(observed, 1)
        rows.append(np.concatenate([[a, chart.stop_margin(0.0, value, 2.0), chart.power(0, 2.0),
                                     chart.dissipation(2.0)], observed[1]]))
    # observe writes its row only, and what arrays() shows
    assert not observed[0].any() and not observed[2].any()
    views = chart.arrays()
    np.testing.assert_array_equal(observed[1], np.concatenate([views["fields"], views["kin"].ravel()]))
    return np.array(rows)


@needs_compiled
@pytest.mark.parametrize("scene", ["scenes/seed_fourbar.toml", "scenes/mechanisms/slider_crank_gas.toml",
                                   "scenes/mechanisms/watt2_sixbar.toml"])
def test_the_python_source_gives_the_compiled_numbers(scene):
    """Bit for bit: the seed (closed-form dyads, a damper), a slider-crank (Newton, a point force
    tabulated on q: the B-spline), a Watt six-bar (two dyads)."""
    ran = _evaluations(physics, str(ROOT / scene))
    source = _evaluations(source_module(), str(ROOT / scene))
    assert np.all(np.isfinite(ran[:, 0]))
    np.testing.assert_array_equal(ran, source)


def test_rewind_continues_from_the_mark():
    """mark() keeps the last configuration and rewind() walks on from it: after a jump away and
    back to the mark, the next evaluation is the one a chart that never left would give (the
    same walk from the same configuration: the same bits)."""
    model = MechanismModel(load_scene(ROOT / "scenes" / "seed_fourbar.toml"))
    x0 = np.ascontiguousarray(model.assemble(model.scene.q0))
    stayed, wandered = model.new_chart(), model.new_chart()
    for chart in (stayed, wandered):
        assert chart.start(x0, 0)
        assert chart.evaluate(x0[0] + 0.3)
    wandered.mark()
    assert wandered.evaluate(x0[0] + 2.9)
    wandered.rewind()
    assert stayed.evaluate(x0[0] + 0.35) and wandered.evaluate(x0[0] + 0.35)
    np.testing.assert_array_equal(stayed.arrays()["kin"], wandered.arrays()["kin"])
    np.testing.assert_array_equal(stayed.arrays()["fields"], wandered.arrays()["fields"])


def test_a_chart_restarts_from_its_own_configuration():
    """A switch restarts the chart in another coordinate from the configuration it holds (its
    kin[0], handed to start() as it is, no copy): the same result, bit for bit, as from a copy."""
    model = MechanismModel(load_scene(ROOT / "scenes" / "seed_fourbar.toml"))
    x0 = np.ascontiguousarray(model.assemble(model.scene.q0))
    own, copied = model.new_chart(), model.new_chart()
    for chart in (own, copied):
        assert chart.start(x0, 0)
        assert chart.evaluate(x0[0] + 0.4)
    assert own.start(own.arrays()["kin"][0], 1)
    assert copied.start(copied.arrays()["kin"][0].copy(), 1)
    for name in ("start", "kin", "fields", "value"):
        np.testing.assert_array_equal(own.arrays()[name], copied.arrays()[name])
