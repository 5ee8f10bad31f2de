"""A port's compile, announced with the time the last one took on this machine.

A GPU port compiles before it runs (MJX's scan: about 17-35 s on a 2-core CPU; MJWarp's kernels:
about 30-60 s), and the command would be silent meanwhile. :func:`compiling` says so first, on the
``loopcheck.ports`` logger (which the command prints as progress, ``loopcheck: ...``; ``-q``
silences it): ``seed_fourbar: mjx compiling (about 17 s)``, with the time of the last compile
measured here, or ``seed_fourbar: mjx compiling (first compile: no time recorded)`` when there is
none. After the compile it records the time taken.

The record is kept beside the compilation cache that the compile fills (JAX's persistent
compilation cache, ``JAX_COMPILATION_CACHE_DIR``; Warp's kernel cache, ``WARP_CACHE_PATH`` or
``~/.cache/warp``), so that a fresh cache starts without one, as its first compile is a full one:
one small JSON file per engine and device, ``loopcheck-compile-<engine>-<device>.json``. It is
written whole (a temporary file in the same folder, then renamed over the old one), and it is a
journal, read and checked, never trusted: a file that cannot be read, is not such a record, names
another engine, or holds a time that is not a finite number of seconds in (0, 1 day] is ignored
(logged at DEBUG), and the compile is announced as a first one. A folder that cannot be written
costs the record only (logged at DEBUG), never the run.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

_log = logging.getLogger("loopcheck.ports")

FORMAT = "loopcheck compile record 1"
MAX_SECONDS = 86400.0  # a day: a longer "compile" is not one


@dataclass(frozen=True)
class CompileRecord:
    """The last compile of ``engine`` on ``device`` measured beside one cache: ``seconds`` > 0."""

    engine: str
    device: str
    seconds: float

    def __post_init__(self) -> None:
        if not self.engine or not self.device:
            raise ValueError("a compile record names its engine and device")
        if isinstance(self.seconds, bool) or not isinstance(self.seconds, (int, float)) or not (
                math.isfinite(self.seconds) and 0 < self.seconds <= MAX_SECONDS):
            raise ValueError(f"a compile time of {self.seconds!r} s is not in (0, {MAX_SECONDS:g}] s")

    def as_dict(self) -> dict:
        return {"format": FORMAT, "engine": self.engine, "device": self.device, "seconds": self.seconds}


def record_path(cache_dir: Path, engine: str, device: str) -> Path:
    """Where the record of ``engine`` on ``device`` is kept beside the cache ``cache_dir``."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in f"{engine}-{device}")
    return Path(cache_dir) / f"loopcheck-compile-{safe}.json"


def read_record(cache_dir: Path | None, engine: str, device: str) -> CompileRecord | None:
    """The record of ``engine`` on ``device`` kept beside ``cache_dir``, or None: none there, or
    one that cannot be read or is not a valid record (the reason logged at DEBUG)."""
    if cache_dir is None:
        return None
    path = record_path(cache_dir, engine, device)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        _log.debug("%s: compile record %s ignored: %s", engine, path, exc)
        return None
    try:
        data = json.loads(text)
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ValueError(f"not a record of format '{FORMAT}'")
        record = CompileRecord(data["engine"], data["device"], data["seconds"])
        if (record.engine, record.device) != (engine, device):
            raise ValueError(f"a record of {record.engine} on {record.device}")
    except (ValueError, KeyError, TypeError) as exc:  # json's errors are ValueErrors
        _log.debug("%s: compile record %s ignored: %s", engine, path, exc)
        return None
    return record


def write_record(cache_dir: Path | None, record: CompileRecord) -> None:
    """Keep ``record`` beside ``cache_dir``, whole (a temporary file renamed over the old one);
    a folder that cannot be written is logged at DEBUG, never raised."""
    if cache_dir is None:
        return
    path = record_path(cache_dir, record.engine, record.device)
    temporary = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", encoding="utf-8", dir=path.parent, prefix=f".{path.name}.",
                                         suffix=".tmp", delete=False) as out:
            temporary = out.name
            json.dump(record.as_dict(), out)
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, path)
        temporary = None
    except OSError as exc:
        _log.debug("%s: compile record %s not written: %s", record.engine, path, exc)
    finally:
        if temporary is not None:
            with contextlib.suppress(OSError):
                os.unlink(temporary)


def about(seconds: float) -> str:
    """A compile time as the announcement rounds it: whole seconds from 10 s, else one decimal
    (at least 0.1)."""
    return f"{seconds:.0f}" if seconds >= 9.95 else f"{max(seconds, 0.1):.1f}"


@dataclass
class Timed:
    """The compile's time (s), set when the :func:`compiling` block ends."""

    seconds: float = 0.0


@contextlib.contextmanager
def compiling(engine: str, device: str, cache_dir: Path | None, what: str) -> Iterator[Timed]:
    """Announce the compile of ``engine`` on ``device`` for ``what`` (the scene's name) with the
    time recorded beside ``cache_dir``, time the block, and record its time when it completes."""
    last = read_record(cache_dir, engine, device)
    estimate = f"about {about(last.seconds)} s" if last is not None else "first compile: no time recorded"
    _log.info("%s: %s compiling (%s)", what, engine, estimate)
    timed = Timed()
    start = time.perf_counter()
    yield timed
    timed.seconds = time.perf_counter() - start
    _log.debug("%s: %s compiled in %.3g s", what, engine, timed.seconds)
    with contextlib.suppress(ValueError):  # a time too short for a record (0 s) is not kept
        write_record(cache_dir, CompileRecord(engine, device, timed.seconds))


def user_cache_dir() -> Path:
    """loopcheck's own cache folder (``$XDG_CACHE_HOME/loopcheck``, else ``~/.cache/loopcheck``):
    where a record goes when the compile fills no cache folder (JAX without a persistent cache)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "loopcheck"


__all__ = ["CompileRecord", "Timed", "about", "compiling", "read_record", "record_path", "user_cache_dir",
           "write_record"]
