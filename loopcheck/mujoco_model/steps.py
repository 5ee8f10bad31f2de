"""The step grid of a MuJoCo-family run: the grid step that puts every load edge of a scene on
the grid (:func:`grid_timestep`, the MuJoCo engine's first candidate and the GPU ports' default)
and the number of steps to the horizon (:func:`step_count`)."""

from __future__ import annotations

import math

from loopcheck.scene import Scene

# The grid step is the largest step ≤ TIMESTEP_CEILING (and ≤ 1/MIN_AUTO_STEPS of the horizon,
# and not below TIMESTEP_FLOOR) that puts every load edge on the step grid.
TIMESTEP_CEILING = 1e-3  # s
TIMESTEP_FLOOR = 1e-5  # s: the grid step's
MIN_AUTO_STEPS = 100


def grid_timestep(scene: Scene, ceiling: float = TIMESTEP_CEILING, *,
                  key: str = "[mujoco] timestep (--timestep)") -> float:
    """The largest step h ≤ min(ceiling, horizon/MIN_AUTO_STEPS) that puts every load edge
    inside the horizon on the step grid (edge/h integral to 1e-9), in s.

    Raises ValueError naming ``simulation.horizon`` (and ``key``, the setting that would give a
    step instead) when that bound is below TIMESTEP_FLOOR. Without such a step down to
    TIMESTEP_FLOOR (edges with no common divisor there), the bound itself is returned and the
    edges stay off the grid (the run warns, and the MuJoCo engine's halving check judges the
    consequence).
    """
    h_max = min(ceiling, scene.horizon / MIN_AUTO_STEPS)
    if h_max < TIMESTEP_FLOOR:
        raise ValueError(f"simulation.horizon {scene.horizon:g} s is too short for an automatic MuJoCo timestep "
                         f"({MIN_AUTO_STEPS} steps of at least {TIMESTEP_FLOOR:g} s): lengthen it or set {key}")
    edges = [e for e in scene.load_edges if 0.0 < e < scene.horizon]
    if not edges:
        return h_max
    first = edges[0]
    for n in range(math.ceil(first / h_max - 1e-9), math.floor(first / TIMESTEP_FLOOR) + 1):
        h = first / n
        if h <= h_max * (1 + 1e-12) and all(abs(e / h - round(e / h)) <= 1e-9 for e in edges):
            return h
    return h_max


def step_count(scene: Scene, h: float) -> int:
    """The number of steps of ``h`` (s) that reach the scene's horizon."""
    return int(math.ceil(scene.horizon / h - 1e-9))
