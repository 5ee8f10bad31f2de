"""A third engine is one package and one entry of the registry (docs/engines.md): a package
written here, with a ``settings`` module (one option) and a ``simulate``, put in
``loopcheck.registry.ENGINES`` as the registry puts an engine declared by an entry point
(tests/compare/test_fake_engine.py installs one as a distribution), gets its scene table read and checked, its flags, its rows in the
scene-format reference, and ``loopcheck.simulate`` runs it, with nothing else changed. (Planted: the
scene reader looking only at ``[reduced]`` and ``[mujoco]`` by name fails the table test.)

The toy engine runs the reduced engine at an rtol of its own: this tests the plumbing, and its
result is checked against the reduced engine run directly."""

from __future__ import annotations

import argparse
import sys
import textwrap

import pytest

import loopcheck
from loopcheck import registry
from loopcheck.format_reference import tables
from loopcheck.scene import SceneError
from loopcheck.scenefile import scene_from_dict
from loopcheck.settings import add_flags, given_flags

from helpers import seed_dict

SETTINGS = '''
from dataclasses import dataclass

from loopcheck.settings import option


@dataclass(frozen=True)
class Settings:
    rtol: float = option(1e-10, "the reduced engine's rtol, as this toy engine asks for it", "number")

    def __post_init__(self):
        if not self.rtol < 0.1:
            raise ValueError(f"rtol must be below 0.1, got {self.rtol!r}")
'''

ENGINE = '''
from loopcheck.reduced import ReducedSettings, simulate as _reduced


def simulate(scene, settings):
    return _reduced(scene, ReducedSettings(rtol=settings.rtol))
'''


@pytest.fixture
def toy_engine(tmp_path, monkeypatch):
    package = tmp_path / "toy_engine"
    package.mkdir()
    (package / "settings.py").write_text(textwrap.dedent(SETTINGS), encoding="utf-8")
    (package / "__init__.py").write_text(textwrap.dedent(ENGINE), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    engine = registry.Engine("toy", "toy_engine", "a toy engine: the reduced engine at its own rtol")
    monkeypatch.setitem(registry.ENGINES, "toy", engine)  # the one line a new engine adds
    yield engine
    for name in [m for m in sys.modules if m.startswith("toy_engine")]:
        del sys.modules[name]


def test_its_scene_table_is_read_and_checked(toy_engine):
    data = seed_dict()
    data["toy"] = {"rtol": 1e-9}
    assert scene_from_dict(data).engine_table("toy") == {"rtol": 1e-9}
    data["toy"] = {"rtol": "tight"}
    with pytest.raises(SceneError, match="'toy.rtol' must be a number, got a string"):
        scene_from_dict(data)
    data["toy"] = {"atol": 1e-9}
    with pytest.raises(SceneError, match="unknown key 'toy.atol'"):
        scene_from_dict(data)


def test_its_flags_and_reference_come_from_its_settings(toy_engine):
    parser = argparse.ArgumentParser()
    add_flags(parser, toy_engine.settings, title="toy", table="toy")
    assert given_flags(parser.parse_args(["--rtol", "1e-8"]), toy_engine.settings) == {"rtol": 1e-8}
    assert "| `toy.rtol` | positive number |" in tables()


def test_loopcheck_simulate_runs_it(toy_engine):
    scene = loopcheck.load_scene("seed_fourbar")
    result = loopcheck.simulate(scene, toy_engine.settings(rtol=1e-9))
    direct = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-9))
    assert result.trajectory.q.tobytes() == direct.trajectory.q.tobytes()
    assert registry.engine_of(toy_engine.settings()) is toy_engine
