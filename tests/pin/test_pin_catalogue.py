"""The Pinocchio engine against the reduced engine on every catalogue scene (scenes/*.toml,
scenes/hard/*.toml, scenes/mechanisms/*.toml), and its own energy audit.

Oracle: the reduced engine (DOP853 at rtol 1e-12, a different formulation: Eksergian's equation
in one coordinate, loops closed by Newton), interpolated at the pin engine's sample times.

Tolerances. The pin engine integrates the tree's constrained dynamics with scipy's DOP853 at
rtol 1e-10 (its default), whose local error control leaves a global error that grows with the
steps a run takes: measured (2026-11-26, pin 4.1.0) relative figures run from round-off to
3.8e-9 in q (fast_crank, 7 600 steps at ~1000 rad/s) and 6.8e-6 in q̇ (long_conservative, 45 s
of coasting: a phase error of its fast swings). Each figure must stay within
max(5 × its scene's measurement, 10 × rtol): 10 × rtol is what the method promises per unit
of the scale and the 5× covers a change of CPU, compiler or Pinocchio's arithmetic. q is
relative to max(1, max |q|), q̇ to max(1, max |q̇|) (rad or m, per s), the peak to itself, the
energy residual to the audit's scale.

Planted: dropping the dampers' force from the generalized forces (``tau -= (c * rate) * g`` in
loopcheck/pin/run.py) fails every test of the seed: the run itself fails its energy gate (residual
0.34 of the scale); with that gate opened (max_energy_residual 1) its figures are dq 0.10,
dq̇ 0.65, dpeak 0.089, audit terms 0.33, each far beyond its bound. Dropping the springs'
½ k (d − d0)² from the audit's potential fails andrews_squeezer's runs (residual 0.65 of the scale).

Cost: the 18 scenes take ~60 s of pin runs on a 2-core machine under load (fast_crank 12 s,
long_conservative 18 s + 15 s of sampling 45 000 states), so the module is marked slow.
"""

from __future__ import annotations

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio", reason="the pin engine's extra is not installed (pip install -e '.[pin]' in loopcheck's checkout)")

import loopcheck  # noqa: E402
from loopcheck.compare.diff import compared_peaks  # noqa: E402
from loopcheck.pin import PinSettings, simulate  # noqa: E402
from loopcheck.scenefile import load_scene  # noqa: E402

from helpers import ROOT  # noqa: E402

pytestmark = pytest.mark.slow

RTOL = PinSettings().rtol
# m: the loops' largest gap over a run, measured 8.5e-9 m at most (fast_crank; the seed 1.9e-10 m).
MAX_GAP = 5e-8
# Measured relative figures at the defaults (see the module's docstring): q, q̇, peak, energy
# residual, and the largest difference of the audit's four terms at the horizon from the reduced
# engine's, relative to the reduced audit's scale.
MEASURED = {
    "seed_fourbar.toml": (6.2e-11, 1.8e-9, 3.7e-11, 3.5e-10, 1.8e-10),
    "hard/dead_centre.toml": (1.0e-11, 1.9e-9, 2.1e-11, 2.8e-10, 4.5e-11),
    "hard/fast_crank.toml": (3.8e-9, 2.0e-6, 2.9e-9, 1.5e-9, 6.3e-9),
    "hard/gravity.toml": (1.3e-10, 8.4e-10, 6.1e-10, 2.7e-10, 6.0e-11),
    "hard/long_conservative.toml": (4.2e-9, 6.8e-6, 1.1e-11, 1.2e-8, 1.2e-8),
    "hard/near_change_point.toml": (1.6e-10, 1.3e-8, 1.4e-10, 4.5e-10, 3.0e-10),
    "hard/off_grid_edge.toml": (7.1e-11, 2.1e-9, 6.1e-11, 4.2e-10, 2.0e-10),
    "hard/start_dead_centre.toml": (1.5e-10, 1.6e-9, 2.7e-9, 4.1e-10, 9.5e-10),
    "hard/stiff_damper.toml": (2.8e-14, 1.1e-10, 3.9e-11, 1.6e-13, 3.8e-14),
    "mechanisms/andrews_squeezer.toml": (9.4e-12, 3.3e-10, 1.5e-11, 1.2e-10, 3.2e-11),
    "mechanisms/drag_link.toml": (3.7e-10, 2.1e-8, 4.1e-10, 9.7e-10, 6.4e-10),
    # a redundantly closed loop (issue 37): Pinocchio's proximal constraint solver takes its dependent rows
    "mechanisms/parallelogram_redundant.toml": (1.4e-12, 9.0e-10, 8.8e-12, 1.6e-9, 1.9e-11),
    "mechanisms/oscillating_slotted_lever.toml": (1.2e-11, 9.6e-10, 3.2e-12, 2.8e-11, 1.5e-11),
    "mechanisms/seed_fourbar.toml": (6.2e-11, 1.8e-9, 3.6e-11, 3.5e-10, 1.8e-10),
    "mechanisms/slider_crank_driven_slider.toml": (8.7e-12, 5.4e-10, 1.9e-10, 8.7e-12, 3.7e-12),
    "mechanisms/slider_crank_gas.toml": (2.1e-10, 1.5e-9, 1.0e-9, 1.5e-11, 2.1e-9),
    "mechanisms/stephenson3_near_toggle.toml": (8.9e-11, 2.5e-9, 1.3e-10, 1.7e-10, 1.6e-10),
    "mechanisms/stephenson3_sixbar.toml": (3.1e-11, 3.8e-10, 2.3e-10, 1.7e-10, 1.2e-10),
    "mechanisms/watt2_sixbar.toml": (1.6e-11, 2.5e-10, 2.7e-11, 1.4e-10, 3.8e-11),
    # measured 2026-11-28, pin 4.1.0 (installed outside the venv for the actuators' branch)
    "mechanisms/servo_fourbar.toml": (3.0e-11, 4.4e-10, 5.5e-11, 1.9e-10, 1.8e-11),
    # two inputs (issue 40): the first input's figures here; every input against the oracle in
    # tests/pin/test_pin_several_dof.py. Measured 2026-11-28, pin 4.1.0.
    "mechanisms/five_bar_robot.toml": (4.8e-11, 5.4e-10, 2.2e-10, 1.1e-10, 1.3e-10),
    # two inputs through a singular configuration of their set (the reference switches coordinates):
    # the first input's figures, measured 2026-11-28, pin 4.1.0
    "hard/five_bar_fold.toml": (4.2e-11, 7.4e-10, 2.2e-11, 1.1e-10, 4.1e-11),
    # issue 41's catalogue scenes, the first input's figures (every input against the oracle:
    # tests/compare/test_catalogue_several_dof_engines.py). Measured 2026-11-28, pin 4.1.0.
    "mechanisms/adaptive_finger.toml": (5.0e-12, 1.7e-10, 2.8e-12, 3.1e-11, 2.8e-12),
    "mechanisms/three_rrr.toml": (2.6e-11, 1.9e-10, 3.2e-12, 9.9e-11, 5.4e-12),
    # the gear pair's coupling a row beside the loop (issue 41), measured 2026-11-28, pin 4.1.0
    "mechanisms/seed_fourbar_geared_flywheel.toml": (5.2e-11, 1.8e-9, 7.3e-11, 3.4e-10, 1.6e-10),
}


def bound(measured: float) -> float:
    return max(5.0 * measured, 10.0 * RTOL)


# Catalogue scenes the pin engine refuses, and the start of its one-line refusal.
REFUSED = {"mechanisms/friction_fourbar.toml": "joint friction 'crank_pin_friction': the Pinocchio engine has no dry"}


def test_the_table_covers_the_catalogue():
    files = {p.relative_to(ROOT / "scenes").as_posix() for pattern in ("*.toml", "hard/*.toml", "mechanisms/*.toml")
             for p in (ROOT / "scenes").glob(pattern)}
    assert files == set(MEASURED) | set(REFUSED) and not set(MEASURED) & set(REFUSED)


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_the_pin_engine_refuses_what_it_cannot_run(name):
    with pytest.raises(ValueError) as caught:
        simulate(load_scene(ROOT / "scenes" / name), PinSettings())
    assert str(caught.value).startswith(REFUSED[name]) and "\n" not in str(caught.value)


_RUNS: dict = {}


def runs(name: str):
    """(scene, reduced, pin) of a catalogue scene, run once for this module."""
    if name not in _RUNS:
        scene = load_scene(ROOT / "scenes" / name)
        _RUNS[name] = (scene, loopcheck.simulate(scene, loopcheck.ReducedSettings(method="dop853", rtol=1e-12)),
                       simulate(scene, PinSettings()))
    return _RUNS[name]


def figures(name: str) -> tuple[float, ...]:
    """The relative figures of MEASURED, from this run."""
    _, ref, r = runs(name)
    q, qdot, _ = ref.trajectory.interpolate(r.trajectory.t)
    dq = np.max(np.abs(q - r.trajectory.q)) / max(1.0, np.max(np.abs(ref.trajectory.q)))
    dw = np.max(np.abs(qdot - r.trajectory.qdot)) / max(1.0, np.max(np.abs(ref.trajectory.qdot)))
    # the peaks as the comparison pairs them (the reference's largest |ω| and pin's extremum of that
    # sign nearest it in time): hard/start_dead_centre's motion is symmetric, its two extrema equal to
    # 1e-9, and each engine's own largest |ω| may be either one (pin's came out the other sign)
    peak_ref, peak_pin = compared_peaks(ref.trajectory, r.trajectory, r.trajectory.t[0], r.trajectory.t[-1])
    dpeak = abs(peak_pin.omega - peak_ref.omega) / abs(peak_ref.omega)
    terms = max(abs(getattr(r.audit, k)[-1] - getattr(ref.audit, k)[-1])
                for k in ("kinetic", "potential", "torque_work", "damper_dissipation")) / ref.audit.scale
    return dq, dw, dpeak, r.audit.relative_residual, terms


@pytest.mark.parametrize("name", sorted(MEASURED))
def test_pin_agrees_with_the_reduced_engine(name):
    dq, dw, dpeak, _, _ = figures(name)
    mq, mw, mpeak, _, _ = MEASURED[name]
    assert dq <= bound(mq), f"{name}: max |Δq| {dq:.3g} of the scale"
    assert dw <= bound(mw), f"{name}: max |Δq̇| {dw:.3g} of the scale"
    assert dpeak <= bound(mpeak), f"{name}: peak {dpeak:.3g} off"


@pytest.mark.parametrize("name", sorted(MEASURED))
def test_its_energy_audit_closes(name):
    """The run's own balance (kinetic from Pinocchio's M, potential from its gravity and the
    springs, the loads' work and the dampers' dissipation integrated alongside the state)."""
    _, _, r = runs(name)
    assert r.audit.relative_residual <= bound(MEASURED[name][3])
    assert r.constraint_violation.max <= MAX_GAP


@pytest.mark.parametrize("name", sorted(MEASURED))
def test_audit_terms_match_the_reduced_engines(name):
    """Each term of the balance at the horizon, against the reduced engine's own audit (an
    independent computation of T, V, the work and the dissipation)."""
    assert figures(name)[4] <= bound(MEASURED[name][4])
