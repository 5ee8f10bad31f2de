"""MuJoCo's warnings: the one handler for loading a model, running it and importing a user's MJCF.

MuJoCo's default handler prints ``WARNING: ...`` and appends it to ``MUJOCO_LOG.TXT`` in the
working folder. While :func:`mujoco_warnings` is active the process's handler is this module's
instead (and :func:`compile_spec` catches the compiler's, which MuJoCo's Python package raises
as Python warnings): each warning is kept (:class:`Warnings`) and logged on the ``loopcheck.mujoco`` logger
(DEBUG) in loopcheck's words, and nothing is printed or written; the previous handler comes back
afterwards. Its callers decide what a warning means: a warning that MuJoCo reset the state (bad
qpos, qvel or qacc: :func:`bad_state`) fails the run at its time; the others (a buffer too small
and the like) are reported (:meth:`Warnings.report`, WARNING on that logger).
"""

from __future__ import annotations

import contextlib
import logging
import re
import warnings
from dataclasses import dataclass, field
from typing import Iterator

import mujoco

_log = logging.getLogger("loopcheck.mujoco")

KEPT = 20  # the first warnings kept (the count goes on)

# The warnings after which mj_step resets the state (mj_checkPos, mj_checkVel, mj_checkAcc).
BAD_STATE = {int(mujoco.mjtWarning.mjWARN_BADQPOS): "position (qpos)",
             int(mujoco.mjtWarning.mjWARN_BADQVEL): "velocity (qvel)",
             int(mujoco.mjtWarning.mjWARN_BADQACC): "acceleration (qacc)"}

# MuJoCo's texts, reworded: (pattern, loopcheck's words; groups as named)
_RESET = re.compile(r"Nan, Inf or huge value in (QPOS|QVEL|QACC) at DOF (\d+)\. The simulation is unstable\. "
                    r"Time = ([-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)")
_WORDS = [
    (_RESET,
     lambda m: f"MuJoCo found a NaN, infinite or huge {m[1].lower()} at dof {m[2]} (t = {float(m[3]):g} s) and "
               "reset the state"),
    (re.compile(r"XML contains a 'NaN'"), lambda m: "MuJoCo's parser found 'NaN' in the file"),
    (re.compile(r"Inertia matrix is too close to singular.*?DOF (\d+)"),
     lambda m: f"MuJoCo found the mass matrix singular at dof {m[1]}"),
]


def in_our_words(text: str) -> str:
    """One line for a MuJoCo warning: loopcheck's wording where it knows the warning, else
    ``MuJoCo warned: <its text>`` on one line."""
    text = " ".join(text.split())
    for pattern, words in _WORDS:
        found = pattern.search(text)
        if found:
            return words(found)
    return f"MuJoCo warned: {text.removeprefix('WARNING: ')}"


@dataclass
class Warnings:
    """The warnings MuJoCo gave inside one :func:`mujoco_warnings` block, in loopcheck's words
    (the first :data:`KEPT`; ``count`` counts all), but for its resets of the state (``resets``
    counts them): a run that MuJoCo reset fails with its own message (:func:`bad_state`)."""

    lines: list[str] = field(default_factory=list)
    count: int = 0
    resets: int = 0

    def add(self, text: str) -> None:
        line = in_our_words(text)
        _log.debug("%s", line)
        if _RESET.search(" ".join(text.split())):
            self.resets += 1
            return
        self.count += 1
        if len(self.lines) < KEPT:
            self.lines.append(line)

    def report(self, where: str) -> None:
        """Log every warning kept on the ``loopcheck.mujoco`` logger at WARNING, naming ``where``
        (a reset of the state is not among them: the run it happened in failed, and an automatic
        timestep search went on to a smaller step)."""
        for line in dict.fromkeys(self.lines):
            _log.warning("warning: %s: %s", where, line)
        if self.count > len(self.lines):
            _log.warning("warning: %s: %d more MuJoCo warnings", where, self.count - len(self.lines))


_active: list[Warnings] = []


def _handler(text: str) -> None:
    # Called from MuJoCo's C code (inside mujoco.rollout too): an exception here would terminate
    # the process, so none leaves.
    try:
        if _active:
            _active[-1].add(text)
        else:  # a warning outside a block (the handler is only installed inside one): still ours
            _log.debug("%s", in_our_words(text))
    except Exception:  # noqa: BLE001 (see above)
        pass


@contextlib.contextmanager
def mujoco_warnings() -> Iterator[Warnings]:
    """Route MuJoCo's warnings into a :class:`Warnings` for the block; the process's previous
    handler is restored afterwards."""
    kept = Warnings()
    previous = mujoco.get_mju_user_warning()
    _active.append(kept)
    mujoco.set_mju_user_warning(_handler)
    try:
        yield kept
    finally:
        _active.remove(kept)
        mujoco.set_mju_user_warning(previous if not _active else _handler)


def compile_spec(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """``spec.compile()``, with the compiler's warnings (which MuJoCo's Python package raises as
    Python warnings, in MuJoCo's words) handed to the active :func:`mujoco_warnings` block (logged
    at DEBUG outside one) instead of printed. ValueError: MuJoCo's compile error."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = spec.compile()
    for w in caught:
        _handler(str(w.message))
    return model


@dataclass(frozen=True)
class BadState:
    """MuJoCo's first reset of a run: which state was bad, at which dof, how many times."""

    what: str
    dof: int
    number: int

    def message(self, time: float | None, options: str) -> str:
        at = f" at t = {time:.6g} s" if time is not None else ""
        return (f"MuJoCo found a NaN, infinite or huge {self.what} at dof {self.dof}{at} and reset the state: the "
                f"simulation is unstable at {options}")


def bad_state(data: mujoco.MjData) -> BadState | None:
    """The bad-state warning ``data`` counts (qpos first), else None."""
    for kind, what in BAD_STATE.items():
        w = data.warning[kind]
        if w.number:
            return BadState(what, int(w.lastinfo), int(w.number))
    return None


def singular_mass_matrix(data: mujoco.MjData, options: str) -> str | None:
    """The failure's message when MuJoCo found the mass matrix singular in the run (its inertia
    warning: the accelerations are not to be trusted), else None."""
    w = data.warning[int(mujoco.mjtWarning.mjWARN_INERTIA)]
    if not w.number:
        return None
    return f"MuJoCo found the mass matrix singular at dof {w.lastinfo} ({w.number} time(s)) at {options}"


__all__ = ["BAD_STATE", "BadState", "Warnings", "bad_state", "compile_spec", "in_our_words", "mujoco_warnings",
           "singular_mass_matrix"]
