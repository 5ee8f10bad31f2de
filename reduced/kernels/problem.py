"""TEMPORARY TOY problem for the adaptive kernel (replaced by the physics at merge).

The integrator (:mod:`reduced.kernels.adaptive`) imports exactly ``acceleration`` and
``stop_margin`` from here and treats ``problem`` and ``chart`` as opaque values it passes
through. The toy is a damped, forced nonlinear pendulum, q̈ = -k sin q - c q̇ + load + w cos t, or with
``linear = 1`` the linear oscillator q̈ = -k q - c q̇ + load + w cos t (a closed form for error
checks with c = w = 0).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


class ToyProblem(NamedTuple):
    k: float        # stiffness (1/s²)
    c: float        # damping (1/s)
    q_stop: float   # the chart ends where q reaches q_stop (from below)
    t_nan: float    # from this time on the acceleration is NaN (math.inf: never)
    linear: float   # 1.0: spring -k q instead of -k sin q
    w: float        # amplitude of an explicit time dependence w cos t


class ToyChart(NamedTuple):
    calls: np.ndarray  # float64 (1,): evaluations of the acceleration (proves mutation works)


def make_toy(k: float = 1.0, c: float = 0.0, q_stop: float = math.inf,
             t_nan: float = math.inf, linear: bool = False,
             w: float = 0.0) -> tuple[ToyProblem, ToyChart]:
    """A toy problem and a fresh chart with its call counter at zero."""
    return (ToyProblem(float(k), float(c), float(q_stop), float(t_nan), 1.0 if linear else 0.0,
                       float(w)),
            ToyChart(np.zeros(1)))


@njit(cache=True)
def acceleration(problem, chart, load, t, q, v):
    """q̈ of the chart coordinate; NaN from ``problem.t_nan`` on (a failure to signal)."""
    chart.calls[0] += 1.0
    if t >= problem.t_nan:
        return math.nan
    spring = q if problem.linear == 1.0 else math.sin(q)
    return -problem.k * spring - problem.c * v + load + problem.w * math.cos(t)


@njit(cache=True)
def stop_margin(problem, chart, t, q, v):
    """> 0 while the chart is fine; the run ends where it crosses zero downwards."""
    return problem.q_stop - q
