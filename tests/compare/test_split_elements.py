"""An element split in two halves on the same points is the same mechanism as the whole.

Two dampers of c/2, two springs of k/2 (same rest length) or two point forces of F/2 on the
same body points must give the trajectory of one element of c, k or F, in both engines; and a
spring and a damper on the same two points must give what they give on two distinct points at
the same place (an alias point of the body). This guards the point-to-row map of the reduced
model: an element that shares a point with another must still see that point move (the map
once kept only the last element on a point, and the earlier element saw its point fixed:
101.55 rad/s instead of 94.74 on the Watt six-bar with a 1e-9 N/m spring on the damper's
points, and a NaN damping term for a spring and a damper on the same points).

Runs: reduced DOP853 at rtol 1e-12 and MuJoCo RK4 at the scene's fixed step, so neither engine
chooses anything from the scene. Tolerances: the halves change only the order of a few additions,
so each engine's two runs differ by round-off carried along the run. Measured over all 24 cases,
max |Δq| and max |Δq̇| / max |q̇|: MuJoCo 2.0e-14 rad and 7.6e-14; reduced 1.4e-12 rad and 2.8e-11
(1.46e-11 rad with numpy 2.4.6 and scipy 1.17.1, 2026-11-28), on the slider-crank's point force, where the round-off of the sum changes the step controller's
sequence (797 samples against 801) and the comparison goes through the dense output; elsewhere
7e-15 rad and 3e-15 (the four-bar over 0.5 s; over 1.2 s it was 6e-14 rad and 2.5e-14). Bounds:
1e-10 rad and 2e-10 relative (7x the largest), 10 orders of magnitude below what the shared-point
bug makes (6.8 rad/s on the six-bar)."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import scene_from_dict
from loopcheck.reference_models import MujocoSettings, simulate_mujoco

from helpers import ROOT

Q_ATOL, QDOT_RTOL = 1e-10, 2e-10  # rad, relative to max |q̇| (see the module docstring)

REDUCED = ReducedSettings(method="dop853", rtol=1e-12)

# scene file, two points of distinct bodies for a line element, a body point for a point force,
# MuJoCo's fixed step (s) and a horizon short enough for a fast test (s)
SCENES = {
    "four_bar": ("seed_fourbar.toml", "ground.damper_end", "coupler.B", "coupler.B", 1e-3, 0.5),
    "slider_crank": ("slider_crank_gas.toml", "ground.O", "piston.pin", "rod.A", 5e-4, 0.1),
    "six_bar": ("watt2_sixbar.toml", "ground.R", "rocker2.D", "rocker2.D", 5e-4, 0.3),
}


def _load(name: str) -> dict:
    with open(ROOT / "scenes" / "mechanisms" / name, "rb") as f:
        return tomllib.load(f)


def _element(kind: str, a: str, b: str, scale: float) -> tuple[str, dict]:
    if kind == "damper":
        return "dampers", {"a": a, "b": b, "coefficient": 40.0 * scale}
    if kind == "spring":
        return "springs", {"a": a, "b": b, "stiffness": 600.0 * scale, "rest_length": 0.3}
    return "point_forces", {"point": b, "direction": 2.0, "q": [-50.0, 0.0, 50.0],
                            "values": [40.0 * scale, 90.0 * scale, 10.0 * scale]}


def _scenes(case: str, kind: str) -> tuple[dict, dict]:
    """The scene with one element of ``kind`` added whole, and with it added as two halves."""
    file, a, b, point, _, horizon = SCENES[case]
    base = _load(file)
    base["simulation"]["horizon"] = horizon
    base.pop("tolerances", None)
    if kind == "point_force":
        a, b = None, point
    whole, halves = copy.deepcopy(base), copy.deepcopy(base)
    table, element = _element(kind, a, b, 1.0)
    whole.setdefault(table, []).append(element)
    for k in range(2):
        table, element = _element(kind, a, b, 0.5)
        halves.setdefault(table, []).append({**element, "name": f"half{k}"})
    return whole, halves


def _spring_and_damper(case: str) -> tuple[dict, dict]:
    """A spring and a damper on the same two points, and the same with the spring's body end on
    an alias point (a second name for the same place on the body)."""
    file, a, b, _, _, horizon = SCENES[case]
    shared = _load(file)
    shared["simulation"]["horizon"] = horizon
    shared.pop("tolerances", None)
    aliased = copy.deepcopy(shared)
    body, name = b.split(".")
    points = aliased["bodies"][body]["points"]
    points["alias"] = list(points[name])
    for data, end in ((shared, b), (aliased, f"{body}.alias")):
        data.setdefault("dampers", []).append(_element("damper", a, b, 1.0)[1] | {"name": "d_shared"})
        data.setdefault("springs", []).append(_element("spring", a, end, 1.0)[1] | {"name": "s_shared"})
    return shared, aliased


def _runs(first: dict, second: dict, engine: str, case: str):
    timestep = SCENES[case][4]
    out = []
    for data in (first, second):
        scene = scene_from_dict(data)
        if engine == "reduced":
            out.append(simulate(scene, REDUCED).trajectory)
        else:
            out.append(simulate_mujoco(scene, MujocoSettings(integrator="rk4", timestep=timestep)).trajectory)
    return out


def _assert_same(a, b) -> None:
    # the reduced runs' samples may fall at other times: compare on the first run's samples
    q, qdot, _ = b.interpolate(a.t)
    assert np.all(np.isfinite(a.q)) and np.all(np.isfinite(b.q))
    assert np.max(np.abs(a.q - q)) <= Q_ATOL
    assert np.max(np.abs(a.qdot - qdot)) <= QDOT_RTOL * np.max(np.abs(a.qdot))


@pytest.mark.parametrize("engine", ["reduced", "mujoco"])
@pytest.mark.parametrize("kind", ["damper", "spring", "point_force"])
@pytest.mark.parametrize("case", sorted(SCENES))
def test_two_halves_on_the_same_points_are_the_whole(case, kind, engine):
    whole, halves = _scenes(case, kind)
    _assert_same(*_runs(whole, halves, engine, case))


@pytest.mark.parametrize("engine", ["reduced", "mujoco"])
@pytest.mark.parametrize("case", sorted(SCENES))
def test_a_spring_and_a_damper_may_share_their_points(case, engine):
    _assert_same(*_runs(*_spring_and_damper(case), engine, case))


def test_each_added_element_acts():
    """The elements of the cases above act: the run without one is far from the run with it
    (else the tests above could pass with an element that does nothing)."""
    for kind in ("damper", "spring", "point_force"):
        whole, _ = _scenes("four_bar", kind)
        without = copy.deepcopy(whole)
        without[_element(kind, "a", "b", 1.0)[0]].pop()
        a, b = _runs(whole, without, "reduced", "four_bar")
        q, _, _ = b.interpolate(a.t)
        assert np.max(np.abs(a.q - q)) > 1e6 * Q_ATOL, kind
