"""RKN4's two error estimates against the true error, tightly enough to see their constants.

The step-doubling estimate of the error of y_h is |y_h − y_2h| / (2⁴ − 1); when the run at 2h is
outside RKN4's stability region it is 2⁴ |y_h − y_h/2| / (2⁴ − 1) instead (loopcheck.reduced.engine,
``estimate_error``). Both are asymptotically exact for a fourth-order method, so on a problem in
the asymptotic range the ratio estimate / true error is close to 1. True error: the largest
|q − q_ref| over the run's samples, q_ref from DOP853 at rtol 1e-12 (its own error, ~1e-11 rad,
is 1e-3 of the smallest true error below).

Slips these catch (each planted and seen failing): the fallback's weight 1/15 instead of 16/15
(the estimate 16× too small: stiff_damper at 0.5 ms accepted at rtol 1e-4 with exit 0, where its
true error is 4.1e-4 of its scale); the main estimate divided by 16 instead of 15 (the seed
accepted at rtol 5.5e-7 at 0.5 ms, estimate 5.7e-7): a 6 % change, so the bound on q's ratio is
±2 %, 3–5× the measured 0.4–0.6 %.
"""

from __future__ import annotations

import numpy as np
import pytest

from loopcheck.compare import cli
from helpers import variant
from loopcheck.errors import NumericalFailure
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import hard_scene_dir

REFERENCE = ReducedSettings(method="dop853", rtol=1e-12, sample_interval=2.5e-4)
STIFF_DAMPER = hard_scene_dir() / "stiff_damper.toml"


def _unchecked(h: float) -> ReducedSettings:
    return ReducedSettings(method="rkn4", step=h, check_error=False)


def _ratios(scene, h: float) -> tuple[float, float]:
    """estimate / true error of RKN4 at step h, in q and in q̇."""
    reference = simulate(scene, REFERENCE)
    result = simulate(scene, _unchecked(h))
    q_ref, v_ref, _ = reference.trajectory.interpolate(result.trajectory.t)
    true_q = np.max(np.abs(result.trajectory.q - q_ref))
    true_v = np.max(np.abs(result.trajectory.qdot - v_ref))
    estimate = result.details.error_estimate
    return estimate.q_abs / true_q, estimate.qdot_abs / true_v


@pytest.mark.parametrize("h", [1e-3, 5e-4])
def test_the_step_doubling_estimate_is_the_true_error_on_the_seed(h):
    """The seed's first 0.7 s (one clean error term). Measured estimate/true: q 1.0064 at 1 ms,
    1.0043 at 0.5 ms; q̇ 1.112 and 1.062 (its next error term is larger). Bounds: q within
    ±2 % (a division by 16 gives 0.943 and 0.941), q̇ within [0.9, 1.25]."""
    ratio_q, ratio_v = _ratios(variant(simulation={"horizon": 0.7}), h)
    assert abs(ratio_q - 1.0) < 0.02, ratio_q
    assert 0.9 < ratio_v < 1.25, ratio_v


def test_the_half_step_estimate_is_the_true_error_where_twice_the_step_is_unstable():
    """stiff_damper at 0.5 ms: the run at 1 ms leaves RKN4's stability region, so the estimate
    comes from the run at 0.25 ms. Measured estimate/true: 1.032 in q and in q̇ (true errors
    1.3e-7 rad, 4.1e-4 rad/s). Bound ±25 % (8× the measured 3 %); the weight 1/15 in place of
    16/15 gives 0.065."""
    scene = load_scene(STIFF_DAMPER)
    with pytest.raises(NumericalFailure) as info:  # the main estimate's run at 2h cannot be made
        simulate(scene, _unchecked(1e-3))
    assert info.value.reason == "unstable"
    ratio_q, ratio_v = _ratios(scene, 5e-4)
    assert 0.8 < ratio_q < 1.25, ratio_q
    assert 0.8 < ratio_v < 1.25, ratio_v


def test_a_run_outside_its_accuracy_by_the_half_step_estimate_is_refused(capsys):
    """`loopcheck reduced stiff_damper.toml --method rkn4 --step 5e-4 --rtol 1e-4`: the estimate,
    4.22e-4 of the run's scale (true error 4.09e-4), is above rtol: exit 1, naming it."""
    status = cli.main(["reduced", str(STIFF_DAMPER), "--method", "rkn4", "--step", "5e-4", "--rtol", "1e-4"])
    assert status == 1
    err = capsys.readouterr().err
    assert "estimates its own error" in err and "4.22e-04" in err and "rtol = 0.0001" in err
