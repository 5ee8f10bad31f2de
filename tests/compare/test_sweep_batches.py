"""A sweep's engines that run in batches (``loopcheck sweep --engines``, ``--batch-size``), shown with
engines written here: a batch engine (the reduced engine's run under another name, with a
``simulate_batch`` that records each batch it is given) registered in this process, and the fake
engine of test_fake_engine.py installed as a distribution for a subprocess.

No optional engine is needed: what is tested is the sweep's part (chunks of one structure, the
padding to the batch size, each variant's failure its own row, the rows equal to the variant-by-
variant rows). The ports' own batches are tests/compare/test_sweep_ports.py's."""

from __future__ import annotations

import importlib
import json
import re
import subprocess
import sys
import os
import textwrap

import pytest

from loopcheck import registry
from loopcheck.compare.cli import main
from loopcheck.compare.sweep_table import CSV_FILE, read_rows

from helpers import ROOT, SEED_SCENE, plots_left_out

BATCH_SETTINGS = '''
"""A batch engine: the reduced engine's run under another name, in batches."""

from dataclasses import dataclass

from loopcheck.settings import option


@dataclass(frozen=True)
class Settings:
    rtol: float = option(1e-10, "the reduced engine's rtol", "number")


BATCH_SIZE = 3
'''

BATCH_ENGINE = '''
from dataclasses import replace

from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.reduced import ReducedSettings, simulate as _reduced

batches = []  # the scenes of each batch it was given, by their damper coefficient
FAIL_AT = 45.0  # a variant with this damper coefficient fails, alone or in a batch


def _coefficient(scene):
    return scene.mechanism.dampers[0].coefficient


def simulate(scene, settings):
    if _coefficient(scene) == FAIL_AT:
        raise NumericalFailure(FailureReason.NON_FINITE, "planted failure of the batch engine", 0.0)
    return replace(_reduced(scene, ReducedSettings(rtol=settings.rtol)), engine="batchy", settings=settings)


def simulate_batch(scenes, settings, each=False):
    batches.append([_coefficient(s) for s in scenes])
    out = []
    for scene in scenes:
        try:
            out.append(simulate(scene, settings))
        except NumericalFailure as exc:
            if not each:
                raise
            out.append(exc)
    return out
'''

SHORT = re.sub(r"(?m)^horizon = 2\.0.*$", "horizon = 0.15", SEED_SCENE.read_text())
WALL = ("variant_wall_s",)


@pytest.fixture
def batchy(tmp_path, monkeypatch):
    """The batch engine, registered as ``batchy`` in this process; its module (to read its batches)."""
    package = tmp_path / "batchy_engine"
    package.mkdir()
    (package / "settings.py").write_text(textwrap.dedent(BATCH_SETTINGS))
    (package / "__init__.py").write_text(textwrap.dedent(BATCH_ENGINE))
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    monkeypatch.setitem(registry.ENGINES, "batchy", registry.Engine("batchy", "batchy_engine"))
    yield importlib.import_module("batchy_engine")
    for name in [m for m in sys.modules if m.startswith("batchy_engine")]:
        del sys.modules[name]


def _sweep(capsys, scene, out, *args):
    with plots_left_out():  # the rows are the subject
        status = main(["sweep", str(scene), "--out", str(out), "--workers", "1", *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _rows(out):
    return [{k: v for k, v in row.items() if not k.endswith("wall_s")} for row in read_rows(out / CSV_FILE)]


def test_batch_rows_equal_the_variant_by_variant_rows_with_padding_and_a_failure(batchy, tmp_path, capsys):
    """Seven variants, batches of 3: chunks of 3, 3 and 1 padded to 3 (the padding's results
    dropped); the variant that fails (damper 45) is its own failed row and its batch's other
    variants pass; every row equals the sweep's at --batch-size 1 (the pool's path, variant by
    variant). Planted: no padding (the last batch has 1 scene), a failure sinking its batch (rows
    1 and 2 fail too), a chunk built past a structure change: each fails here."""
    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    vary = ("--vary", "dampers.0.coefficient=[40, 45, 50, 55, 60, 65, 70]", "--engines", "reduced,batchy")
    status, printed, err = _sweep(capsys, scene, tmp_path / "b3", *vary)
    assert status == 1, printed + err  # the planted failure
    assert batchy.batches == [[40.0, 45.0, 50.0], [55.0, 60.0, 65.0], [70.0, 70.0, 70.0]]
    batched = _rows(tmp_path / "b3")
    assert [r["status"] for r in batched] == ["passed", "failed"] + ["passed"] * 5
    assert batched[1]["reason"] == "non-finite: planted failure of the batch engine"
    assert "batchy in batches of 3" in printed and "6 passed, 0 failed the gate, 1 failed numerically" in printed
    batchy.batches.clear()
    status, printed, _ = _sweep(capsys, scene, tmp_path / "b1", *vary, "--batch-size", "1")
    assert batchy.batches == [] and status == 1  # variant by variant: simulate, no batch
    assert _rows(tmp_path / "b1") == batched


def test_a_structure_change_closes_a_batch(batchy, tmp_path, capsys):
    """Variants of other step counts (the horizon varied) never share a batch: one batch each,
    padded (planted: a key without the horizon puts them in one batch)."""
    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    status, printed, err = _sweep(capsys, scene, tmp_path / "h", "--vary", "simulation.horizon=[0.1, 0.12]",
                                  "--engines", "reduced,batchy", "--batch-size", "2")
    assert status == 0, printed + err
    assert batchy.batches == [[55.0, 55.0], [55.0, 55.0]]
    assert [r["simulation.horizon"] for r in _rows(tmp_path / "h")] == [0.1, 0.12]


def test_a_batch_larger_than_the_device_holds_is_split_before_any_work(batchy, tmp_path, capsys):
    """The engine's batch_limit (what one batch of this structure may hold) splits the chunk:
    batches of 2, the last padded to 2 (planted: the limit ignored gives batches of 3)."""
    (tmp_path / "batchy_engine" / "__init__.py").open("a").write("\n\ndef batch_limit(scene, settings):\n    return 2\n")
    importlib.reload(batchy)
    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    status, printed, err = _sweep(capsys, scene, tmp_path / "l", "--vary", "dampers.0.coefficient=[50, 55, 60]",
                                  "--engines", "reduced,batchy")
    assert status == 0, printed + err
    assert batchy.batches == [[50.0, 55.0], [60.0, 60.0]]


def test_the_engines_list_is_checked_before_any_work(tmp_path, capsys):
    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    for engines, message in (("reduced,nosuch", "unknown engine 'nosuch'"),
                             ("mujoco", "must include 'reduced', the reference every engine is judged against"),
                             ("reduced,reduced", "an engine is named twice")):
        status = main(["sweep", str(scene), "--out", str(tmp_path / "x"), "--vary", "linkage.c2=[0.9, 1.0]",
                       "--engines", engines])
        captured = capsys.readouterr()
        assert status == 2 and message in captured.err and not captured.out, captured.err
        assert len(captured.err.strip().splitlines()) == 1
        assert not (tmp_path / "x").exists()


def _cli(args, folder, cwd):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(folder), str(ROOT), os.environ.get("PYTHONPATH"))
                                                       if p)}
    return subprocess.run([sys.executable, "-m", "loopcheck.compare.cli", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


@pytest.mark.slow  # a fresh process (~3 s): an installed distribution is what it shows
def test_an_installed_engine_reaches_sweep_engines(tmp_path):
    """The fake engine of test_fake_engine.py, installed and nothing else edited, is swept: its
    columns, its gate at its own tolerances, its peaks beside the reference's in sweep.json."""
    from test_fake_engine import install

    (tmp_path / "site").mkdir()
    folder = install(tmp_path / "site")
    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    out = tmp_path / "out"
    done = _cli(["sweep", str(scene), "--vary", "dampers.0.coefficient=[50, 60]", "--engines", "reduced,fake",
                 "--workers", "1", "-o", str(out)], folder, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.startswith("2 variants (1 worker, ") and "2 passed, 0 failed the gate" in done.stdout
    sweep = json.loads((out / "sweep.json").read_text())
    assert sweep["engines"] == ["reduced", "fake"] and sweep["schema_version"] == 1
    rows = sweep["rows"]
    assert [r["gate.passed"] for r in rows] == [True, True] and all(r["fake.peak_omega"] for r in rows)
    assert rows[0]["fake.peak_omega"] == pytest.approx(rows[0]["reduced.peak_omega"], rel=1e-8)  # rtol 1e-10 vs 1e-12
    assert sorted(p.name for p in out.iterdir()) == ["loopcheck-manifest.txt", "sweep.csv", "sweep.json", "sweep_peak_omega.png",
                                                     "sweep_worst_differences.png"]


def test_batch_size_where_nothing_batches_and_batches_on_dask_are_said_before_any_work(batchy, tmp_path, capsys):
    """--batch-size with no batch engine: one warning line, the sweep runs; --scheduler with a batch
    engine: refused in one line (exit 2), nothing written, no scheduler reached (planted: without the
    check the sweep connects, and fails only after its journal is opened)."""
    pytest.importorskip("distributed", reason="the distributed extra is not installed")
    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    status, printed, err = _sweep(capsys, scene, tmp_path / "w", "--vary", "dampers.0.coefficient=[50]",
                                  "--engines", "reduced", "--batch-size", "4")
    assert status == 0 and err.strip().splitlines() == [
        "loopcheck: warning: --batch-size 4: no engine of reduced runs in batches (none declares a batch size); the "
        "variants run one by one"], err
    status = main(["sweep", str(scene), "--out", str(tmp_path / "d"), "--vary", "dampers.0.coefficient=[50]",
                   "--engines", "reduced,batchy", "--scheduler", "tcp://127.0.0.1:9"])
    captured = capsys.readouterr()
    assert status == 2 and not captured.out and captured.err.strip().splitlines() == [
        "loopcheck: error: --scheduler runs engines variant by variant; batchy run in batches in this process: give "
        "--batch-size 1 with --scheduler"], captured.err
    assert not (tmp_path / "d").exists() and batchy.batches == []


def test_a_sweep_of_several_engines_in_batches_resumes_from_its_checked_journal(batchy, tmp_path, capsys,
                                                                              monkeypatch):
    """--engines reduced,mujoco,batchy (two judged engines: diff.ENGINE.* columns, list cells among
    them) interrupted at variant 4 of 6, in the chunk of variants 3..5: the journal holds rows
    0..2; the list cell of row 2 damaged makes it run again (one warning), and the rows are an
    uninterrupted sweep's
    Variant 1 (damper 45) fails in the batch engine: its row is failed, naming it, with MuJoCo's
    comparison kept (planted: a journal check blind to the engines' list columns keeps the
    damaged row; a judged engine's failure dropping the others' figures)."""
    import loopcheck.compare.sweep as sweep_module
    from loopcheck.compare.sweep_journal import journal_path

    scene = tmp_path / "short.toml"
    scene.write_text(SHORT)
    args = ("--vary", "dampers.0.coefficient=40:65:6", "--engines", "reduced,mujoco,batchy")
    status, printed, _ = _sweep(capsys, scene, tmp_path / "ref", *args)
    assert status == 1, printed
    assert "  batchy: 5 passed its gate, 0 failed it, 1 failed numerically" in printed
    reference = _rows(tmp_path / "ref")
    assert "diff.batchy.mode_mismatches" in reference[0] and "gate.mujoco.passed" in reference[0]
    failed = reference[1]
    assert failed["status"] == "failed" and failed["reason"] == "batchy: non-finite: planted failure of the batch engine"
    assert failed["gate.mujoco.passed"] is True and failed["gate.batchy.passed"] is None
    real = sweep_module.run_variant

    def interrupted(index, *a, **k):
        if index == 4:
            raise KeyboardInterrupt
        return real(index, *a, **k)

    monkeypatch.setattr(sweep_module, "run_variant", interrupted)
    status, _, _ = _sweep(capsys, scene, tmp_path / "cut", *args)
    assert status == 130
    journal = journal_path(tmp_path / "cut")
    lines = journal.read_bytes().splitlines(keepends=True)
    assert len(lines) == 2 + 3  # the interrupted chunk's rows were not written
    import csv
    import io

    columns = next(csv.reader([lines[1].decode()]))
    cell = columns.index("diff.batchy.mode_mismatches")
    row2 = next(csv.reader([lines[4].decode()]))
    assert json.loads(row2[cell]) == [0], row2[cell]  # a list: one mode, no mismatch
    row2[cell] = "7"  # a number where a list is written
    damaged = io.StringIO()
    csv.writer(damaged, lineterminator="\n").writerow(row2)
    journal.write_bytes(b"".join(lines[:4]) + damaged.getvalue().encode())
    ran = []
    monkeypatch.setattr(sweep_module, "run_variant", lambda index, *a, **k: ran.append(index) or real(index, *a, **k))
    batchy.batches.clear()
    status, printed, err = _sweep(capsys, scene, tmp_path / "cut", *args, "--resume")
    assert status == 1, printed + err
    assert ran == [2, 3, 4, 5] and batchy.batches == [[50.0, 55.0, 60.0], [65.0, 65.0, 65.0]]
    assert len([line for line in err.splitlines() if "discarded" in line]) == 1, err
    assert _rows(tmp_path / "cut") == reference
