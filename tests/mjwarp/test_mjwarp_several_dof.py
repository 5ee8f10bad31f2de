"""The MJWarp engine on a scene of several degrees of freedom (issue 41): the two-motor five-bar
robot (scenes/mechanisms/five_bar_robot.toml) over its first 0.2 s (both motors act: the second from 0.1 s)
at the grid step (1 ms, RK4, float32) against the independent full-coordinate oracle
(tests/oracles/five_bar_robot.py), every input recorded, under the known-defect rule of issue 39:
the run completes and carries its known defect; no test asks MJWarp to meet the reference's
tolerances.

Measured (2026-11-28, MJWarp 4.0.0, warp 1.19.0, CPU) over 0.2 s: max |Δq| 1.2e-5 rad (O1) and
6.2e-6 rad (O5), max |Δq̇| 1.1e-4 and 5.7e-5 rad/s; loop gap 1.8e-7 m; energy residual 6.8e-6 of
the scale. Bounds 6e-5 rad and 6e-4 rad/s (~5x: float32 sums depend on the order of operations,
which another CPU or a GPU changes). Over the whole 0.8 s the run passes its own gates: |Δq| 1.5e-3
and 2.3e-3 rad, |Δq̇| 0.021 and 0.023 rad/s, loop gap 9.8e-6 m, energy residual 1.5e-4.

Planted: the later inputs left out of the ports' results (``other_inputs`` of ``finish`` in
loopcheck/mujoco_model/port.py) fails test_every_input_is_recorded_and_follows_the_oracle and
test_loopcheck_mjwarp_prints_every_inputs_peak; the second motor's control held at zero
(``ctrl[:, 1] = 0.0`` in ``prepare``) fails test_every_input_is_recorded_and_follows_the_oracle
(|Δq| 3.8e-3 rad on O1).

Cost: MJWarp's kernels (compiled once per process, cached by warp), then one 200-step run (~2 s on a
CPU: MJWarp on the CPU is kernel-launch bound).
"""

from __future__ import annotations

import dataclasses

import pytest

pytest.importorskip("warp", reason="the mjwarp engine's extra is not installed (pip install -e '.[mjwarp]' in loopcheck's checkout)")
pytest.importorskip("mujoco_warp", reason="MJWarp is not installed (pip install --no-deps mujoco-warp)")

from loopcheck.registry import ENGINES  # noqa: E402
from loopcheck.scenefile import load_scene  # noqa: E402
from oracles.five_bar_robot import SCENE, assert_inputs_follow  # noqa: E402

pytestmark = pytest.mark.slow  # MJWarp's kernels on first use, then ~2 s of run
HORIZON = 0.2  # s: the second motor's pulse starts at 0.1 s
Q_TOL, RATE_TOL = 6e-5, 6e-4  # rad, rad/s: ~5x MJWarp's measured difference from the oracle (above)


@pytest.fixture(scope="module")
def run():
    engine = ENGINES["mjwarp"]
    scene = dataclasses.replace(load_scene(SCENE), horizon=HORIZON)
    result = engine.simulate(scene, engine.settings())  # through the registry: its check_dof lets it run
    return scene, result


def test_the_mjwarp_engine_declares_several_dof():
    assert ENGINES["mjwarp"].several_dof


def test_every_input_is_recorded_and_follows_the_oracle(run):
    scene, result = run
    assert result.engine == "mjwarp" and result.n_steps == 200 and result.settings.timestep == 1e-3
    assert_inputs_follow(scene, result, Q_TOL, RATE_TOL)


def test_the_run_completes_with_its_known_defect_stated(run):
    _, result = run
    assert result.caveats and "J̇·q̇ from the previous evaluation" in result.caveats[0]
    assert result.audit.relative_residual < result.settings.max_energy_residual
    assert result.constraint_violation.max < result.settings.max_constraint_violation
    assert abs(result.audit.torque_work[-1]) > 1.0  # the motors' work is booked


def test_loopcheck_mjwarp_prints_every_inputs_peak(run):
    from loopcheck.mujoco_model.text import result_lines

    scene, result = run
    lines = result_lines(scene, result)
    assert [line.split()[2] for line in lines if line.startswith("peak qdot")] == ["O1", "O5"]
    assert lines[-1].startswith("known defect     MJWarp 4.0.0 computes")
