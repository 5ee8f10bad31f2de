"""The work-precision study: outputs, convergence within each series, recommendations.

Nothing here depends on wall-clock figures: errors and statuses only.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import matplotlib.image
import pytest

from loopcheck.compare.cost import (LOOP_EXACT, RATIO_SPREAD_LIMIT, CostRatio, LoadAverage, Measurement, Verdict,
                                    cheapest_meeting, converges, cost_report, ground_truth, ladder, recommend,
                                    summary_lines, sweep, write_cost_outputs)
from loopcheck.compare.run import compare_engines
from loopcheck.errors import NumericalFailure
from loopcheck.reduced import simulate
from loopcheck.reference_models import MujocoSettings
from loopcheck.scenefile import load_scene

from helpers import SEED_SCENE

TARGET = 1e-4


@pytest.fixture(scope="module")
def study():
    scene = load_scene(SEED_SCENE)
    truth = ground_truth(scene)
    measurements = sweep(scene, ladder(scene, quick=True), truth, repeats=2, workers=2)  # 2: a spread to record
    recommendations = recommend(scene, measurements, truth, TARGET, repeats=1)
    return scene, truth, measurements, recommendations


def by_series(measurements, name):
    return [m for m in measurements if m.config.series == name]


@pytest.mark.slow  # each test of the work-precision study (its fixture ~3 s); the diagram's test stays fast
def test_truth_is_checked_and_accurate(study):
    _, truth, _, _ = study
    # rtol 1e-12 against 1e-11: the truth is good to ~1e-11 in peak ω (the looser run's error).
    assert truth.error["peak_omega_rel"] < 1e-10
    assert truth.error["q_max_abs"] < 1e-8


@pytest.mark.slow
def test_quick_sweep_writes_outputs(study, tmp_path):
    scene, truth, measurements, recommendations = study
    report = cost_report(scene, truth, measurements, recommendations, repeats=2)
    paths = write_cost_outputs(report, measurements, tmp_path, TARGET)
    assert [p.name for p in paths] == ["cost.png", "cost.csv", "cost.json"]
    assert matplotlib.image.imread(paths[0]).shape[1] > 600
    lines = paths[1].read_text().splitlines()
    assert len(lines) == len(measurements) + 1 and lines[0].startswith("status,")
    data = json.loads(paths[2].read_text(), parse_constant=lambda token: pytest.fail(f"bare {token} in cost.json"))
    assert not data["source"].startswith("/")  # relative to the working folder, or the file name
    assert data["measurements"][0]["constraint_violation"] is None  # reduced: not measured, null
    assert data["timing"]["repeats"] == 2 and len(data["measurements"]) == len(measurements)
    assert all(m.ok for m in measurements)  # every configuration in the quick ladder is stable
    assert {row["verdict"] for row in data["measurements"]} == {"pass", "fail"}


@pytest.mark.slow
def test_the_record_keeps_the_spread_of_the_repeats_and_the_load(study, tmp_path):
    """Issue: the headline swung from 9.47x to 55.43x with nothing recorded. cost.json keeps each
    configuration's min, median and max wall time over its repeats, the load average at the start
    and the end, and the headline as an interval. (Planted: the median alone recorded fails.)"""
    scene, truth, measurements, recommendations = study
    load = LoadAverage((0.5, 0.4, 0.3), (1.5, 0.6, 0.35), 2)
    report = cost_report(scene, truth, measurements, recommendations, repeats=2, load=load)
    (path,) = [p for p in write_cost_outputs(report, measurements, tmp_path, TARGET) if p.name == "cost.json"]
    data = json.loads(path.read_text())
    assert data["timing"]["load_average"]["start"] == [0.5, 0.4, 0.3]
    assert data["timing"]["load_average"]["end"] == [1.5, 0.6, 0.35]
    for row in data["measurements"]:
        assert row["repeats"] == 2
        assert 0.0 < row["wall_min_s"] <= row["wall_median_s"] <= row["wall_max_s"], row["label"]
    ratio = data["recommendation"]["mujoco_over_reduced_wall"]
    assert 0.0 < ratio["low"] <= ratio["median"] <= ratio["high"]
    rec = data["recommendation"]
    # The interval is the repeats' extremes: MuJoCo's fastest over the reduced solver's slowest, and back.
    assert ratio["low"] == pytest.approx(rec["mujoco"]["wall_min_s"] / rec["reduced"]["wall_max_s"], rel=1e-12)
    assert ratio["high"] == pytest.approx(rec["mujoco"]["wall_max_s"] / rec["reduced"]["wall_min_s"], rel=1e-12)


def test_a_study_records_the_load_average_it_ran_under():
    now = LoadAverage.now()
    assert now is None or (len(now) == 3 and all(x >= 0.0 for x in now))
    for start in ((0.5, math.nan, 0.1), (0.5, 0.4), (-1.0, 0.0, 0.0)):  # never a NaN or short record
        with pytest.raises(ValueError, match="load average start"):
            LoadAverage(start, None, 2)


def test_the_headline_interval_warns_when_too_wide_or_when_it_contains_one():
    """The headline's warnings (issue: 9.47x then 55.43x). Planted: no warning, or the interval
    taken from the medians alone, fails."""
    configs = ladder(load_scene(SEED_SCENE), quick=True)
    red = Measurement(configs[0], "ok", verdict=Verdict.PASS, wall_min_s=0.010, wall_median_s=0.011,
                      wall_max_s=0.012, repeats=3)
    steady = Measurement(configs[-1], "ok", verdict=Verdict.PASS, wall_min_s=0.050, wall_median_s=0.055,
                         wall_max_s=0.060, repeats=3)
    ratio = CostRatio.of(steady, red)
    assert ratio.low == pytest.approx(0.050 / 0.012) and ratio.high == pytest.approx(0.060 / 0.010)
    assert ratio.median == pytest.approx(5.0) and ratio.warnings() == ()
    loaded = replace(steady, wall_max_s=0.600)  # one repeat slowed 10x by another job
    assert ratio.spread < RATIO_SPREAD_LIMIT < CostRatio.of(loaded, red).spread
    assert any("uncertain" in w for w in CostRatio.of(loaded, red).warnings())
    crossing = replace(steady, wall_min_s=0.008)  # MuJoCo's fastest repeat beats the reduced solver's slowest
    assert any("contains 1" in w for w in CostRatio.of(crossing, red).warnings())
    with pytest.raises(ValueError):
        Measurement(configs[0], "ok", verdict=Verdict.PASS, wall_min_s=0.02, wall_median_s=0.01, wall_max_s=0.03)


def _as_run_would(scene, config):
    """What `loopcheck run` says of one MuJoCo configuration, through run's own API: pass, or the failure."""
    s = config.settings
    settings = MujocoSettings(integrator=s.integrator, timestep=s.timestep, solref=s.solref, solimp=s.solimp)
    try:
        return compare_engines(scene, mujoco=settings).gate.passed
    except NumericalFailure:
        return False


@pytest.mark.slow
def test_every_point_carries_the_verdict_run_gives_it(study):
    """One verdict for one run (issue: cost marked mujoco-default "ok" with a 2.96 mm loop gap that
    run fails as drift). Each MuJoCo point's verdict is the one `loopcheck run` gives the same
    settings (compare_engines, run's defaults: its drift and energy limits, its gate at the scene's
    tolerances); the reduced points fail where run's own error check refuses them. (Planted: the
    verdict taken from the sweep's status, cost's own rule, fails on every soft and first-order point.)"""
    scene, _, measurements, _ = study
    mujoco = [m for m in measurements if m.config.engine == "mujoco"]
    assert {m.verdict for m in mujoco} == {Verdict.PASS, Verdict.FAIL}
    for m in mujoco:
        assert m.passed == _as_run_would(scene, m.config), (m.config.label, m.verdict_reasons)
    soft = [m for m in mujoco if m.config.series == "MuJoCo rk4 (mujoco-default)"]
    assert soft and all(not m.passed and m.verdict_reasons[0].startswith("constraint-drift") for m in soft)
    for m in (m for m in measurements if m.config.engine == "reduced"):
        try:
            simulate(scene, replace(m.config.settings, check_error=True))
            own = True
        except NumericalFailure:
            own = False
        assert own or not m.passed, m.config.label


@pytest.mark.slow
def test_the_table_says_what_the_reduced_loop_column_means(study):
    """The reduced engine has no loop gap: its loop column says so, never `nan` (issue: `cost`'s
    table printed nan). Planted: the old format string fails."""
    scene, truth, measurements, recommendations = study
    report = cost_report(scene, truth, measurements, recommendations, repeats=2)
    lines = summary_lines(report, measurements)
    assert not any("nan" in line.lower().split() or " nan " in line.lower() for line in lines), lines
    reduced_rows = [line for line in lines if line.startswith(("RKN4 ", "DOP853 "))]
    assert reduced_rows and all(LOOP_EXACT in line for line in reduced_rows)
    mujoco_rows = [line for line in lines if line.startswith("MuJoCo ")]
    assert mujoco_rows and not any(LOOP_EXACT in line for line in mujoco_rows)
    assert any(line.startswith("at peak error <=") and "between" in line for line in lines)


@pytest.mark.slow
@pytest.mark.parametrize("series", ["RKN4", "DOP853", "MuJoCo rk4 (hard)", "MuJoCo euler (hard)",
                                    "MuJoCo implicitfast (hard)", "MuJoCo implicit (hard)"])
def test_error_falls_with_step_in_convergent_series(study, series):
    _, truth, measurements, _ = study
    points = by_series(measurements, series)
    assert len(points) >= 2
    floor = max(truth.error["peak_omega_rel"], 1e-13)
    assert converges(points, floor, "peak_omega_rel")
    assert converges(points, max(truth.error["q_max_abs"], 1e-13), "q_max_abs")


@pytest.mark.slow
def test_mujoco_default_softness_is_an_accuracy_floor(study):
    """With MuJoCo's default solref/solimp the RK4 error does not fall with the step: the
    soft loop constraint, not the integrator, limits accuracy (3.2e-2 in peak ω at 1 ms and 0.25 ms)."""
    _, _, measurements, _ = study
    soft = by_series(measurements, "MuJoCo rk4 (mujoco-default)")
    hard = by_series(measurements, "MuJoCo rk4 (hard)")
    assert min(m.peak_omega_rel for m in soft) > 1e-3
    assert max(m.peak_omega_rel for m in hard) < 1e-4


@pytest.mark.slow
def test_recommendations_meet_their_target_when_rerun(study):
    _, _, _, recommendations = study
    for engine in ("reduced", "mujoco"):
        r = recommendations[engine]
        assert r.reached, engine
        assert r.confirmed_ok, (engine, r.confirmed)
        assert r.confirmed.peak_omega_rel <= TARGET


@pytest.mark.slow
def test_unreachable_target_is_said_plainly(study):
    scene, truth, measurements, _ = study
    recs = recommend(scene, measurements, truth, 1e-15, repeats=1)
    assert not recs["mujoco"].reached and not recs["reduced"].reached


def synthetic(configs, walls_errors, verdict=Verdict.PASS) -> list[Measurement]:
    """Measurements of real configurations with chosen wall times (s) and peak errors."""
    reasons = () if verdict is Verdict.PASS else ("q_max_abs = 1 rad > tolerance 1e-3 rad",)
    return [Measurement(c, "ok", verdict=verdict, verdict_reasons=reasons, peak_omega_rel=e, wall_min_s=w,
                        wall_median_s=w, wall_max_s=w, repeats=1)
            for c, (w, e) in zip(configs, walls_errors)]


@pytest.mark.slow
def test_the_cheapest_configuration_meeting_the_target_is_chosen(study):
    """Issue 9, planted bug 2 (the most expensive one recommended). Of four reduced and four
    MuJoCo configurations, three of each meet the target at different costs; the cheapest
    overall misses it, one failed run is cheaper still."""
    scene, truth, _, _ = study
    configs = ladder(load_scene(SEED_SCENE), quick=True)
    reduced = [c for c in configs if c.engine == "reduced"][:4]
    mujoco = [c for c in configs if c.engine == "mujoco"][:4]
    walls_errors = [(0.5, 1e-5), (0.1, 1e-6), (0.9, 1e-7), (0.01, 1e-2)]
    measurements = synthetic(reduced, walls_errors) + synthetic(mujoco, walls_errors)
    measurements.append(Measurement(reduced[0], "unstable", verdict_reasons=("unstable: blew up",)))
    measurements += synthetic(reduced[:1], [(0.001, 1e-8)], Verdict.FAIL)  # cheapest and accurate, but run fails it
    for engine, chosen in (("reduced", reduced[1]), ("mujoco", mujoco[1])):
        best = cheapest_meeting(measurements, engine, TARGET)
        assert best.config == chosen and best.wall_median_s == 0.1
    assert cheapest_meeting(measurements, "reduced", 1e-9) is None
    recs = recommend(scene, measurements, truth, TARGET, repeats=1)  # confirms by re-running
    assert recs["reduced"].measurement.config == reduced[1]
    assert recs["mujoco"].measurement.config == mujoco[1]


@pytest.mark.slow
def test_recommendation_is_the_cheapest_of_the_real_sweep(study):
    _, _, measurements, recommendations = study
    for engine in ("reduced", "mujoco"):
        meeting = [m for m in measurements
                   if m.config.engine == engine and m.ok and m.passed and m.peak_omega_rel <= TARGET]
        assert len({m.wall_median_s for m in meeting}) > 1  # a choice to make
        assert recommendations[engine].measurement.wall_median_s == min(m.wall_median_s for m in meeting)


def test_the_diagram_keeps_plain_log_labels_with_a_front(tmp_path, saved_figures):
    """Every label of cost.png is plain text (no mathtext parser), also after the Pareto front
    and the target are drawn: a later loglog call would put matplotlib's formatters back."""
    from loopcheck.compare.cost import pareto_front
    from loopcheck.compare.cost_plot import plot_cost

    configs = ladder(load_scene(SEED_SCENE), quick=True)
    measurements = synthetic([c for c in configs if c.engine == "reduced"][:3],
                             [(0.5, 1e-5), (0.1, 1e-6), (0.9, 1e-7)])
    plot_cost(measurements, pareto_front(measurements), TARGET, "seed", tmp_path / "cost.png")
    (fig,) = saved_figures
    ax = fig.axes[0]
    labels = [t.get_text() for axis in (ax.xaxis, ax.yaxis)
              for t in axis.get_majorticklabels() + axis.get_minorticklabels() if t.get_text()]
    assert labels and not any("$" in text for text in labels), labels


def test_failing_points_are_hollow_and_the_axes_hold_the_data(tmp_path, saved_figures):
    """cost.png: a point `loopcheck run` fails is drawn hollow, every point lies inside the axes
    (scaled to the data) and both axes name their unit. (Planted: failing points drawn filled fails.)"""
    from loopcheck.compare.cost_plot import plot_cost

    configs = ladder(load_scene(SEED_SCENE), quick=True)
    reduced = [c for c in configs if c.engine == "reduced"][:3]
    passing = synthetic(reduced[:2], [(0.5, 1e-5), (0.1, 1e-6)])
    failing = synthetic(reduced[2:], [(2e-4, 3e-2)], Verdict.FAIL)
    plot_cost(passing + failing, passing[1:], TARGET, "seed", tmp_path / "cost.png",
              headline="MuJoCo costs 5.00x (between 4.00x and 6.00x over the repeats)")
    (fig,) = saved_figures
    ax = fig.axes[0]
    hollow = [line for line in ax.get_lines() if line.get_linestyle() in ("None", "none")
              and line.get_markerfacecolor() in ("white", "none", (1.0, 1.0, 1.0, 1.0))]
    assert [tuple(line.get_xdata()) for line in hollow] == [(3e-2,)]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 < 1e-6 and 3e-2 < x1 < 1.0 and y0 < 2e-4 and 0.5 < y1 < 5.0  # the data, within a decade
    assert "(s;" in ax.get_ylabel() and "dimensionless" in ax.get_xlabel()
    assert "between 4.00x and 6.00x" in ax.get_title()
