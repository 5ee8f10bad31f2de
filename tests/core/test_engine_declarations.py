"""The engine contract's optional declarations (loopcheck.registry.Engine): an engine that declares
none of them still has a ladder, a batch size, no stress probes, a batch that is a loop of single
runs, and a one-line refusal for sensitivity; a declaration that breaks its rule is refused naming
the engine."""

from __future__ import annotations

import math
import sys
import textwrap

import pytest

from loopcheck.registry import Engine, Rung

BARE = '''
"""A bare engine: Settings and simulate, nothing declared."""
from dataclasses import dataclass
from loopcheck.settings import option


@dataclass(frozen=True)
class Settings:
    step: float = option(1e-3, "a step", "number", unit="s")
'''

RUN = '''
from dataclasses import dataclass

calls = []


def simulate(scene, settings):
    calls.append((scene, settings))
    return ("ran", scene, settings.step)
'''


@pytest.fixture
def package(tmp_path, monkeypatch):
    """Write a package ``NAME`` (its settings module's text extra appended) and return its Engine."""
    made = []

    def make(name: str, extra: str = "") -> Engine:
        folder = tmp_path / name
        folder.mkdir()
        (folder / "__init__.py").write_text(RUN)
        (folder / "settings.py").write_text(BARE + textwrap.dedent(extra))
        made.append(name)
        return Engine(name.replace("pkg_", ""), name)

    monkeypatch.syspath_prepend(str(tmp_path))
    yield make
    for name in made:
        for module in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            del sys.modules[module]


def test_an_engine_that_declares_nothing_has_every_default(package):
    engine = package("pkg_bare")
    base = engine.settings(step=2e-3)
    (rung,) = engine.ladder("scene", base)
    assert rung.settings is base and math.isnan(rung.parameter) and rung.series == "bare"
    assert engine.label == "bare"
    assert engine.stress_probes("scene", base) == ()
    assert engine.fixed_step(base) is None  # no step grid declared: the steps adapt
    assert engine.batch_size == 1
    assert engine.simulate_batch(["a", "b"], base) == [("ran", "a", 2e-3), ("ran", "b", 2e-3)]
    with pytest.raises(ValueError, match=r"engine 'bare' declares no peak accuracy \(peak_accuracy\(settings\) in "
                                         r"pkg_bare.settings\)"):
        engine.peak_accuracy(base)


def test_declarations_are_read_from_the_settings_module(package):
    engine = package("pkg_full", '''
        from loopcheck.registry import Rung
        LABEL = "Full"
        BATCH_SIZE = 8


        def accuracy_ladder(scene, base, quick):
            steps = (1e-2,) if quick else (1e-2, 1e-3)
            return [Rung("fixed", h, Settings(step=h)) for h in steps]


        def stress_probes(scene, base):
            return [Rung("coarse", 0.1, Settings(step=0.1))]


        def peak_accuracy(settings):
            return settings.step ** 4


        def fixed_step(settings):
            return settings.step
    ''')
    base = engine.settings()
    assert [r.parameter for r in engine.ladder("s", base)] == [1e-2, 1e-3]
    assert [r.parameter for r in engine.ladder("s", base, quick=True)] == [1e-2]
    assert engine.label == "Full" and engine.batch_size == 8
    assert engine.stress_probes("s", base)[0].series == "coarse"
    assert engine.peak_accuracy(engine.settings(step=1e-2)) == pytest.approx(1e-8, rel=1e-15)
    assert engine.fixed_step(engine.settings(step=2e-3)) == 2e-3


@pytest.mark.parametrize("extra, message", [
    ("BATCH_SIZE = 0", r"engine 'bad': BATCH_SIZE is 0, not a whole number >= 1"),
    ("BATCH_SIZE = 2.0", r"BATCH_SIZE is 2.0"),
    ("def peak_accuracy(settings):\n    return float('nan')", r"peak_accuracy gave nan"),
    ("def accuracy_ladder(scene, base, quick):\n    return [base]", r"accuracy_ladder gave .* not a Rung"),
    ("def fixed_step(settings):\n    return 0.0", r"engine 'bad': fixed_step gave 0.0, not a positive step in s or None"),
])
def test_a_declaration_that_breaks_its_rule_is_refused_naming_the_engine(package, extra, message):
    engine = package("pkg_bad", extra)
    with pytest.raises((ValueError, TypeError), match=message):
        engine.batch_size if "BATCH" in extra else (engine.peak_accuracy(engine.settings()) if "peak" in extra
                                                    else engine.fixed_step(engine.settings()) if "fixed" in extra
                                                    else engine.ladder("s", engine.settings()))


@pytest.mark.parametrize("parameter", [0.0, -1e-3, math.inf, True])
def test_a_rung_refuses_a_parameter_that_is_not_positive_and_finite(parameter):
    with pytest.raises(ValueError, match="Rung.parameter"):
        Rung("s", parameter, None)


def test_the_presentation_declarations_default_to_the_engine_alone(package, monkeypatch):
    """A bare engine registered beside the built-ins: its name as label, the first colour of the
    palette the others leave (the built-in ports declare none and take the first two), itself as
    its only run, nothing inherited, no words, notes, lines, refusals or model files of its own."""
    import loopcheck.registry as registry

    engine = package("pkg_plain")
    monkeypatch.setitem(registry.ENGINES, engine.name, engine)
    declared = {e.colour for e in registry.BUILT_IN if e._declared("COLOUR")}
    spare = [c for c in registry.PALETTE if c not in declared]
    assert [registry.ENGINES[n].colour for n in ("mjx", "mjwarp", "plain")] == spare[:3]
    assert len({e.colour for e in registry.ENGINES.values()}) == len(registry.ENGINES)  # no two alike
    assert engine.runs == ("plain",) and registry.engine_of_run("plain") is engine
    assert engine.inherits is None and engine.model_files == ()
    assert engine.settings_text("result") is None and engine.gate_notes("scene", "result", ("f",)) == ()
    assert engine.result_lines("scene", "result") is None
    assert engine.check_work("scene", engine.settings()) is None
    assert registry.model_reader("model.xyz") is None


def test_the_presentation_declarations_are_read_where_the_engine_declares_them(package, monkeypatch):
    import loopcheck.registry as registry

    engine = package("pkg_shown", '''
        COLOUR = "tab:cyan"
        RUNS = ("shown_user",)
        INHERITS = ("mujoco", ("timestep",))
        MODEL_FILES = (".SHOWN",)


        def settings_text(result):
            return f"step {result.settings.step:g}"


        def gate_notes(scene, result, failures):
            return [f"{len(failures)} failures"]
    ''')
    monkeypatch.setitem(registry.ENGINES, engine.name, engine)
    assert engine.colour == "tab:cyan" and engine.runs == ("shown", "shown_user")
    assert registry.engine_of_run("shown_user") is engine
    assert engine.inherits == ("mujoco", frozenset({"timestep"}))
    assert registry.model_reader("a/b/model.shown") is engine and engine.model_files == (".shown",)

    class Result:
        settings = engine.settings(step=0.5)

    assert engine.settings_text(Result()) == "step 0.5"
    assert engine.gate_notes("scene", Result(), ("a", "b")) == ("2 failures",)


def test_the_built_in_engines_declare_their_labels_colours_and_runs():
    """The built-ins' declarations: what tables and plots called them before the declarations
    (a user's own MuJoCo model is MuJoCo's run), the ports inheriting [mujoco]'s model options."""
    from loopcheck.mujoco_model.options import ModelOptions
    from loopcheck.registry import ENGINES, engine_of_run, model_reader
    from loopcheck.settings import options

    assert {n: e.label for n, e in ENGINES.items() if n in ("reduced", "mujoco", "pin", "mjx", "mjwarp")} == {
        "reduced": "reduced", "mujoco": "MuJoCo", "pin": "Pinocchio", "mjx": "MJX", "mjwarp": "MJWarp"}
    assert (ENGINES["reduced"].colour, ENGINES["mujoco"].colour, ENGINES["pin"].colour) == (
        "tab:blue", "tab:orange", "tab:green")
    assert engine_of_run("model") is ENGINES["mujoco"] and model_reader("Robot.XML") is ENGINES["mujoco"]
    assert model_reader("scene.toml") is None
    shared = frozenset(o.name for o in options(ModelOptions))
    assert ENGINES["mjx"].inherits == ENGINES["mjwarp"].inherits == ("mujoco", shared)
    assert ENGINES["mujoco"].inherits is None and ENGINES["pin"].inherits is None
def test_a_rung_says_what_run_would_run_and_how_it_is_labelled(package):
    """A rung's verdict settings (``run_settings``, default its own) and its label; a ladder whose
    verdict settings are another engine's is refused. (Planted: ``as_run`` returning ``settings``
    always fails the first assertion; the type check skipping ``run_settings`` fails the last.)"""
    engine = package("pkg_loose", '''
        from loopcheck.registry import Rung


        def accuracy_ladder(scene, base, quick):
            return [Rung("fixed", 1e-2, Settings(step=1e-2), run_settings=Settings(step=2e-2)),
                    Rung("tol", 1e-6, Settings(step=1e-3), "rtol")]
    ''')
    loose, tight = engine.ladder("s", engine.settings())
    assert loose.as_run == engine.settings(step=2e-2) and tight.as_run is tight.settings
    assert (loose.label, tight.label) == ("fixed h=1.0e-02", "tol rtol=1.0e-06")
    assert engine.ladder("s", engine.settings())[0].settings == engine.settings(step=1e-2)
    plain = package("pkg_plain")
    (single,) = plain.ladder("s", plain.settings())
    assert single.label == "plain"  # the default point: the engine's label, no parameter
    with pytest.raises(ValueError, match="Rung.symbol"):
        Rung("s", 1e-3, None, "")
    bad = package("pkg_mixed", '''
        from loopcheck.registry import Rung


        def accuracy_ladder(scene, base, quick):
            return [Rung("fixed", 1e-2, Settings(step=1e-2), run_settings="not its settings")]
    ''')
    with pytest.raises(TypeError, match="engine 'mixed': accuracy_ladder gave .* not a Rung of its Settings"):
        bad.ladder("s", bad.settings())


def test_the_reference_declares_its_truth_and_an_engine_without_one_is_refused(package):
    """``Engine.truth()``: the reduced reference's two runs (DOP853 at rtol 1e-12 and 1e-11); an
    engine declaring none is refused in one line naming what is missing."""
    from loopcheck.registry import ENGINES, REFERENCE

    tight, check = ENGINES[REFERENCE].truth()
    assert (tight.label, check.label) == ("DOP853 rtol=1.0e-12", "DOP853 rtol=1.0e-11")
    assert (tight.settings.method, tight.settings.rtol, check.settings.rtol) == ("dop853", 1e-12, 1e-11)
    with pytest.raises(ValueError, match=r"engine 'bare2' declares no ground truth \(truth\(\) in pkg_bare2.settings\)"):
        package("pkg_bare2").truth()
    one = package("pkg_one", '''
        from loopcheck.registry import Rung


        def truth():
            return (Rung("t", 1e-3, Settings()),)
    ''')
    with pytest.raises(ValueError, match="truth\\(\\) gave 1 runs, not two"):
        one.truth()


FAILING_BATCH = '''
from dataclasses import dataclass

batches = []


def simulate(scene, settings):
    if scene == "bad":
        raise ValueError("bad scene")
    return ("ran", scene, settings.step)


def simulate_batch(scenes, settings):  # no `each`: a bad scene sinks the batch
    batches.append(list(scenes))
    return [simulate(scene, settings) for scene in scenes]


def batch_limit(scene, settings):
    return 2 if scene == "small" else 0
'''


def test_a_batch_with_each_gives_each_variant_its_own_outcome(package, tmp_path):
    """each=True: the default loop and a package's batch that raises (it takes no ``each``) both
    give one outcome per scene, a failing scene's exception in its slot (planted: without the
    fallback the batch's ValueError escapes)."""
    bare = package("pkg_loop")
    base = bare.settings()
    assert bare.simulate_batch(["a", "b"], base, each=True) == [("ran", "a", 1e-3), ("ran", "b", 1e-3)]
    engine = package("pkg_failing")
    (tmp_path / "pkg_failing" / "__init__.py").write_text(FAILING_BATCH)  # before its first import
    got = engine.simulate_batch(["a", "bad", "c"], base, each=True)
    assert got[0] == ("ran", "a", 1e-3) and got[2] == ("ran", "c", 1e-3)
    assert isinstance(got[1], ValueError) and str(got[1]) == "bad scene"
    assert sys.modules["pkg_failing"].batches == [["a", "bad", "c"]]  # the batch was tried first
    with pytest.raises(ValueError, match="bad scene"):
        engine.simulate_batch(["a", "bad"], base)
    assert engine.batch_limit("small", base) == 2 and bare.batch_limit("small", base) is None
    with pytest.raises(ValueError, match=r"engine 'failing': batch_limit gave 0, not a whole number >= 1"):
        engine.batch_limit("big", base)


def test_an_engine_that_does_not_declare_several_dof_refuses_a_scene_of_several_in_one_line(package):
    from pathlib import Path

    from loopcheck.scene import SceneError
    from loopcheck.scenefile import load_scene

    engine = package("pkg_one")
    assert not engine.several_dof
    scene = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "mechanisms" / "five_bar_robot.toml")
    for call in (lambda: engine.check_dof(scene), lambda: engine.check_work(scene, engine.settings()),
                 lambda: engine.simulate(scene, engine.settings()),
                 lambda: engine.simulate_batch([scene], engine.settings())):
        with pytest.raises(SceneError) as info:
            call()
        assert str(info.value) == ("scene 'five_bar_robot' has 2 degrees of freedom (inputs O1, O5); "
                                   "the one engine runs one-DOF linkages only")
    assert package("pkg_many", "SEVERAL_DOF = True").several_dof
