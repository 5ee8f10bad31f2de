"""A summary run (``simulate(..., summary=True)``: a reduced-only sweep's rows) gives a full run's
summaries.

A summary run samples the compiled DOP853 at its step ends, and as a full run only in the steps
beside each local maximum of |q̇| over the step ends (loopcheck.reduced.kernels.adaptive,
``_sample_piece_summary``). Its chart walks to fewer positions, by other paths, so the next load
piece or chart starts from a configuration closed to another round-off; the solver's step sequence
follows such last bits (the regression fixture holds no steps for the same reason). Measured over
the 1 000 variants of benchmarks/sweep.py (seed, damper 40-70 x coupler 35-45): at rtol 1e-10 958
variants take the same steps, the others within 3 of ~350; at rtol 1e-12 975, within 2 of ~600.
Bounds, and why:

- the peak: the samples around it are the full run's, at the same times, so the peak is the full
  run's to round-off (measured: at most 2.1e-12 relative at rtol 1e-10, 3.9e-12 at 1e-12). Held
  to the regression fixture's bound, 1e-10 relative, and its peak time to its 1e-9 s;
- the steps: within STEPS_RTOL (1 %: 3 times the largest measured difference, 3 of 336);
- the energy residual: taken at the step ends only, where the work and dissipation are the
  solver's own, without the dense output's error between steps (measured 0.17 to 1.15 times the
  full run's: above 1 only where the steps differ). Held within ENERGY_RATIO of the full run's
  (a lost term shows as 1e5 times and more) and to the run's own bound (the status).
"""

from __future__ import annotations

import json
import math
import warnings

import pytest

from loopcheck.compare.settings import reduced_settings
from loopcheck.compare.sweep import run_variant
from loopcheck.compare.sweep_scene import load_sweep
from loopcheck.reduced import simulate
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path
from loopcheck.sweep_spec import Engines

from core_outputs import FIXTURE, NOT_RECORDED, ROOT, key, recorded_scenes

PEAK_RTOL, TIME_TOL = 1e-10, 1e-9  # the regression fixture's (tests/reduced/kernels/test_core_regression.py)
STEPS_RTOL = 0.01
ENERGY_RATIO = 2.0

RECORDED = json.loads(FIXTURE.read_text(encoding="utf-8"))


@pytest.mark.parametrize("path", recorded_scenes(), ids=key)
def test_a_summary_run_keeps_the_recorded_peak(path):
    """Every shipped scene the fixture holds, DOP853 from its recorded x0: the summary run's peak
    is the recorded one (or it fails for the recorded reason). (Its steps are not the fixture's to
    hold: another compiler's; the next tests hold them to the full run's.)"""
    import dataclasses

    from loopcheck.errors import NumericalFailure

    old = RECORDED["runs"][f"{key(path)}:dop853"]
    scene = dataclasses.replace(load_scene(path), x0=tuple(RECORDED["x0"][key(path)]))
    settings = reduced_settings(scene, method="dop853", check_error=False)
    try:
        run = simulate(scene, settings, summary=True)
    except NumericalFailure as failure:
        assert {"failure": failure.reason.value} == old
        return
    assert "failure" not in old, old
    assert run.peak.omega == pytest.approx(old["peak_omega"], rel=PEAK_RTOL, abs=0.0)
    assert run.peak.time == pytest.approx(old["peak_time"], abs=TIME_TOL)


@pytest.mark.parametrize("name", sorted(NOT_RECORDED))
def test_a_summary_run_is_the_full_run_on_the_scenes_the_fixture_lacks(name):
    """The shipped scenes newer than the fixture (a joint coupling, actuators, joint friction with
    its stick and slip events: pieces the stop event cuts), DOP853: the summary run's status, peak,
    steps and energy residual against the full run's, within the module's bounds."""
    from loopcheck.errors import NumericalFailure

    with warnings.catch_warnings():  # the redundant parallelogram's Grübler count: its own tests'
        warnings.simplefilter("ignore")
        scene = load_scene(ROOT / "scenes" / name)
    settings = reduced_settings(scene, method="dop853")
    runs = []
    for summary in (False, True):
        try:
            runs.append(simulate(scene, settings, summary=summary))
        except NumericalFailure as failure:
            runs.append(failure.reason)
    full, summary = runs
    if not hasattr(full, "peak"):
        assert summary == full
        return
    assert summary.peak.omega == pytest.approx(full.peak.omega, rel=PEAK_RTOL, abs=0.0)
    assert summary.peak.time == pytest.approx(full.peak.time, abs=TIME_TOL)
    assert summary.n_steps == pytest.approx(full.n_steps, rel=STEPS_RTOL)
    assert 0.0 <= summary.audit.max_abs_residual <= full.audit.max_abs_residual * ENERGY_RATIO
    events = [(e.mode, e.direction) for e in full.details.friction_events]
    assert [(e.mode, e.direction) for e in summary.details.friction_events] == events
    for a, b in zip(summary.details.friction_events, full.details.friction_events):
        assert a.time == pytest.approx(b.time, abs=TIME_TOL)


def _seed_variants():
    path = default_scene_path()
    data, _ = load_sweep(path)
    return path, data, [{"dampers.0.coefficient": d, "bodies.coupler.mass": m}
                        for d, m in ((40.0, 35.0), (55.0, 40.0), (70.0, 45.0))]


def test_a_summary_sweep_row_equals_the_full_runs_row():
    """Rows of a small reduced-only sweep of the seed both ways, through the sweep's own
    run_variant: as a summary run (the default) and as a full run (trajectories kept)."""
    path, data, variants = _seed_variants()
    for index, values in enumerate(variants):
        summary = run_variant(index, values, data, str(path), engines=Engines.REDUCED)
        full = run_variant(index, values, data, str(path), keep_trajectories=True, engines=Engines.REDUCED)
        assert summary["status"] == full["status"] == "passed", (summary, full)
        assert summary["reduced.n_steps"] == pytest.approx(full["reduced.n_steps"], rel=STEPS_RTOL)
        assert summary["reduced.peak_omega"] == pytest.approx(full["reduced.peak_omega"], rel=PEAK_RTOL, abs=0.0)
        assert summary["reduced.t_peak"] == pytest.approx(full["reduced.t_peak"], abs=TIME_TOL)
        for name in ("reduced.energy_residual", "reduced.energy_residual_rel"):
            assert 0.0 < summary[name] <= full[name] * ENERGY_RATIO, name


def test_a_summary_run_evaluates_far_fewer_samples():
    """The point of it: on the seed the summary run's samples (each one evaluation of q̈) are
    under a third of the full run's (measured 746 of 2 887 at rtol 1e-12), at the full run's
    sample times (the nominal seed's steps are the same: no load piece starts after a refined one)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(default_scene_path())
    settings = reduced_settings(scene)
    full, summary = simulate(scene, settings), simulate(scene, settings, summary=True)
    assert summary.n_steps == pytest.approx(full.n_steps, rel=STEPS_RTOL)
    assert summary.n_evaluations < full.n_evaluations  # the dense outputs of the steps not cut: none
    assert len(summary.trajectory.t) < len(full.trajectory.t) / 3
    assert set(summary.trajectory.t) <= set(full.trajectory.t)  # the same sample times, fewer of them
    assert math.isfinite(summary.audit.max_abs_residual)
    # no joints' trajectory (their assembly modes were 0.14 ms of a seed variant's 4 ms): its input's q
    # still the full run's at the same times, bit for bit
    assert summary.joints is None and full.joints is not None
    at = {t: k for k, t in enumerate(full.trajectory.t)}
    assert all(full.trajectory.q[at[t]] == q for t, q in zip(summary.trajectory.t, summary.trajectory.q))
