"""The integrators' two event hooks on closed forms (Python subclasses of RightHandSide: the
kernels know nothing of linkages): ``locate`` (RKN4 takes the step that crossed the stop margin
again, to its root) and ``stop_at_start`` (a load piece's start ends the run at once)."""

from __future__ import annotations

import math

from helpers import ClosedForm, run_dop853, run_rkn


class Located(ClosedForm):
    def locate(self, t, q, v):
        return True


class BrokenLooseAt(ClosedForm):
    """Ends the run at the start of load piece ``piece`` (the value of its load)."""

    def __init__(self, *args, piece_value, **kw):
        super().__init__(*args, **kw)
        self.piece_value, self.load = piece_value, None

    def acceleration(self, load, t, q, v):
        self.load = load
        return super().acceleration(load, t, q, v)

    def stop_at_start(self, t, q, v):
        return self.values[self.load] == self.piece_value


def test_rkn4_locates_the_stop_at_its_root_when_asked():
    """q̈ = −q from (0, 1), the margin 0.5 − q: RKN4 at h = 0.01 ends at π/6 to 5.9e-11 s (measured:
    the root on the step's cubic Hermite interpolant, of order 4 in h; asserted 2e-10), where without
    ``locate`` it ends at the first step past it (0.53 s); there q − 0.5 = 1.1e-11 and q̇ − cos t =
    8e-12 (the re-taken step's own state; asserted 5e-11). Planted: the step not taken again."""
    outcome, t, q, v, *_ = run_rkn(Located(lambda t, q, v, u: -q, stop=lambda t, q, v: 0.5 - q), [0.0, 3.0],
                                   0.0, 1.0, 0.01, use_stop=True)
    assert outcome.stopped and abs(t[-1] - math.pi / 6) < 2e-10 and outcome.t_reached == t[-1]
    assert abs(q[-1] - 0.5) < 5e-11 and abs(v[-1] - math.cos(t[-1])) < 5e-11
    assert t[-2] < t[-1] and len(t) == math.floor(math.pi / 6 / 0.01) + 2  # the crossing step replaced


def test_a_piece_start_can_end_the_run():
    """A problem that asks at the start of its second piece (load 2.0 from t = 0.5): both
    integrators end there, the last sample at 0.5 s with no step of the new piece."""
    def make():
        return BrokenLooseAt(lambda t, q, v, u: u, values=(1.0, 2.0), piece_value=2.0,
                             stop=lambda t, q, v: 1.0)
    for run in (lambda rhs: run_rkn(rhs, [0.0, 0.5, 1.0], 0.0, 0.0, 0.01, use_stop=True),
                lambda rhs: run_dop853(rhs, [0.0, 0.5, 1.0], 0.0, 0.0, use_stop=True)):
        outcome, t, q, *_ = run(make())
        assert outcome.stopped and t[-1] == 0.5 and abs(q[-1] - 0.125) < 1e-12
