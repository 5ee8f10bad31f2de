"""The output writer's guarantees (loopcheck/compare/output.py), each under the fault it is meant to survive.

Faults are real: exceptions raised by a writer part-way, a directory in the way, a second
process writing the same folder, SIGINT and SIGTERM sent to a process while it writes.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from loopcheck.compare import output
from loopcheck.compare.output import OutputError, Terminated, json_text, signals_as_exceptions, write_file, write_folder

from helpers import interruptible, spawn  # noqa: F401 - fixtures

NAMES = ("reduced.csv", "mujoco.csv", "plot.png", "report.json")


def snapshot(folder: Path) -> dict:
    """Every entry below ``folder`` (hidden ones included) with its kind and content."""
    out = {}
    for path in sorted(folder.rglob("*")):
        rel = str(path.relative_to(folder))
        out[rel] = ("link", os.readlink(path)) if path.is_symlink() else \
            ("dir", None) if path.is_dir() else ("file", path.read_bytes()) if path.is_file() else ("other", None)
    return out


def writers(tag: str, fail_at: str | None = None, error: BaseException | None = None) -> dict:
    """Files whose content is ``tag``; the writer of ``fail_at`` writes half a file, then raises."""
    def make(name):
        def write(path: Path):
            if name == fail_at:
                path.write_text(f"{tag} half")
                raise error
            path.write_text(f"{tag} {name}")
        return write
    return {name: make(name) for name in NAMES}


@pytest.fixture
def old_folder(tmp_path) -> Path:
    """An output folder holding an earlier run's complete set and a file of the user's."""
    out = tmp_path / "out"
    write_folder(out, writers("old"))
    (out / "notes.txt").write_text("mine")
    return out


def test_a_set_replaces_the_old_one_and_nothing_else(old_folder):
    write_folder(old_folder, writers("new"))
    assert snapshot(old_folder) == {**{n: ("file", f"new {n}".encode()) for n in NAMES},
                                    "notes.txt": ("file", b"mine")}
    assert [p.name for p in old_folder.parent.iterdir()] == ["out"]  # no staging left beside it


def test_an_out_folder_holds_one_run(tmp_path):
    """Issue 24: a mechanism.gif of an earlier run stayed beside a new report. The files the
    previous run's manifest lists and the new set lacks go; the user's files, a listed name
    that is now a folder or a link, and names that escape the folder stay."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere.txt"
    elsewhere.write_text("keep")
    write_folder(out, {**writers("old"), "mechanism.gif": lambda p: p.write_text("gif"),
                       "old.png": lambda p: p.write_text("png")}, one_run=True)
    assert (out / output.MANIFEST_FILE).read_text().splitlines() == [*NAMES, "mechanism.gif", "old.png"]
    (out / "notes.txt").write_text("mine")
    (out / "old.png").unlink()
    (out / "old.png").mkdir()  # listed, but now the user's folder
    with open(out / output.MANIFEST_FILE, "a") as f:  # a tampered manifest cannot reach outside
        f.write("../elsewhere.txt\nnotes.txt/\n\n")
    write_folder(out, writers("new"), one_run=True)
    assert snapshot(out) == {**{n: ("file", f"new {n}".encode()) for n in NAMES}, "notes.txt": ("file", b"mine"),
                             "old.png": ("dir", None), output.MANIFEST_FILE: ("file", "".join(
                                 f"{n}\n" for n in NAMES).encode())}
    assert elsewhere.read_text() == "keep"


def test_without_a_manifest_nothing_is_removed_and_a_failed_commit_puts_the_stale_file_back(tmp_path, monkeypatch):
    out = tmp_path / "out"
    write_folder(out, {**writers("old"), "mechanism.gif": lambda p: p.write_text("gif")})  # no manifest
    write_folder(out, writers("new"), one_run=True)
    assert (out / "mechanism.gif").read_text() == "gif"
    write_folder(out, {**writers("old"), "mechanism.gif": lambda p: p.write_text("gif"),
                       "old.png": lambda p: p.write_text("png")}, one_run=True)
    before = snapshot(out)
    real_replace = os.replace

    def failing_last(src, dst):  # the set swaps in, the GIF is set aside, then old.png's fails
        if Path(src) == out / "old.png":
            raise OSError(errno.EIO, "Input/output error")
        real_replace(src, dst)
    monkeypatch.setattr(output.os, "replace", failing_last)
    with pytest.raises(OSError, match="Input/output"):
        write_folder(out, writers("new"), one_run=True)
    monkeypatch.undo()
    assert snapshot(out) == before


@pytest.mark.parametrize("error", [RuntimeError("plot failed"), KeyboardInterrupt(), Terminated(),
                                   OSError(errno.ENOSPC, "No space left on device")],
                         ids=["exception", "ctrl-c", "sigterm", "disk-full"])
@pytest.mark.parametrize("fail_at", ["mujoco.csv", "report.json"])
def test_failure_while_writing_leaves_the_folder_as_it_was(old_folder, error, fail_at):
    """Issue 9, planted bug 3 (a failed run leaves a half-written folder)."""
    before = snapshot(old_folder.parent)
    with pytest.raises(type(error)):
        write_folder(old_folder, writers("new", fail_at, error))
    assert snapshot(old_folder.parent) == before


@pytest.mark.parametrize("error", [RuntimeError("plot failed"), KeyboardInterrupt(), Terminated(),
                                   OSError(errno.ENOSPC, "No space left on device")],
                         ids=["exception", "ctrl-c", "sigterm", "disk-full"])
@pytest.mark.parametrize("fail_at", ["reduced.csv", "mujoco.csv", "report.json"])
def test_writers_in_two_processes_fail_as_one(old_folder, error, fail_at):
    """write_folder(workers=2) runs every other writer in a forked child (mujoco.csv and
    report.json here): a failure on either side, whatever it raises, is raised here with its
    type and leaves the folder as it was; without one the set is the same as one process's."""
    before = snapshot(old_folder.parent)
    with pytest.raises(type(error)):
        write_folder(old_folder, writers("new", fail_at, error), workers=2)
    assert snapshot(old_folder.parent) == before
    write_folder(old_folder, writers("new"), workers=2)
    assert snapshot(old_folder) == {**{n: ("file", f"new {n}".encode()) for n in NAMES},
                                    "notes.txt": ("file", b"mine")}


def test_failure_while_writing_a_new_folder_creates_nothing(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        write_folder(tmp_path / "out", writers("new", "report.json", KeyboardInterrupt()))
    assert list(tmp_path.iterdir()) == []


def test_an_old_report_in_the_way_leaves_no_mix(old_folder):
    """A folder named report.json: refused before anything is replaced, whether it was there
    at the start or appeared while the files were being written."""
    (old_folder / "report.json").unlink()
    (old_folder / "report.json").mkdir()
    before = snapshot(old_folder)
    with pytest.raises(OutputError, match="report.json' is a folder"):
        write_folder(old_folder, writers("new"))
    assert snapshot(old_folder) == before

    (old_folder / "report.json").rmdir()
    (old_folder / "report.json").write_text("old report.json")
    before = snapshot(old_folder)
    files = writers("new")
    write_png = files["plot.png"]

    def obstacle_appears(path):  # another process puts a folder where report.json goes
        write_png(path)
        (old_folder / "report.json").unlink()
        (old_folder / "report.json").mkdir()
    files["plot.png"] = obstacle_appears
    with pytest.raises(OutputError, match="only regular files"):
        write_folder(old_folder, files)
    assert snapshot(old_folder) == {**before, "report.json": ("dir", None)}


def test_a_commit_failing_part_way_is_rolled_back(old_folder, monkeypatch):
    before = snapshot(old_folder.parent)
    real_replace, calls = os.replace, []

    def replace_failing_on_the_fifth(src, dst):
        calls.append(dst)
        if len(calls) == 5:  # after two files swapped in: 2 × (set aside old, move in new)
            raise OSError(errno.EIO, "Input/output error")
        real_replace(src, dst)
    monkeypatch.setattr(output.os, "replace", replace_failing_on_the_fifth)
    with pytest.raises(OSError, match="Input/output"):
        write_folder(old_folder, writers("new"))
    monkeypatch.undo()
    assert snapshot(old_folder.parent) == before


@pytest.mark.parametrize("existed", [True, False], ids=["into-a-folder", "a-new-folder"])
def test_an_interrupt_during_the_commit_undoes_it(old_folder, monkeypatch, interruptible, existed):
    """The commit is held against signals and undone when one came meanwhile: the folder is as
    it was (issue 24: every signal before the run's end leaves it so), then KeyboardInterrupt."""
    if not existed:
        old_folder = old_folder.parent / "fresh"
    before = snapshot(old_folder.parent)
    real_replace, real_rename = os.replace, os.rename

    def then_interrupt(real):
        def call(src, dst):
            real(src, dst)
            os.kill(os.getpid(), signal.SIGINT)
        return call
    monkeypatch.setattr(output.os, "replace", then_interrupt(real_replace))
    monkeypatch.setattr(output.os, "rename", then_interrupt(real_rename))
    with signals_as_exceptions(), pytest.raises(KeyboardInterrupt):
        write_folder(old_folder, writers("new"), one_run=True)
    monkeypatch.undo()
    assert snapshot(old_folder.parent) == before


@pytest.mark.parametrize("kind", ["symlink", "dangling symlink", "fifo", "device", "folder"])
def test_only_regular_files_are_replaced(tmp_path, kind):
    target = tmp_path / "model.xml"
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    if kind == "symlink":
        target.symlink_to(victim)
    elif kind == "dangling symlink":
        target.symlink_to(tmp_path / "nowhere")
    elif kind == "fifo":
        os.mkfifo(target)
    elif kind == "device":  # a null device of our own: a planted bug must not replace the real one
        if os.geteuid() != 0:
            pytest.skip("creating a device node needs root")
        os.mknod(target, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    else:
        target.mkdir()
    before = snapshot(tmp_path)
    with pytest.raises(OutputError, match="folder|only regular files"):
        write_file(target, "<mujoco/>")
    assert snapshot(tmp_path) == before
    if kind == "device":
        assert target.is_char_device()


def test_a_regular_file_is_replaced(tmp_path):
    (tmp_path / "model.xml").write_text("old")
    assert write_file(tmp_path / "model.xml", "<mujoco/>") == tmp_path / "model.xml"
    assert snapshot(tmp_path) == {"model.xml": ("file", b"<mujoco/>")}


def test_json_is_strict_and_paths_are_not_absolute(tmp_path, monkeypatch):
    text = json_text({"a": float("nan"), "b": [float("inf"), -float("inf"), 1.5], "c": (1, 2)})
    assert json.loads(text, parse_constant=lambda token: pytest.fail(f"bare {token} in JSON")) == \
        {"a": None, "b": [None, None, 1.5], "c": [1, 2]}
    monkeypatch.chdir(tmp_path)
    assert output.portable_source(str(tmp_path / "scenes" / "a.toml")) == "scenes/a.toml"
    assert output.portable_source("/elsewhere/b.toml") == "b.toml"
    assert output.portable_source("rel/c.toml") == "rel/c.toml"


# --------------------------------------------------------------- other processes and signals

CHILD = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from loopcheck.compare.output import Terminated, signals_as_exceptions, write_folder
    out, ready, tag = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    names = ("reduced.csv", "mujoco.csv", "plot.png", "report.json")

    def make(name):
        def write(path):
            path.write_text(tag + " " + name)
            if name == "mujoco.csv":  # half-way through the set: wait to be told
                ready.write_text("staging")
                deadline = time.monotonic() + 120  # never poll forever, whatever the test does
                while ready.read_text() != "go":
                    if time.monotonic() > deadline:
                        sys.exit(3)
                    time.sleep(0.01)
        return write

    try:
        with signals_as_exceptions():
            write_folder(out, {n: make(n) for n in names})
    except KeyboardInterrupt:
        sys.exit(130)
    except Terminated:
        sys.exit(143)
""")


def start_child(spawn, out: Path, ready: Path, tag: str) -> subprocess.Popen:
    proc = spawn([sys.executable, "-c", CHILD, str(out), str(ready), tag],
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not (ready.exists() and ready.read_text() == "staging"):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "child never reached the middle of its writing"
        time.sleep(0.01)
    return proc


def finish(proc: subprocess.Popen) -> int:
    _, err = proc.communicate(timeout=60)
    assert "Traceback" not in err, err
    return proc.returncode


@pytest.mark.parametrize("ending", ["ctrl-c", "completes"])
def test_two_runs_on_one_folder_leave_one_complete_set(tmp_path, ending, spawn):
    """Run A stages, run B writes the same new folder and finishes, then A is interrupted (B's
    set must stay: issue 10, lost data 1) or completes (A's set replaces B's, whole)."""
    out, ready = tmp_path / "out", tmp_path / "ready"
    a = start_child(spawn, out, ready, "A")
    write_folder(out, {n: (lambda p, n=n: p.write_text(f"B {n}")) for n in NAMES})  # run B
    if ending == "ctrl-c":
        a.send_signal(signal.SIGINT)
        assert finish(a) == 130
        survivor = "B"
    else:
        ready.write_text("go")
        assert finish(a) == 0
        survivor = "A"
    ready.unlink()
    assert snapshot(tmp_path) == {"out": ("dir", None),
                                  **{f"out/{n}": ("file", f"{survivor} {n}".encode()) for n in NAMES}}


def test_sigterm_while_writing_leaves_no_partial_folder(old_folder, spawn):
    """Issue 10, lost data 3: SIGTERM mid-write; the old files are untouched, nothing hidden stays."""
    ready = old_folder.parent / "ready"
    child = start_child(spawn, old_folder, ready, "new")
    before = snapshot(old_folder)
    assert any(name.startswith(output.STAGING_PREFIX) for name in before)  # it is staging in there
    child.send_signal(signal.SIGTERM)
    assert finish(child) == 143
    ready.unlink()
    assert snapshot(old_folder.parent) == {"out": ("dir", None),
                                           **{f"out/{n}": ("file", f"old {n}".encode()) for n in NAMES},
                                           "out/notes.txt": ("file", b"mine")}


FORKING_CHILD = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from loopcheck.compare.output import Terminated, signals_as_exceptions, write_folder
    out, started = Path(sys.argv[1]), Path(sys.argv[2])
    names = [f"plot{i}.png" for i in range(6)]

    def make(name):
        def write(path):
            with open(started, "a") as f:
                f.write(name + "\\n")
            time.sleep(0.5)  # a plot: ~0.1-0.5 s
            path.write_text("new " + name)
        return write

    try:
        with signals_as_exceptions():
            write_folder(out, {n: make(n) for n in names}, workers=3, one_run=True)
    except KeyboardInterrupt:
        sys.exit(130)
    except Terminated:
        sys.exit(143)
""")


@pytest.mark.slow  # ~4 s each: seven signals, each into a ~1 s forked write (the fast tests above signal one writer)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_forked_writers_run_ends_all_of_them_and_changes_nothing(tmp_path, spawn, signum):
    """Issue 24: a signal to the process group while write_folder's forked writers run (a run's
    plots) hung the parent or was swallowed. Six writers of 0.5 s in three processes (~1 s);
    the signal is sent when the first writer has started plus 0 to 0.6 s. Every time: the exit
    status of the signal, no process of the group left, the folder as it was, no staging."""
    old = tmp_path / "old"
    write_folder(old, {f"plot{i}.png": (lambda p, i=i: p.write_text(f"old {i}")) for i in range(6)}, one_run=True)
    before = snapshot(old)
    status = {signal.SIGINT: 130, signal.SIGTERM: 143}[signum]
    for delay in (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.6):
        started = tmp_path / f"started-{delay}"
        proc = spawn([sys.executable, "-c", FORKING_CHILD, str(old), str(started)], stdout=subprocess.PIPE,
                     stderr=subprocess.PIPE, text=True, start_new_session=True)
        deadline = time.monotonic() + 60
        while not started.exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.005)
        time.sleep(delay)
        os.killpg(proc.pid, signum)
        assert finish(proc) == status, delay  # a hang fails in finish (60 s)
        left = subprocess.run(["ps", "-o", "pid=,stat=,args=", "-g", str(proc.pid)], capture_output=True, text=True)
        assert left.stdout == "", f"{delay} s after the first writer: left {left.stdout}"
        assert snapshot(old) == before, delay


@pytest.mark.parametrize("existed", [False, True])
def test_a_signal_while_the_command_says_what_it_wrote_comes_after_the_line_and_the_files(tmp_path, existed):
    """``committed`` runs inside the commit's held signals: a SIGTERM sent while the command
    prints its "wrote" line neither undoes the set nor cuts the line; it is delivered after both
    (Terminated), so an interrupted exit never leaves new files without the line (loopcheck run's
    signal test caught the gap once in CI at 0.9 of a run). Planted: calling ``committed``
    before the held signals are checked undoes the set, and this fails."""
    out = tmp_path / "out"
    if existed:
        write_folder(out, {"a.txt": lambda p: p.write_text("old")}, one_run=True)
    said = []

    def committed(paths):
        os.kill(os.getpid(), signal.SIGTERM)
        said.append([p.name for p in paths])

    with pytest.raises(Terminated), signals_as_exceptions():
        write_folder(out, {"a.txt": lambda p: p.write_text("new")}, one_run=True, committed=committed)
    assert said == [["a.txt"]] and (out / "a.txt").read_text() == "new"


@pytest.mark.parametrize("signum, raised", [(signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_that_lands_in_a_weakref_callback_still_ends_the_run(signum, raised, capsys):
    """Python cannot raise out of a weakref's callback (matplotlib drops transforms that way): it
    prints "Exception ignored in" and goes on. The signal is sent again and raises in the run's own
    code, with nothing printed (seen once in .ci/run: a SIGTERM at 0.9 s of `loopcheck run` printed a
    traceback). Planted: without the unraisable hook the run is not stopped, and the test fails."""
    import time
    import weakref

    class Node:
        pass

    def callback(ref):
        os.kill(os.getpid(), signum)
        sum(range(100_000))  # the handler runs here, inside the callback

    with signals_as_exceptions() as received, pytest.raises(raised):
        node = Node()
        keep = weakref.ref(node, callback)
        del node
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:  # the run goes on until the signal raises in it
            time.sleep(0.001)
    assert keep() is None and received == [signum]
    assert "Exception ignored" not in capsys.readouterr().err


@pytest.mark.parametrize("signum, raised", [(signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_sent_again_at_the_end_of_the_block_raises_and_leaves_no_thread(signum, raised):
    """The block ends right after a weakref's callback swallowed a signal (its resend, a thread,
    pending): the resend is waited for inside the block, so the signal still raises, under the
    block's handlers, and no thread of it is left running into the interpreter's exit (a thread
    running Python while the process finalizes is how a "Fatal Python error ... finalizing" comes).
    Planted: without the join the block ends normally with the thread alive, and this fails."""
    import threading
    import weakref

    class Node:
        pass

    def callback(ref):
        os.kill(os.getpid(), signum)
        sum(range(100_000))  # the handler runs here, inside the callback

    import time

    before = threading.active_count()
    late: list[int] = []  # a resend that outlives the block lands here, not in pytest
    outer = signal.signal(signum, lambda s, frame: late.append(s))
    try:
        with pytest.raises(raised):
            with signals_as_exceptions():
                node = Node()
                keep = weakref.ref(node, callback)
                del node  # the block ends at once: the signal is being sent again
        assert keep() is None and threading.active_count() == before
    finally:
        time.sleep(0.05)
        signal.signal(signum, outer)
    assert late == []


@pytest.mark.parametrize("signum, raised", [(signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)])
def test_a_second_signal_does_not_cut_the_clean_up_short(signum, raised):
    """One exception ends the command: a second signal while the first one's exception unwinds
    (a second Ctrl-C; the group's signal reaching this process after a forked writer died of it and
    its exception was raised) is recorded, not raised in the clean-up. Seen as a staging folder
    left once in 25 runs of the signal test. (Planted: raising every time, the clean-up is cut.)"""
    cleaned = []
    with pytest.raises(raised):
        with signals_as_exceptions() as received:
            try:
                os.kill(os.getpid(), signum)
                sum(range(100_000))  # the first raises here
            finally:
                os.kill(os.getpid(), signum)
                sum(range(100_000))  # the second would raise here
                cleaned.append(True)
    assert cleaned == [True] and received == [signum, signum]
