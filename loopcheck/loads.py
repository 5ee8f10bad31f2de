"""Torque profiles T(t) on the input link (N·m), piecewise constant in time.

Each profile lists its discontinuities (``edges``) so that integrators can put a
step boundary on each one, and can be evaluated on one smooth piece
(:meth:`LoadProfile.on_piece`) so that every stage inside a step sees the same
side of an edge (seed-notes erratum 5, README).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np


def _finite(owner: str, name: str, value: float) -> None:
    if not math.isfinite(value):
        raise ValueError(f"{owner}.{name} must be finite, got {value}")


class LoadProfile:
    """Base class: the load on the input joint over time, a right-continuous, piecewise-constant
    function: a torque (N·m) on a revolute input, a force (N) on a prismatic one."""

    def __call__(self, t: float) -> float:
        """The load at t (N·m or N); at an edge, the value after it."""
        raise NotImplementedError

    @property
    def edges(self) -> tuple[float, ...]:
        """Times (s) where T(t) jumps."""
        raise NotImplementedError

    def on_piece(self, start: float, end: float) -> Callable[[float], float]:
        """T on the open interval (start, end), extended continuously to its ends."""
        inside = self(0.5 * (start + end))
        return lambda t: inside

    def sample(self, times: np.ndarray) -> np.ndarray:
        """T at each time (right-continuous), shape like ``times``."""
        return np.array([self(float(t)) for t in np.ravel(times)]).reshape(np.shape(times))

    def impulse_bound(self, horizon: float) -> float:
        """An upper bound of ∫₀^horizon |T| dt (N·m·s), for the scene's work limit."""
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantLoad(LoadProfile):
    """T = amplitude for all t."""

    amplitude: float

    def __post_init__(self):
        _finite("ConstantLoad", "amplitude", self.amplitude)

    def __call__(self, t: float) -> float:
        return self.amplitude

    def sample(self, times: np.ndarray) -> np.ndarray:
        return np.full(np.shape(times), self.amplitude)

    def impulse_bound(self, horizon: float) -> float:
        return abs(self.amplitude) * horizon

    @property
    def edges(self) -> tuple[float, ...]:
        return ()


@dataclass(frozen=True)
class PulseLoad(LoadProfile):
    """T = amplitude for start ≤ t < start + duration, zero otherwise."""

    amplitude: float
    start: float
    duration: float

    def __post_init__(self):
        for name in ("amplitude", "start", "duration"):
            _finite("PulseLoad", name, getattr(self, name))
        for name in ("start", "duration"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"PulseLoad.{name} must not be negative, got {getattr(self, name)}")

    def __call__(self, t: float) -> float:
        return self.amplitude if self.start <= t < self.start + self.duration else 0.0

    def sample(self, times: np.ndarray) -> np.ndarray:
        times = np.asarray(times, dtype=float)
        return np.where((times >= self.start) & (times < self.start + self.duration), self.amplitude, 0.0)

    @property
    def edges(self) -> tuple[float, ...]:
        return (self.start, self.start + self.duration)

    def impulse_bound(self, horizon: float) -> float:
        return abs(self.amplitude) * max(0.0, min(self.duration, horizon - self.start))


@dataclass(frozen=True)
class PiecewiseConstantLoad(LoadProfile):
    """T = values[i] for times[i] ≤ t < times[i+1]; zero before times[0]; the last value holds."""

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self):
        if len(self.times) != len(self.values) or not self.times:
            raise ValueError("PiecewiseConstantLoad.times and .values must have the same, non-zero length,"
                             f" got {len(self.times)} and {len(self.values)}")
        for name in ("times", "values"):
            for i, v in enumerate(getattr(self, name)):
                _finite("PiecewiseConstantLoad", f"{name}[{i}]", v)
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ValueError("PiecewiseConstantLoad.times must be strictly increasing")

    def __call__(self, t: float) -> float:
        i = bisect.bisect_right(self.times, t) - 1
        return 0.0 if i < 0 else self.values[i]

    def sample(self, times: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.times, np.asarray(times, dtype=float), side="right") - 1
        return np.where(i < 0, 0.0, np.asarray(self.values)[np.maximum(i, 0)])

    @property
    def edges(self) -> tuple[float, ...]:
        return self.times

    def impulse_bound(self, horizon: float) -> float:
        return max(abs(v) for v in self.values) * horizon


@dataclass(frozen=True)
class TabulatedForce:
    """F(q): a force magnitude (N) tabulated over the input coordinate q (rad or m).

    An interpolating spline of degree 5 through the table (scipy's ``make_interp_spline``;
    degree 3 or 1 for tables of fewer than 6 or 4 points): periodic with ``period`` when given
    (the table is closed by repeating its first value one period on), else with not-a-knot ends
    and F held at the end values outside the table. C⁴ in q: a cubic spline (C²) made DOP853 at
    rtol 1e-12 misjudge its steps across the knots of the catalogue's gas-force table (energy
    balance 3.6e-9 over 0.2 s, against 7.7e-11 with degree 5 and 16 % fewer evaluations).
    Like any interpolating spline it overshoots between the points of a sharply peaked table
    (the catalogue's gas force, 20° apart: 4.2 % above its largest value, 3.3 % with a cubic):
    tabulate densely near a peak.
    """

    coordinate: tuple[float, ...]
    values: tuple[float, ...]
    period: float | None = None

    def __post_init__(self):
        from scipy.interpolate import make_interp_spline

        q = np.asarray(self.coordinate, dtype=float)
        f = np.asarray(self.values, dtype=float)
        if self.period is not None:
            if q[-1] - q[0] >= self.period * (1 - 1e-12):  # the last point is the first repeated
                q, f = q[:-1], f[:-1]
            q, f = np.append(q, q[0] + self.period), np.append(f, f[0])
        degree = 5 if len(q) >= 6 else 3 if len(q) >= 4 else 1
        spline = make_interp_spline(q, f, k=degree, bc_type="periodic" if self.period is not None and degree > 1
                                    else None) if len(q) > 2 else None
        object.__setattr__(self, "_knots", q)
        object.__setattr__(self, "_spline", spline)

    def __call__(self, q: float | np.ndarray) -> float | np.ndarray:
        knots = self._knots
        x = np.asarray(q, dtype=float)
        if self.period is not None:
            x = knots[0] + np.mod(x - knots[0], self.period)
        else:
            x = np.clip(x, knots[0], knots[-1])
        if self._spline is None:  # two points: the straight line
            out = np.interp(x, knots, np.asarray(self.values if self.period is None else
                                                 (self.values[0], self.values[0]), dtype=float))
        else:
            out = self._spline(x)
        return float(out) if np.ndim(out) == 0 else out

    def bound(self) -> float:
        """max |F| over the table's spline (N), sampled finely; for the scene's work limit."""
        knots = self._knots
        return float(np.max(np.abs(self(np.linspace(knots[0], knots[-1], 64 * len(knots))))))
