"""What the integrators see of a problem: q̈ = f(t, q, q̇) behind one C-level interface.

:class:`RightHandSide` is a compiled class whose methods the integrators call through its
table of C function pointers (Cython's ``cpdef`` methods: a virtual call from compiled code, an
ordinary method from Python). The integrators (:mod:`.fixed_step`, :mod:`.adaptive`) take one as
an argument and know nothing else of the problem; the linkage chart of :mod:`.physics` is one,
and a Python subclass is another (the integrators' order tests use closed forms written so,
``tests/reduced/kernels/test_kernel_integrators.py``; a Python override is called through the interpreter, slow
but the same algorithm).

Only :meth:`acceleration` must be defined. The others default to a problem that observes
nothing, exchanges no energy and never asks to stop:

- ``acceleration(load, t, q, v)``: q̈ on load piece ``load`` (its index: the loads over time are
  constant on a piece); NaN where the problem cannot be evaluated;
- ``power(load, v)`` and ``dissipation(v)``: right after an ``acceleration``, the rates (W) of
  the two energy flows the integrators integrate alongside the state: the work done on the
  system and the energy dissipated;
- ``stop_margin(t, q, v)``: > 0 while no event has happened (the problem's coordinate serves,
  and whatever else it watches); the run ends where it crosses to ≤ 0. It is read on the load
  piece of the latest ``acceleration`` (the integrators evaluate q̈ on a piece before its
  margin); what the event was and what follows is the caller's (:mod:`.partition` asks the chart);
- ``locate(t, q, v)``: at a stop the fixed-step integrator found after a step, True where the
  event must be located at its root (the step taken again to it), False where stopping after
  the step will do;
- ``stop_at_start(t, q, v)``: True where the run must end at a load piece's start, right after
  its first ``acceleration`` (an event the load edge itself causes: a stuck joint broken loose,
  an actuator's force moved past its forcerange or back inside);
- ``observation_size()`` and ``observe(out, row)``: what the problem records at a sample, right
  after the sample's ``acceleration``, into ``out[row, :observation_size()]``;
- ``mark()`` and ``rewind()``: remember the problem's state at a piece's start, and go back to
  it, so that the piece's samples are evaluated in order from its start once it is integrated.
"""

import cython


@cython.cclass
class RightHandSide:
    """q̈ = f(t, q, q̇), constant-load on each piece of the load history (module docstring)."""

    @cython.ccall
    def acceleration(self, load: cython.Py_ssize_t, t: cython.double, q: cython.double,
                     v: cython.double) -> cython.double:
        raise NotImplementedError("a RightHandSide defines acceleration(load, t, q, v)")

    @cython.ccall
    def power(self, load: cython.Py_ssize_t, v: cython.double) -> cython.double:
        return 0.0

    @cython.ccall
    def dissipation(self, v: cython.double) -> cython.double:
        return 0.0

    @cython.ccall
    def stop_margin(self, t: cython.double, q: cython.double, v: cython.double) -> cython.double:
        return 1.0

    @cython.ccall
    def locate(self, t: cython.double, q: cython.double, v: cython.double) -> cython.bint:
        return False

    @cython.ccall
    def stop_at_start(self, t: cython.double, q: cython.double, v: cython.double) -> cython.bint:
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
