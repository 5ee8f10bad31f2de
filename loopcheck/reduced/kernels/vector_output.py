"""The n-coordinate integrators' samples: :class:`.output.Samples` with q, q̇, q̈ as rows of n.

A :class:`VectorSamples` holds time, q, q̇, q̈ (each sample a row of n), what the problem observed
(:class:`.vector_problem.VectorRightHandSide`) and the two energy flows (the work done on the
system and the energy dissipated since the run's start, J) of every sample, in arrays that grow
by doubling, as :class:`.output.Samples` does for one coordinate (reserved a piece at a time,
never per step; reusable across runs with :meth:`VectorSamples.clear`). How a run ended is an
:class:`.output.Outcome` with the statuses of :mod:`.output`.
"""

import cython
import numpy as np


@cython.cclass
class VectorSamples:
    """Growable sample buffers of n coordinates (module docstring); ``width`` observed values per sample."""

    def __init__(self, n: cython.Py_ssize_t, width: cython.Py_ssize_t, capacity: cython.Py_ssize_t = 256):
        if n < 1 or width < 0 or capacity < 1:
            raise ValueError(f"VectorSamples(n={n}, width={width}, capacity={capacity}): n ≥ 1, width ≥ 0 and "
                             f"capacity ≥ 1")
        self.dimension = n
        self.width = width
        self.n = 0
        self._allocate(capacity)

    @cython.cfunc
    def _allocate(self, capacity: cython.Py_ssize_t):
        self.t = np.empty(capacity)
        self.q = np.empty((capacity, self.dimension))
        self.v = np.empty((capacity, self.dimension))
        self.a = np.empty((capacity, self.dimension))
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
        """Copies of the samples held: t (m,), q, v, a (m, n), observed (m, width), energy (m, 2)."""
        n = self.n
        return (np.array(self.t[:n]), np.array(self.q[:n]), np.array(self.v[:n]), np.array(self.a[:n]),
                np.array(self.observed[:n, :self.width]), np.array(self.energy[:n]))


@cython.ccall
def check_vector_run(out: VectorSamples, dimension: cython.Py_ssize_t, width: cython.Py_ssize_t,
                     q0: cython.double[::1], v0: cython.double[::1], edges: cython.Py_ssize_t,
                     pieces: cython.Py_ssize_t):
    """What an n-coordinate integrator's loops trust, checked once at its entry (they run without
    bounds checks): the problem's ``dimension`` n ≥ 1 is the length of q0, v0 and of ``out``'s rows,
    ``out`` holds rows of the problem's ``width`` observed values, and the load history has one more
    edge than pieces, at least one piece. ValueError otherwise."""
    if dimension < 1 or q0.shape[0] != dimension or v0.shape[0] != dimension:
        raise ValueError(f"the problem has dimension() {dimension}, the initial state {q0.shape[0]} and "
                         f"{v0.shape[0]} values: one per coordinate, at least one")
    if out.dimension != dimension:
        raise ValueError(f"VectorSamples of {out.dimension} coordinates != the problem's dimension() {dimension}")
    if out.width != width:
        raise ValueError(f"VectorSamples width {out.width} != the problem's observation_size() {width}")
    if pieces < 1 or edges != pieces + 1:
        raise ValueError(f"{edges} edges for {pieces} load pieces: one more edge than pieces, at least one piece")
