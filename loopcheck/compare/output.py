"""Every file loopcheck writes goes through here: destinations checked up front, outputs replaced as a set.

Guarantees
----------
Checked before any work (:func:`check_folder`, :func:`check_file`): an empty name, a name
longer than the file system allows, a folder whose parent does not exist, is not a folder
or cannot be written (tried: a staging folder is made and removed there, since ``os.access``
says yes to root in /proc or /sys), a file name that is a folder (``.``, ``..``, a trailing ``/``), and an
existing output that is not a regular file (a symbolic link, a device node, a folder), and an
output that is one of the command's input files (the same file: by name, through a symbolic
link or a hard link, compared by device and inode) are refused with :class:`OutputError` (a
``ValueError``: exit status 2) naming the path.

Written all-or-nothing (:func:`write_folder`, :func:`write_file`):

- Every file of a set is first written into a fresh staging folder with a unique hidden
  name (``.loopcheck-stage-*``), inside the output folder when it exists, beside it when it does
  not. Nothing in the output folder changes while files are being produced, so a failure
  (an exception, Ctrl-C, SIGTERM converted to an exception by :func:`signals_as_exceptions`)
  leaves the output folder exactly as it was.
- A run removes only what it created: its own staging folder (and, if its commit fails
  part-way, the files it had already moved in, putting back the ones they replaced). It never
  removes the output folder, so run A interrupted after run B has written the same folder
  leaves B's files alone.
- Commit: a new folder is the staging folder renamed into place (one atomic step); into an
  existing folder each file is swapped in with ``os.replace``, under an exclusive ``flock`` on
  the folder so that two runs committing at once cannot interleave their sets. Before the
  first swap every target is checked again: if any is not a regular file (say a folder named
  ``report.json`` appeared) nothing is replaced. An ``OSError`` part-way rolls the swapped files
  back. SIGINT and SIGTERM are held during the commit (it takes microseconds) and delivered
  right after it, so an interrupted commit still leaves one complete set.
- Only regular files are replaced: an existing symbolic link, device node, FIFO or folder at
  a target is refused, never renamed over.
- An ``--out`` folder holds one run (``write_folder(one_run=True)``): the set carries a
  manifest (:data:`MANIFEST_FILE`), and the regular files the previous run's manifest lists
  that the new set lacks (a ``mechanism.gif`` from a run with ``--animate``) are removed in
  the same commit, rolled back with it. A file no manifest lists (the user's) is never removed.

Not covered: SIGKILL or a power cut while staging can leave a ``.loopcheck-stage-*`` folder (the
outputs themselves are still either old or new); files are not fsync'ed.
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import shutil
import signal
import stat
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from enum import Enum
from pathlib import Path

import numpy as np

STAGING_PREFIX = ".loopcheck-stage-"
MANIFEST_FILE = "loopcheck-manifest.txt"  # in an --out folder: the names the run that wrote it wrote
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143  # 128 + SIGINT, 128 + SIGTERM


class OutputError(ValueError):
    """A destination that cannot be written (exit status 2)."""


class WriterDied(RuntimeError):
    """A forked file writer (:func:`_run_writers`) that ended without writing its files: killed by
    a signal other than SIGINT/SIGTERM (SIGKILL, the out-of-memory killer), or an exception that
    did not come back. Nothing was written (exit status 1, one line)."""


class Terminated(BaseException):
    """SIGTERM, raised as an exception so that ``finally`` blocks and clean-ups run."""


# ---------------------------------------------------------------------------- checks

def _name_max(folder: Path) -> int:
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _check_text(path: str | os.PathLike, flag: str, what: str) -> Path:
    text = os.fspath(path)
    if text == "":
        raise OutputError(f"{flag} is empty: give a {what} name")
    if "\0" in text:
        raise OutputError(f"{flag} {text!r}: a path cannot contain a NUL character")
    if len(os.fsencode(os.path.abspath(text))) >= 4096:
        raise OutputError(f"{flag}: path of {len(text)} characters is too long")
    limit = _name_max(Path("."))
    for part in Path(text).parts:
        if len(os.fsencode(part)) > limit:
            raise OutputError(f"{flag}: a name of {len(part)} characters is too long (at most {limit} bytes)")
    return Path(text)


def _check_parent(parent: Path, flag: str, shown: str) -> None:
    if not parent.exists():
        raise OutputError(f"{flag} {shown}: folder '{parent}' does not exist (create it first)")
    if not parent.is_dir():
        raise OutputError(f"{flag} {shown}: '{parent}' is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{flag} {shown}: cannot write in '{parent}' (permission denied or read-only)")
    _probe(parent, flag, shown)


def _probe(folder: Path, flag: str, shown: str) -> None:
    """Create and remove a staging-named folder in ``folder``: what writing there needs first.
    ``os.access`` says yes to root in /proc or /sys, and on some read-only mounts; this does not."""
    with _signals_blocked():  # never left behind
        try:
            probe = tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=folder)
        except OSError as exc:
            raise OutputError(f"{flag} {shown}: cannot write in '{folder}' "
                              f"({exc.strerror or exc})") from None
        os.rmdir(probe)


def _refuse_non_regular(target: Path, flag: str) -> None:
    """Raise unless ``target`` is absent or a regular file (not following symbolic links)."""
    try:
        mode = os.lstat(target).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputError(f"{flag}: cannot use '{target}': {exc.strerror}") from None
    if stat.S_ISREG(mode):
        return
    kind = ("a symbolic link" if stat.S_ISLNK(mode) else "a folder" if stat.S_ISDIR(mode)
            else "a device node" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
    raise OutputError(f"{flag}: '{target}' is {kind}; loopcheck replaces only regular files, move it away first")


def _refuse_inputs(target: Path, inputs: Iterable[str | os.PathLike], flag: str) -> None:
    """Raise if ``target`` is one of the files ``inputs``: the same file by device and inode, so
    through a symbolic link (followed, at either end) or a hard link too."""
    try:
        there = os.stat(target)
    except OSError:  # absent (or unreachable: the other checks say why): not an input
        return
    for source in inputs:
        try:
            read = os.stat(source)
        except OSError:
            continue
        if (there.st_dev, there.st_ino) == (read.st_dev, read.st_ino):
            same = "" if os.path.abspath(target) == os.path.abspath(source) else f" (the same file as '{source}')"
            raise OutputError(f"{flag} '{target}' is an input of this command{same}: loopcheck never writes over "
                              "its input; give another name")


def refuse_same_outputs(outputs: Iterable[tuple[str, str | os.PathLike]]) -> None:
    """Raise if two of one command's outputs, ``(flag, path)`` each, name the same file: the same
    path once resolved (symbolic links followed, the file there or not), or the same existing file
    by device and inode (a hard link); the second written would replace the first."""
    seen: list[tuple[str, str | os.PathLike, str, tuple | None]] = []
    for flag, path in outputs:
        real = os.path.realpath(path)
        try:
            st = os.stat(real)
            inode = (st.st_dev, st.st_ino)
        except OSError:
            inode = None
        for other_flag, other, other_real, other_inode in seen:
            if real == other_real or (inode is not None and inode == other_inode):
                raise OutputError(f"{flag} '{path}' and {other_flag} '{other}' name the same file: each output needs "
                                  "its own; give another name")
        seen.append((flag, path, real, inode))


def check_folder(path: str | os.PathLike, names: Iterable[str] = (), *, flag: str = "--out",
                 inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """Check that the folder ``path`` can receive the files ``names``, before any work.

    The folder may exist (it must then be a writable folder, and each of ``names`` in it
    absent or a regular file) or not (its parent must then be a writable folder). Neither the
    folder nor any of ``names`` in it may be one of the files ``inputs``.

    Raises
    ------
    OutputError
        Naming the path and the reason.
    """
    out = _check_text(path, flag, "folder")
    inputs, names = tuple(inputs), tuple(names)
    _refuse_inputs(out, inputs, flag)
    for name in names:
        _refuse_inputs(out / name, inputs, flag)
    try:
        return _check_folder(out, names, flag)
    except OSError as exc:
        raise OutputError(f"{flag} '{out}': {exc.strerror or exc}") from None


def _check_folder(out: Path, names: Iterable[str], flag: str) -> Path:
    shown = f"'{out}'"
    if out.exists() or out.is_symlink():
        if not out.is_dir():
            raise OutputError(f"{flag} {shown} is a file, not a folder" if out.is_file() or out.is_symlink()
                              else f"{flag} {shown} is not a folder")
        if not os.access(out, os.W_OK | os.X_OK):
            raise OutputError(f"{flag} {shown}: cannot write in it (permission denied or read-only)")
        _probe(out, flag, shown)
        for name in names:
            _refuse_non_regular(out / name, flag)
    else:
        parent = out.parent
        if parent == DEFAULT_ROOT and not parent.exists() and not parent.is_symlink():
            parent = Path(".")  # the default folder's root is created with the outputs (write_folder)
        # A path below a file ("file.txt/out") fails here: its parent is not a folder.
        _check_parent(parent, flag, shown)
    return out


def check_file(path: str | os.PathLike, *, flag: str = "-o", inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """Check that the file ``path`` can be written (created, or a regular file replaced).

    Raises
    ------
    OutputError
        For an empty name, a folder (``.``, ``..``, a trailing ``/``, an existing folder), a
        missing or unwritable parent folder, an existing target that is not a regular file, or
        a target that is one of the files ``inputs`` (through a link too).
    """
    target = _check_text(path, flag, "file")
    _refuse_inputs(target, inputs, flag)
    try:
        return _check_file(target, os.fspath(path), flag)
    except OSError as exc:
        raise OutputError(f"{flag} '{target}': {exc.strerror or exc}") from None


def _check_file(target: Path, text: str, flag: str) -> Path:
    if target.name in ("", ".", "..") or text.endswith(os.sep) or target.is_dir():
        raise OutputError(f"{flag} '{text}' is a folder: give a file name, e.g. model.xml")
    _check_parent(target.parent, flag, f"'{text}'")
    _refuse_non_regular(target, flag)
    return target


# ---------------------------------------------------------------------------- signals

RESEND_S = 0.01  # s: a signal swallowed by a callback is sent again this long after (signals_as_exceptions)
_ENDING: list[int] = []  # the signal whose exception is ending the command (signals_as_exceptions)

@contextlib.contextmanager
def signals_as_exceptions() -> Iterator[list[int]]:
    """For the duration of the block, SIGTERM raises :class:`Terminated` and SIGINT
    ``KeyboardInterrupt`` (so clean-ups run); the previous handlers are restored after.
    A signal that is ignored when the block starts stays ignored. Yields the list of the
    signals received, in order: code that turns the exception into another one (a C
    extension interrupted while it is imported raises ImportError) cannot hide the signal.

    Does nothing outside the main thread (Python only handles signals there).
    """
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    # One exception ends the command: a second signal (a second Ctrl-C; the group's signal after a
    # forked writer died of it, whose exception is already raised) is recorded, not raised again,
    # so that it cannot land in a clean-up (the staging folder's removal) and cut it short.
    _ENDING.clear()

    def terminate(signum, frame):
        received.append(signum)
        if not _ENDING:
            _ENDING.append(signum)
            raise Terminated()

    def interrupt(signum, frame):
        received.append(signum)
        if not _ENDING:
            _ENDING.append(signum)
            signal.default_int_handler(signum, frame)

    # A signal that lands while Python runs a callback that cannot raise (a weakref's, matplotlib
    # drops transforms that way; a __del__) would have its exception printed as "Exception
    # ignored in" and swallowed: it is sent again instead, from a thread once this callback is
    # left, to raise where the run sees it (its handler records it again).
    previous_hook = sys.unraisablehook
    resends: list[threading.Timer] = []

    def unraisable(info) -> None:
        if isinstance(info.exc_value, (Terminated, KeyboardInterrupt)) and received:
            _ENDING.clear()  # swallowed: nothing is ending yet
            resend = threading.Timer(RESEND_S, os.kill, args=(os.getpid(), received.pop()))
            resend.daemon = True
            resends.append(resend)
            resend.start()
            return
        previous_hook(info)

    wanted = {signal.SIGTERM: terminate, signal.SIGINT: interrupt}
    # A signal the caller chose to ignore (``nohup``, a background job) stays ignored.
    previous = {s: signal.signal(s, handler) for s, handler in wanted.items()
                if signal.getsignal(s) is not signal.SIG_IGN}
    sys.unraisablehook = unraisable
    try:
        yield received
    finally:
        try:  # a signal being sent again comes while this block's handlers hold: no thread outlives the block
            for resend in resends:
                resend.join()
        finally:
            sys.unraisablehook = previous_hook
            for signum, handler in previous.items():
                signal.signal(signum, handler)
            _ENDING.clear()


class _Abandoned(BaseException):
    """A commit undone because SIGINT or SIGTERM came during it (the held signal then raises)."""


@contextlib.contextmanager
def _signals_held() -> Iterator[list[int]]:
    """Hold SIGINT and SIGTERM for a short critical section, then deliver them. Yields the list
    of the signals held so far (the ones not ignored), so that the section can undo its work."""
    if threading.current_thread() is not threading.main_thread():
        yield []
        return
    pending: list[int] = []
    previous = {s: signal.getsignal(s) for s in _HANDLED}
    for s, handler in previous.items():
        if handler is not signal.SIG_IGN:
            signal.signal(s, lambda signum, frame: pending.append(signum))
    try:
        yield pending
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(pending):
            handler = previous[s]
            if callable(handler):
                handler(s, None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), s)


# ---------------------------------------------------------------------------- writing

@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive advisory lock on a folder (no lock file: ``flock`` on the folder itself)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _previous_run(out: Path) -> list[str]:
    """The files the previous run wrote into ``out`` (its manifest), that this run may remove:
    plain names of regular files that are there now. No manifest, or an unreadable one: none."""
    try:
        if not stat.S_ISREG(os.lstat(out / MANIFEST_FILE).st_mode):
            return []
        listed = (out / MANIFEST_FILE).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return []
    names = []
    for name in listed:
        if (not name or name in (".", "..", MANIFEST_FILE) or "/" in name or os.sep in name or "\0" in name
                or name.startswith(STAGING_PREFIX)):
            continue
        try:
            if stat.S_ISREG(os.lstat(out / name).st_mode):
                names.append(name)
        except OSError:
            continue
    return names


def _swap_in(content: Path, backup: Path, out: Path, names: list[str], flag: str,
             stale: Iterable[str] = (), held: list[int] | None = None) -> None:
    """Move ``content/name`` over ``out/name`` for every name and set the ``stale`` files of
    ``out`` aside, all or none (see module notes); undone if ``held`` (signals that came
    meanwhile) is not empty at the end."""
    for name in names:  # nothing is replaced if any target is not a regular file
        _refuse_non_regular(out / name, flag)
    backup.mkdir()
    moved: list[list] = []  # [name, an old file was set aside, the new file is in place]
    try:
        for name in names:
            had_old = os.path.lexists(out / name)
            if had_old:
                os.replace(out / name, backup / name)
            moved.append([name, had_old, False])
            os.replace(content / name, out / name)
            moved[-1][2] = True
        for name in stale:  # removed with the staging folder once the set is in place
            os.replace(out / name, backup / name)
            moved.append([name, True, False])
        if held:
            raise _Abandoned()
    except BaseException:
        for name, had_old, placed in reversed(moved):  # put back what was there
            with contextlib.suppress(OSError):
                if placed:
                    os.unlink(out / name)
                if had_old:
                    os.replace(backup / name, out / name)
        raise


_HANDLED = (signal.SIGINT, signal.SIGTERM)
_ERROR_LIMIT = 32_768  # bytes of a child's pickled exception (a pipe holds 64 KiB: the child never blocks)


@contextlib.contextmanager
def _signals_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked (kept pending by the kernel) for the block, then unblocked:
    a signal that came meanwhile is handled right after it (by this process's handler)."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, _HANDLED)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _fork_writer(files: Mapping[str, Callable[[Path], None]], names: list[str], content: Path,
                 children: dict[int, int]) -> None:
    """Fork a child that runs the writers of ``names`` into ``content``, and record it in
    ``children`` (its pid: the read end of a pipe on which it reports what it raised) before
    any signal can interrupt this process, so that the caller always reaps it. The child
    starts with SIGINT and SIGTERM blocked, sets both to their default action (a signal to the process group kills it: the
    parent handles the signal and cleans up) and only then unblocks them, so no signal ever
    runs this process's handlers in the child; it leaves by ``os._exit``, running none of the
    parent's clean-ups."""
    import pickle

    # Held (this process's handlers only record a signal) and blocked (the kernel keeps it
    # pending): a signal cannot raise between the fork and the child's registration.
    with _signals_held(), _signals_blocked():
        read_end, write_end = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child
            status = 1
            try:
                os.close(read_end)
                for signum in _HANDLED:
                    signal.signal(signum, signal.SIG_DFL)
                signal.pthread_sigmask(signal.SIG_UNBLOCK, _HANDLED)
                for name in names:
                    files[name](content / name)
                status = 0
            except BaseException as exc:  # noqa: BLE001 - reported to the parent
                try:
                    data = pickle.dumps(exc)
                    if len(data) > _ERROR_LIMIT:
                        raise ValueError("too long")
                except Exception:  # noqa: BLE001 - an exception that does not pickle: its text
                    data = pickle.dumps(RuntimeError(f"{type(exc).__name__}: {exc}"[:1000]))
                with contextlib.suppress(OSError):
                    os.write(write_end, data)
            finally:
                os._exit(status)
        children[pid] = read_end
        os.close(write_end)


def _child_outcome(pid: int, status: int, read_end: int) -> BaseException | None:
    """What a reaped writer child ended with: None (it wrote its files) or the exception to raise."""
    import pickle

    data = b""
    while chunk := os.read(read_end, 65536):
        data += chunk
    if os.WIFSIGNALED(status):
        signum = os.WTERMSIG(status)
        if signum in _HANDLED and not _ENDING:  # the group's signal: this process's own comes after, not raised
            _ENDING.append(signum)
        return (KeyboardInterrupt() if signum == signal.SIGINT else Terminated() if signum == signal.SIGTERM
                else WriterDied(f"a file writer (process {pid}) was killed by {_signal_name(signum)}"))
    if os.WEXITSTATUS(status) == 0:
        return None
    try:
        return pickle.loads(data)
    except Exception:  # noqa: BLE001
        return WriterDied(f"a file writer (process {pid}) failed with exit status {os.WEXITSTATUS(status)}")


def _signal_name(signum: int) -> str:
    try:
        return f"{signal.Signals(signum).name} (signal {signum})"
    except ValueError:
        return f"signal {signum}"


def _run_writers(files: Mapping[str, Callable[[Path], None]], content: Path, workers: int) -> None:
    """Every writer, into ``content``. With ``workers`` > 1 (and fork available, not in a pool's
    daemon worker, which may have no children, and JAX not loaded) ``workers`` - 1 forked child processes
    (:func:`_fork_writer`) share the writers with this one: the plots of a run are independent
    and cost ~0.1 s each. A child's exception is raised here. Whatever ends this process's part
    (an exception, Ctrl-C, SIGTERM), every child still running is killed and reaped, with
    SIGINT and SIGTERM held meanwhile, before the exception goes on: no child outlives it."""
    import multiprocessing

    names = list(files)
    # JAX (the mjx engine) runs threads of its own: a fork could deadlock on a lock one of them
    # holds, and JAX warns of it; the writers then run here, one after another (~1 s for a run's plots)
    threaded = "jax" in sys.modules
    if (workers < 2 or len(names) < 2 or not hasattr(os, "fork") or multiprocessing.current_process().daemon
            or threaded):
        for name in names:
            files[name](content / name)
        return
    workers = min(workers, len(names))
    children: dict[int, int] = {}  # pid -> read end of its pipe
    try:
        for k in range(1, workers):
            _fork_writer(files, names[k::workers], content, children)
        for name in names[0::workers]:
            files[name](content / name)
        while children:
            pid = next(iter(children))
            _, status = os.waitpid(pid, 0)
            read_end = children.pop(pid)
            try:
                error = _child_outcome(pid, status, read_end)
            finally:
                os.close(read_end)
            if error is not None:
                raise error
    finally:
        with _signals_blocked():
            for pid, read_end in children.items():
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                with contextlib.suppress(ChildProcessError):
                    os.waitpid(pid, 0)
                os.close(read_end)


# The commands' output folders are loopcheck-out/<scene>/ by default: this folder, in the working
# folder, is the one missing parent that a folder check accepts and a write creates.
DEFAULT_ROOT = Path("loopcheck-out")


def write_folder(path: str | os.PathLike, files: Mapping[str, Callable[[Path], None]], *,
                 flag: str = "--out", workers: int = 1, one_run: bool = False,
                 committed: Callable[[list[Path]], None] | None = None) -> list[Path]:
    """Write a set of files into the folder ``path``, all or nothing.

    Parameters
    ----------
    path : the output folder; it is created if absent (its parent must exist, or be
        :data:`DEFAULT_ROOT`, which is then created too).
    files : file name -> function that writes that file at the path it is given (a staging
        path, not the final one). Files are committed in this order.
    workers : how many processes write the files (:func:`_run_writers`); 1, here only.
    one_run : the folder holds one run's outputs (an ``--out`` folder): the set is written with
        its manifest (:data:`MANIFEST_FILE`, one name a line), and the files the previous run's
        manifest lists that this set does not contain are removed in the same commit (a
        failure puts them back). Files no manifest lists are never touched.
    committed : called with the final paths once the set is in place, while SIGINT and SIGTERM
        are still held: a command says what it wrote there, so that a signal cannot fall between
        the files and that line (it is delivered after both, and the exit status says it came).

    Returns
    -------
    The final paths, in the order of ``files``.

    Raises
    ------
    OutputError
        If the destination is not usable (checked first, and again before the commit).
    Whatever a writer raises (including ``KeyboardInterrupt``/:class:`Terminated`): the folder
    is then exactly as it was.
    """
    names = list(files)
    if one_run:
        if MANIFEST_FILE in names:
            raise ValueError(f"{MANIFEST_FILE} is written by write_folder itself")
        names.append(MANIFEST_FILE)
    out = check_folder(path, names, flag=flag)
    existed = out.is_dir()
    staging = None
    try:
        if out.parent == DEFAULT_ROOT:
            out.parent.mkdir(exist_ok=True)  # the commands' default root; left, empty, if the write fails
        with _signals_blocked():  # a signal now comes once staging is set, and so is cleaned up
            staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out if existed else out.parent))
        content = staging / "set"
        content.mkdir()
        _run_writers(files, content, workers)
        if one_run:
            (content / MANIFEST_FILE).write_text("".join(f"{n}\n" for n in files), encoding="utf-8")
        for name in names:
            if not (content / name).is_file():
                raise RuntimeError(f"the writer of {name} produced no file")
        with _signals_held() as held:  # a signal that comes during the commit undoes it
            if not existed:
                try:
                    os.rename(content, out)  # the whole set appears at once
                except OSError as exc:  # the folder appeared meanwhile: swap file by file
                    if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                        raise
                else:
                    if held:
                        os.rename(out, content)
                        raise _Abandoned()
                    if committed is not None:
                        committed([out / name for name in files])
                    return [out / name for name in files]
                if not out.is_dir():
                    raise OutputError(f"{flag} '{out}' appeared meanwhile and is not a folder")
            with _locked(out):
                stale = [n for n in _previous_run(out) if n not in names] if one_run else []
                _swap_in(content, staging / "replaced", out, names, flag, stale, held)
            if committed is not None:
                committed([out / name for name in files])
    finally:
        if staging is not None:
            with _signals_blocked():  # a second signal does not cut the clean-up short
                shutil.rmtree(staging, ignore_errors=True)
    return [out / name for name in files]


def write_file(path: str | os.PathLike, text: str, *, flag: str = "-o") -> Path:
    """Write ``text`` (UTF-8) to the file ``path``, replacing only a regular file, atomically."""
    target = check_file(path, flag=flag)
    return write_folder(target.parent, {target.name: lambda p: p.write_text(text, encoding="utf-8")},
                        flag=flag)[0]


# ---------------------------------------------------------------------------- content

def plain(value):
    """``value`` as strict-JSON data: NaN and ±inf become None; tuples, numpy scalars and
    arrays, enums and paths become lists, numbers and strings."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, Enum):
        return plain(value.value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def json_text(data) -> str:
    """Strict JSON (no NaN or Infinity tokens), indented, with a final newline."""
    return json.dumps(plain(data), indent=2, allow_nan=False) + "\n"


def portable_source(source: str) -> str:
    """A scene's source path without the user's folders: relative to the working directory
    when the file is below it, else the file name alone."""
    if source.startswith("<"):
        return source
    path = Path(source)
    if not path.is_absolute():
        return source
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        return path.name
