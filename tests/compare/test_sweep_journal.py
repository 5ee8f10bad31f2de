"""The journal of a sweep's finished rows (loopcheck.compare.sweep_journal), checked, never trusted.

``sweep --resume`` keeps the longest prefix of rows that check (complete lines, the sweep's
columns, every cell readable, index k and variant k's values) and runs the rest again, with one
warning naming the journal; the journal is locked while a sweep holds it (a second one is refused
in one line); a sweep is refused (exit 2, one line) when a journal of an interrupted run is
beside its --out and neither --resume nor --restart is given, when the journal is of another
sweep (its identity covers the scene data and the specification) and when its first line is not
this project's journal header.

The journals are real ones (a 7-variant reduced-only sweep of the short seed, interrupted before
its last variant) and mutations of them: duplicated, swapped, missing, cut, interleaved (two
writers), out-of-range and damaged rows, and 40 random splices checked against an oracle (row k
is kept only where the first k lines are the true rows). Plants that fail here: a cut last line
taken as a row (no line-end check); the identity without the spec, or without the scene data;
no flock; a rerun without --resume overwriting the journal (the old behaviour)."""

from __future__ import annotations

import fcntl
import random
import warnings
from dataclasses import replace

import pytest

from loopcheck.compare import sweep as sweep_module
from loopcheck.compare.cli import main
from loopcheck.compare.sweep_journal import Journal, journal_path
from loopcheck.compare.sweep_scene import load_sweep
from loopcheck.compare.sweep_table import CSV_FILE, read_rows
from loopcheck.sweep_spec import Engines, spec_from_args

from helpers import plots_left_out, short_seed_file, spawn  # noqa: F401 - fixture

VARY = ["--vary", "dampers.0.coefficient=40:60:7", "--engines", "reduced", "--workers", "1"]
N = 7


def _no_wall(rows):
    return [{k: v for k, v in r.items() if "wall_s" not in k} for r in rows]


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The scene, the reference rows (an uninterrupted sweep), and the journal lines of the same
    sweep interrupted before its last variant: header, column line, rows 0..5, and row 6 from
    the reference (as the journal writes it)."""
    folder = tmp_path_factory.mktemp("journal")
    scene = short_seed_file(folder)
    with plots_left_out(), pytest.MonkeyPatch.context() as patch:
        assert main(["sweep", str(scene), "--out", str(folder / "ref"), *VARY]) == 0
        real = sweep_module.run_variant

        def interrupted(index, *args, **kwargs):
            if index == N - 1:
                raise KeyboardInterrupt
            return real(index, *args, **kwargs)

        patch.setattr(sweep_module, "run_variant", interrupted)
        assert main(["sweep", str(scene), "--out", str(folder / "cut"), *VARY]) == 130
    lines = journal_path(folder / "cut").read_bytes().splitlines(keepends=True)
    assert len(lines) == 2 + N - 1 and lines[0].startswith(b"# loopcheck sweep journal ")
    last = (folder / "ref" / CSV_FILE).read_bytes().splitlines()[-1] + b"\n"
    return {"scene": scene, "ref": list(read_rows(folder / "ref" / CSV_FILE)), "head": lines[:2],
            "rows": lines[2:] + [last]}


@pytest.fixture
def resume(made, tmp_path, capsys, monkeypatch):
    """resume(body, *flags): a sweep into tmp_path/sw over a journal of ``made``'s header and
    ``body``; returns (status, printed, stderr, the variants run)."""
    ran = []
    real = sweep_module.run_variant

    def recorded(index, *args, **kwargs):
        ran.append(index)
        return real(index, *args, **kwargs)

    monkeypatch.setattr(sweep_module, "run_variant", recorded)

    def run(body: bytes | None, *flags, head: bytes | None = None):
        if body is not None:
            journal_path(tmp_path / "sw").write_bytes((b"".join(made["head"]) if head is None else head) + body)
        ran.clear()
        with plots_left_out():
            status = main(["sweep", str(made["scene"]), "--out", str(tmp_path / "sw"), *VARY, *flags])
        captured = capsys.readouterr()
        return status, captured.out, captured.err, list(ran)

    return run


def _warned_once(err, path):
    lines = [line for line in err.splitlines() if line.startswith("loopcheck: warning:") and str(path) in line]
    assert len(lines) == 1 and "discarded" in lines[0], err
    assert "Traceback" not in err and "invalid literal" not in err


@pytest.mark.parametrize("order, kept", [
    ([0, 1, 1, 2, 3], 2),  # a duplicated row
    ([0, 2, 1, 3], 1),  # swapped rows
    ([0, 1, 3, 4], 2),  # a missing row
    ([0, 1, 0, 2, 1, 3, 2], 2),  # two resumes appending at once (the 74 twice, 74 never)
    ([0, 1, 2, 3, 4, 5, 6, 6], 7),  # a row after the last variant
], ids=["duplicate", "swapped", "missing", "concurrent", "beyond-the-last"])
def test_rows_out_of_order_keep_the_prefix_that_checks(order, kept, made, resume, tmp_path):
    status, printed, err, ran = resume(b"".join(made["rows"][i] for i in order), "--resume")
    assert status == 0, err
    assert ran == list(range(kept, N))
    _warned_once(err, journal_path(tmp_path / "sw"))
    assert _no_wall(read_rows(tmp_path / "sw" / CSV_FILE)) == _no_wall(made["ref"])
    assert not journal_path(tmp_path / "sw").exists()


def test_a_line_cut_by_a_kill_is_not_a_row(made, resume, tmp_path):
    """Row 4's line cut inside its last cell (variant_wall_s, still a number) with no line end, as
    a kill during the write leaves it: it runs again. (Planted: without the line-end check it is
    kept and variants 5, 6 alone run.)"""
    cut = made["rows"][4].rstrip(b"\n")[:-3]
    assert cut.count(b",") == made["rows"][4].count(b",")  # every cell there, the last one shorter
    status, _, err, ran = resume(b"".join(made["rows"][:4]) + cut, "--resume")
    assert status == 0, err
    assert ran == [4, 5, 6]
    rows = list(read_rows(tmp_path / "sw" / CSV_FILE))
    assert _no_wall(rows) == _no_wall(made["ref"])
    _warned_once(err, journal_path(tmp_path / "sw"))


def _replace_cell(line: bytes, column: int, text: bytes) -> bytes:
    cells = line.rstrip(b"\n").split(b",")
    cells[column] = text
    return b",".join(cells) + b"\n"


@pytest.mark.parametrize("damage", [
    lambda line: _replace_cell(line, 0, b"x"),  # the index: never "invalid literal for int()"
    lambda line: _replace_cell(line, 0, b"9"),  # an index out of range, the values variant 3's
    lambda line: _replace_cell(line, 3, b"45.5"),  # another variant's value
    lambda line: _replace_cell(line, 4, b"nan"),  # a figure not finite
    lambda line: _replace_cell(line, 4, b"fast"),  # a figure not a number
    lambda line: _replace_cell(line, 1, b"great"),  # no such status
    lambda line: line[:10] + b"\xff\xfe" + line[10:],  # not UTF-8
    lambda line: line.rstrip(b"\n") + b",1\n",  # a cell too many
], ids=["index", "index-number", "value", "nan", "text", "status", "bytes", "cells"])
def test_a_damaged_row_is_one_warning_and_runs_again(damage, made, resume, tmp_path):
    status, _, err, ran = resume(b"".join(made["rows"][:3]) + damage(made["rows"][3]) + made["rows"][4], "--resume")
    assert status == 0, err
    assert ran == [3, 4, 5, 6]
    _warned_once(err, journal_path(tmp_path / "sw"))
    assert _no_wall(read_rows(tmp_path / "sw" / CSV_FILE)) == _no_wall(made["ref"])


def test_a_damaged_column_line_discards_every_row(made, resume, tmp_path):
    head = made["head"][0] + made["head"][1].replace(b"index", b"indx")
    status, _, err, ran = resume(b"".join(made["rows"][:3]), "--resume", head=head)
    assert status == 0 and ran == list(range(N)), err
    _warned_once(err, journal_path(tmp_path / "sw"))


def test_fuzzed_journals_keep_exactly_the_rows_an_oracle_keeps(made, tmp_path):
    """40 journals spliced at random from whole and cut true rows (fixed seed). The oracle: the
    first k lines equal to the true rows 0..k-1 are kept; replayed, then the journal holds just
    them, and a warning names the journal exactly when something was discarded."""
    data, _ = load_sweep(str(made["scene"]))
    spec = replace(spec_from_args(["dampers.0.coefficient=40:60:7"]), engines=Engines.REDUCED)
    good, head = made["rows"], b"".join(made["head"])
    rng = random.Random(20261128)
    out = tmp_path / "sw"
    for trial in range(40):
        pieces = []
        for _ in range(rng.randint(0, 10)):
            line = good[rng.choice([rng.randrange(N), min(len(pieces), N - 1)])]
            pieces.append(line if rng.random() < 0.8 else line[:rng.randrange(1, len(line))])
        body = b"".join(pieces)
        journal_path(out).write_bytes(head + body)
        lines = body.splitlines(keepends=True)
        k = 0
        while k < min(len(lines), N) and lines[k] == good[k]:
            k += 1
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            journal = Journal(out, data, spec, resume=True)
            rows = list(journal.replay())
            journal.close(False)
        assert [r["index"] for r in rows] == list(range(k)), (trial, body)
        assert journal.kept == k
        assert len(said) == (1 if len(body) > len(b"".join(good[:k])) else 0), (trial, body, said)
        if said:
            assert str(journal_path(out)) in str(said[0].message)
        if k:
            assert journal_path(out).read_bytes() == head + b"".join(good[:k])


# -- refusals -------------------------------------------------------------------------------

def test_a_rerun_without_resume_is_refused_and_keeps_the_rows(made, resume, tmp_path):
    """The issue: a rerun without --resume emptied the journal at once (232 rows, 18 left after a
    Ctrl-C one second later). Now it is refused before any work, naming both flags, and
    --restart discards the rows."""
    body = b"".join(made["rows"][:5])
    status, printed, err, ran = resume(body)
    assert status == 2 and printed == "" and ran == [] and err.count("\n") == 1, err
    assert "--resume" in err and "--restart" in err and str(journal_path(tmp_path / "sw")) in err
    assert journal_path(tmp_path / "sw").read_bytes() == b"".join(made["head"]) + body
    assert not (tmp_path / "sw").exists()
    status, _, err, ran = resume(None, "--restart")
    assert status == 0 and ran == list(range(N)), err
    assert not journal_path(tmp_path / "sw").exists()


@pytest.mark.parametrize("first", [b"index,status,reason\n", b"# another tool's sweep journal 0123\n", b"\xff\n"],
                         ids=["a-csv", "another-header", "not-text"])
@pytest.mark.parametrize("flags", [("--resume",), (), ("--restart",)], ids=["resume", "plain", "restart"])
def test_a_file_that_is_not_this_projects_journal_is_refused(first, flags, made, resume, tmp_path):
    body = b"".join(made["rows"][:3])
    status, printed, err, ran = resume(body, *flags, head=first)
    assert status == 2 and printed == "" and ran == [] and err.count("\n") == 1, err
    assert "is not a loopcheck sweep journal" in err and str(journal_path(tmp_path / "sw")) in err
    assert journal_path(tmp_path / "sw").read_bytes() == first + body  # left as it was


@pytest.mark.parametrize("other", [
    ["--vary", "dampers.0.coefficient=40:60:6"],  # the spec's values
    ["--vary", "torque.value=40:60:7"],  # the spec's key
    ["--engines", "both"],  # the spec's engines
    "scene",  # the scene's own settings
], ids=["values", "key", "engines", "scene-settings"])
def test_a_journal_of_another_sweep_is_refused(other, made, tmp_path, capsys):
    """The journal's identity covers the sweep's specification and the scene data. (Planted: an
    identity of the scene data alone passes the first three; of the spec alone, the last.)"""
    journal_path(tmp_path / "sw").write_bytes(b"".join(made["head"] + made["rows"][:3]))
    scene, args = made["scene"], list(VARY)
    if other == "scene":
        scene = tmp_path / "rtol.toml"
        scene.write_text(made["scene"].read_text() + "\n[reduced]\nrtol = 1e-10\n")
    elif other[0] == "--engines":
        args[args.index("--engines") + 1] = other[1]
    else:
        args[:2] = other
    status = main(["sweep", str(scene), "--out", str(tmp_path / "sw"), *args, "--resume"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "journal of another sweep" in err, err
    assert "--restart" in err


def test_a_journal_in_use_is_refused_in_one_line(made, resume, tmp_path):
    """A second sweep into the same folder while the first holds the journal (its flock): refused,
    with or without --resume; the kernel's lock goes with the process that held it."""
    body = b"".join(made["rows"][:3])
    journal_path(tmp_path / "sw").write_bytes(b"".join(made["head"]) + body)
    with open(journal_path(tmp_path / "sw"), "rb") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        for flags in (("--resume",), ("--restart",)):
            status, printed, err, ran = resume(None, *flags)
            assert status == 2 and printed == "" and ran == [] and err.count("\n") == 1, err
            assert "is in use by another loopcheck sweep" in err
    status, _, err, ran = resume(None, "--resume")  # released
    assert status == 0 and ran == [3, 4, 5, 6], err


def test_resume_and_restart_together_are_refused(resume):
    status, printed, err, ran = resume(None, "--resume", "--restart")
    assert status == 2 and ran == [] and "--resume and --restart" in err and err.count("\n") == 1, err


CHILD = """
import os, sys, time
from loopcheck.compare import sweep as sweep_module
from loopcheck.compare.cli import main
marker = sys.argv[1]
def run(index, *args, **kwargs):
    if index == 3:
        open(marker, "w").close()
        time.sleep(60)
    return real(index, *args, **kwargs)
real, sweep_module.run_variant = sweep_module.run_variant, run
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.timeout(120)
def test_a_sweep_running_in_another_process_holds_its_journal_until_it_dies(made, resume, tmp_path, spawn):
    """A real second process: while it runs (at variant 3, rows 0-2 journaled) a resume here is
    refused in one line; once it is killed (SIGKILL: no clean-up of its own) the kernel has
    released the lock and the resume runs variants 3-6 only."""
    import os
    import signal
    import sys
    import time

    from helpers import ROOT

    marker = tmp_path / "at-3"
    child = spawn([sys.executable, "-c", CHILD, str(marker), "sweep", str(made["scene"]), "--out",
                   str(tmp_path / "sw"), *VARY], cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)},
                  stdout=-1, stderr=-1)
    deadline = time.monotonic() + 60
    while not marker.exists() and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert marker.exists(), child.communicate(timeout=5)
    status, printed, err, ran = resume(None, "--resume")
    assert status == 2 and ran == [] and "is in use by another loopcheck sweep" in err and err.count("\n") == 1, err
    os.kill(child.pid, signal.SIGKILL)
    child.wait(timeout=30)
    status, _, err, ran = resume(None, "--resume")
    assert status == 0 and ran == [3, 4, 5, 6], err
    assert _no_wall(read_rows(tmp_path / "sw" / CSV_FILE)) == _no_wall(made["ref"])


def test_a_monte_carlo_sweep_resumes_with_its_drawn_values_and_not_another_seed(made, tmp_path, capsys, monkeypatch):
    """The values of a Monte Carlo row are checked against the sample drawn again from the seed;
    a resume with another seed is another sweep."""
    mc = ["--vary", "dampers.0.coefficient=uniform(40, 60)", "--samples", "5", "--engines", "reduced",
          "--workers", "1"]
    out, real, ran = tmp_path / "mc", sweep_module.run_variant, []

    def interrupted_at_3(index, *args, **kwargs):
        ran.append(index)
        if index == 3 and len(ran) == 4:
            raise KeyboardInterrupt
        return real(index, *args, **kwargs)

    monkeypatch.setattr(sweep_module, "run_variant", interrupted_at_3)
    with plots_left_out():
        assert main(["sweep", str(made["scene"]), "--out", str(out), *mc, "--seed", "3"]) == 130
        assert main(["sweep", str(made["scene"]), "--out", str(out), *mc, "--seed", "4", "--resume"]) == 2
        assert "journal of another sweep" in capsys.readouterr().err
        ran.clear()
        assert main(["sweep", str(made["scene"]), "--out", str(out), *mc, "--seed", "3", "--resume"]) == 0
        assert ran == [3, 4]
        assert main(["sweep", str(made["scene"]), "--out", str(tmp_path / "ref"), *mc, "--seed", "3"]) == 0
    assert _no_wall(read_rows(out / CSV_FILE)) == _no_wall(read_rows(tmp_path / "ref" / CSV_FILE))
