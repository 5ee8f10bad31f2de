"""The engine contract: an engine installed by another distribution, declared by one entry point in
the ``loopcheck.engines`` group, reaches ``loopcheck check --engines``, ``loopcheck run --engines``
and ``loopcheck.check(scene, engines=[...])`` with no other edit.

The fake engine is a package written here (a ``settings`` module with one option, and a
``simulate``) and a distribution's metadata (a ``.dist-info`` folder with ``METADATA`` and
``entry_points.txt``) on a temporary folder of ``sys.path`` / ``PYTHONPATH``: what ``pip install``
leaves, without pip. It runs the reduced engine at an rtol of its own and names the result
``fake``, so its verdict is known: it passes the seed's gate by orders of magnitude (the reduced
engine at rtol 1e-10 against itself at 1e-12: |Δ peak| ~1e-9 of a 1e-4 tolerance)."""

from __future__ import annotations

import dataclasses
import importlib
import json
import os
import subprocess
import sys
import textwrap
import tomllib

import pytest

import loopcheck
from loopcheck import registry
from loopcheck.reduced import ReducedSettings, simulate as simulate_reduced

from helpers import ROOT, SEED_SCENE

SHORT = "0.2"  # s: the seed's horizon cut (the plumbing is the subject)

SETTINGS = '''
"""A fake engine: the reduced engine's run under another name."""

from dataclasses import dataclass

from loopcheck.settings import option


@dataclass(frozen=True)
class Settings:
    rtol: float = option(1e-10, "the reduced engine's rtol, as the fake engine asks for it", "number")
'''

ENGINE = '''
from dataclasses import replace

from loopcheck.reduced import ReducedSettings, simulate as _reduced


def simulate(scene, settings):
    return replace(_reduced(scene, ReducedSettings(rtol=settings.rtol)), engine="fake", settings=settings)
'''


def install(folder, entry: str = "fake = fake_engine", dist: str = "fake_engine"):
    """The package and a distribution declaring ``entry`` in loopcheck's group, under ``folder``."""
    package = folder / "fake_engine"
    package.mkdir(exist_ok=True)
    (package / "settings.py").write_text(textwrap.dedent(SETTINGS), encoding="utf-8")
    (package / "__init__.py").write_text(textwrap.dedent(ENGINE), encoding="utf-8")
    info = folder / f"{dist}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n", encoding="utf-8")
    (info / "entry_points.txt").write_text(f"[{registry.GROUP}]\n{entry}\n", encoding="utf-8")
    return folder


@pytest.fixture
def on_path(tmp_path, monkeypatch):
    """The fake distribution on sys.path; the registry's reading of the entry points; the modules
    it loads unloaded after."""
    install(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    yield tmp_path
    for name in [m for m in sys.modules if m.startswith("fake_engine")]:
        del sys.modules[name]


def _cli(args, folder, cwd):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(folder), str(ROOT), os.environ.get("PYTHONPATH")) if p)}
    return subprocess.run([sys.executable, "-m", "loopcheck.compare.cli", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


def test_the_built_ins_are_declared_in_pyproject():
    """pyproject.toml's entry points are the registry's built-in table (planted: a sixth line fails)."""
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"][registry.GROUP]
    assert declared == {e.name: e.package for e in registry.BUILT_IN}
    assert list(registry.ENGINES)[:5] == list(declared)


def test_an_installed_engine_is_registered_and_reaches_the_api(on_path, monkeypatch):
    found = registry.registered()
    assert list(found)[:5] == [e.name for e in registry.BUILT_IN] and found["fake"].package == "fake_engine"
    assert found["fake"].description == "A fake engine: the reduced engine's run under another name."
    monkeypatch.setitem(registry.ENGINES, "fake", found["fake"])  # as the registry reads it at import
    scene = dataclasses.replace(loopcheck.load_scene(SEED_SCENE), horizon=float(SHORT))
    checked = loopcheck.check(scene, engines=["reduced", "fake"])
    assert checked.engines == ("reduced", "fake") and checked.passed and checked.outlier is None
    c = checked.comparison("fake")
    assert c.other.engine == "fake" and c.other.settings == found["fake"].settings()
    direct = simulate_reduced(scene, ReducedSettings(rtol=1e-10))
    assert c.other.peak.omega == direct.peak.omega  # the fake engine's own run, bit for bit
    own = found["fake"].settings(rtol=1e-8)
    assert loopcheck.check(scene, ["reduced", "fake"], settings=[own]).comparison("fake").other.settings == own


@pytest.mark.parametrize("entry, message", [
    ("Fake-1 = fake_engine", "entry point 'Fake-1 = fake_engine' of bad_dist .loopcheck.engines.: engine name 'Fake-1'"),
    ("fake = fake_engine:simulate", "'fake_engine:simulate' is not a package name"),
    ("mujoco = fake_engine", "the engine 'mujoco' is loopcheck.reference_models's"),
])
def test_a_bad_declaration_is_refused_in_one_line_naming_the_distribution(tmp_path, monkeypatch, entry, message):
    install(tmp_path, entry, dist="bad_dist")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    with pytest.raises(ValueError, match=message):
        registry.registered()


@pytest.mark.slow  # three fresh processes (~2 s each): the subprocess is what shows an installed distribution
def test_an_installed_engine_reaches_check_and_run_engines(tmp_path):
    """In a fresh process, the distribution on PYTHONPATH is all it takes: `check --engines
    reduced,fake` judges it, `run --engines reduced,fake` writes its CSV and verdict; without the
    distribution the same command refuses the name (exit 2), and a distribution declaring an engine
wrongly stops every command in one line naming it (exit 2)."""
    (tmp_path / "site").mkdir()
    folder = install(tmp_path / "site")
    done = _cli(["check", str(SEED_SCENE), "--engines", "reduced,fake", "--horizon", SHORT], folder, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert any(line.startswith("      fake     ok  ") for line in done.stdout.splitlines()), done.stdout
    assert done.stdout.rstrip().endswith("1 passed, 0 failed")
    out = tmp_path / "out"
    done = _cli(["run", str(SEED_SCENE), "--engines", "reduced,fake", "--horizon", SHORT, "-o", str(out)], folder, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["other_engine"] == "fake" and [e["engine"] for e in report["engines"]] == ["fake"]
    assert report["engines"][0]["passed"] is True and (out / "fake.csv").is_file()
    bare = _cli(["check", str(SEED_SCENE), "--engines", "reduced,fake"], tmp_path / "empty", tmp_path)
    assert bare.returncode == 2 and "unknown engine 'fake'" in bare.stderr and not bare.stdout
    (tmp_path / "bad").mkdir()
    bad = install(tmp_path / "bad", "Fake = fake_engine", dist="bad_dist")  # one line, exit 2, no traceback
    done = _cli(["check", str(SEED_SCENE)], bad, tmp_path)
    assert done.returncode == 2 and not done.stdout and done.stderr.splitlines() == [
        "loopcheck: entry point 'Fake = fake_engine' of bad_dist (loopcheck.engines): engine name 'Fake': lower-case "
        "letters, digits and _, a letter first"], done.stderr


def test_an_installed_engine_has_its_own_command(on_path, monkeypatch, capsys):
    """`loopcheck fake` exists by registration alone: its flag from its Settings, its title from its
    docstring, and the lines every run has (no lines of its own declared); its label, colour and
    report name are the registry's defaults (planted: the engines' commands listed by name in the
    CLI, as before the registry, leave `fake` an invalid choice, exit 2)."""
    from loopcheck.compare import cli
    from loopcheck.compare.plots import engine_colour
    from loopcheck.compare.report import output_name
    from loopcheck.compare.text import engine_label

    fake = registry.registered()["fake"]
    monkeypatch.setitem(registry.ENGINES, "fake", fake)  # as the registry reads it at import
    assert cli.main(["fake", "--help"]) == 0
    shown = " ".join(capsys.readouterr().out.split())
    assert "--rtol RTOL" in shown and "A fake engine: the reduced engine's run under another name." in shown
    assert cli.main(["fake", str(SEED_SCENE), "--rtol", "1e-9"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == ["scene", "input", "effects", "settings", "peak", "energy", "cost"]
    assert lines[3].split() == ["settings", "DOP853", "rtol=1e-09"]
    peak = simulate_reduced(loopcheck.load_scene(SEED_SCENE), ReducedSettings(rtol=1e-9)).peak.omega
    assert lines[4].split()[2] == f"{peak:+.10g}"
    assert engine_label("fake") == output_name("fake") == "fake"
    assert engine_colour("fake") not in {e.colour for e in registry.BUILT_IN}
