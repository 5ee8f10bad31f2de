"""A walk of a chart whose closures never settle fails, named, instead of spinning.

A walk halves a jump whose closure is untrusted, up to physics.MAX_HALVINGS deep: a tree of up to
2^30 closures. With the slider column of Φ_x written into the wrong row (a fault planted in
the kinematics' constraints) every closure of a slider mechanism came out untrusted, and a 0.05 s DOP853
run of the driven slider-crank was still going after 22 minutes. Each walk is now bounded by
physics.MAX_WALK_CLOSURES and spending it fails the run with its reason.

Here the same fault is put into the kernels run as plain Python (``LOOPCHECK_PURE_PYTHON=1``, in a
subprocess: the package reads the variable at import), with the bound lowered to 200 closures so that
plain Python reaches it in seconds: every method must stop with a NumericalFailure that names
the walk's bound and the setting to change; without the bound the probe was still running after
90 s. (Compiled, with the fault planted in the source and the shipped bound of 20 000, the
catalogue's energy test fails on the driven slider-crank in 0.07 s and on the Whitworth
mechanism in 0.06 s, where it had hung.)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from helpers import ROOT

PROBE = """
import dataclasses, json, time, warnings
warnings.simplefilter("ignore")
from loopcheck.reduced.kernels import compiled
assert not compiled()
from loopcheck.reduced import MechanismModel, ReducedSettings, simulate
from loopcheck.scenefile import load_scene
from loopcheck.errors import NumericalFailure
from loopcheck.reduced.kernels import physics
from loopcheck.kernels import loops

scene = dataclasses.replace(load_scene("scenes/mechanisms/slider_crank_driven_slider.toml"), horizon=0.05)
names = MechanismModel(scene).coordinate_names
sliders = [j for j, name in enumerate(names) if name.endswith(".s")]
assert sliders
right = loops.Loops._constraints

def wrong_rows(kernel):
    # the fault: each slider column's entries of a loop's two rows (x, y) swapped
    out = right(kernel)
    A = kernel.A
    for k in range(kernel.I[loops.TABLES + loops.TABLE_ENTRIES * loops.LOOPS]):
        for g in sliders:
            A[2 * k, g], A[2 * k + 1, g] = A[2 * k + 1, g], A[2 * k, g]
    return out

loops.Loops._constraints = wrong_rows
physics.MAX_WALK_CLOSURES = 200  # the bound the messages name
physics._c_max_walk_closures = 200  # the bound the walk reads
out = {}
for method in ("dop853", "rkn4", "scipy-dop853"):
    start = time.perf_counter()
    try:
        simulate(scene, ReducedSettings(method=method, check_error=False))
        out[method] = ["no failure", "", time.perf_counter() - start]
    except NumericalFailure as exc:
        out[method] = [str(exc.reason), str(exc), time.perf_counter() - start]
print(json.dumps(out))
"""


@pytest.mark.slow  # ~3 s: the kernels uncompiled (LOOPCHECK_PURE_PYTHON), in a subprocess
def test_a_walk_that_cannot_settle_fails_with_its_reason():
    env = {**os.environ, "LOOPCHECK_PURE_PYTHON": "1"}
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    for method, (reason, message, seconds) in json.loads(done.stdout).items():
        assert reason == "singular", (method, reason, message)
        assert "more than 200 closures of the loops" in message, (method, message)
        assert ("--step" if method == "rkn4" else "--rtol") in message, (method, message)
