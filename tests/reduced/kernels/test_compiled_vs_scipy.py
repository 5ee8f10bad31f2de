"""The compiled DOP853 run against scipy's ``solve_ivp`` on the same compiled equation, on every
shipped scene: the trajectory the reduced engine gave before it was compiled (scipy drove it)
is the one it gives now.

Both run scipy's DOP853 algorithm at the scene's rtol (1e-12) on the same equation, scipy with
its sums in the kernel's order (helpers.scipy_in_kernel_order: numpy's BLAS sums in an order
that depends on the CPU, and at rtol 1e-12 a last bit moves the steps), so they take the same
steps (asserted) and differ by round-off: the dense output's sums in another
order, the chart's Newton started from other points. Measured on every scene: |Δq| ≤ 2.3e-13
rad (long_conservative, 100 s), |Δq̇| ≤ 1.1e-13 of the run's largest |q̇|, peak ω ≤ 6.3e-13
relative (start_dead_centre, whose two extrema tie to 1.7e-12). Bounds 4–10× those.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import load_scene

from helpers import ROOT, scipy_in_kernel_order

# scipy's methods refuse the scenes with events (friction_fourbar: tests/reduced/test_joint_events.py)
SCENES = sorted(p for folder in ("scenes", "scenes/hard", "scenes/mechanisms")
                for p in (ROOT / folder).glob("*.toml") if p.stem != "friction_fourbar")
Q_BOUND = 1e-12        # rad
QDOT_BOUND = 1e-12     # of the run's largest |q̇|
PEAK_BOUND = 3e-12     # relative


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENES, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_compiled_dop853_gives_scipys_trajectory(path):
    scene = load_scene(path)
    with warnings.catch_warnings(), scipy_in_kernel_order():  # the BLAS's order varies with the CPU
        warnings.simplefilter("ignore")
        compiled = simulate(scene, ReducedSettings(method="dop853"))
        scipy = simulate(scene, ReducedSettings(method="scipy-dop853"))
    assert compiled.n_steps == scipy.n_steps
    assert len(compiled.details.switches) == len(scipy.details.switches)
    tr = compiled.trajectory
    q, qdot, _ = scipy.trajectory.interpolate(tr.t)
    scale = max(1.0, float(np.max(np.abs(tr.qdot))))
    assert np.max(np.abs(tr.q - q)) <= Q_BOUND
    assert np.max(np.abs(tr.qdot - qdot)) <= QDOT_BOUND * scale
    assert abs(compiled.peak.omega - scipy.peak.omega) <= PEAK_BOUND * abs(scipy.peak.omega)
