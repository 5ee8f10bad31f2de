"""MuJoCo on issue 41's two catalogue scenes of several inputs (scenes/mechanisms/adaptive_finger.toml,
2 DOF with one motor and a spring-held phalanx joint; scenes/mechanisms/three_rrr.toml, 3 DOF)
against the independent full-coordinate oracle (tests/oracles/catalogue_several_dof.py), every
input's q and q̇ at every step of the whole run, MuJoCo's own energy balance, and ``loopcheck.check``
(MuJoCo judged by its own tolerances against the reduced reference).

Measured (2026-11-28, MuJoCo at its automatic timestep: RK4 0.5 ms on both): finger D 1.1e-7 rad,
8.1e-5 rad/s; J 4.3e-8 rad, 1.7e-5 rad/s; energy residual 1.7e-5 of the scale. 3-RRR A1 2.6e-7 rad, 1.2e-4 rad/s; A2 3.0e-7, 1.8e-4; A3 1.8e-7, 1.3e-4; energy 3.5e-6.
The oracle's own accuracy at rtol 1e-9: below 1e-9 rad and 5e-8 rad/s. Bounds 1.5e-6 rad and 1e-3
rad/s (≥ 5x the largest), energy 1e-4 (6x the finger's).

Planted (made, the file run, then removed): the joint springs left out of the model MuJoCo is built
from (their fixed tendon's stiffness 0 in loopcheck/mujoco_model/build.py): the finger's inputs off
by far more than their bounds (D by 0.29 rad from the earlier start at 0 rad), and its check fails.
"""

from __future__ import annotations

import numpy as np
import pytest

import loopcheck
from loopcheck.reference_models.run import simulate_mujoco
from loopcheck.scenefile import load_scene

from helpers import ROOT
from oracles import catalogue_several_dof as catalogue

Q_TOL, RATE_TOL = 1.5e-6, 1e-3  # rad, rad/s (module docstring)
ENERGY_TOL = 1e-4
ORACLE_RTOL = 1e-9
CASES = {"finger": ("adaptive_finger", catalogue.finger, catalogue.FINGER_INPUTS, catalogue.FINGER_GUESS),
         "three_rrr": ("three_rrr", catalogue.three_rrr, catalogue.RRR_INPUTS, catalogue.RRR_GUESS)}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_input_follows_the_oracle_and_the_energy_balances(case):
    name, describe, names, guess = CASES[case]
    scene = load_scene(ROOT / "scenes" / "mechanisms" / f"{name}.toml")
    result = simulate_mujoco(scene)
    assert result.details.timestep_automatic
    grids = [(result.details.grid_q, result.details.grid_qdot), *result.details.other_grid]
    assert len(grids) == len(result.inputs) == len(names)
    t = np.linspace(0.0, scene.horizon, len(result.details.grid_q))  # MuJoCo's grid: every step
    oracle, _, accuracy = catalogue.inputs(describe(), names, guess, scene.initial_q(), scene.initial_qdot(), t,
                                           ORACLE_RTOL)
    assert accuracy[0] < Q_TOL / 100 and accuracy[1] < RATE_TOL / 100
    for input_name, (q, qdot) in zip(names, grids):
        assert np.max(np.abs(q - oracle[input_name][0])) < Q_TOL, input_name
        assert np.max(np.abs(qdot - oracle[input_name][1])) < RATE_TOL, input_name
    assert result.audit.relative_residual < ENERGY_TOL


@pytest.mark.parametrize("case", sorted(CASES))
def test_loopcheck_check_passes_mujoco_on_every_input(case):
    scene = load_scene(ROOT / "scenes" / "mechanisms" / f"{CASES[case][0]}.toml")
    check = loopcheck.check(scene)
    assert check.passed and len(check.comparison("mujoco").other.inputs) == len(scene.inputs)
