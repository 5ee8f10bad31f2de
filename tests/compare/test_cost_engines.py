"""``loopcheck cost`` over the registry: the default pair's ladder as it always was, each installed
optional engine on the seed (its points judged as ``check --engines`` judges them), an engine that
fails or refuses (its points' verdicts, the study complete), and an engine installed for the test
reaching the command with no other edit (a one-point ladder: it declares none).

Tests needing Pinocchio, MJX or MJWarp skip without them (CI's extras job runs this file)."""

from __future__ import annotations

import dataclasses
import importlib
import json
import sys
import textwrap

import pytest

from loopcheck import registry
from loopcheck.compare import cost
from loopcheck.compare.engines import check_engines
from loopcheck.mujoco_model.options import SWEEP_ENERGY_LIMIT, SWEEP_VIOLATION_LIMIT
from loopcheck.reduced import ReducedSettings
from loopcheck.reference_models import MujocoSettings
from loopcheck.scenefile import load_scene

from helpers import SEED_SCENE

from test_fake_engine import _cli, install

SHORT = 0.2  # s: the seed's horizon cut (the plumbing is the subject; the ports compile per step count)


def _short_seed():
    return dataclasses.replace(load_scene(SEED_SCENE), horizon=SHORT)


def test_the_default_pair_ladder_is_the_one_cost_always_ran():
    """The reduced and MuJoCo ladders, now declared by the engines, are cost's quick ladder of
    before, point for point: labels, the settings the sweep runs and those run's verdict uses
    (planted: the MuJoCo rungs' verdict settings left at the sweep's loose limits fails; so does a
    reduced rung whose verdict does not check its error)."""
    scene = load_scene(SEED_SCENE)
    configs = cost.ladder(scene, quick=True)
    assert [c.engine for c in configs] == ["reduced"] * 6 + ["mujoco"] * 16
    assert [c.label for c in configs[:6]] == ["RKN4 h=1.0e-02", "RKN4 h=3.0e-03", "RKN4 h=1.0e-03",
                                              "DOP853 rtol=1.0e-04", "DOP853 rtol=1.0e-07", "DOP853 rtol=1.0e-10"]
    assert configs[0].settings == ReducedSettings(method="rkn4", step=1e-2, check_error=False)
    assert cost.run_settings(configs[0]) == ReducedSettings(method="rkn4", step=1e-2)
    assert cost.run_settings(configs[3]) == ReducedSettings(method="dop853", rtol=1e-4)
    assert [c.label for c in configs[6:10]] == ["MuJoCo euler (hard) h=1.0e-03", "MuJoCo euler (hard) h=2.5e-04",
                                                "MuJoCo euler (mujoco-default) h=1.0e-03",
                                                "MuJoCo euler (mujoco-default) h=2.5e-04"]
    soft = configs[8]
    assert soft.settings == MujocoSettings(integrator="euler", timestep=1e-3, solref=(0.02, 1.0),
                                           solimp=(0.9, 0.95, 0.001, 0.5, 2.0),
                                           max_constraint_violation=SWEEP_VIOLATION_LIMIT,
                                           max_energy_residual=SWEEP_ENERGY_LIMIT)
    assert cost.run_settings(soft) == dataclasses.replace(
        soft.settings, max_constraint_violation=MujocoSettings().max_constraint_violation,
        max_energy_residual=MujocoSettings().max_energy_residual)
    assert configs[-3].settings == MujocoSettings(integrator="rk4", timestep=2.5e-4, max_constraint_violation=0.1,
                                                  max_energy_residual=1.0)
    assert len(cost.ladder(scene)) == 7 + 10 + 4 * 2 * 7


def _installed(name: str) -> bool:
    try:
        registry.ENGINES[name].load()
    except ImportError:
        return False
    return True


@pytest.mark.slow  # the ports compile (MJX ~20 s, MJWarp ~45 s on a CPU); Pinocchio's run alone is ~1 s
@pytest.mark.parametrize("name", ["pin", "mjx", "mjwarp"])
def test_each_installed_engine_runs_its_quick_ladder_and_is_judged_as_check_judges_it(name):
    """On the seed over 0.2 s, the engine's first quick rung runs (one repeat) and its verdict is
    the one ``check --engines`` gives the same settings (known defects included: MJX may fail; no
    test requires it to pass); the report names it and, where both reached the target, its ratio to
    the reference."""
    if not _installed(name):
        pytest.skip(f"the engine '{name}' is not installed (its extra: pip install -e '.[{name}]')")
    scene = _short_seed()
    truth = cost.ground_truth(scene)
    engines = (registry.REFERENCE, name)
    reference = [c for c in cost.ladder(scene, engines[:1], quick=True) if c.series == "DOP853"]
    configs = reference + [c for c in cost.ladder(scene, engines, quick=True) if c.engine == name][:1]
    measurements = cost.sweep(scene, configs, truth, repeats=1, workers=1)
    m = measurements[-1]
    assert m.config.engine == name and m.repeats in (0, 1)
    check = check_engines(scene, engines, {name: cost.run_settings(m.config)})
    assert m.passed == check.verdict(name).passed, (m.verdict_reasons, check.verdict(name))
    if m.ok:
        assert m.peak_omega_rel < 1e-2 and m.wall_median_s > 0.0  # a measured point, not NaN
    recs = cost.recommend(scene, measurements, truth, 1e-2, repeats=1, engines=engines)
    report = cost.cost_report(scene, truth, measurements, recs, repeats=1)
    assert report["engines"] == list(engines)
    assert (report["recommendation"][cost.ratio_key(name)] is not None) == (
        recs[name].reached and recs[registry.REFERENCE].reached)


@pytest.mark.skipif(not _installed("pin"), reason="Pinocchio (the extra loopcheck[pin]) is not installed")
def test_a_point_run_refuses_is_measured_and_fails_as_run_fails_it():
    """Pinocchio's ladder loosens its loop limit: its coarsest point (rtol 1e-4) opens the seed's loop
    by 4.6e-5 m over 0.5 s, 46x run's 1e-6 m. The sweep measures it (status ok, its errors) and its
    verdict is run's: constraint-drift, as ``check --engines`` says. (Planted: the verdict's run made
    with the sweep's loose settings passes it, and fails this test.)"""
    scene = dataclasses.replace(load_scene(SEED_SCENE), horizon=0.5)
    truth = cost.ground_truth(scene)
    (config,) = [c for c in cost.ladder(scene, ("pin",)) if c.parameter == 1e-4]
    m = cost.measure(scene, config, truth, repeats=1)
    assert m.ok and m.constraint_violation > 1e-5 and not m.passed
    assert m.verdict_reasons[0].startswith("constraint-drift")
    check = check_engines(scene, (registry.REFERENCE, "pin"), {"pin": cost.run_settings(config)})
    assert not check.verdict("pin").passed and "constraint-drift" in check.verdict("pin").failure


BROKEN = '''
"""A broken engine: one rung refused, one a numerical failure, one that runs."""
from dataclasses import dataclass

from loopcheck.registry import Rung
from loopcheck.settings import option


@dataclass(frozen=True)
class Settings:
    mode: float = option(1.0, "1 refuses, 2 fails, 3 runs", "number")


def accuracy_ladder(scene, base, quick):
    return [Rung("broken", float(k), Settings(mode=float(k)), "mode") for k in (1, 2, 3)]
'''

BROKEN_RUN = '''
from dataclasses import replace

from loopcheck.errors import NumericalFailure
from loopcheck.reduced import ReducedSettings, simulate as _reduced


def simulate(scene, settings):
    if settings.mode == 1.0:
        raise ValueError("the broken engine does not run mode 1")
    if settings.mode == 2.0:
        raise NumericalFailure("unstable", "the broken engine blew up in mode 2", time=0.1)
    return replace(_reduced(scene, ReducedSettings(rtol=1e-10)), engine="broken", settings=settings)
'''


@pytest.fixture
def broken(tmp_path, monkeypatch):
    package = tmp_path / "broken_engine"
    package.mkdir()
    (package / "settings.py").write_text(textwrap.dedent(BROKEN), encoding="utf-8")
    (package / "__init__.py").write_text(textwrap.dedent(BROKEN_RUN), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    monkeypatch.setitem(registry.ENGINES, "broken", registry.Engine("broken", "broken_engine"))
    yield "broken"
    for name in [m for m in sys.modules if m.startswith("broken_engine")]:
        del sys.modules[name]


def test_an_engine_that_fails_or_refuses_has_those_verdicts_and_the_study_completes(broken, tmp_path):
    """The known-defect rule: a refusal and a numerical failure are their points' verdicts (status
    ``refused``, the failure's reason), the engine's running point is measured, the study writes its
    three files and prints each. (Planted: measure() letting the ValueError through fails.)"""
    scene = _short_seed()
    report, measurements, target = cost.study(scene, quick=True, repeats=1, workers=1,
                                              engines=(registry.REFERENCE, broken))
    ours = [m for m in measurements if m.config.engine == broken]
    assert [m.status for m in ours] == ["refused", "unstable", "ok"]
    assert [m.verdict.value for m in ours[:2]] == ["fail", "fail"]
    assert ours[0].verdict_reasons == ("refused: the broken engine does not run mode 1",)
    assert ours[1].verdict_reasons[0].startswith("unstable: the broken engine blew up")
    assert ours[2].passed and ours[2].peak_omega_rel < 1e-6
    assert report["engines"] == [registry.REFERENCE, broken]
    assert report["recommendation"][broken]["label"] == "broken mode=3.0e+00"
    lines = cost.summary_lines(report, measurements)
    assert any(line.startswith("broken mode=1.0e+00") and "refused: the broken engine" in line for line in lines)
    assert any(line.startswith("at peak error <=") and " broken costs " in line for line in lines)
    paths = cost.write_cost_outputs(report, measurements, tmp_path / "out", target)
    rows = paths[1].read_text().splitlines()
    assert sum(row.split(",")[0] == "refused" for row in rows) == 1
    assert json.loads(paths[2].read_text())["measurements"][-3]["status"] == "refused"


def test_the_diagram_draws_every_engine_in_its_own_colours_under_its_label(tmp_path, saved_figures):
    """cost.png: each engine's series in its own colour family, grouped under the engine's label in
    the legend; a series with no measured point is listed as such. (Planted: one colour family for
    every engine fails.)"""
    from loopcheck.compare.cost_plot import plot_cost

    scene = load_scene(SEED_SCENE)
    configs = cost.ladder(scene, quick=True)
    rkn4 = configs[0]
    mujoco = next(c for c in configs if c.engine == "mujoco")
    made = [cost.Measurement(c, "ok", verdict=cost.Verdict.PASS, peak_omega_rel=e, wall_min_s=w, wall_median_s=w,
                             wall_max_s=w, repeats=1) for c, (w, e) in ((rkn4, (0.1, 1e-6)), (mujoco, (0.2, 1e-5)))]
    made.append(cost.Measurement(dataclasses.replace(mujoco, series="lost"), "refused", verdict_reasons=("refused",)))
    plot_cost(made, [], 1e-4, "seed", tmp_path / "cost.png", truth="DOP853 rtol 1e-12")
    (fig,) = saved_figures
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[:2] == [registry.ENGINES["reduced"].label, "  RKN4"]
    assert registry.ENGINES["mujoco"].label in labels and "  lost (not measured)" in labels
    colours = [tuple(line.get_color()) for line in ax.get_lines() if len(line.get_xdata()) == 1]
    assert len(colours) == 2  # the two measured series, one point each
    (r0, _, b0, _), (r1, _, b1, _) = colours
    assert b0 > r0 and r1 > b1  # the reference's family blue, the next engine's orange
    assert "(s;" in ax.get_ylabel() and "dimensionless" in ax.get_xlabel() and "DOP853 rtol 1e-12" in ax.get_title()


@pytest.mark.slow  # a fresh process: the subprocess is what shows an installed distribution
def test_an_installed_engine_reaches_cost_as_a_command(tmp_path):
    """`loopcheck cost --engines reduced,fake`: the fake engine of test_fake_engine (it declares no
    ladder: one point at its defaults) is swept, judged, recommended and drawn with no other edit."""
    (tmp_path / "site").mkdir()
    folder = install(tmp_path / "site")
    out = tmp_path / "out"
    done = _cli(["cost", str(SEED_SCENE), "--engines", "reduced,fake", "--quick", "--repeats", "1", "--workers", "2",
                 "-o", str(out)], folder, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert any(line.startswith("fake ") and line.split()[1] == "pass" for line in done.stdout.splitlines()), done.stdout
    assert "cheapest fake configuration that run passes" in done.stdout
    report = json.loads((out / "cost.json").read_text())
    assert report["engines"] == ["reduced", "fake"] and report["recommendation"]["fake"]["label"] == "fake"
    assert report["recommendation"]["fake_over_reduced_wall"]["median"] > 0.0
    (row,) = [r for r in report["measurements"] if r["engine"] == "fake"]
    assert row["verdict"] == "pass" and row["parameter"] is None  # a single point: no parameter (NaN, null)
    assert (out / "cost.png").stat().st_size > 10_000
    bare = _cli(["cost", str(SEED_SCENE), "--engines", "reduced,fake"], tmp_path / "empty", tmp_path)
    assert bare.returncode == 2 and "unknown engine 'fake'" in bare.stderr and not bare.stdout


def test_an_engine_whose_extra_is_missing_is_refused_in_one_line_before_any_work(tmp_path, capsys, monkeypatch):
    """`loopcheck cost --engines reduced,pin` without Pinocchio: one line naming the extra, exit 2,
    nothing computed nor written. (Planted: the engines not loaded up front fails: the study starts.)"""
    from loopcheck.compare.cli import main

    if _installed("pin"):
        pytest.skip("Pinocchio is installed: nothing is missing")

    def computed(*args, **kwargs):
        raise AssertionError("work started before the engines were loaded")

    monkeypatch.setattr(cost, "ground_truth", computed)
    status = main(["cost", str(SEED_SCENE), "--engines", "reduced,pin", "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("loopcheck: error: the pin engine needs Pinocchio"), err
    assert not (tmp_path / "out").exists()
