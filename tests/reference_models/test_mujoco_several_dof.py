"""MuJoCo built from a scene of several degrees of freedom (issue 40): the five-bar robot
(scenes/mechanisms/five_bar_robot.toml, two motors) against the independent full-coordinate oracle
(tests/oracles/multibody.py; ``five_bar()`` of tests/reduced/test_multibody_oracle.py is the same
robot), every input's q and q̇ over the run, and the energy balance of MuJoCo's own record.

Tolerances, measured at MuJoCo's automatic timestep (RK4, 0.5 ms, accepted against 1 ms):
max |Δq| 1.6e-5 rad (O1) and 2.6e-5 rad (O5), max |Δq̇| 2.2e-3 rad/s (O1) and 9.3e-4 rad/s (O5),
so the bounds 1e-4 rad and 1e-2 rad/s leave about 4x; at 0.25 ms the differences fall to 6.6e-6
rad and 9.9e-4 rad/s (MuJoCo's own error, not the oracle's: its rtol-halving difference at
rtol 1e-9 is 4e-9 rad and 7e-8 rad/s). The energy audit's relative residual is 4.3e-6 there
(bound 2e-5).
"""

from __future__ import annotations

import os

import mujoco
import numpy as np
import pytest

from loopcheck.reference_models.mjcf_import import import_mjcf
from loopcheck.reference_models.run import mjcf_text, simulate_mujoco
from loopcheck.reference_models.settings import MujocoSettings
from loopcheck.scenefile import load_scene
from oracles.multibody import simulate
from reduced.test_multibody_oracle import five_bar  # the same robot, described for the oracle

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "mechanisms", "five_bar_robot.toml")
Q_TOL, RATE_TOL = 1e-4, 1e-2  # rad, rad/s: 4x MuJoCo's measured error at its automatic step (above)
ORACLE_RTOL = 1e-9  # its accuracy (4e-9 rad, 7e-8 rad/s) is far below the tolerances
BODIES = {"O1": "left_crank", "O5": "right_crank"}  # each input joint: the crank it drives from the ground


@pytest.fixture(scope="module")
def runs():
    scene = load_scene(SCENE)
    result = simulate_mujoco(scene)
    model = five_bar()
    names = ("left_crank", "left_arm", "right_arm", "right_crank")  # the scene's coordinates, in its order
    q0, qd0 = model.assemble(dict(zip(names, scene.x0)), dict(zip(BODIES.values(), scene.initial_q())),
                             dict(zip(BODIES.values(), scene.initial_qdot())))
    t = np.linspace(0.0, scene.horizon, len(result.details.grid_q))  # MuJoCo's grid: every step
    oracle, accuracy = simulate(model, q0, qd0, t, rtol=ORACLE_RTOL)
    return scene, result, model, oracle, accuracy


def test_every_input_of_the_five_bar_follows_the_oracle(runs):
    scene, result, model, oracle, accuracy = runs
    assert accuracy[0] < Q_TOL / 100 and accuracy[1] < RATE_TOL / 100
    assert result.settings.timestep == 5e-4 and result.details.timestep_automatic
    grids = [(result.details.grid_q, result.details.grid_qdot), *result.details.other_grid]
    assert len(grids) == len(result.inputs) == 2
    for name, (q, qdot), (trajectory, peak) in zip(scene.inputs, grids, result.inputs):
        body = BODIES[name]
        assert np.max(np.abs(q - oracle.angle(model, body))) < Q_TOL, name
        assert np.max(np.abs(qdot - oracle.rate(model, body))) < RATE_TOL, name
        # the trajectory holds the grid (and a sample each side of a load edge), its peak the largest |q̇|
        assert np.isin(q, trajectory.q).all()
        k = int(np.argmax(np.abs(oracle.rate(model, body))))
        assert peak.omega == pytest.approx(oracle.rate(model, body)[k], abs=RATE_TOL), name
    assert result.other_inputs[0][1].omega < -15.0 < 20.0 < result.peak.omega  # two different peaks, not one twice


def test_the_five_bar_starts_with_every_input_at_its_rate(runs):
    scene, result, *_ = runs
    for (trajectory, _), q0, qdot0 in zip(result.inputs, scene.initial_q(), scene.initial_qdot()):
        assert trajectory.q[0] == pytest.approx(q0, abs=1e-12)
        assert trajectory.qdot[0] == pytest.approx(qdot0, abs=1e-12)
    assert result.details.initial_residuals["velocity"] <= result.details.initial_residuals["limits"][1]


def test_the_five_bar_energy_balance_from_mujocos_record(runs):
    _, result, *_ = runs
    # both motors' work is booked (actuator sensors): without the second one's the residual is ~1 J
    assert result.audit.relative_residual < 2e-5
    assert np.max(np.abs(result.audit.torque_work)) > 1.0


def test_the_step_search_judges_every_input(runs):
    _, result, *_ = runs
    check = result.details.timestep_checks[-1]
    assert set(check.inputs) <= {"O1", "O5"} and len(check.inputs) == 3 and check.units == ("rad",) * 3
    assert check.as_dict()["inputs"] == list(check.inputs)
    assert check.max_dq == pytest.approx(7.97e-5, rel=0.05)  # O5's: O1's alone is 5.0e-5



def test_the_exported_five_bar_starts_at_every_inputs_rate_and_drives_both_motors(tmp_path):
    scene = load_scene(SCENE)
    path = tmp_path / "five_bar.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=5e-4)))
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    for name, qdot0 in zip(scene.inputs, scene.initial_qdot()):  # the cranks' hinges are on the ground
        assert data.qvel[model.jnt_dofadr[model.joint(name).id]] == pytest.approx(qdot0, abs=1e-15), name
    assert [model.actuator(k).name for k in range(model.nu)] == ["left_motor", "right_motor"]
    assert [model.actuator_trnid[k, 0] for k in range(model.nu)] == [model.joint("O1").id, model.joint("O5").id]


def test_import_mjcf_reads_both_motors_as_the_inputs(tmp_path):
    """The five-bar's MJCF (export-mjcf) reads back with 2 DOF by rank, its two motors' joints the
    inputs in the actuators' order, said in one line (the full round trip: test_mjcf_import)."""
    path = tmp_path / "five_bar.xml"
    path.write_text(mjcf_text(load_scene(SCENE), MujocoSettings(timestep=5e-4)))
    imported = import_mjcf(path)
    assert imported.scene.inputs == ("O1", "O5")
    assert "2 degrees of freedom (the rank of the loop equations at keyframe 'home'); inputs, in order: 'O1', 'O5'" \
        in imported.said
    assert "driven by an actuator: 'O1' (actuator 'left_motor'), 'O5' (actuator 'right_motor')" in \
        "\n".join(imported.said)


def test_loopcheck_mujoco_prints_every_inputs_peak(runs):
    from loopcheck.reference_models.text import result_lines

    scene, result, *_ = runs
    lines = result_lines(scene, result)
    assert lines[1] == "inputs           O1 (rad), O5 (rad), mode (+1) at q0"
    peaks = [line for line in lines if line.startswith("peak qdot")]
    assert [line.split()[2] for line in peaks] == ["O1", "O5"]
    assert f"{result.other_inputs[0][1].omega:+.10g} rad/s" in peaks[1]


def test_input_rates_hold_every_input_at_its_rate_and_keep_the_loops_closed():
    """ẋ0 = K q̇0 (the MuJoCo model's initial rates): R ẋ = q̇ and Φ_x ẋ = 0 to round-off; a count
    of rates other than the inputs' is refused."""
    from loopcheck import kinematics as loops

    scene = load_scene(SCENE)
    system = loops.compile_linkage(scene.mechanism.linkage)
    x = np.asarray(scene.x0)
    xdot = loops.input_rates(system, x, scene.initial_qdot())
    np.testing.assert_allclose(system.input_rows @ xdot, scene.initial_qdot(), rtol=0, atol=1e-15)
    assert np.max(np.abs(loops.all_constraints(system, x)[1] @ xdot)) < 1e-15
    with pytest.raises(loops.AssemblyError, match="1 input rates for 2 inputs"):
        loops.input_rates(system, x, [0.5])
