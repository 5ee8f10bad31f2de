"""The journal of a sweep's finished rows: written beside the output folder as each row finishes,
read back by ``loopcheck sweep --resume`` instead of running those variants again, removed once the
sweep's files are committed (the module docstring of :mod:`loopcheck.compare.sweep`).

A journal is a text file: its first line ``# loopcheck sweep journal <identity>`` (a digest of the
scene data and the sweep's specification: its keys, values, samples, seed and engines), then
sweep.csv's column line, then one line per finished row, in variant order.

Its rows are checked, never trusted. One sweep at a time holds a journal: it is locked
(``fcntl.flock``, released by the kernel when the process ends, however it ends) from the moment
it is opened until the sweep ends; a second sweep into the same folder is refused in one line.
With ``--resume`` the rows are read once, under the lock, and the longest prefix of rows that
check is kept: row ``k`` is a complete line (cut by a kill, it is not), of exactly the sweep's
columns, every cell readable (finite numbers, known status), its index ``k`` and its varied
values variant ``k``'s. The rest is discarded (one warning naming the journal and the rows) and
those variants run again. Without ``--resume`` an existing journal is refused (it holds another
run's finished rows) unless ``--restart`` discards it.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import warnings
from pathlib import Path
from typing import Any, BinaryIO, Iterator, Mapping

from .sweep_summary import STATUSES
from .sweep_table import columns, input_column, input_of, is_list_column, parse_cell
from loopcheck.sweep_spec import SweepSpec, count, variant_values

JOURNAL_SUFFIX = ".sweep-journal.csv"
JOURNAL_MAGIC = "# loopcheck sweep journal "
_BAD_COLUMNS = "its column line is not this sweep's"


class JournalError(ValueError):
    """A journal that cannot be used as asked (exit status 2): none to resume, not a journal of
    this project, the journal of another sweep, one of this sweep's left without ``--resume`` or
    ``--restart``, or one in use by a sweep running now."""


def journal_path(out: str | os.PathLike) -> Path:
    """The journal of a sweep into ``out``: beside it, never inside (``<out>.sweep-journal.csv``)."""
    folder = Path(os.path.abspath(out))
    return folder.parent / f"{folder.name}{JOURNAL_SUFFIX}"


def _identity(data: Mapping[str, Any], spec: SweepSpec) -> str:
    """A digest of what decides a sweep's rows: the scene data and the specification."""
    import hashlib

    text = json.dumps({"data": data, "spec": repr(spec)}, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _line(cells) -> bytes:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(cells)
    return buf.getvalue().encode("utf-8")


def _open_locked(path: Path, create: bool) -> BinaryIO | None:
    """The journal at ``path`` opened for reading and writing and locked (None: there is none
    and ``create`` is false). Raises JournalError when another process holds it."""
    import fcntl

    for _ in range(5):
        try:
            fd = os.open(path, os.O_RDWR | (os.O_CREAT if create else 0), 0o666)
        except FileNotFoundError:
            return None
        f = os.fdopen(fd, "r+b")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.close()
            raise JournalError(f"{path} is in use by another loopcheck sweep into the same folder, running now: "
                               "wait for it to end (or stop it), then --resume") from None
        try:
            same = os.path.samestat(os.fstat(f.fileno()), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            return f
        f.close()  # removed (or replaced) by the sweep that held it just before: open it again
    raise JournalError(f"{path} keeps being replaced by another loopcheck sweep: wait for it to end")


def _claim(f: BinaryIO, path: Path, identity: str, resume: bool, restart: bool) -> bool:
    """Whether the rows of the locked journal ``f`` are to be read (its header this sweep's and
    ``resume``); False: it is to be written afresh. Raises JournalError as the module docstring says."""
    first = f.readline()
    if not first:  # created, never written: no row to lose or to resume
        if resume:
            raise JournalError(f"--resume: the journal {path} holds no row: nothing to resume")
        return False
    if not first.startswith(JOURNAL_MAGIC.encode()):
        raise JournalError(f"{path} is not a loopcheck sweep journal (its first line is not "
                           f"'{JOURNAL_MAGIC.strip()} ...'): move it away or remove it")
    if first != f"{JOURNAL_MAGIC}{identity}\n".encode():
        if restart:
            return False
        raise JournalError(f"{path} is the journal of another sweep (its scene file, keys, values, samples, seed or "
                           "engines differ): --restart discards its rows, or give another --out")
    if resume:
        return True
    if restart:
        return False
    raise JournalError(f"{path} holds the finished rows of an interrupted run of this sweep: --resume continues it, "
                       "--restart discards them")


def _one_of(resume: bool, restart: bool) -> None:
    if resume and restart:
        raise JournalError("--resume and --restart: give one of them (--resume continues the journal's sweep, "
                           "--restart discards its rows)")


def check_journal(out: str | os.PathLike, data: Mapping[str, Any], spec: SweepSpec, *, resume: bool = False,
                  restart: bool = False) -> None:
    """Before any work: whether a sweep into ``out`` may use its journal as ``resume`` and
    ``restart`` ask (JournalError otherwise). Reads only the journal's first line; the sweep
    itself checks it again when it locks it (:class:`Journal`)."""
    _one_of(resume, restart)
    path = journal_path(out)
    try:
        f = _open_locked(path, create=False)
    except OSError as exc:
        if resume or path.exists():
            raise JournalError(f"cannot open the journal {path}: {exc.strerror or exc}") from None
        return
    if f is None:
        if resume:
            raise JournalError(f"--resume: no journal {path} of an interrupted sweep into {os.fspath(out)!r}: "
                               "nothing to resume")
        return
    with f:
        _claim(f, path, _identity(data, spec), resume, restart)


class Journal:
    """The rows of a sweep written as they finish, beside its output folder, locked for as long as
    it is open; removed once the sweep's files are committed. With ``resume`` the rows it holds
    are checked and replayed (:meth:`replay`). A journal that cannot be created is a warning, not
    an error (the sweep runs on, but cannot be resumed)."""

    def __init__(self, out, data: Mapping[str, Any], spec: SweepSpec, resume: bool = False, restart: bool = False,
                 inputs: tuple[str, ...] = ()):
        self.path, self.spec, self.file = journal_path(out), spec, None
        self.inputs = tuple(inputs)  # the scene's, when it has several (sweep_table.columns)
        self.kept = 0  # rows read back (known once replay() is exhausted)
        self.written = 0
        self._replay = False
        _one_of(resume, restart)
        try:
            self.file = _open_locked(self.path, create=not resume)
        except OSError as exc:
            if resume:
                raise JournalError(f"cannot open the journal {self.path}: {exc.strerror or exc}") from None
            warnings.warn(f"no journal of finished rows ({self.path}: {exc.strerror or exc}): an interrupted "
                          "sweep cannot be resumed")
            return
        if self.file is None:
            raise JournalError(f"--resume: no journal {self.path} of an interrupted sweep into "
                               f"{os.fspath(out)!r}: nothing to resume")
        try:
            self._replay = _claim(self.file, self.path, _identity(data, spec), resume, restart)
            if not self._replay:
                self.file.seek(0)
                self.file.truncate()
                self.file.write(f"{JOURNAL_MAGIC}{_identity(data, spec)}\n".encode() + _line(columns(spec, self.inputs)))
                self.file.flush()
        except BaseException:
            self.file.close()
            self.file = None
            raise

    def replay(self) -> Iterator[dict[str, Any]]:
        """The journal's rows that check, in order, with their types (as read back from
        sweep.csv), each marked ``_journaled``. Read once: once exhausted, :attr:`kept` is their
        number, the rest of the journal is cut off (one warning) and new rows follow them."""
        if not self._replay:
            return
        self._replay = False
        f, cols = self.file, columns(self.spec, self.inputs)
        end = f.tell()
        problem = None
        if f.readline() != _line(cols):
            problem = _BAD_COLUMNS
        else:
            end = f.tell()
            n = count(self.spec)
            for k, values in enumerate(variant_values(self.spec)):
                line = f.readline()
                if not line:
                    break
                row, problem = _checked(line, k, values, cols, self.inputs)
                if row is None:
                    break
                self.kept = k + 1
                end = f.tell()
                yield row
            else:
                if f.readline():
                    problem = f"rows after the last variant (#{n - 1})"
        f.seek(end)
        rest = f.read()
        if rest:
            lines = rest.count(b"\n") + (0 if rest.endswith(b"\n") else 1)
            warnings.warn(f"{self.path}: kept its first {self.kept} row{'s' if self.kept != 1 else ''}, discarded the "
                          f"{lines} line{'s' if lines != 1 else ''} after them ({problem}): those variants run again")
        f.seek(end)
        f.truncate()
        if self.kept == 0 and problem == _BAD_COLUMNS:
            f.write(_line(cols))
        f.flush()

    def write(self, cells: list) -> None:
        if self.file is not None:
            self.file.write(_line(cells))
            self.file.flush()
            self.written += 1

    def close(self, done: bool) -> None:
        """Close (and unlock) the journal; remove it first when the sweep's files are committed,
        or when it holds no row (a sweep stopped before its first one leaves nothing to resume)."""
        if self.file is None:
            return
        if done or (not self.kept and not self.written):
            try:
                os.unlink(self.path)
            except OSError:
                pass
        self.file.close()
        self.file = None


def _checked(line: bytes, k: int, values: Mapping[str, float], cols: tuple[str, ...],
             inputs: tuple[str, ...] = ()) -> tuple[dict | None, str]:
    """Row ``k`` read from its journal ``line`` and checked, or None and what is wrong with it.
    With several ``inputs``, each later input's figures must also agree with each other
    (:func:`_inputs_problem`)."""
    if not line.endswith(b"\n"):
        return None, f"row {k}: its line is cut (no line end)"
    try:
        cells = next(csv.reader([line.decode("utf-8")]), [])
    except (UnicodeDecodeError, csv.Error):
        return None, f"row {k}: not a line of CSV text"
    if len(cells) != len(cols):
        return None, f"row {k}: {len(cells)} cells where {len(cols)} were expected"
    row: dict[str, Any] = {}
    for col, text in zip(cols, cells):
        try:
            value = parse_cell(col, text)
        except ValueError:  # json.JSONDecodeError is one
            value = math.nan
        if (isinstance(value, float) and not math.isfinite(value)) or \
                (is_list_column(col) and value is not None and not isinstance(value, list)):
            return None, f"row {k}: its {col} cell {text[:20]!r} is not readable"
        row[col] = value
    if row["index"] != k:
        return None, f"row {k}: its index is {row['index']}"
    if row["status"] not in STATUSES:
        return None, f"row {k}: its status {row['status'][:20]!r} is not one"
    for key, value in values.items():
        if row[key] is None or float(row[key]) != float(value):
            return None, f"row {k}: its {key} is {row[key]!r}, not variant {k}'s {value!r}"
    if inputs[1:]:
        problem = _inputs_problem(row, cols, inputs)
        if problem:
            return None, f"row {k}: {problem}"
    row["_journaled"] = True
    return row, ""


def _inputs_problem(row: Mapping[str, Any], cols: tuple[str, ...], inputs: tuple[str, ...]) -> str:
    """What is wrong with the figures of the inputs of a row of a scene of several degrees of
    freedom ("" when nothing): a row that holds an engine's first-input peak holds every input's;
    for each input and judged engine, its ``peak_omega_abs`` is exactly |``peak_omega_other`` −
    ``peak_omega_reference``| (the cells are the floats' repr), and with one judged engine the
    engines' ``peak_omega`` cells are those two peaks. A cell changed by hand, or swapped with
    another input's, fails one of these."""
    from loopcheck.registry import REFERENCE

    def at(name: str, column: str) -> str:
        return column if name == inputs[0] else input_column(name, column)

    stems = [c[:-len("peak_omega_abs")] for c in cols if c.startswith("diff.") and c.endswith(".peak_omega_abs")]
    judged = [c.split(".", 1)[0] for c in cols if c.endswith(".max_constraint_violation")]
    for name in inputs:
        for stem in stems:
            ref, other, gap = (row.get(at(name, stem + f)) for f in ("peak_omega_reference", "peak_omega_other",
                                                                    "peak_omega_abs"))
            if ref is None and other is None and gap is None:
                continue
            if ref is None or other is None or gap is None or abs(other - ref) != gap:
                return (f"its {at(name, stem + 'peak_omega_abs')} cell is not |{at(name, stem + 'peak_omega_other')} "
                        f"- {at(name, stem + 'peak_omega_reference')}|")
        if len(stems) == 1 and len(judged) == 1:
            for engine, figure in ((REFERENCE, "peak_omega_reference"), (judged[0], "peak_omega_other")):
                peak, diff = row.get(at(name, f"{engine}.peak_omega")), row.get(at(name, "diff." + figure))
                if diff is not None and peak != diff:
                    return f"its {at(name, engine + '.peak_omega')} cell is not its {at(name, 'diff.' + figure)}"
    for col in cols:
        if input_of(col, inputs)[0] or not col.endswith(".peak_omega") or col.count(".") != 1:
            continue
        given = [row.get(at(name, col)) is not None for name in inputs]
        if any(given) and not all(given):
            return f"it holds {col} of some inputs but not of every input ({', '.join(inputs)})"
    return ""
