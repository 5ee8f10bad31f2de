"""``--sensitivity`` against a derivative known in closed form (loopcheck.compare.sensitivity).

A parallelogram four-bar (crank and rocker of equal length 0.5 m, coupler as long as the ground)
keeps its coupler parallel to the ground, so 𝔍 is constant:

    𝔍(x) = I_G + m (x − a)² + I_rocker + m_coupler c1²,

with x the crank's centre of mass and a its pivot, both along the crank's frame axis (m). From
rest, a torque T for d seconds with nothing else acting gives the peak speed P = T d / 𝔍 (held
after the pulse), and dP/dx = −2 T d m (x − a) / 𝔍².

The crank's pivot sits at a = 0.9 m of its frame and its centre at x = 1.0 m, so the module's
step (h = |x| (10 rtol)^(1/3) = 2.2e-4 m) is set by x while P curves on the scale x − a = 0.1 m:
the truncation of the central difference (4.1e-4) dominates the error bar, its noise part is
1.1e-7. Richardson removes it: measured |D − dP/dx| 9.6e-9 (2.0e-10 of D) against the printed
error bar 4.1e-4. The correction with the wrong sign (subtracted) leaves 8.2e-4: twice the bar.
"""

from __future__ import annotations

import math

import pytest

from loopcheck.compare.sensitivity import sensitivities
from loopcheck.sweep_spec import spec_from_args
from loopcheck.scenefile import scene_from_dict
from loopcheck.reduced import simulate

T, D = 0.05, 0.5  # N·m, s
MASS, X, PIVOT, I_G = 1.0, 1.0, 0.9, 1e-6  # crank: kg, m, m, kg·m²
C1, M_COUPLER, I_ROCKER = 0.5, 1e-3, 1e-6  # m, kg, kg·m²
PARALLELOGRAM = {
    "linkage": {"type": "planar", "input": "O1"},
    "bodies": {"ground": {"points": {"O1": [0.0, 0.0], "O3": [1.0, 0.0]}},
               "crank": {"points": {"O": [PIVOT, 0.0], "A": [PIVOT + C1, 0.0]}, "mass": MASS, "com": [X, 0.0],
                         "inertia": I_G},
               "coupler": {"points": {"A": [0.0, 0.0], "B": [1.0, 0.0]}, "mass": M_COUPLER, "com": [0.5, 0.0],
                           "inertia": 1e-3},
               "rocker": {"points": {"O3": [0.0, 0.0], "B": [C1, 0.0]}, "pivot_inertia": I_ROCKER, "pivot": "O3"}},
    "joints": [{"name": "O1", "type": "revolute", "a": "ground.O1", "b": "crank.O"},
               {"name": "A", "type": "revolute", "a": "crank.A", "b": "coupler.A"},
               {"name": "B", "type": "revolute", "a": "coupler.B", "b": "rocker.B"},
               {"name": "O3", "type": "revolute", "a": "ground.O3", "b": "rocker.O3"}],
    "torque": {"type": "pulse", "value": T, "start": 0.0, "duration": D},
    "initial": {"q": 1.2, "guess": {"crank": 1.2, "coupler": 0.0, "rocker": 1.2}},  # turns to 2.05 rad: clear of 0, π
    "simulation": {"horizon": 0.6},
}


def _inertia(x: float) -> float:
    return I_G + MASS * (x - PIVOT) ** 2 + I_ROCKER + M_COUPLER * C1 ** 2


def test_the_parallelogram_peak_is_the_closed_form():
    """The oracle's premise: P = T d / 𝔍 (measured 2.9e-14 relative; bound 2e-13)."""
    result = simulate(scene_from_dict(PARALLELOGRAM))
    assert math.isclose(result.peak.omega, T * D / _inertia(X), rel_tol=2e-13)


def test_the_sensitivity_is_within_its_error_bar_of_the_closed_form():
    [s] = sensitivities(PARALLELOGRAM, spec_from_args(["bodies.crank.com.0=0.95:1.05:3"]))
    truth = -2.0 * T * D * MASS * (X - PIVOT) / _inertia(X) ** 2  # −47.57 (rad/s)/m
    assert s.nominal == X and s.step < 0.01 * (X - PIVOT)
    assert abs(s.derivative - truth) <= s.error, (s, truth)  # what the printed error bar claims
    # Richardson removes the h² term: measured 2.0e-10 of D, bound 1e-9 (D(h) alone is 8.6e-6 off)
    assert abs(s.derivative - truth) <= 1e-9 * abs(truth), (s, truth)
    assert abs(s.at_h - truth) > 1e3 * abs(s.derivative - truth)  # the case does test the correction


def test_mujocos_own_sensitivity_is_within_its_error_bar_of_the_closed_form():
    """MuJoCo's own d(peak)/dx (``engines``), its timestep chosen at the nominal scene and frozen:
    with 𝔍 and the torque constant, RK4 is exact and the peak sits at the pulse's end on the grid,
    so MuJoCo's peak is the closed form (measured 3e-13 relative; bound 1e-10) and its D is off
    the truth only by the differences' truncation, which its error bar holds: its declared ε, 3e-6,
    makes h = 1.4e-2 m, 14 % of x − a, where P curves (measured |D − dP/dx| 0.23 (rad/s)/m, 4.9e-3
    of it, against the bar 2.12; bound 1e-2 of it). The correction with the wrong sign leaves 4.35:
    twice the bar."""
    reference, mujoco = sensitivities(PARALLELOGRAM, spec_from_args(["bodies.crank.com.0=0.95:1.05:3"]),
                                      engines=("reduced", "mujoco"))
    truth = -2.0 * T * D * MASS * (X - PIVOT) / _inertia(X) ** 2
    assert (reference.engine, mujoco.engine) == ("reduced", "mujoco")
    assert mujoco.frozen_step is not None and D / mujoco.frozen_step == pytest.approx(round(D / mujoco.frozen_step))
    assert math.isclose(mujoco.peak, T * D / _inertia(X), rel_tol=1e-10)
    assert abs(mujoco.derivative - truth) <= mujoco.error, (mujoco, truth)
    assert abs(mujoco.derivative - truth) <= 1e-2 * abs(truth), (mujoco, truth)
