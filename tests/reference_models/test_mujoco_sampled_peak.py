"""The MuJoCo peak of a first-order integrator's run is its extreme sample, never a summit of the
interpolant between samples (loopcheck/trajectory.py: ``Trajectory.refined_extrema``).

The quintic Hermite interpolant through Euler's samples is off by O(h q̈) between them (Euler's q̈
at a sample is the step's start acceleration, its q̇ and q consistent with it to first order only),
so the summit it finds between samples is an artefact: on the probe below it stands above every
sample MuJoCo computed. A fourth-order run (RK4) and the reduced engine's dense output still
locate their peak between samples.

Probe: a four-bar written here in the style of hand-made MJCF (degrees, euler frames, a site-form
connect, MuJoCo's default integrator, Euler, at 2 ms): ground pivots 0.3 m apart, crank 0.1 m,
coupler 0.28 m, rocker 0.2 m, a heavy coupler with its centre of mass off its line; gravity swings
it, a damper on the crank slows it, a motor's keyframe control may drive it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import loopcheck
from loopcheck.reference_models.mjcf_import import import_mjcf
from loopcheck.reference_models.user_model import run_model

CRANK, COUPLER, ROCKER, BASE, THETA0 = 0.1, 0.28, 0.2, 0.3, math.radians(70.0)


def _four_bar(damping: float, gravity: float, ctrl: float | None) -> str:
    b = (CRANK * math.cos(THETA0), CRANK * math.sin(THETA0))
    dx, dy = BASE - b[0], -b[1]
    diagonal = math.hypot(dx, dy)
    coupler = math.atan2(dy, dx) + math.acos((COUPLER**2 + diagonal**2 - ROCKER**2) / (2 * COUPLER * diagonal))
    c = (b[0] + COUPLER * math.cos(coupler), b[1] + COUPLER * math.sin(coupler))
    rocker = math.atan2(c[1], c[0] - BASE)
    motor = (f'<actuator><motor name="drive" joint="crank_pivot"/></actuator>'
             f'<keyframe><key name="push" ctrl="{ctrl!r}"/></keyframe>') if ctrl is not None else ""
    return f"""<mujoco model="probe_fourbar_euler">
  <compiler angle="degree"/>
  <option timestep="0.002" gravity="0 {gravity!r} 0"/>
  <worldbody>
    <body name="crank" euler="0 0 {math.degrees(THETA0)!r}">
      <joint name="crank_pivot" type="hinge" axis="0 0 1" damping="{damping!r}"/>
      <inertial pos="{CRANK / 2!r} 0 0" mass="0.05" diaginertia="3e-5 3e-5 5e-5"/>
      <body name="coupler" pos="{CRANK!r} 0 0" euler="0 0 {math.degrees(coupler - THETA0)!r}">
        <joint name="elbow" type="hinge" axis="0 0 1"/>
        <inertial pos="{COUPLER / 2!r} 0.01 0" mass="0.4" diaginertia="1e-4 3e-3 3e-3"/>
        <site name="coupler_end" pos="{COUPLER!r} 0 0"/>
      </body>
    </body>
    <body name="rocker" pos="{BASE!r} 0 0" euler="0 0 {math.degrees(rocker)!r}">
      <joint name="rocker_pivot" type="hinge" axis="0 0 1"/>
      <inertial pos="{ROCKER / 2!r} 0 0" mass="0.08" diaginertia="1e-5 3e-4 3e-4"/>
      <site name="rocker_end" pos="{ROCKER!r} 0 0"/>
    </body>
  </worldbody>
  <equality>
    <connect name="coupler_pin" site1="coupler_end" site2="rocker_end"/>
  </equality>
  {motor}
</mujoco>
"""


def _imported(tmp_path: Path, damping: float, gravity: float, ctrl: float | None, horizon: float):
    path = tmp_path / "fourbar_euler.xml"
    path.write_text(_four_bar(damping, gravity, ctrl))
    return import_mjcf(path, keyframe="push" if ctrl is not None else None, horizon=horizon)


def _old_rule(trajectory) -> float:
    """The peak the interpolant refines between the samples (the rule before: every trajectory
    was taken to support it)."""
    t = trajectory
    return loopcheck.Trajectory(t.t, t.q, t.qdot, t.qddot, refined_extrema=True).peak_rate().omega


def test_an_euler_peak_is_the_extreme_sample(tmp_path):
    """A four-bar driven and swinging under gravity (crank damping 0.2 N·m·s, control 0.05 N·m) over
    1.5 s, run by MuJoCo as written (Euler, 2 ms) and as loopcheck builds it from the imported scene
    (Euler, 2 ms): each peak, its own and the compared one, is the extreme sample, and its error is
    no more than the samples' own error next to it.

    Measured (as written): exact peak −0.6163038 rad/s at the horizon; the extreme sample −0.6164158
    (1.1e-4 off, as are the samples within 20 ms of it against the exact q̇); the interpolant's
    summit between samples (the old rule) −0.6168197, 4.0e-4 beyond every sample, 5.2e-4 off. As
    built: the extreme sample 1.6e-3 off, the old rule's summit 4.1e-4 beyond it. Tolerance: the
    samples' own error within 20 ms of the peak plus h·max|Δq̈ per step|/8 (a smooth summit's
    shortfall between samples, h²|q⃛|/8); the old rule is 4.7x beyond it as written."""
    imported = _imported(tmp_path, 0.2, -9.81, 0.05, horizon=1.5)
    exact = loopcheck.simulate(imported.scene, loopcheck.ReducedSettings())
    h = 0.002
    runs = {"as written": run_model(imported),
            "as built": loopcheck.simulate(imported.scene, loopcheck.MujocoSettings(integrator="euler", timestep=h))}
    for label, run in runs.items():
        trajectory = run.trajectory
        assert trajectory.refined_extrema is False, label
        k = int(np.argmax(np.abs(trajectory.qdot)))
        assert abs(_old_rule(trajectory)) > abs(trajectory.qdot[k]), label  # the probe is one the old rule raises
        compared = loopcheck.compare_results(imported.scene, exact, run).diff
        # the peak is a sample: no summit of the interpolant above the samples
        assert run.peak.omega == trajectory.qdot[k] and run.peak.time == trajectory.t[k], label
        # (to round-off: the compared span ends at the horizon, a rounding before the last sample's time)
        assert np.min(np.abs(trajectory.qdot - compared.peak_omega_other)) <= 1e-12 * abs(run.peak.omega), label
        _, exact_rate, _ = exact.trajectory.interpolate(trajectory.t)
        near = np.abs(trajectory.t - trajectory.t[k]) <= 0.02
        sample_error = float(np.max(np.abs(trajectory.qdot - exact_rate)[near]))
        shortfall = h * float(np.max(np.abs(np.diff(trajectory.qddot))[near[1:]])) / 8
        bound = sample_error + shortfall
        assert compared.peak_omega_abs <= bound, (label, compared.peak_omega_abs, bound)
        assert abs(run.peak.omega - exact.peak.omega) <= bound, label


def test_an_interior_euler_peak_is_not_raised_above_the_samples(tmp_path):
    """The four-bar with a light damper (0.005 N·m·s), a weak pull (1 m/s²) and a motor (0.02 N·m)
    over 4 s: its peak is inside the run (t ≈ 3.57 s). MuJoCo's Euler peak is its extreme sample;
    the interpolant's summit stood 8.1e-4 rad/s above every sample (measured). Asserted exactly: the
    peak is a sample, and no larger than the largest."""
    imported = _imported(tmp_path, 0.005, -1.0, 0.02, horizon=4.0)
    run = run_model(imported)
    trajectory = run.trajectory
    k = int(np.argmax(np.abs(trajectory.qdot)))
    assert trajectory.t[k] < imported.scene.horizon - 0.1  # inside the run
    assert abs(_old_rule(trajectory)) > abs(trajectory.qdot[k])  # the probe is one the old rule raises
    assert run.peak.omega == trajectory.qdot[k]
    assert abs(run.peak.omega) <= float(np.max(np.abs(trajectory.qdot)))


def test_fourth_order_and_dense_output_peaks_are_still_located_between_samples(tmp_path):
    """The interior peak of the same four-bar by RK4 at 2 ms, and by the reduced engine: their
    samples support a summit between them, and the peak is that summit, above every sample.

    Measured: exact 8.3374253 rad/s at 3.56694 s, its largest sample (1 ms apart) 8.3373541; RK4's
    summit 8.3374230 (2.6e-7 off), its largest sample 8.3371167 (3.7e-5 off). Tolerance 2e-6
    relative: RK4's own error at 2 ms with 8x room, and 18x below its largest sample's shortfall."""
    imported = _imported(tmp_path, 0.005, -1.0, 0.02, horizon=4.0)
    exact = loopcheck.simulate(imported.scene, loopcheck.ReducedSettings())
    rk4 = loopcheck.simulate(imported.scene, loopcheck.MujocoSettings(integrator="rk4", timestep=0.002))
    for run in (exact, rk4):
        assert run.trajectory.refined_extrema
        assert abs(run.peak.omega) > float(np.max(np.abs(run.trajectory.qdot)))
    assert rk4.peak.omega == pytest.approx(exact.peak.omega, rel=2e-6)
