"""The reduced solver gives what the numba core gave on every shipped scene, both methods.

The fixture (``tests/data/numba_core_outputs.json``, written by ``tests/core_outputs.py`` and
labelled with the numba core's commit and versions) holds each run's peak, cost and states at
101 times, or the reason it failed. Bounds, from the decision that the compiled core may move
only what a change of compiler can (operation order, libm's last bits): peaks within 1e-10
relative, states within 1e-9 (absolute, in rad or m, and per s for rates, scaled by the run's
largest |q| or |q̇| when that is above 1). Measured against the code that recorded it: equal.
A run that failed must fail for the same reason. Steps and evaluations are not held: another
compiler may take another step where the controller's test is within round-off.

Each run starts from the x0 it was recorded from (the fixture's ``"x0"``, core_outputs.py says
why). The scenes' own x0, now assembled by the compiled kinematics, are within X0_TOL of it:
measured 6.7e-16 at most (slider_crank_driven_slider; the four-bar shorthand's 2.2e-16, one
ulp, from the Newton polish's residual summed as R(θ)(c e(φ)) instead of c e(θ + φ)). From the
scene's own x0 the runs' peaks moved by 7.4e-12 relative at most (hard/fast_crank, DOP853), but
two DOP853 runs' states moved beyond STATE_TOL: hard/fast_crank q̇ by 4.9e-6 (5.0e-9 of its
largest |q̇|), hard/long_conservative by 2.7e-7 (5.8e-9): their step sequences follow x0's last
bit (docs/architecture.md, "The four-bar closed form"). From the recorded x0 every run is what
the numba core gave, bit for bit.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from loopcheck.scenefile import load_scene

from core_outputs import FIXTURE, METHODS, NOT_RECORDED, key, outputs, recorded_scenes, shipped_scenes

PEAK_RTOL, STATE_TOL = 1e-10, 1e-9
X0_TOL = 2e-15  # rad or m: 3 times the largest measured move of a shipped scene's x0 (6.7e-16)

RECORDED = json.loads(FIXTURE.read_text(encoding="utf-8"))


def test_the_fixture_covers_every_shipped_scene_and_is_labelled():
    """Every shipped scene but those added after the numba core (NOT_RECORDED, each held by its own oracle)."""
    assert set(NOT_RECORDED) <= {key(p) for p in shipped_scenes()}
    assert set(RECORDED["runs"]) == {f"{key(p)}:{m}" for p in recorded_scenes() for m in METHODS}
    assert RECORDED["label"]["core"] == "numba" and RECORDED["label"]["commit"] and RECORDED["label"]["x0"]
    assert set(RECORDED["x0"]) == {key(p) for p in recorded_scenes()}


@pytest.mark.parametrize("path", recorded_scenes(), ids=key)
def test_a_scene_assembles_where_its_recorded_runs_started(path):
    recorded = np.array(RECORDED["x0"][key(path)])
    x0 = np.array(load_scene(path).x0)
    assert x0.shape == recorded.shape
    assert np.max(np.abs(x0 - recorded)) <= X0_TOL


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("path", recorded_scenes(), ids=key)
def test_a_shipped_run_is_what_the_numba_core_gave(path, method):
    old = RECORDED["runs"][f"{key(path)}:{method}"]
    new = outputs(path, method, RECORDED["x0"][key(path)])
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
