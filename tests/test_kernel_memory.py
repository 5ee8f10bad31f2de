"""The compiled runs free every array numba allocates.

Most of the physics runs without numba's runtime (``reduced.kernels._options``): no reference
counts, so an array such a function obtained from a callee that allocates would never be
freed. numba counts its allocations when ``NUMBA_NRT_STATS=1`` is set before it is imported,
hence the subprocess: each method (the compiled ones and scipy's on the compiled equation),
on the seed and on scenes that switch charts and tabulate a point force (whose spline is
evaluated in a scratch array), and the charts' entry points called from Python (a walk, the
coefficients at a configuration), each run once to compile and once counted; after the result
is dropped every allocation must have been freed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROBE = """
import gc, json, warnings
import numpy as np
from numba.core.runtime import rtsys
from reduced import load_scene, ReducedSettings
from reduced.dynamics import MechanismModel
from reduced.engine import integrate
from reduced.partition import Chart
warnings.simplefilter("ignore")
out = {}

def count(name, job):
    job()
    gc.collect()
    before = rtsys.get_allocation_stats()
    job()
    gc.collect()
    after = rtsys.get_allocation_stats()
    out[name] = [after.alloc - before.alloc, after.free - before.free,
                 after.mi_alloc - before.mi_alloc, after.mi_free - before.mi_free]

for path in ("scenes/seed_fourbar.toml", "scenes/mechanisms/slider_crank_gas.toml",
             "scenes/hard/dead_centre.toml"):
    model = MechanismModel(load_scene(path))
    for method in ("dop853", "rkn4", "scipy-dop853"):
        count(f"{path}:{method}", lambda: integrate(model, ReducedSettings(method=method)))
    count(f"{path}:walk", lambda: Chart(model, 0, model.x0).walk(model.x0[0] + np.linspace(0, 1, 50)))
    count(f"{path}:coefficients_at", lambda: model.coefficients_at(model.x0))
print(json.dumps(out))
"""


def test_every_allocation_of_a_run_is_freed():
    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    counts = json.loads(done.stdout)
    assert len(counts) == 15
    assert counts["scenes/seed_fourbar.toml:dop853"][0] > 0, "numba counted no allocation (NUMBA_NRT_STATS not read?)"
    for run, (alloc, free, mi_alloc, mi_free) in counts.items():
        assert (alloc, mi_alloc) == (free, mi_free), f"{run}: {alloc - free} arrays not freed"
