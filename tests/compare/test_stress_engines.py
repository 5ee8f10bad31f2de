"""``loopcheck stress --engines`` and sensitivity with any engine (issue 39, "Studies over the registry").

Oracles: ``loopcheck check --engines``' verdict of the same scene (the known-defect rule: an engine's
verdict in a stress case is the one check gives, failures and refusals included, and the
catalogue goes on); the reference's own sensitivity (another engine's d(peak)/dp must agree with it
within the two error bars, where the engine has no known defect); the engines' declarations read
without loading an engine. The optional engines (Pinocchio, MJX, MJWarp) run the seed over 0.2 s
and are skipped without their extra; MJX's known defect (docs/engines.md) means no test here
requires it to pass. The fake engine's commands: tests/compare/test_fake_engine_studies.py.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from loopcheck.compare.engines import check_engines
from loopcheck.compare.sensitivity import SensitivityFailure, _frozen, sensitivities, sensitivity_lines
from loopcheck.compare.stress import Case, RunStatus, run_catalogue, run_case, stress_data, table_lines
from loopcheck.errors import FailureReason
from loopcheck.registry import ENGINES, REFERENCE
from loopcheck.scenefile import load_scene
from loopcheck.sweep_spec import spec_from_args
from loopcheck.compare.sweep_scene import load_sweep

from helpers import ROOT, SEED_SCENE

SHORT = 0.2  # s: the seed's first 0.2 s (the plumbing and the verdicts are the subject)
OPTIONAL = ("pin", "mjx", "mjwarp")
# The ports compile their step loop (MJX: about 35 s on a CPU, once per structure and step count, kept by
# JAX's persistent cache where JAX_COMPILATION_CACHE_DIR is set, as in CI; MJWarp: its kernels): slow.
ENGINES_JUDGED = ["mujoco", "pin", *(pytest.param(n, marks=pytest.mark.slow) for n in ("mjx", "mjwarp"))]


def _short_seed(folder, extra: str = "") -> str:
    """The seed over SHORT seconds (and ``extra`` appended: tables of its own), as a file."""
    text = SEED_SCENE.read_text().replace("horizon = 2.0 ", f"horizon = {SHORT} ")
    assert f"horizon = {SHORT} " in text
    path = folder / "seed_short.toml"
    path.write_text(text + extra, encoding="utf-8")
    return str(path)


def _installed(name: str) -> None:
    try:
        ENGINES[name].load()
    except ImportError as exc:
        pytest.skip(f"the {name} engine's extra is not installed: {exc}")


# The declarations (read from the engines' settings modules: no engine is loaded)

def test_the_built_in_engines_declare_their_grids_probes_and_peak_accuracy():
    from loopcheck.reduced.settings import ReducedSettings

    scene = load_scene(SEED_SCENE)
    reduced, mujoco, mjx, mjwarp, pin = (ENGINES[n] for n in ("reduced", "mujoco", "mjx", "mjwarp", "pin"))
    assert reduced.fixed_step(ReducedSettings()) is None  # DOP853 adapts
    assert reduced.fixed_step(ReducedSettings(method="rkn4", step=2e-4)) == 2e-4
    assert reduced.peak_accuracy(ReducedSettings()) == pytest.approx(1e-11, rel=1e-15)  # 10 × rtol 1e-12
    assert pin.fixed_step(pin.settings()) is None and pin.peak_accuracy(pin.settings()) == pytest.approx(1e-9)
    assert [(r.series, r.parameter) for r in reduced.stress_probes(scene, ReducedSettings())] == [
        ("rkn4", 1e-3), ("rkn4", 1e-4)]
    base = mujoco.settings(solimp=(0.99, 0.999, 0.001, 0.5, 2.0))
    probes = mujoco.stress_probes(scene, base)
    assert [(r.series, r.parameter) for r in probes] == [(i, h) for i in ("euler", "implicit", "implicitfast", "rk4")
                                                        for h in (1e-3, 1e-4, 1e-5)]
    assert all(r.settings.solimp == base.solimp for r in probes)  # the scene's settings, integrator and step varied
    assert {r.series for r in mjx.stress_probes(scene, mjx.settings())} == {"euler", "implicitfast", "rk4"}
    assert len(mjwarp.stress_probes(scene, mjwarp.settings())) == 12
    for engine in (mujoco, mjx, mjwarp):
        assert engine.fixed_step(engine.settings()) is None  # automatic: chosen by the run
        assert engine.fixed_step(engine.settings(timestep=5e-4)) == 5e-4
        assert 0.0 < engine.peak_accuracy(engine.settings(timestep=5e-4)) < 1e-3


def test_sensitivity_freezes_what_the_engine_chose_at_the_nominal_scene():
    """A setting left to the engine (None) takes the nominal run's value; one the scene gives stays."""
    scene = load_scene(SEED_SCENE)  # its [mujoco] table leaves the timestep to MuJoCo
    chosen = ENGINES["mujoco"].settings(timestep=5e-4)
    assert ENGINES["mujoco"].settings().timestep is None
    assert _frozen("mujoco", scene, chosen).timestep == 5e-4
    pinned = replace(scene, engine_tables={**scene.engine_tables, "mujoco": {"timestep": 1e-3}})
    assert _frozen("mujoco", pinned, chosen).timestep == 1e-3
    assert _frozen("reduced", scene, ENGINES["reduced"].settings()) == ENGINES["reduced"].settings()


# stress over a list of engines, in process

def test_a_failing_engine_and_a_refused_one_are_their_verdicts_and_the_study_goes_on(tmp_path):
    """MuJoCo's RK4 at 1 ms on the stiff damper loses its loop (the catalogue's probe shows it), and
    MJX refuses the implicit integrator the scene's [mujoco] table asks for (its settings, read
    without JAX): each case's outcomes are check --engines' verdicts, and both cases run."""
    stiff = (ROOT / "scenes" / "hard" / "stiff_damper.toml").read_text()
    stiff = stiff.replace("timestep = 1e-4", "timestep = 1e-3").replace("horizon = 2.0", f"horizon = {SHORT}")
    (tmp_path / "stiff.toml").write_text(stiff, encoding="utf-8")
    implicit = _short_seed(tmp_path, "")
    text = (tmp_path / "seed_short.toml").read_text()
    assert "[mujoco]" not in text
    (tmp_path / "seed_short.toml").write_text(text + '\n[mujoco]\nintegrator = "implicit"\n', encoding="utf-8")
    cases = (Case("stiff_rk4_1ms", str(tmp_path / "stiff.toml")), Case("implicit", implicit))
    results = run_catalogue(cases, engines=("reduced", "mujoco"))
    assert [r.name for r in results] == ["stiff_rk4_1ms", "implicit"]
    stiff_result = results[0]
    assert not stiff_result.passed and stiff_result.outcome("reduced").status is RunStatus.OK
    failed = stiff_result.outcome("mujoco")
    check = check_engines(load_scene(tmp_path / "stiff.toml"), ("reduced", "mujoco"))
    assert failed.status is FailureReason.CONSTRAINT_DRIFT and failed.failure == check.verdict("mujoco").failure
    assert failed.result is None and failed.comparison is None
    assert results[1].passed  # MuJoCo's implicit integrator at its automatic step passes the short seed
    refused = run_case(cases[1], ("reduced", "mjx", "mujoco"))
    assert refused.engines == ("reduced", "mjx", "mujoco") and not refused.passed
    assert refused.outcome("mujoco").passed  # the refusal is MJX's verdict alone
    assert refused.outcome("mjx").status is RunStatus.REFUSED and "MJX has no implicit" in refused.outcome("mjx").failure
    data = stress_data([stiff_result, refused])
    assert data["schema_version"] == 2
    assert data["cases"][0]["engines"]["mujoco"]["status"] == "constraint-drift"
    assert data["cases"][1]["engines"]["mjx"]["status"] == "refused"
    lines = table_lines([refused])  # three engines: a line per engine under the case's
    assert lines[0].split() == ["case", "reduced", "mjx", "mujoco", "verdict"]
    assert lines[2].split() == ["implicit", "ok", "refused", "ok", "FAIL"]
    assert [line.split()[0] for line in lines[3:6]] == ["reduced", "mjx", "mujoco"]
    assert lines[4].split()[1:] == ["-"] * 5  # MJX did not run: no figures
    assert any(line.strip() == f"problem: MJX refused: {refused.outcome('mjx').failure}"
               or line.strip() == f"problem: mjx refused: {refused.outcome('mjx').failure}" for line in lines)


@pytest.mark.parametrize("name", ENGINES_JUDGED)
def test_each_engine_in_a_stress_case_has_the_verdict_check_gives(tmp_path, name):
    """The seed over 0.2 s with the reference and one engine: the engine's outcome is its
    ``check --engines`` verdict (MJX fails the seed's gate by its known defect: the rule holds as
    well), judged by its own tolerances."""
    if name in OPTIONAL:
        _installed(name)
    path = _short_seed(tmp_path)
    result = run_case(Case("seed_short", path), ("reduced", name))
    check = check_engines(load_scene(path), ("reduced", name))
    outcome, verdict = result.outcome(name), check.verdict(name)
    assert result.engines == ("reduced", name)
    assert outcome.passed == verdict.passed and result.passed == check.passed
    assert outcome.failure == verdict.failure and outcome.known_defects == verdict.known_defects
    assert all(f"{ENGINES[name].label} known defect: {d}" in result.notes for d in outcome.known_defects)
    if outcome.comparison is not None:
        assert outcome.comparison.gate.tolerances == load_scene(path).tolerances_for(name)
        assert outcome.figures["peak_omega_rel"] == verdict.comparison.diff.peak_omega_rel
        assert outcome.comparison.other.engine == name
    if name == "mujoco" or name == "pin":
        assert result.passed, result.problems


@pytest.mark.parametrize("name", ENGINES_JUDGED)
def test_each_engine_has_its_own_sensitivity_beside_the_reference(tmp_path, name):
    """d(peak)/d(damper coefficient) on the seed over 0.2 s (the peak at the horizon, still rising):
    the engine's own D, at its declared ε, with its step frozen. Where the engine has no known
    defect its D agrees with the reference's within the two error bars (MJX's is only required to
    be a number with its bar: its defect changes the dynamics)."""
    if name in OPTIONAL:
        _installed(name)
    data, _ = load_sweep(_short_seed(tmp_path))
    items = sensitivities(data, spec_from_args(["dampers.0.coefficient=50:60:2"]), str(tmp_path), engines=(REFERENCE, name))
    reference, own = items
    assert (reference.engine, own.engine) == (REFERENCE, name) and own.key == reference.key
    assert own.step == pytest.approx(abs(own.nominal) * ENGINES[name].peak_accuracy(ENGINES[name].settings()) ** (1 / 3))
    assert math.isfinite(own.derivative) and own.error > 0.0
    assert (own.frozen_step is None) == (name == "pin")  # Pinocchio's steps adapt; the MuJoCo family's are frozen
    if own.frozen_step is not None:
        assert SHORT / own.frozen_step == pytest.approx(round(SHORT / own.frozen_step))  # the grid step
    if name != "mjx":
        assert abs(own.derivative - reference.derivative) <= own.error + reference.error, (own, reference)


def test_an_engine_that_fails_near_the_nominal_scene_is_its_line_and_the_sensitivity_goes_on(tmp_path):
    """MuJoCo's RK4 at 1 ms loses the stiff damper's loop: its sensitivity is that failure, in one line
    naming the key, and the reference's is computed and printed as without it."""
    stiff = (ROOT / "scenes" / "hard" / "stiff_damper.toml").read_text()
    stiff = stiff.replace("timestep = 1e-4", "timestep = 1e-3").replace("horizon = 2.0", f"horizon = {SHORT}")
    (tmp_path / "stiff.toml").write_text(stiff, encoding="utf-8")
    data, _ = load_sweep(str(tmp_path / "stiff.toml"))
    spec = spec_from_args(["dampers.0.coefficient=1e6:2e6:2"])
    items = sensitivities(data, spec, str(tmp_path), engines=("mujoco", "reduced"))
    reference, failed = items
    assert reference.engine == "reduced" and math.isfinite(reference.derivative)  # the reference's rows first
    assert isinstance(failed, SensitivityFailure) and (failed.engine, failed.key) == ("mujoco", "dampers.0.coefficient")
    assert failed.failure.startswith("numerical failure (constraint-drift): mujoco: the sensitivity to "
                                     "'dampers.0.coefficient' needs the scene at dampers.0.coefficient = ")
    alone = sensitivities(data, spec, str(tmp_path))
    assert alone == [reference]
    lines = sensitivity_lines(items)
    assert lines[-1].split()[:4] == ["mujoco", "numerical", "failure", "(constraint-drift):"]
    assert failed.as_dict() == {"key": "dampers.0.coefficient", "engine": "mujoco", "failure": failed.failure}
