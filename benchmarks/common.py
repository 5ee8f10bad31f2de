"""Timing helpers for the benchmark scripts (not part of the test suite)."""

from __future__ import annotations

import statistics
import time
from typing import Callable


def median_time(run: Callable[[], object], repeats: int = 7) -> float:
    """Median wall time (s) of ``repeats`` calls, after one warm-up call."""
    run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def largest_passing(candidates, error_of: Callable[[float], float], target: float):
    """The first candidate (ordered cheapest first) whose error is at most ``target``."""
    for c in candidates:
        err = error_of(c)
        if err <= target:
            return c, err
    return None, None
