"""The kernels run uncompiled with ``LOOPCHECK_PURE_PYTHON=1`` (the README's way to debug them).

The switch makes ``loopcheck.reduced.kernels`` and ``loopcheck.kernels`` import their ``.py`` sources even where the compiled modules
sit beside them. Run in a subprocess (the switch is read at import): the kinematics tests (closed
form against the general path against finite differences) and a short run of each compiled
integrator on the seed, whose results must be those of the compiled kernels in this process.
Small on purpose: the whole suite uncompiled would take hours.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import warnings

import numpy as np

from helpers import ROOT

SHORT_RUNS = {"rkn4": {"step": 1e-3, "check_error": False}, "dop853": {"rtol": 1e-8}}
PROBE = f"""
import dataclasses, json, warnings
from loopcheck.reduced import kernels
from loopcheck.reduced.kernels import adaptive, fixed_step, output, partition, physics, problem
from loopcheck.kernels import loops
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path
from loopcheck.reduced import simulate, ReducedSettings
assert kernels.PURE_PYTHON and not kernels.compiled()
assert all(m.__file__.endswith(".py") for m in (adaptive, fixed_step, output, partition, physics, problem, loops))
warnings.simplefilter("ignore")
scene = dataclasses.replace(load_scene(default_scene_path()), horizon=0.05)
runs = {SHORT_RUNS!r}
out = {{}}
for method, settings in runs.items():
    r = simulate(scene, ReducedSettings(method=method, **settings))
    out[method] = [r.trajectory.q.tolist(), r.trajectory.qdot.tolist(), r.n_steps]
print(json.dumps(out))
"""


def _uncompiled(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "LOOPCHECK_PURE_PYTHON": "1"}
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


def test_this_session_runs_the_compiled_kernels():
    from loopcheck.reduced import kernels

    assert kernels.compiled() and not kernels.PURE_PYTHON


def test_the_kinematics_tests_pass_uncompiled():
    """The reduced engine's (test_reduced_kinematics.py) and the mechanism layer's (test_loops.py:
    loopcheck.kinematics over loopcheck/kernels/loops.py's source, the slow reference) against the closed forms."""
    kinematics_tests = [str(p) for name in ("test_reduced_kinematics.py", "test_loops.py")
                        for p in (ROOT / "tests").rglob(name)]
    assert len(kinematics_tests) == 2
    done = _uncompiled("-m", "pytest", "-q", "-p", "no:cacheprovider", *kinematics_tests)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert " passed" in done.stdout


def test_short_runs_uncompiled_equal_the_compiled_ones():
    """Same operations in the same order, and the C build contracts nothing (-ffp-contract=off):
    equal to round-off, 1e-13 relative (seen: equal bit for bit)."""
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.scenefile import load_scene
    from loopcheck.shipped_scenes import default_scene_path

    done = _uncompiled("-c", PROBE)
    assert done.returncode == 0, done.stderr[-3000:]
    plain = json.loads(done.stdout)
    scene = dataclasses.replace(load_scene(default_scene_path()), horizon=0.05)
    for method, settings in SHORT_RUNS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            compiled = simulate(scene, ReducedSettings(method=method, **settings))
        q, qdot, n_steps = plain[method]
        assert n_steps == compiled.n_steps
        np.testing.assert_allclose(q, compiled.trajectory.q, rtol=1e-13, atol=0)
        np.testing.assert_allclose(qdot, compiled.trajectory.qdot, rtol=1e-13, atol=1e-13)
