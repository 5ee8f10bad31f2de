"""Pinocchio on the hand-written two-finger gripper (tests/data/mjcf/two_finger_gripper.xml, issue 41)
as written: its knuckles coupled by a joint equality (polycoef "0 1 0 0 0", the mirrored side: the
scene's a1 = −1), which the pin engine adds as a row beside its loops (loopcheck/pin/run.py); and on a
quadratic coupling (tests/data/mjcf/cam_rotors.xml: p'' = −1, so its γ = p''(s) ẋ² is not 0).

Oracle: the reduced engine (DOP853 at rtol 1e-12; the coupling one more row of its loop equations),
judged on the comparison's grid by loopcheck.compare.run.judge, every input. Measured (2026-11-28,
pin 4.1.0 at its defaults, DOP853 rtol 1e-10):
- the gripper, 3 inputs (right knuckle, right tip, left tip), over 0.15 s and the same over 1 s:
  max |Δq| 1.6e-12, 5.1e-11, 5.1e-11 rad; max |Δq̇| 1.5e-10, 6.3e-9, 6.3e-9 rad/s; energy residual
  1.0e-11 of the audit's scale; largest gap (loops, and the coupling as a length) 9.9e-13 m.
- cam_rotors over 0.5 s: |Δq| 9.9e-11 rad, |Δq̇| 1.6e-9 rad/s, energy residual 2.7e-11, the
  coupling's residual 1.6e-12 m as a length (× the mechanism's size).
Asserted: |Δq| ≤ 5e-10 rad (gripper 10×, cam 5×); |Δq̇| ≤ 5e-8 rad/s on the gripper (8×), 1e-8 on
the cam (6×); energy residual ≤ 1e-10 (10×, 4×); gap ≤ 1e-11 m (10×, 6×).

Planted (loopcheck/pin/model.py, CouplingRow.state): γ = 0 fails the cam test (its run fails its
own drift gate: the coupling opened by 3.0e-4 m at 0.29 s); the gripper's linear coupling does not
see it. The row's sign flipped (c_y + p' c_x) fails both: the gripper's knuckle off by 0.54 rad and
its fingertips by 0.17 rad, the cam's run refused at the start (the coupling's rate 0.18 m/s).
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pinocchio", reason="the pin engine's extra is not installed (pip install -e '.[pin]' in loopcheck's checkout)")

import loopcheck  # noqa: E402
from loopcheck.compare.run import judge  # noqa: E402
from loopcheck.registry import ENGINES  # noqa: E402
from loopcheck.reference_models.mjcf_import import import_mjcf  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "data" / "mjcf"
GRIPPER = DATA / "two_finger_gripper.xml"
CAM = DATA / "cam_rotors.xml"
Q, ENERGY, GAP = 5e-10, 1e-10, 1e-11  # rad, of the scale, m (the module's docstring)


@pytest.fixture
def pin():
    engine = ENGINES["pin"]
    if not engine.several_dof:
        pytest.skip("the pin engine of several DOF is not merged in this tree")
    return engine


def _against_the_reference(pin, path: Path, horizon: float, inputs: int, qdot: float):
    scene = dataclasses.replace(import_mjcf(path).scene, horizon=horizon)
    assert scene.dof == inputs and len(scene.mechanism.linkage.couplings) == 1
    reference = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-12))
    run = pin.simulate(scene, pin.settings())
    comparison = judge(scene, reference, run, scene.tolerances)  # every input, on the comparison's own grid
    assert len(comparison.diffs) == inputs
    for name, diff in zip(scene.inputs, comparison.diffs):
        assert diff.q_max_abs <= Q and diff.omega_max_abs <= qdot, \
            f"{name}: |Δq| {diff.q_max_abs:.3g}, |Δq̇| {diff.omega_max_abs:.3g}"
    return run


def test_pin_follows_the_reduced_gripper_as_written_on_every_input(pin):
    """Coupled, 3 DOF: the two loops (3 rows each) and the coupling's row; its own energy balance
    (kinetic from Pinocchio's M, the sprung fingertips' potential, the servo's work, the joint
    dampers' dissipation) and the gap, the coupling's residual in it."""
    run = _against_the_reference(pin, GRIPPER, 0.15, 3, qdot=5e-8)
    assert run.details.constraint_rows == 7
    assert run.audit.relative_residual <= ENERGY
    assert run.constraint_violation.max <= GAP


def test_a_quadratic_coupling_follows_the_reduced_engine(pin):
    """cam_rotors: y = p(x) with p'' ≠ 0, no loop: the coupling's row alone closes the mechanism."""
    run = _against_the_reference(pin, CAM, 0.5, 1, qdot=1e-8)
    assert run.details.constraint_rows == 1
    assert run.audit.relative_residual <= ENERGY
    assert run.constraint_violation.max <= GAP


def test_check_runs_every_engine_on_the_gripper(tmp_path):
    """``loopcheck check two_finger_gripper.xml --engines reduced,mujoco,pin``, a subprocess from a
    tmp folder: MuJoCo runs the file as written (and fails: 51x its tolerance on the fingertips'
    peak, as plain ``check`` says), pin the imported scene and passes with each input's figures; the
    outlier is MuJoCo; exit 1; nothing written to the folder."""
    command = [sys.executable, "-m", "loopcheck.compare.cli", "check", str(GRIPPER), "--engines", "reduced,mujoco,pin",
               "--horizon", "0.3"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(Path(loopcheck.__file__).parent.parent),
                                                                  os.environ.get("PYTHONPATH")) if p)}
    done = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    pin_line = next(k for k, line in enumerate(lines) if line.startswith("      pin      "))
    assert lines[pin_line].startswith("      pin      ok    right_knuckle_joint: peak ")
    assert "right_tip_joint: peak" in lines[pin_line + 1] and "left_tip_joint: peak" in lines[pin_line + 2]
    assert any(line.startswith("      mujoco   FAIL  right_knuckle_joint: peak 9.582354") for line in lines)
    assert f"               ran {GRIPPER} as written (the others: its scene as imported)" in lines
    assert lines[-2].startswith("      farthest from the others: mujoco") and lines[-1] == "0 passed, 1 failed"
    assert "Traceback" not in done.stderr and list(tmp_path.iterdir()) == []
