"""The studies' process pool (loopcheck.compare.pool.ordered_map, used by ``loopcheck sweep`` and
``loopcheck cost``) with a worker killed from outside, as the OOM killer would: a real SIGKILL of a
real worker process (a task that kills its own process, once or every time, guarded by a marker
file in tmp_path). The pool notices the dead worker (its sentinel), runs its task once more on a
fresh worker, and a task whose worker dies twice becomes ``lost(item, reason)``: in a sweep, the
chunk's rows ``failed`` with "worker killed by signal 9" and exit status 1. A SIGTERM to the
group of a sweep whose worker was killed ends it. (Planted, each fails here: no retry (TRIES = 1);
the old multiprocessing.Pool (the map hangs: ended by the test's timeout); lost rows marked
"passed".)"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import time

import pytest

from loopcheck.compare import sweep as sweep_module
from loopcheck.compare.cli import main
from loopcheck.compare.pool import ordered_map
from loopcheck.compare.sweep_table import CSV_FILE, read_rows

from helpers import ROOT, plots_left_out, short_seed_file, spawn  # noqa: F401 - fixture

pytestmark = pytest.mark.skipif(multiprocessing.get_start_method() != "fork",
                                reason="the workers must inherit the planted task (forked)")


def _dies(arg):
    """Item 2 kills its own worker with SIGKILL: once (marker absent, then made) or every time."""
    marker, item, always = arg
    if item == 2 and (always or not os.path.exists(marker)):
        open(marker, "w").close()
        os.kill(os.getpid(), signal.SIGKILL)
    return item * 10


@pytest.mark.timeout(60)
def test_a_task_whose_worker_is_killed_runs_again_on_a_fresh_worker(tmp_path):
    marker = str(tmp_path / "killed")
    out = list(ordered_map(_dies, [(marker, i, False) for i in range(6)], 2,
                           lost=lambda item, reason: ("lost", item[1], reason)))
    assert out == [0, 10, 20, 30, 40, 50]
    assert os.path.exists(marker)  # the worker was killed


@pytest.mark.timeout(60)
def test_a_task_whose_worker_dies_twice_is_lost_with_its_signal(tmp_path):
    marker = str(tmp_path / "killed")
    out = list(ordered_map(_dies, [(marker, i, True) for i in range(5)], 2,
                           lost=lambda item, reason: ("lost", item[1], reason)))
    assert out == [0, 10, ("lost", 2, "worker killed by signal 9"), 30, 40]
    with pytest.raises(RuntimeError, match="worker killed by signal 9"):  # without lost: an error, not a hang
        list(ordered_map(_dies, [(marker, i, True) for i in range(3)], 2))


def _variant_killing_its_worker(marker, parent):
    """A run_variant whose variant 3 kills its worker process (never the parent: the sweep runs
    its first two variants itself), once when ``marker`` is absent, else every time."""
    real = sweep_module.run_variant

    def run(index, *args, **kwargs):
        if index == 3 and os.getpid() != parent and (marker is None or not os.path.exists(marker)):
            if marker is not None:
                open(marker, "w").close()
            os.kill(os.getpid(), signal.SIGKILL)
        return real(index, *args, **kwargs)
    return run


@pytest.mark.timeout(120)
@pytest.mark.parametrize("once", [True, False], ids=["killed-once", "killed-twice"])
def test_a_sweep_whose_worker_is_killed_finishes(once, tmp_path, capsys, monkeypatch):
    scene = short_seed_file(tmp_path)
    marker = tmp_path / "killed" if once else None
    monkeypatch.setattr(sweep_module, "run_variant", _variant_killing_its_worker(marker, os.getpid()))
    with plots_left_out():
        status = main(["sweep", str(scene), "--out", str(tmp_path / "sw"), "--vary", "torque.value=240:250:6",
                       "--engines", "reduced", "--workers", "2"])
    printed = capsys.readouterr().out
    rows = list(read_rows(tmp_path / "sw" / CSV_FILE))
    assert [r["index"] for r in rows] == list(range(6))
    if once:
        assert status == 0 and marker.exists(), printed
        assert [r["status"] for r in rows] == ["passed"] * 6
    else:
        assert status == 1, printed
        assert [r["status"] for r in rows] == ["passed"] * 3 + ["failed"] + ["passed"] * 2
        assert rows[3]["reason"] == "worker killed by signal 9" and rows[3]["reduced.peak_omega"] is None
        assert rows[3]["torque.value"] == 246.0
        assert "1 failed numerically" in printed


CHILD = """
import os, sys, time
from loopcheck.compare import sweep as sweep_module
from loopcheck.compare.cli import main
folder, parent = sys.argv[1], os.getpid()
def run(index, *args, **kwargs):
    if os.getpid() != parent:
        open(os.path.join(folder, f"worker-{os.getpid()}"), "w").close()
        time.sleep(60)
    return real(index, *args, **kwargs)
real, sweep_module.run_variant = sweep_module.run_variant, run
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.timeout(120)
def test_sigterm_to_the_group_ends_a_sweep_whose_worker_was_killed(tmp_path, spawn):
    """The issue's hang: a worker killed from outside, then SIGTERM to the sweep's process group."""
    scene = short_seed_file(tmp_path)
    pids = tmp_path / "pids"
    pids.mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = spawn([sys.executable, "-c", CHILD, str(pids), "sweep", str(scene), "--out", str(tmp_path / "sw"),
                  "--vary", "torque.value=240:250:8", "--engines", "reduced", "--workers", "2"],
                 cwd=tmp_path, env=env, start_new_session=True, stdout=-1, stderr=-1)
    deadline = time.monotonic() + 60
    while len(list(pids.iterdir())) < 2 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    workers = [int(p.name.split("-")[1]) for p in pids.iterdir()]
    assert len(workers) == 2, proc.communicate(timeout=5)
    os.kill(workers[0], signal.SIGKILL)
    deadline = time.monotonic() + 30  # its chunk is given to a fresh worker (a third pid)
    while len(list(pids.iterdir())) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(list(pids.iterdir())) == 3
    began = time.monotonic()
    os.killpg(proc.pid, signal.SIGTERM)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 143 and err.decode().endswith("loopcheck: terminated\n"), err
    assert time.monotonic() - began < 10
    assert not (tmp_path / "sw").exists()


@pytest.mark.timeout(60)
def test_a_cost_configuration_whose_worker_dies_twice_is_failed(tmp_path, monkeypatch):
    """``loopcheck cost``'s pool: the configuration measured in a worker killed twice is a
    measurement of status ``failed`` whose message is the signal; the others are measured."""
    from loopcheck.compare import cost
    from loopcheck.scenefile import load_scene

    from helpers import SEED_SCENE

    configs = cost.ladder(load_scene(SEED_SCENE), quick=True)[:4]
    parent = os.getpid()

    def measure(scene, config, truth, repeats):
        if config == configs[2] and os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
        return cost.Measurement(config, status="ok", verdict=cost.Verdict.PASS)

    monkeypatch.setattr(cost, "measure", measure)
    got = cost.sweep(None, configs, cost.Truth(None, 0.0), repeats=1, workers=2)
    assert [m.config for m in got] == configs
    assert [m.status for m in got] == ["ok", "ok", "failed", "ok"]
    assert got[2].message == "worker killed by signal 9"
