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
    ''')
    base = engine.settings()
    assert [r.parameter for r in engine.ladder("s", base)] == [1e-2, 1e-3]
    assert [r.parameter for r in engine.ladder("s", base, quick=True)] == [1e-2]
    assert engine.label == "Full" and engine.batch_size == 8
    assert engine.stress_probes("s", base)[0].series == "coarse"
    assert engine.peak_accuracy(engine.settings(step=1e-2)) == pytest.approx(1e-8, rel=1e-15)


@pytest.mark.parametrize("extra, message", [
    ("BATCH_SIZE = 0", r"engine 'bad': BATCH_SIZE is 0, not a whole number >= 1"),
    ("BATCH_SIZE = 2.0", r"BATCH_SIZE is 2.0"),
    ("def peak_accuracy(settings):\n    return float('nan')", r"peak_accuracy gave nan"),
    ("def accuracy_ladder(scene, base, quick):\n    return [base]", r"accuracy_ladder gave .* not a Rung"),
])
def test_a_declaration_that_breaks_its_rule_is_refused_naming_the_engine(package, extra, message):
    engine = package("pkg_bad", extra)
    with pytest.raises((ValueError, TypeError), match=message):
        engine.batch_size if "BATCH" in extra else (engine.peak_accuracy(engine.settings()) if "peak" in extra
                                                    else engine.ladder("s", engine.settings()))


@pytest.mark.parametrize("parameter", [0.0, -1e-3, math.inf, True])
def test_a_rung_refuses_a_parameter_that_is_not_positive_and_finite(parameter):
    with pytest.raises(ValueError, match="Rung.parameter"):
        Rung("s", parameter, None)


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
