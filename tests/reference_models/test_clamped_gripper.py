"""A gripper in the xArm7 hand's style (tests/data/mjcf/clamped_gripper.xml): a position servo on a fixed
tendon over two coupled drivers, its force clamped by its forcerange, with frictionloss, joint ranges and
collidable pads, checked as written.

Oracles: the servo's unclamped force at the clamp's event (the tendon's length and rate on the exact
solution) is the bound; the reduced engine's energy audit (the servo's work against the kinetic energy,
the springs', the dampers' and the friction's dissipation); MuJoCo as written at the options `check`
advises for it (the gate's tolerances).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loopcheck.api import reduced_settings, simulate
from loopcheck.compare.cli import main
from loopcheck.reference_models.mjcf_import import import_mjcf

GRIPPER = Path(__file__).parent.parent / "data" / "mjcf" / "clamped_gripper.xml"


def test_the_servo_saturates_then_takes_over_at_its_bound():
    """ctrl 60: the unclamped force 0.333·60 − 100 l − 10 l̇ is 20 N at rest, held at 5 N until it comes
    back to 5 N (the clamp's one event, at 9.15 ms), then the servo takes over. With the drivers coupled
    (l = the input's angle q) the unclamped force at the event is 5 N within the clamp's hysteresis
    (5e-9 N; bound 1e-7). The audit balances (measured 4.4e-11 relative, bound 1e-9). Planted: no clamp
    event (N_CLAMPED = 0 in dynamics.build_arrays): no event: fails."""
    scene = import_mjcf(GRIPPER).scene
    (servo,) = scene.mechanism.actuators
    assert (servo.gain, servo.bias, servo.forcerange, servo.ctrlrange) == (0.333, (0.0, -100.0, -10.0), (-5.0, 5.0),
                                                                           (0.0, 255.0))
    result = simulate(scene, reduced_settings(scene))
    (event,) = result.details.clamp_events
    assert event.mode == "free" and event.actuator == "fingers_actuator"
    k = np.flatnonzero(result.trajectory.t == event.time)
    q, v = result.trajectory.q[k], result.trajectory.qdot[k]
    assert np.max(np.abs(0.333 * 60 - 100 * q - 10 * v - 5.0)) < 1e-7
    assert result.audit.relative_residual < 1e-9


def test_check_passes_as_written(capsys):
    """`loopcheck check` on the gripper as written: exit 0 (measured max |Δq| 1.2e-5 rad against the
    tolerance 1e-3, peak 3.1e-5 relative against 1e-4; 0.9 s)."""
    assert main(["check", str(GRIPPER)]) == 0
    out = capsys.readouterr().out
    assert "ok    " in out and "1 passed, 0 failed" in out


def test_pads_that_touch_are_named(tmp_path, capsys):
    """ctrl 255 with the fingers' range opened (so that no range stops them first): the pads meet at
    0.094 s in MuJoCo as written, and `check` exits 1 naming both pads and the time, not a refusal."""
    text = GRIPPER.read_text().replace('ctrl="60"', 'ctrl="255"').replace('range="-0.2 0.85"', 'range="-1.2 0.85"')
    path = tmp_path / "touch.xml"
    path.write_text(text)
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "geom 'left_pad' and geom 'right_pad' touch" in out and "at t = 0.094 s" in out
    assert "the exact reference has no contacts" in out
