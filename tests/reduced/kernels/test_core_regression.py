"""The reduced solver gives what the numba core gave on every shipped scene, both methods.

The fixture (``tests/data/numba_core_outputs.json``, written by ``tests/core_outputs.py`` and
labelled with the numba core's commit and versions) holds each run's peak, cost and states at
101 times, or the reason it failed. Bounds, from the decision that the compiled core may move
only what a change of compiler can (operation order, libm's last bits): peaks within 1e-10
relative, states within 1e-9 (absolute, in rad or m, and per s for rates, scaled by the run's
largest |q| or |q̇| when that is above 1). Measured against the code that recorded it: equal.
A run that failed must fail for the same reason. Steps and evaluations are not held: another
compiler may take another step where the controller's test is within round-off.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from core_outputs import FIXTURE, METHODS, key, outputs, shipped_scenes

PEAK_RTOL, STATE_TOL = 1e-10, 1e-9

RECORDED = json.loads(FIXTURE.read_text(encoding="utf-8"))


def test_the_fixture_covers_every_shipped_scene_and_is_labelled():
    assert set(RECORDED["runs"]) == {f"{key(p)}:{m}" for p in shipped_scenes() for m in METHODS}
    assert RECORDED["label"]["core"] == "numba" and RECORDED["label"]["commit"]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("path", shipped_scenes(), ids=key)
def test_a_shipped_run_is_what_the_numba_core_gave(path, method):
    old = RECORDED["runs"][f"{key(path)}:{method}"]
    new = outputs(path, method)
    if "failure" in old:
        assert new == old
        return
    assert "failure" not in new, new
    assert new["peak_omega"] == pytest.approx(old["peak_omega"], rel=PEAK_RTOL, abs=0.0)
    assert new["peak_time"] == pytest.approx(old["peak_time"], abs=STATE_TOL)
    assert np.array_equal(new["t"], old["t"]) or np.allclose(new["t"], old["t"], rtol=0.0, atol=STATE_TOL)
    for name in ("q", "qdot"):
        a, b = np.asarray(new[name]), np.asarray(old[name])
        scale = max(1.0, float(np.max(np.abs(b))))
        assert np.max(np.abs(a - b)) <= STATE_TOL * scale, name
