"""Every script in examples/ runs as a user would run it, from another folder, and prints what
its docstring promises. Oracles: the seed's peak against the regression fixture recorded by the
numba core (tests/data), the damper family's peaks falling as damping grows (the physics: more
dissipation during the pulse), the energy balance of the free swing."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from helpers import DATA, ROOT

EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
SEED_PEAK = json.loads((DATA / "numba_core_outputs.json").read_text())["runs"][
    "seed_fourbar.toml:dop853"]["peak_omega"]


def run(name: str, tmp_path, *args: str) -> str:
    done = subprocess.run([sys.executable, str(ROOT / "examples" / name), *args], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_there_are_three_to_five_examples_each_with_a_docstring():
    assert 3 <= len(EXAMPLES) <= 5
    for path in EXAMPLES:
        assert path.read_text().startswith('"""'), path.name


def test_seed(tmp_path):
    out = run("seed.py", tmp_path)
    reduced = float(re.search(r"reduced ([0-9.]+) rad/s", out).group(1))
    assert reduced == pytest.approx(SEED_PEAK, abs=1e-8)  # printed to 8 decimals
    assert "gate passed" in out


def test_linkage_in_python(tmp_path):
    out = run("linkage_in_python.py", tmp_path)
    assert float(re.search(r"energy residual ([0-9.e+-]+)", out).group(1)) < 1e-8


def test_damper_sweep(tmp_path):
    peaks = [float(p) for p in re.findall(r"peak ([0-9.]+) rad/s", run("damper_sweep.py", tmp_path))]
    assert len(peaks) == 5 and all(a > b for a, b in zip(peaks, peaks[1:]))
    assert peaks[2] == pytest.approx(SEED_PEAK, abs=1e-6)  # 55 N·s/m is the seed itself


@pytest.mark.slow  # ~4 s: the example runs `loopcheck run` on the seed, plots included, in a subprocess
def test_read_report(tmp_path):
    out = run("read_report.py", tmp_path, str(tmp_path / "seed"))
    assert "exited 0" in out and "gate passed: True" in out
    assert (tmp_path / "seed" / "report.json").is_file()
