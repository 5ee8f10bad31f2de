"""The journal of a sweep's finished rows: written beside the output folder as each row finishes,
read back by ``loopcheck sweep --resume`` instead of running those variants again, removed once the
sweep's files are committed (the module docstring of :mod:`loopcheck.compare.sweep`)."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import warnings
from pathlib import Path
from typing import Any, Iterator, Mapping

from .sweep_table import columns, parse_cell
from loopcheck.sweep_spec import SweepSpec

JOURNAL_SUFFIX = ".sweep-journal.csv"
JOURNAL_MAGIC = "# loopcheck sweep journal "


class JournalError(ValueError):
    """--resume without a journal of this very sweep beside --out (exit status 2)."""


def journal_path(out: str | os.PathLike) -> Path:
    """The journal of a sweep into ``out``: beside it, never inside (``<out>.sweep-journal.csv``)."""
    folder = Path(os.path.abspath(out))
    return folder.parent / f"{folder.name}{JOURNAL_SUFFIX}"


def _identity(data: Mapping[str, Any], spec: SweepSpec) -> str:
    """A digest of what decides a sweep's rows: the scene data and the specification."""
    import hashlib

    text = json.dumps({"data": data, "spec": repr(spec)}, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def journaled_rows(out: str | os.PathLike, data: Mapping[str, Any], spec: SweepSpec) -> int:
    """How many rows the journal beside ``out`` holds for this sweep (checked before any work).

    Raises
    ------
    JournalError
        No journal, or the journal of another sweep (scene, keys, values or engines differ).
    """
    path = journal_path(out)
    try:
        with open(path, encoding="utf-8", newline="") as f:
            first = f.readline()
            if first != f"{JOURNAL_MAGIC}{_identity(data, spec)}\n":
                raise JournalError(f"--resume: {path} is the journal of another sweep (its scene file, keys, values "
                                   "or engines differ): run without --resume to start afresh")
            return sum(1 for _ in _complete_rows(f)) if f.readline() else 0
    except FileNotFoundError:
        raise JournalError(f"--resume: no journal {path} of an interrupted sweep into "
                           f"{os.fspath(out)!r}: nothing to resume") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise JournalError(f"--resume: cannot read {path}: {exc}") from None


def _complete_rows(f) -> Iterator[str]:
    """The complete lines (the last one, cut by a kill, is not) of the journal after its header."""
    for line in f:
        if line.endswith("\n"):
            yield line


class Journal:
    """The rows of a sweep written as they finish, beside its output folder; removed once the
    sweep's files are committed. A journal that cannot be written is a warning, not an error."""

    def __init__(self, out, data: Mapping[str, Any], spec: SweepSpec, resume: bool):
        self.path, self.file = journal_path(out), None
        self.replayed = journaled_rows(out, data, spec) if resume else 0
        try:
            if resume:
                self._truncate_partial_line()
                self.file = open(self.path, "a", newline="", encoding="utf-8")
            else:
                if self.path.exists():
                    warnings.warn(f"{self.path}: the rows of an interrupted sweep are replaced by this one's "
                                  "(--resume continues a sweep)")
                self.file = open(self.path, "w", newline="", encoding="utf-8")
                self.file.write(f"{JOURNAL_MAGIC}{_identity(data, spec)}\n")
                csv.writer(self.file).writerow(columns(spec))
                self.file.flush()
        except OSError as exc:
            warnings.warn(f"no journal of finished rows ({self.path}: {exc.strerror or exc}): an interrupted "
                          "sweep cannot be resumed")
            self.file = None
        self.writer = csv.writer(self.file) if self.file else None
        self.written = 0

    def _truncate_partial_line(self) -> None:
        with open(self.path, "rb+") as f:
            data = f.read()
            keep = data.rfind(b"\n") + 1
            if keep < len(data):
                f.truncate(keep)

    def replay(self, spec: SweepSpec) -> Iterator[dict[str, Any]]:
        """The journaled rows, in order, with their types (as read back from sweep.csv)."""
        if not self.replayed:
            return
        with open(self.path, encoding="utf-8", newline="") as f:
            f.readline()
            for i, row in enumerate(csv.DictReader(_complete_rows(f), fieldnames=next(csv.reader([f.readline()])))):
                if i >= self.replayed:
                    return
                yield {k: parse_cell(k, v) for k, v in row.items()}

    def write(self, cells: list) -> None:
        if self.writer:
            self.writer.writerow(cells)
            self.file.flush()
            self.written += 1

    def close(self, done: bool) -> None:
        """Close the journal; remove it when the sweep's files are committed, or when it holds
        no row (a sweep stopped before its first one leaves nothing to resume)."""
        if self.file:
            self.file.close()
        if done or (self.file and not self.replayed and not self.written):
            with contextlib.suppress(OSError):
                os.unlink(self.path)
