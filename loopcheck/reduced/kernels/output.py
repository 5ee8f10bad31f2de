"""The integrators' output: samples appended to buffers that the caller owns, and how a run ended.

A :class:`Samples` holds time, q, q̇, q̈, what the problem observed (:class:`.problem.RightHandSide`)
and the two energy flows (the work done on the system and the energy dissipated since the
run's start, J) of every sample, in arrays that grow by doubling. An integrator reserves room
for a piece's samples before it writes them (:meth:`Samples.reserve`), never per step: a run
reallocates O(log m) times for m samples (a :class:`Samples` may be cleared and reused across
runs, and then reallocates only while it grows). Several charts of one run append to the same
buffers, so a run's samples come out in one piece.
"""

import cython
import numpy as np

# How a run ended (:attr:`Outcome.status`; ``loopcheck.reduced.charts`` names them for users).
OK = 0                 #: reached the end of the last piece, or the stop event ended it
STEP_SIZE = 1          #: DOP853: its budget of evaluations spent, or the step below the spacing of floats
NONFINITE = 2          #: a non-finite state, or q̈ not finite at a stage or sample (fail_time: where)
SPEED = 3              #: |q̇| > speed_limit at a sample (fail_time, fail_value: where, q̇)
UNSTABLE = 4           #: RKN4: the step outside the stability region (detail: Re hλ, Im hλ, |R|, limit)
FAILED = 5             #: the problem could not be evaluated (its own status says why)
NO_BETTER = 6          #: chart switching: the stop event fired but no coordinate is better
TOO_MANY_SWITCHES = 7  #: chart switching: more switches than allowed
SINGULAR_START = 8     #: chart switching: the initial configuration is singular in its coordinate
RANGE_REACHED = 9      #: a joint reached a bound of its range (fail_time; detail: range, side, u, bound)


@cython.cclass
class Outcome:
    """How an integrator's run ended and what it cost (one per run, filled by the integrator)."""

    def __init__(self):
        self.status = OK
        self.stopped = False
        self.n_steps = 0
        self.n_evaluations = 0
        self.n_sample_evaluations = 0
        self.t_reached = float("nan")
        self.fail_time = float("nan")
        self.fail_value = float("nan")
        self.detail = np.full(4, np.nan)

    def __repr__(self):
        return (f"Outcome(status={self.status}, stopped={self.stopped}, n_steps={self.n_steps}, "
                f"n_evaluations={self.n_evaluations}, t_reached={self.t_reached}, fail_time={self.fail_time})")


@cython.cclass
class Samples:
    """Growable sample buffers (module docstring); ``width`` observed values per sample."""

    def __init__(self, width: cython.Py_ssize_t, capacity: cython.Py_ssize_t = 256):
        if width < 0 or capacity < 1:
            raise ValueError(f"Samples(width={width}, capacity={capacity}): width ≥ 0 and capacity ≥ 1")
        self.width = width
        self.n = 0
        self._allocate(capacity)

    @cython.cfunc
    def _allocate(self, capacity: cython.Py_ssize_t):
        self.t = np.empty(capacity)
        self.q = np.empty(capacity)
        self.v = np.empty(capacity)
        self.a = np.empty(capacity)
        self.observed = np.empty((capacity, max(self.width, 1)))
        self.energy = np.empty((capacity, 2))

    @cython.ccall
    def reserve(self, extra: cython.Py_ssize_t):
        """Room for ``extra`` more samples (grows by doubling, keeping the samples held)."""
        capacity: cython.Py_ssize_t = self.t.shape[0]
        if self.n + extra <= capacity:
            return
        while capacity < self.n + extra:
            capacity *= 2
        n = self.n
        t, q, v, a = np.asarray(self.t), np.asarray(self.q), np.asarray(self.v), np.asarray(self.a)
        observed, energy = np.asarray(self.observed), np.asarray(self.energy)
        self._allocate(capacity)  # then each held sample copied once, into the new buffers
        np.asarray(self.t)[:n] = t[:n]
        np.asarray(self.q)[:n] = q[:n]
        np.asarray(self.v)[:n] = v[:n]
        np.asarray(self.a)[:n] = a[:n]
        np.asarray(self.observed)[:n] = observed[:n]
        np.asarray(self.energy)[:n] = energy[:n]

    @cython.ccall
    def clear(self):
        """Forget every sample (keeps the buffers)."""
        self.n = 0

    def arrays(self):
        """Copies of the samples held: t, q, v, a (m,), observed (m, width), energy (m, 2)."""
        n = self.n
        return (np.array(self.t[:n]), np.array(self.q[:n]), np.array(self.v[:n]), np.array(self.a[:n]),
                np.array(self.observed[:n, :self.width]), np.array(self.energy[:n]))


@cython.ccall
def check_run(out: Samples, width: cython.Py_ssize_t, edges: cython.Py_ssize_t, pieces: cython.Py_ssize_t):
    """What an integrator's loops trust, checked once at its entry (they run without bounds
    checks): ``out`` holds rows of the problem's ``width`` observed values, and the load history
    has one more edge than pieces, at least one piece. ValueError otherwise."""
    if out.width != width:
        raise ValueError(f"Samples width {out.width} != the problem's observation_size() {width}")
    if pieces < 1 or edges != pieces + 1:
        raise ValueError(f"{edges} edges for {pieces} load pieces: one more edge than pieces, at least one piece")
