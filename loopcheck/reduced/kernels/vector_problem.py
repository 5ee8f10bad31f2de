"""What the n-coordinate integrators see of a problem: q̈ = f(t, q, q̇), q ∈ Rⁿ, behind one C-level interface.

:class:`VectorRightHandSide` is :class:`.problem.RightHandSide` for n ≥ 1 coordinates: a compiled
class whose methods the integrators (:mod:`.vector_adaptive`, :mod:`.vector_fixed_step`) call
through its table of C function pointers (``cpdef``: a virtual call from compiled code, an
ordinary method from Python). The integrators know nothing else of the problem. A compiled
subclass (a linkage's chart in n coordinates) is called at C speed; a Python subclass works too
(the integrators' tests write closed forms so, ``tests/reduced/kernels/test_vector_integrators.py``),
called through the interpreter: slow, but the same algorithm.

Arrays: every ``q``, ``v`` (q̇) and ``a`` (q̈) is a C-contiguous view of n doubles that the
integrator owns (its workspace): read ``q`` and ``v``, write ``a``; never keep a reference to any
of them beyond the call (they are overwritten at the next one), and never write ``q`` or ``v``.

Only :meth:`~VectorRightHandSide.dimension` and :meth:`~VectorRightHandSide.acceleration` must be
defined. The others default to a problem that observes nothing, exchanges no energy and never
asks to stop; each is the scalar interface's method with q, q̇ as n-vectors:

- ``dimension()``: n, the number of coordinates (the integrators check their initial state
  against it once, at their entry);
- ``acceleration(load, t, q, v, a)``: q̈ into ``a`` on load piece ``load`` (its index: the loads
  over time are constant on a piece). Returns 0 where it evaluated; any other value where the
  problem cannot be evaluated there (the problem keeps why; the integrator ends the run:
  NONFINITE for DOP853, FAILED for RKN4, as a non-finite q̈ does, which is also refused);
- ``power(load, v)`` and ``dissipation(v)``: right after an ``acceleration``, the rates (W) of
  the two energy flows the integrators integrate alongside the state: the work done on the
  system (Σᵢ Qᵢ q̇ᵢ for generalised forces Qᵢ) and the energy dissipated (≥ 0);
- ``stop_margin(t, q, v)``: > 0 while no event has happened (the problem's coordinates serve,
  and whatever else it watches); the run ends where it crosses to ≤ 0 (a terminal event of
  direction −1, located at its root by DOP853; :mod:`.vector_fixed_step` stops after the step,
  or at the root where ``locate`` says so). It is read on the load piece of the latest
  ``acceleration`` (the integrators evaluate q̈ on a piece before its margin); what the event was
  and what follows (another set of coordinates) is the caller's;
- ``locate(t, q, v)``: at a stop the fixed-step integrator found after a step, True where the
  event must be located at its root (the step taken again to it);
- ``stop_at_start(t, q, v)``: True where the run must end at a load piece's start, right after
  its first ``acceleration`` (an event the load edge itself causes);
- ``observation_size()`` and ``observe(out, row)``: what the problem records at a sample, right
  after the sample's ``acceleration``, into ``out[row, :observation_size()]``;
- ``mark()`` and ``rewind()``: remember the problem's state at a piece's start, and go back to
  it, so that the piece's samples are evaluated in order from its start once it is integrated
  (a problem whose evaluation depends on its history, as a chart's Newton walk does).

A compiled subclass, written in Cython's pure-Python mode as the kernels are (a ``.py`` with
its ``.pxd`` declaring ``cdef class Pendulums(VectorRightHandSide)`` and its fields, listed in
``setup.py``), here n pendulums (g/L = ``w2``) in a chain of springs ``k``, with viscous damping
``c`` and a torque ``u[load]`` on the first::

    @cython.cclass
    class Pendulums(VectorRightHandSide):
        def __init__(self, n, w2, k, c, u):
            self.n, self.w2, self.k, self.c = n, w2, k, c
            self.u = np.ascontiguousarray(u, dtype=np.float64)     # one torque per load piece

        @cython.ccall
        def dimension(self) -> cython.Py_ssize_t:
            return self.n

        @cython.ccall
        def acceleration(self, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1],
                         v: cython.double[::1], a: cython.double[::1]) -> cython.int:
            i: cython.Py_ssize_t
            for i in range(self.n):
                a[i] = -self.w2 * sin(q[i]) - self.c * v[i]
                if i > 0:
                    a[i] -= self.k * (q[i] - q[i - 1])
                if i < self.n - 1:
                    a[i] += self.k * (q[i + 1] - q[i])
            a[0] += self.u[load]
            return 0

        @cython.ccall
        def power(self, load: cython.Py_ssize_t, v: cython.double[::1]) -> cython.double:
            return self.u[load] * v[0]

        @cython.ccall
        def dissipation(self, v: cython.double[::1]) -> cython.double:
            s: cython.double = 0.0
            i: cython.Py_ssize_t
            for i in range(self.n):
                s += self.c * v[i] * v[i]
            return s

:class:`ScalarAsVector` is a compiled subclass too: a scalar :class:`.problem.RightHandSide` seen
as one with n = 1 (the n-coordinate integrators run at n = 1 on today's problems: their tests
compare them with the scalar integrators so).
"""

import cython

if cython.compiled:
    from cython.cimports.loopcheck.reduced.kernels.problem import RightHandSide
else:
    from loopcheck.reduced.kernels.problem import RightHandSide


@cython.cclass
class VectorRightHandSide:
    """q̈ = f(t, q, q̇) in n coordinates, constant-load on each piece of the load history (module docstring)."""

    @cython.ccall
    def dimension(self) -> cython.Py_ssize_t:
        raise NotImplementedError("a VectorRightHandSide defines dimension(): its number of coordinates")

    @cython.ccall
    def acceleration(self, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1],
                     v: cython.double[::1], a: cython.double[::1]) -> cython.int:
        raise NotImplementedError("a VectorRightHandSide defines acceleration(load, t, q, v, a)")

    @cython.ccall
    def power(self, load: cython.Py_ssize_t, v: cython.double[::1]) -> cython.double:
        return 0.0

    @cython.ccall
    def dissipation(self, v: cython.double[::1]) -> cython.double:
        return 0.0

    @cython.ccall
    def stop_margin(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.double:
        return 1.0

    @cython.ccall
    def locate(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.bint:
        return False

    @cython.ccall
    def stop_at_start(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.bint:
        return False

    @cython.ccall
    def observation_size(self) -> cython.Py_ssize_t:
        return 0

    @cython.ccall
    def observe(self, out: cython.double[:, ::1], row: cython.Py_ssize_t):
        pass

    @cython.ccall
    def mark(self):
        pass

    @cython.ccall
    def rewind(self):
        pass


@cython.cclass
class ScalarAsVector(VectorRightHandSide):
    """A scalar :class:`.problem.RightHandSide` as a :class:`VectorRightHandSide` of one
    coordinate: each method calls the scalar one with q[0], v[0] (q̈ not finite: status 0 all
    the same, the integrators refuse the non-finite q̈ as the scalar ones do)."""

    def __init__(self, scalar: RightHandSide):
        self.scalar = scalar

    @cython.ccall
    def dimension(self) -> cython.Py_ssize_t:
        return 1

    @cython.ccall
    def acceleration(self, load: cython.Py_ssize_t, t: cython.double, q: cython.double[::1],
                     v: cython.double[::1], a: cython.double[::1]) -> cython.int:
        a[0] = self.scalar.acceleration(load, t, q[0], v[0])
        return 0

    @cython.ccall
    def power(self, load: cython.Py_ssize_t, v: cython.double[::1]) -> cython.double:
        return self.scalar.power(load, v[0])

    @cython.ccall
    def dissipation(self, v: cython.double[::1]) -> cython.double:
        return self.scalar.dissipation(v[0])

    @cython.ccall
    def stop_margin(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.double:
        return self.scalar.stop_margin(t, q[0], v[0])

    @cython.ccall
    def locate(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.bint:
        return self.scalar.locate(t, q[0], v[0])

    @cython.ccall
    def stop_at_start(self, t: cython.double, q: cython.double[::1], v: cython.double[::1]) -> cython.bint:
        return self.scalar.stop_at_start(t, q[0], v[0])

    @cython.ccall
    def observation_size(self) -> cython.Py_ssize_t:
        return self.scalar.observation_size()

    @cython.ccall
    def observe(self, out: cython.double[:, ::1], row: cython.Py_ssize_t):
        self.scalar.observe(out, row)

    @cython.ccall
    def mark(self):
        self.scalar.mark()

    @cython.ccall
    def rewind(self):
        self.scalar.rewind()
