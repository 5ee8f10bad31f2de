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
