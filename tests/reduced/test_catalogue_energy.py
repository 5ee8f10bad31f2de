"""The energy balance of the adaptive reduced run on every catalogue mechanism.

Oracle: conservation of energy, independent of the integrator: kinetic ½ 𝔍 q̇² plus potential V
minus the work of the input load and the point forces plus the damper dissipation must stay
constant (loopcheck/reduced/energy.py audits it by Gauss quadrature on the run's dense output). The issue
asks below 1e-9 of the work done. DOP853 at rtol 1e-12 over the first 0.05 s of each scene
(Andrews: its whole 0.03 s) measured: Andrews 1.4e-11, planar seed 9.2e-12, slider driven 6.9e-12,
gas slider-crank 3.7e-11, Stephenson III 1.8e-12 (near toggle 1.6e-12), Watt II 2.6e-12,
oscillating slotted lever 3.3e-12 relative; 1e-9 is the issue's bound, ~30x the worst. It caught a real fault:
with a cubic (C²) force spline the gas slider-crank measured 1.7e-9.
"""

from __future__ import annotations

import dataclasses

import pytest

from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import load_scene

from helpers import ROOT

CATALOGUE = sorted((ROOT / "scenes" / "mechanisms").glob("*.toml"))
HORIZON = 0.05  # s: the general path costs ~0.45 ms per evaluation; every scene moves by then
ENERGY_BOUND = 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("path", CATALOGUE, ids=[p.stem for p in CATALOGUE])
def test_adaptive_run_balances_its_energy(path):
    scene = load_scene(path)
    scene = dataclasses.replace(scene, horizon=min(scene.horizon, HORIZON))
    result = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12))
    audit = result.audit
    assert audit.scale > 0.0 and result.trajectory.t[-1] == pytest.approx(scene.horizon)
    assert audit.relative_residual < ENERGY_BOUND, audit.relative_residual
