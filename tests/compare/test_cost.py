"""The work-precision study: outputs, convergence within each series, recommendations.

Nothing here depends on wall-clock figures: errors and statuses only.
"""

from __future__ import annotations

import json

import matplotlib.image
import pytest

from loopcheck.compare.cost import (Measurement, cheapest_meeting, converges, cost_report, ground_truth, ladder,
                          recommend, sweep, write_cost_outputs)
from loopcheck.scenefile import load_scene

from helpers import SEED_SCENE

TARGET = 1e-4


@pytest.fixture(scope="module")
def study():
    scene = load_scene(SEED_SCENE)
    truth = ground_truth(scene)
    measurements = sweep(scene, ladder(quick=True), truth, repeats=1, workers=2)
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
    report = cost_report(scene, truth, measurements, recommendations, repeats=1)
    paths = write_cost_outputs(report, measurements, tmp_path, TARGET)
    assert [p.name for p in paths] == ["cost.png", "cost.csv", "cost.json"]
    assert matplotlib.image.imread(paths[0]).shape[1] > 600
    lines = paths[1].read_text().splitlines()
    assert len(lines) == len(measurements) + 1 and lines[0].startswith("status,")
    data = json.loads(paths[2].read_text(), parse_constant=lambda token: pytest.fail(f"bare {token} in cost.json"))
    assert not data["source"].startswith("/")  # relative to the working folder, or the file name
    assert data["measurements"][0]["constraint_violation"] is None  # reduced: not measured, null
    assert data["timing"]["repeats"] == 1 and len(data["measurements"]) == len(measurements)
    assert all(m.ok for m in measurements)  # every configuration in the quick ladder is stable


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
    soft loop constraint, not the integrator, limits accuracy (about 2.6e-2 in peak ω)."""
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


def synthetic(configs, walls_errors) -> list[Measurement]:
    """Measurements of real configurations with chosen wall times (s) and peak errors."""
    return [Measurement(c, "ok", peak_omega_rel=e, wall_median_s=w, repeats=1)
            for c, (w, e) in zip(configs, walls_errors)]


@pytest.mark.slow
def test_the_cheapest_configuration_meeting_the_target_is_chosen(study):
    """Issue 9, planted bug 2 (the most expensive one recommended). Of four reduced and four
    MuJoCo configurations, three of each meet the target at different costs; the cheapest
    overall misses it, one failed run is cheaper still."""
    scene, truth, _, _ = study
    configs = ladder(quick=True)
    reduced = [c for c in configs if c.engine == "reduced"][:4]
    mujoco = [c for c in configs if c.engine == "mujoco"][:4]
    walls_errors = [(0.5, 1e-5), (0.1, 1e-6), (0.9, 1e-7), (0.01, 1e-2)]
    measurements = synthetic(reduced, walls_errors) + synthetic(mujoco, walls_errors)
    measurements.append(Measurement(reduced[0], "unstable", wall_median_s=1e-6))
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
        meeting = [m for m in measurements if m.config.engine == engine and m.ok and m.peak_omega_rel <= TARGET]
        assert len({m.wall_median_s for m in meeting}) > 1  # a choice to make
        assert recommendations[engine].measurement.wall_median_s == min(m.wall_median_s for m in meeting)


def test_the_diagram_keeps_plain_log_labels_with_a_front(tmp_path, saved_figures):
    """Every label of cost.png is plain text (no mathtext parser), also after the Pareto front
    and the target are drawn: a later loglog call would put matplotlib's formatters back."""
    from loopcheck.compare.cost import pareto_front
    from loopcheck.compare.plots import plot_work_precision

    configs = ladder(quick=True)
    measurements = synthetic([c for c in configs if c.engine == "reduced"][:3],
                             [(0.5, 1e-5), (0.1, 1e-6), (0.9, 1e-7)])
    plot_work_precision(measurements, pareto_front(measurements), TARGET, "seed", tmp_path / "cost.png")
    (fig,) = saved_figures
    ax = fig.axes[0]
    labels = [t.get_text() for axis in (ax.xaxis, ax.yaxis)
              for t in axis.get_majorticklabels() + axis.get_minorticklabels() if t.get_text()]
    assert labels and not any("$" in text for text in labels), labels
