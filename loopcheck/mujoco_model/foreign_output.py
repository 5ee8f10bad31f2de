"""What JAX, XLA and Warp say, kept from the user and logged in loopcheck's words, as MuJoCo's
warnings are (:mod:`loopcheck.mujoco_model.warning_handler`).

The GPU ports' libraries talk on every channel: Warp prints its banner with ``print`` and its
CUDA warning ("Warp CUDA warning: Could not find or load the NVIDIA CUDA driver ...") from C++
on the process's stderr; JAX logs "An NVIDIA GPU may be present on this machine, but a
CUDA-enabled jaxlib is not installed. Falling back to cpu." on Python's logging, which prints it
bare on stderr when no handler is configured; XLA's C++ logs its own lines (``W1128 ...]``) on
stderr; MJX calls ``logging.info`` on the root logger, which configures the root logger
(``logging.basicConfig``) and so printed every later loopcheck progress line twice
("INFO:loopcheck.compare.engines: ..."); and all of them may raise Python warnings.

While :func:`foreign_output` is active (a port's import, its device's start, its compile and its
run):

- the process's stdout and stderr (file descriptors 1 and 2, where C++ and ``print`` write) go to
  a temporary file in the system's temporary folder (never the working folder);
- Python's warnings are recorded, not shown;
- records of the libraries' loggers (the port names them: ``jax``, ``absl``, ``mujoco.mjx``;
  ``warp``, ``mujoco_warp``) and of the root logger are kept, and a root handler that a library
  configures meanwhile is removed again.

When the block ends, each line is logged on the ``loopcheck.ports`` logger in loopcheck's words
(:func:`in_our_words`): "JAX runs on the CPU: ..." for its fall-back, a warning (a Python warning,
a log record at WARNING or above, a line that says "warning" or "error", XLA's ``W``/``E``/``F``
lines) as ``warning: <engine>: <library> said: <text>`` at WARNING, and the rest (banners, module
loads) at DEBUG (``loopcheck -v`` shows them). Nothing of theirs reaches the user unfiltered.
Nothing loopcheck logs itself may happen inside a block (it would be kept as the library's): a
port announces its compile before it enters one.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import re
import sys
import tempfile
import warnings
from typing import Iterator

_log = logging.getLogger("loopcheck.ports")

KEPT = 20  # the first lines kept per block (the count goes on)

_XLA_LINE = re.compile(r"^([IWEF])\d{4} [\d:.]+\s+\d+\s+\S+:\d+\]\s*(.*)$")  # absl's C++ log prefix

# (pattern, level, loopcheck's words; groups as named): what the libraries say and what it means
_WORDS = [
    (re.compile(r"CUDA-enabled jaxlib is not installed\. Falling back to (\w+)", re.I), logging.INFO,
     lambda m: f"JAX runs on the {m[1].upper()}: an NVIDIA GPU may be present, but the installed jaxlib has no "
               "CUDA (pip install 'jax[cuda12]' to use it)"),
    (re.compile(r"No GPU/TPU found, falling back to (\w+)", re.I), logging.INFO,
     lambda m: f"JAX found no GPU or TPU and runs on the {m[1].upper()}"),
    (re.compile(r"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver", re.I), logging.INFO,
     lambda m: "Warp found no NVIDIA CUDA driver and runs on the CPU"),
    (re.compile(r"^Warp [\d.]+\w* initialized", re.I), logging.DEBUG, lambda m: f"Warp said: {m.string}"),
]
_WARNS = re.compile(r"(warn(ing)?|error)s?\b|\b(failed|fatal)\b", re.I)  # UserWarning, RuntimeError too


def in_our_words(library: str, text: str, level: int = logging.DEBUG) -> tuple[int, str]:
    """The level and one line for something ``library`` ("JAX", "Warp") said at ``level``
    (its own, when it says one): loopcheck's wording where it knows the message, else
    ``<library> said: <its text>`` on one line, at WARNING when it is a warning or an error."""
    text = " ".join(text.split())
    for pattern, known_level, words in _WORDS:
        found = pattern.search(text)
        if found:
            return known_level, words(found)
    xla = _XLA_LINE.match(text)
    if xla:
        level = max(level, {"I": logging.DEBUG, "W": logging.WARNING, "E": logging.WARNING,
                            "F": logging.ERROR}[xla[1]])
        return min(level, logging.WARNING), f"XLA said: {xla[2]}"
    if _WARNS.search(text):
        level = max(level, logging.WARNING)
    return min(level, logging.WARNING), f"{library} said: {text}"


class _Kept(logging.Handler):
    """A logging handler keeping (level, text) of each record."""

    def __init__(self) -> None:
        logging.Handler.__init__(self, logging.DEBUG)
        self.records: list[tuple[int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.records.append((record.levelno, record.getMessage()))
        except Exception:  # noqa: BLE001 - a library's malformed record is dropped, never raised into it
            pass


def _flush_c_streams() -> None:
    """Flush C's stdio buffers (a library's printf to a pipe sits there until flushed)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to call (not on Linux/macOS)
        pass


@contextlib.contextmanager
def _descriptors_kept(lines: list[str]) -> Iterator[None]:
    """Fds 1 and 2 into a temporary file (the system's temporary folder) for the block; its
    lines appended to ``lines`` afterwards."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    _flush_c_streams()
    saved = []
    with tempfile.TemporaryFile(mode="w+b", prefix="loopcheck-") as kept:
        try:
            for fd in (1, 2):
                try:
                    saved.append((fd, os.dup(fd)))
                except OSError:  # a closed descriptor: nothing to keep from it
                    continue
                os.dup2(kept.fileno(), fd)
            yield
        finally:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            _flush_c_streams()
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            kept.seek(0)
            lines.extend(kept.read().decode("utf-8", "replace").splitlines())


@contextlib.contextmanager
def foreign_output(engine: str, library: str, loggers: tuple[str, ...] = ()) -> Iterator[None]:
    """Keep what ``library`` ("JAX", "Warp") says while the block runs (module docstring), on the
    process's stdout and stderr, as Python warnings, and on the root logger and ``loggers`` (its
    loggers' names, kept from propagating meanwhile), and log it afterwards in loopcheck's words,
    naming ``engine`` (its registry name). A block inside a block adds nothing (the outer one
    keeps it all)."""
    if _depth[0]:
        yield
        return
    handler = _Kept()
    root = logging.getLogger()
    roots_before = list(root.handlers)
    loggers = [logging.getLogger(name) for name in loggers]
    propagation = [lg.propagate for lg in loggers]
    lines: list[str] = []
    caught: list[warnings.WarningMessage] = []
    _depth[0] += 1
    try:
        for lg in loggers:
            lg.addHandler(handler)
            lg.propagate = False
        root.addHandler(handler)  # a library's logging.info() on the root then configures nothing
        with _descriptors_kept(lines), warnings.catch_warnings(record=True) as recorded:
            warnings.simplefilter("always")
            try:
                yield
            finally:
                caught = list(recorded)
    finally:
        _depth[0] -= 1
        for lg, propagate in zip(loggers, propagation):
            lg.removeHandler(handler)
            lg.propagate = propagate
        root.removeHandler(handler)
        for added in [h for h in root.handlers if h not in roots_before]:  # logging.basicConfig() by a library
            root.removeHandler(added)
        said = [(logging.DEBUG if issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning))
                 else logging.WARNING, str(w.message)) for w in caught]
        said += handler.records
        said += [(logging.DEBUG, line) for line in lines if line.strip()]
        _report(engine, library, said)


_depth = [0]


def _report(engine: str, library: str, said: list[tuple[int, str]]) -> None:
    seen: set[str] = set()
    shown = 0
    for level, text in said:
        level, line = in_our_words(library, text, level)
        if line in seen:
            continue
        seen.add(line)
        if shown == KEPT:
            _log.debug("%s: %s said more (not kept)", engine, library)
            break
        shown += 1
        if level >= logging.WARNING:
            _log.warning("warning: %s: %s", engine, line)
        else:
            _log.log(level, "%s: %s", engine, line)


__all__ = ["foreign_output", "in_our_words"]
