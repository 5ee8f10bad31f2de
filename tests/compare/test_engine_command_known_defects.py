"""``loopcheck NAME`` (one engine alone) on a run that its own gate failed: the failure's line,
then each known defect the failed run carries (``NumericalFailure.partial.caveats``), as ``loopcheck
run --engines`` prints them under the engine's line. The issue-39 rule: a port's run is stated with
its known defect, a failed one's too (``loopcheck mjx`` on the five-bar robot: its loops drift at
0.60 s, MJX 3.17.0's missing J̇·q̇).

The engine is a toy package written here: the reduced engine's run, failed as a port's gate fails
it (the run carried by the failure, its caveat set), so that the command's printing is the subject
and no optional engine is needed. Planted: the caveat loop of ``_failure`` in
loopcheck/compare/cli.py left out fails it (the failure's line alone)."""

from __future__ import annotations

import sys
import textwrap

import pytest

from loopcheck import registry
from loopcheck.compare.cli import main

from helpers import SEED_SCENE

SETTINGS = '''
"""A toy engine whose runs fail their gate with a known defect."""

from dataclasses import dataclass

from loopcheck.settings import option


@dataclass(frozen=True)
class Settings:
    rtol: float = option(1e-8, "the reduced engine's rtol", "number")
'''

ENGINE = '''
from dataclasses import replace

from loopcheck.errors import FailureReason, NumericalFailure, with_partial
from loopcheck.reduced import ReducedSettings, simulate as _reduced

DEFECT = "Toy 1.0 drops a term of the loops' acceleration: expect errors of order 1e-3 on closed loops"


def simulate(scene, settings):
    result = replace(_reduced(scene, ReducedSettings(rtol=settings.rtol)), engine="toy", caveats=(DEFECT,))

    def gate():
        raise NumericalFailure(FailureReason.CONSTRAINT_DRIFT, "Toy's loops opened by 0.0014 m at t = 0.604 s", 0.604)
    return with_partial(gate, result)
'''


@pytest.fixture
def toy(tmp_path, monkeypatch):
    package = tmp_path / "toy_defect_engine"
    package.mkdir()
    (package / "settings.py").write_text(textwrap.dedent(SETTINGS), encoding="utf-8")
    (package / "__init__.py").write_text(textwrap.dedent(ENGINE), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(registry.ENGINES, "toy", registry.Engine("toy", "toy_defect_engine", "a toy engine"))
    yield
    for name in [m for m in sys.modules if m.startswith("toy_defect_engine")]:
        del sys.modules[name]


def test_a_failed_run_is_stated_with_its_known_defect(toy, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["toy", str(SEED_SCENE)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == [
        "loopcheck: numerical failure (constraint-drift): Toy's loops opened by 0.0014 m at t = 0.604 s",
        "loopcheck: known defect: Toy 1.0 drops a term of the loops' acceleration: expect errors of order 1e-3 on "
        "closed loops"]
