"""What MuJoCo's automatic timestep search reports it took (``details.search_cost``) is what its
own checks say it ran: every check runs its coarse step and its fine step h/2, except that a
check whose coarse step is the previous check's fine step reuses that run; each run's steps are
the horizon over its step, rounded up. The count is made here from the check records alone,
independently of the search's own bookkeeping, on two shipped mechanisms without their fixed step
whose search jumps by the fitted order (a new coarse run: measured 3 checks, 5 runs each)."""

from __future__ import annotations

import math
import tomllib

import pytest

from loopcheck.scenefile import scene_from_dict
from loopcheck.reference_models import simulate_mujoco

from helpers import ROOT


def _runs_and_steps(horizon: float, checks) -> tuple[int, int]:
    steps_run = []
    for i, check in enumerate(checks):
        h = check.timestep
        reused = i > 0 and h == checks[i - 1].timestep / 2
        steps_run += ([] if reused else [h]) + [h / 2]
    return len(steps_run), sum(math.ceil(horizon / h - 1e-9) for h in steps_run)


@pytest.mark.parametrize("name", ["slider_crank_driven_slider.toml", "oscillating_slotted_lever.toml"])
def test_the_search_cost_counts_every_run_its_checks_made(name):
    with open(ROOT / "scenes" / "mechanisms" / name, "rb") as f:
        data = tomllib.load(f)
    data.pop("mujoco", None)  # the automatic step
    scene = scene_from_dict(data)
    details = simulate_mujoco(scene).details
    checks = details.timestep_checks
    runs, steps = _runs_and_steps(scene.horizon, checks)
    assert runs > len(checks) + 1  # a jump by the fitted order: a run that is no halving's
    assert (details.search_cost.runs, details.search_cost.steps) == (runs, steps)
