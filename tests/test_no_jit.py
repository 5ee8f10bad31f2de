"""The kernels run as plain Python with ``NUMBA_DISABLE_JIT=1`` (the README's way to debug them).

Run in a subprocess (numba reads the variable at import): the kinematics tests (closed form
against the compiled path against finite differences) and a short run of each compiled
integrator on the seed, whose results must be those of the compiled kernels in this process.
Small on purpose: the whole suite without the JIT would take hours.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHORT_RUNS = {"rkn4": {"step": 1e-3, "check_error": False}, "dop853": {"rtol": 1e-8}}
PROBE = f"""
import dataclasses, json, warnings
from numba import config
from reduced import load_scene, default_scene_path, simulate, ReducedSettings
assert config.DISABLE_JIT
warnings.simplefilter("ignore")
scene = dataclasses.replace(load_scene(default_scene_path()), horizon=0.05)
runs = {SHORT_RUNS!r}
out = {{}}
for method, settings in runs.items():
    r = simulate(scene, ReducedSettings(method=method, **settings))
    out[method] = [r.trajectory.q.tolist(), r.trajectory.qdot.tolist(), r.n_steps]
print(json.dumps(out))
"""


def _without_jit(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


def test_the_kinematics_tests_pass_without_the_jit():
    done = _without_jit("-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/test_reduced_kinematics.py")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert " passed" in done.stdout


def test_short_runs_without_the_jit_equal_the_compiled_ones():
    """Same operations in the same order, so equal to round-off: 1e-13 relative (seen: equal
    bit for bit; numba does not reassociate or fuse without fastmath)."""
    import numpy as np

    from reduced import ReducedSettings, default_scene_path, load_scene, simulate

    done = _without_jit("-c", PROBE)
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


def test_a_cold_cache_is_told_from_a_warm_one(tmp_path):
    """``xval`` announces a compilation only when numba's cache lacks the kernels: an empty
    NUMBA_CACHE_DIR is cold; this process, which has run them, has them in its cache."""
    from reduced import simulate
    from reduced.precompile import kernels_cached

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from reduced import ReducedSettings, default_scene_path, load_scene
        simulate(dataclasses.replace(load_scene(default_scene_path()), horizon=0.01), ReducedSettings())
    assert kernels_cached()
    cold = subprocess.run([sys.executable, "-c", "from reduced.precompile import kernels_cached as k; print(k())"],
                          cwd=ROOT, env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}, capture_output=True,
                          text=True, timeout=120)
    assert cold.stdout.strip() == "False", cold.stderr
