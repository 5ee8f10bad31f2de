"""The fake engine of tests/compare/test_fake_engine.py, installed for the test, reaches ``loopcheck
stress --engines reduced,fake`` and ``loopcheck sweep --sensitivity-engines reduced,fake`` as commands,
with no other edit (issue 39). Not in CI's optional-engines job: its subprocesses run the checkout's
loopcheck, which finds the shipped scenes (``--case``) through the editable install of the main venv.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from helpers import ROOT, SEED_SCENE
from test_fake_engine import install

SHORT = 0.2  # s: the seed's first 0.2 s


def _short_seed(folder) -> str:
    text = SEED_SCENE.read_text().replace("horizon = 2.0 ", f"horizon = {SHORT} ")
    assert f"horizon = {SHORT} " in text
    path = folder / "seed_short.toml"
    path.write_text(text, encoding="utf-8")
    return str(path)


def _cli(args, folder, cwd):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(folder), str(ROOT), os.environ.get("PYTHONPATH"))
                                                       if p)}
    return subprocess.run([sys.executable, "-m", "loopcheck.compare.cli", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


@pytest.mark.slow  # three fresh processes (~2 s each): the subprocess is what shows an installed distribution
def test_the_fake_engine_reaches_stress_and_sensitivity_as_commands(tmp_path):
    """``loopcheck stress --engines reduced,fake --case dead_centre`` runs it beside the reference and
    judges it (the fake engine is the reduced one at rtol 1e-10: it passes); the sensitivity refuses
    it in one line while it declares no peak accuracy (exit 2, nothing written), and prints its own
    d(peak)/dp beside the reference's once it declares one."""
    (tmp_path / "site").mkdir()
    folder = install(tmp_path / "site")
    out = tmp_path / "stress"
    done = _cli(["stress", "--engines", "reduced,fake", "--case", "dead_centre", "--out", str(out)], folder, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].split()[:3] == ["case", "reduced", "fake"]
    assert lines[1].split()[:3] == ["dead_centre", "ok", "ok"] and lines[1].endswith("PASS")
    case = json.loads((out / "stress.json").read_text())["cases"][0]
    assert case["engines"]["fake"]["status"] == "ok" and case["engines"]["fake"]["figures"]["peak_omega_rel"] < 1e-6

    scene = _short_seed(tmp_path)
    sweep = ["sweep", scene, "--vary", "dampers.0.coefficient=50,60", "--sensitivity-engines", "reduced,fake",
             "--workers", "1", "--out"]
    done = _cli([*sweep, str(tmp_path / "refused")], folder, tmp_path)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip().splitlines() == [
        "loopcheck: error: engine 'fake' declares no peak accuracy (peak_accuracy(settings) in fake_engine.settings), "
        "which sensitivity needs to choose its steps"]
    assert not (tmp_path / "refused").exists()
    with open(folder / "fake_engine" / "settings.py", "a", encoding="utf-8") as f:
        f.write("\n\ndef peak_accuracy(settings):\n    return 10.0 * settings.rtol\n")
    done = _cli([*sweep, str(tmp_path / "sensitivity")], folder, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    rows = [line.split() for line in done.stdout.splitlines() if line.split()[:1] in (["dampers.0.coefficient"],
                                                                                      ["fake"])]
    assert [row[0] for row in rows] == ["dampers.0.coefficient", "fake"] and rows[0][1] == "reduced"
    recorded = json.loads((tmp_path / "sensitivity" / "sweep.json").read_text())["sensitivity"]
    reference, fake = recorded
    assert (reference["engine"], fake["engine"]) == ("reduced", "fake")
    assert abs(fake["derivative"] - reference["derivative"]) <= fake["error"] + reference["error"]
