"""MJX failed part-way on the seed (its loops drift beyond the bound at t = 1.012 s, the missing
J̇·q̇ of docs/engines.md): its run travels with its failure, so that its known defect is printed
under its failure line, report.json carries it with the failure's time, and engines.png draws
MJX's |Δq̇| up to that time instead of saying it did not run. The engine-generic part (any engine's
run failed by its own gate) is tested with MuJoCo C in tests/compare/test_engines_check.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("jax", reason="the mjx engine's extra is not installed (pip install -e '.[mjx]' in loopcheck's checkout, then "
                    "mujoco-mjx: docs/engines.md)")
pytest.importorskip("mujoco.mjx", reason="MJX is not installed (pip install --no-deps mujoco-mjx: docs/engines.md)")

from loopcheck.compare.cli import main  # noqa: E402

from helpers import SEED_SCENE  # noqa: E402

pytestmark = pytest.mark.slow  # the seed's whole 2 s through MJX: one compile of a 2000-step scan


def test_mjx_failed_on_drift_keeps_its_defect_and_its_curve(tmp_path, capsys, saved_figures):
    out = tmp_path / "out"
    assert main(["run", str(SEED_SCENE), "--engines", "reduced,mujoco,mjx", "-o", str(out)]) == 1
    printed = capsys.readouterr().out.splitlines()
    at = next(k for k, line in enumerate(printed) if line.strip().startswith("mjx") and "constraint-drift" in line)
    assert printed[at + 1].strip().startswith("known defect: MJX 3.17.0 omits J̇·q̇")
    (entry,) = [e for e in json.loads((out / "report.json").read_text())["engines"] if e["engine"] == "mjx"]
    assert entry["known_defects"] and entry["known_defects"][0].startswith("MJX 3.17.0 omits J̇·q̇")
    assert entry["failed_at"] == pytest.approx(1.012, abs=0.01) and entry["failure"].startswith("numerical failure")
    engines = next(fig for fig in saved_figures if "each engine's input rate" in fig.axes[0].get_title())
    legend = [text.get_text() for text in engines.axes[0].get_legend().get_texts()]
    mjx = next(k for k, text in enumerate(legend) if text.startswith("MJX"))
    assert legend[mjx].startswith("MJX: FAILED at t = 1.01") and "did not run" not in legend[mjx]
    curves = [line for line in engines.axes[0].get_lines() if len(line.get_xdata()) > 2]
    t = np.asarray(curves[mjx].get_xdata())
    assert t[0] < 0.01 and entry["failed_at"] - 0.01 < t[-1] <= entry["failed_at"]
