"""The reduced solver's outputs on every shipped scene, for a regression fixture.

Recorded once from the numba-compiled core (``python tests/core_outputs.py`` writes
``tests/data/numba_core_outputs.json``), so that a core built another way (the compiled
extension of the next step) can be held to what this one computes: peaks within 1e-10
relative, states within 1e-9 (the change of compiler can move the order of operations and
libm's last bits, nothing more). The fixture is labelled with the code and versions that made
it; it is the old core's answer, not an independent truth (the physics is checked against
closed forms, energy balances and MuJoCo elsewhere).
"""

from __future__ import annotations

import json
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FIXTURE = ROOT / "tests" / "data" / "numba_core_outputs.json"
METHODS = ("dop853", "rkn4")
N_TIMES = 101  # states compared at these many times spread over the horizon


def shipped_scenes() -> list[Path]:
    scenes = ROOT / "scenes"
    return sorted([*scenes.glob("*.toml"), *scenes.glob("hard/*.toml"), *scenes.glob("mechanisms/*.toml")])


def outputs(path: Path, method: str) -> dict:
    """What the reduced solver gives for one scene and method: the peak, the cost, the states
    (q, q̇) at N_TIMES times over the horizon (the run's own interpolant), or its failure.
    The run's own accuracy check is off (``check_error=False``), so that RKN4 at its default
    step records a trajectory on the hard scenes too, where its estimate refuses the run."""
    from compare.settings import reduced_settings
    from reduced import NumericalFailure, load_scene, simulate

    scene = load_scene(path)
    try:
        run = simulate(scene, reduced_settings(scene, method=method, check_error=False))
    except NumericalFailure as failure:
        return {"failure": failure.reason.value}
    times = np.linspace(0.0, float(run.trajectory.t[-1]), N_TIMES)
    q, qdot, _ = run.trajectory.interpolate(times)
    return {"peak_omega": run.peak.omega, "peak_time": run.peak.time, "steps": run.n_steps,
            "evaluations": run.n_evaluations, "t": times.tolist(), "q": q.tolist(), "qdot": qdot.tolist()}


def key(path: Path) -> str:
    return path.relative_to(ROOT / "scenes").as_posix()


def record() -> dict:
    import numba

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    label = {"core": "numba", "numba": numba.__version__, "numpy": np.__version__,
             "python": platform.python_version(), "machine": platform.machine(), "commit": commit}
    runs = {f"{key(p)}:{m}": outputs(p, m) for p in shipped_scenes() for m in METHODS}
    return {"label": label, "runs": runs}


if __name__ == "__main__":
    data = record()
    FIXTURE.write_text(json.dumps(data, indent=None, separators=(",", ":")) + "\n", encoding="utf-8")
    print(f"wrote {len(data['runs'])} runs to {FIXTURE}", file=sys.stderr)
