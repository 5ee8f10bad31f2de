"""MuJoCo's automatic timestep search: it goes on while the work limits allow, jumps to the step
the observed order predicts, chooses the step for the tolerances the gate applies, and says,
when it gives up, which step would be needed and what it would cost.

The hard case is our own six-bar near its toggle: the shipped Stephenson III near-toggle scene
with its output link shortened from 0.2581 to 0.257 m and no [mujoco] timestep. The search used to
stop at 1.5625e-5 s (the first step halved six times, the floor) and call the run inaccurate;
measured: the halvings fall with order 2.1, and 1.5625e-5 s (check at 7.8e-6 s) meets the
tolerances, after which the engines agree to 2e-8 in the peak (tolerance 1.7e-5).
"""

from __future__ import annotations

import math
import tomllib

import pytest

from dataclasses import replace

from loopcheck.compare.run import compare_engines
from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.scenefile import scene_from_dict
from loopcheck.reference_models import simulate_mujoco
from loopcheck.reference_models.timestep import (MAX_SEARCH_STEPS, STEP_MARGIN, CheckOutcome, FailedCheck,
                                            MeasuredCheck, _predicted_step)

from helpers import ROOT, variant

MECHANISMS = ROOT / "scenes" / "mechanisms"


def _load(name: str, **changes) -> dict:
    with open(MECHANISMS / name, "rb") as f:
        data = tomllib.load(f)
    data.pop("mujoco", None)  # the automatic step
    data.update(changes)
    return data


def _near_toggle() -> dict:
    data = _load("stephenson3_near_toggle.toml")
    data["bodies"]["output"]["points"]["D"] = [0.257, 0.0]
    return data


def _record(h: float, d: float, limit: float) -> MeasuredCheck:
    return MeasuredCheck(h, "rad", d, d, d, (limit,) * 3, CheckOutcome.EXCEEDED)


@pytest.mark.parametrize("order", [1.0, 2.0, 4.0])
def test_the_predicted_step_follows_the_fitted_order(order):
    """Differences that fall exactly as h^p: the prediction is the step where they meet their
    limit (closed form h·(limit/d)^(1/p)), times the margin."""
    d = lambda h: 3.0 * h ** order
    limit = d(1e-4) / 50.0  # met at 1e-4 · 50^(-1/p)
    evidence = [_record(4e-4, d(4e-4), limit), _record(1e-4, d(1e-4), limit)]
    expected = STEP_MARGIN * 1e-4 * 50.0 ** (-1.0 / order)
    step, fitted = _predicted_step(evidence)
    assert step == pytest.approx(expected, rel=1e-12)
    assert fitted == pytest.approx(order, rel=1e-12)


def test_report_json_keeps_the_keys_of_each_outcome():
    """details.timestep_check in report.json (schema 4): a measured check's differences, limits and
    ``accepted``, ``unconfirmed`` only when true, ``order`` only when fitted; a failed one's
    ``failure``. The typed records write what the mappings they replaced held."""
    unconfirmed = MeasuredCheck(1.25e-4, "rad", 1e-4, 0.1, 0.2, (2.5e-3, 0.125, 0.25), CheckOutcome.UNCONFIRMED,
                                order=2.5)
    assert unconfirmed.as_dict() == {"timestep": 1.25e-4, "unit": "rad", "max_dq": 1e-4, "max_domega": 0.1,
                                     "dpeak": 0.2, "limits": [2.5e-3, 0.125, 0.25], "accepted": False,
                                     "unconfirmed": True, "order": 2.5}
    accepted = replace(unconfirmed, outcome=CheckOutcome.ACCEPTED, order=None)
    assert accepted.accepted and list(accepted.as_dict())[-1] == "accepted" and accepted.as_dict()["accepted"]
    failed = FailedCheck(5e-4, "m", "unstable: MuJoCo's state is not finite")
    assert failed.outcome is CheckOutcome.FAILED and not failed.accepted
    assert failed.as_dict() == {"timestep": 5e-4, "unit": "m", "failure": "unstable: MuJoCo's state is not finite",
                                "accepted": False}
    with pytest.raises(ValueError, match="FailedCheck"):
        MeasuredCheck(5e-4, "m", 0.0, 0.0, 0.0, (1.0,) * 3, CheckOutcome.FAILED)


def test_no_prediction_when_the_differences_do_not_fall():
    assert _predicted_step([_record(4e-4, 1e-3, 1e-6), _record(2e-4, 1e-3, 1e-6)]) == (None, None)
    assert _predicted_step([_record(4e-4, 1e-3, 1e-6)]) == (None, None)


@pytest.mark.slow  # ~15 s: 124 000 MuJoCo steps of a six-bar
def test_a_six_bar_near_its_toggle_passes_the_gate_at_the_defaults():
    c = compare_engines(scene_from_dict(_near_toggle()))
    h = c.other.settings.timestep
    assert c.gate.passed, c.gate.failures
    assert h < 1.5625e-5 and c.other.details.timestep_automatic  # below where the search stopped
    checks = c.other.details.timestep_checks
    assert any(isinstance(r, MeasuredCheck) and r.order for r in checks)  # it jumped by the fitted order


def test_the_step_is_chosen_for_the_gate_tolerances():
    """stephenson3_sixbar without its fixed step, gated at q 1e-6 rad and ω 1e-3 rad/s: the step
    chosen for the file's tolerances failed it (Δω 2.2e-3 rad/s); chosen for these, it passes."""
    scene = scene_from_dict(_load("stephenson3_sixbar.toml", simulation={"horizon": 0.25}))
    tight = replace(scene.tolerances, q_atol=1e-6, omega_atol=1e-3)
    c = compare_engines(scene, tolerances=tight)
    assert c.gate.passed, c.gate.failures
    assert c.other.details.timestep_checks[-1].limits[1] == pytest.approx(0.25 * 1e-3)


def test_a_fixed_step_that_fails_the_gate_is_named():
    with open(MECHANISMS / "stephenson3_sixbar.toml", "rb") as f:
        data = tomllib.load(f)
    data["simulation"]["horizon"] = 0.25
    scene = scene_from_dict(data)
    tight = replace(scene.tolerances, q_atol=1e-7, omega_atol=1e-4)
    c = compare_engines(scene, tolerances=tight)
    assert not c.gate.passed
    assert "[mujoco] timestep" in c.gate.failures[-1]


def test_a_search_beyond_the_work_limit_says_what_step_it_would_need():
    """Tolerances of 1e-13 rad: the fitted order predicts a step whose check would exceed the
    search's work limit; the failure says which step, its cost, and the keys to change."""
    scene = variant(simulation={"horizon": 0.2},
                    tolerances={"peak_omega_rtol": 1e-13, "q_atol": 1e-13, "omega_atol": 1e-13})
    with pytest.raises(NumericalFailure) as info:
        simulate_mujoco(scene)
    message = str(info.value)
    assert info.value.reason == FailureReason.INACCURATE
    assert "need a step of about" in message and f"{MAX_SEARCH_STEPS:,} steps" in message
    wanted = float(message.split("need a step of about ")[1].split(" s")[0])
    assert scene.horizon / wanted * 1.5 > MAX_SEARCH_STEPS / 10  # predicted well beyond reach
    assert "--timestep" in message and "--q-atol" in message
    assert math.isfinite(wanted)
