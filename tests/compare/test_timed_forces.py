"""Point forces over time ([[timed_forces]]): F(t) along a fixed ground direction at a body
point, with the input load's profiles (constant, pulse, table), in both engines.

Oracles: a force split into two halves at the same point moves the linkage as the whole (a
four-bar, a slider-crank whose piston takes a pressure history while the crank is the input, a
six-bar; both engines); a constant timed force is the same physics as a constant F(q) point
force; a block pushed along its slider by a pulse or a table follows the piecewise-quadratic
closed form; the energy audits hold the forces' work; both engines agree; every edge is a
stop of the reduced integrators and on MuJoCo's automatic step grid.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import scene_from_dict
from loopcheck.scene import SceneError
from loopcheck.reference_models import MujocoSettings, simulate_mujoco
from loopcheck.mujoco_model.steps import grid_timestep

from helpers import ROOT

REDUCED = ReducedSettings(method="dop853", rtol=1e-12)
# (file, horizon s, MuJoCo step s, the force: point, direction rad, profile); the edges fall on the step grid
CASES = {
    "four_bar": ("seed_fourbar.toml", 0.5, 2e-4,
                 {"point": "coupler.B", "direction": -1.2, "type": "pulse", "value": 150.0, "start": 0.1,
                  "duration": 0.2}),
    "slider_crank": ("slider_crank_gas.toml", 0.05, 1e-4,  # a pressure history on the piston, towards the crank
                     {"point": "piston.pin", "direction": math.pi, "type": "table",
                      "times": [0.0, 0.01, 0.02, 0.03], "values": [300.0, 1500.0, -200.0, 600.0]}),
    "six_bar": ("stephenson3_sixbar.toml", 0.5, 2e-4,
                {"point": "link.D", "direction": 0.4, "type": "table", "times": [0.05, 0.25], "values": [20.0, -10.0]}),
}


def _data(name: str) -> dict:
    file, horizon, _, _ = CASES[name]
    with open(ROOT / "scenes" / "mechanisms" / file, "rb") as f:
        data = tomllib.load(f)
    data["simulation"] = {"horizon": horizon}
    data.pop("tolerances", None)
    return data


def _with(name: str, halves: bool):
    data = _data(name)
    force = dict(CASES[name][3])
    if halves:
        key = "values" if "values" in force else "value"
        half = [0.5 * v for v in force[key]] if key == "values" else 0.5 * force[key]
        data["timed_forces"] = [{**force, key: half, "name": "a"}, {**force, key: half, "name": "b"}]
    else:
        data["timed_forces"] = [force]
    return scene_from_dict(data)


def _max_dq(a, b) -> float:
    """max |Δq| of run b (its quintic interpolant) on run a's samples."""
    return float(np.max(np.abs(b.trajectory.interpolate(a.trajectory.t)[0] - a.trajectory.q)))


# ~1-1.5 s each (three scenes, both engines): the four-bar in the fast suite, the others slow
@pytest.fixture(scope="module", params=[n if n == "four_bar" else pytest.param(n, marks=pytest.mark.slow) for n in CASES])
def runs(request):
    name = request.param
    mujoco = MujocoSettings(integrator="rk4", timestep=CASES[name][2])
    out = {"name": name}
    for label, scene in (("whole", _with(name, False)), ("halves", _with(name, True)),
                         ("without", scene_from_dict(_data(name)))):
        out[label] = (simulate(scene, REDUCED), simulate_mujoco(scene, mujoco))
    return out


def test_two_halves_move_as_the_whole(runs):
    # Measured max |Δq|: reduced 1.3e-15, 5.3e-15, 3.9e-14 rad (four-bar, slider-crank, six-bar),
    # MuJoCo 0, 1.8e-15, 0; bounds 3e-13 and 1e-14 rad. The force moves the input by 0.037-2.9 rad
    # (asserted ≥ 1e-2), eleven decades above the bounds.
    for engine, bound in ((0, 3e-13), (1, 1e-14)):
        whole, halves, without = (runs[k][engine] for k in ("whole", "halves", "without"))
        assert _max_dq(whole, halves) <= bound, (runs["name"], engine, _max_dq(whole, halves))
        assert _max_dq(whole, without) >= 1e-2, (runs["name"], engine, _max_dq(whole, without))


def test_both_engines_agree_and_audit_the_work(runs):
    # RK4 at 0.1-0.2 ms against DOP853 at rtol 1e-12, edges on the step grid: measured max |Δq|
    # 2.2e-8, 2.3e-7, 3.3e-6 rad, bounds about 4.5x. Audits (relative to the energy scale): reduced
    # 2.0e-11, 4.1e-13, 1.3e-11, bound 1e-10; MuJoCo 1.2e-6, 2.1e-5, 1.8e-6 (trapezoid rule), bound
    # 1e-4; the force's work left out of either audit would be ≥ 1e-2 of the scale.
    reduced, mujoco = runs["whole"]
    bound = {"four_bar": 1e-7, "slider_crank": 1e-6, "six_bar": 1.5e-5}[runs["name"]]
    assert _max_dq(mujoco, reduced) <= bound, (runs["name"], _max_dq(mujoco, reduced))
    assert reduced.audit.relative_residual <= 1e-10, reduced.audit.relative_residual
    assert mujoco.audit.relative_residual <= 1e-4, mujoco.audit.relative_residual


def test_every_edge_is_a_stop_and_on_mujocos_grid(runs):
    scene = _with(runs["name"], False)
    edges = [e for e in scene.load_edges if 0.0 < e < scene.horizon]
    assert edges
    reduced, _ = runs["whole"]
    for e in edges:  # a sample at the edge itself (DOP853 stops there)
        assert np.min(np.abs(reduced.trajectory.t - e)) == 0.0, e
    # MuJoCo's automatic step, for edges no round step divides: a pulse from 0.2074 of the horizon
    # lasting as long
    data = _data(runs["name"])
    odd_time = 0.2074 * data["simulation"]["horizon"]
    data["timed_forces"] = [{"point": CASES[runs["name"]][3]["point"], "direction": 0.0, "type": "pulse",
                             "value": 1.0, "start": odd_time, "duration": odd_time}]
    odd = scene_from_dict(data)
    h = grid_timestep(odd)
    edges = [e for e in odd.load_edges if 0.0 < e < odd.horizon]
    assert edges and all(abs(e / h - round(e / h)) <= 1e-9 for e in edges), (h, edges)


# -- a constant timed force is a constant F(q) point force ----------------------------------------

@pytest.mark.slow  # ~2 s: four runs of the six-bar
def test_constant_timed_force_is_a_constant_point_force():
    """Both engines, the six-bar: the same force given over t (constant) and over q (a table of two
    equal values): the same equations, so the same motion to round-off (measured 0 and 0)."""
    timed, tabulated = _data("six_bar"), _data("six_bar")
    timed["timed_forces"] = [{"point": "link.D", "direction": 0.4, "type": "constant", "value": 20.0}]
    tabulated["point_forces"] = [{"point": "link.D", "direction": 0.4, "q": [-1.0, 1.0], "values": [20.0, 20.0]}]
    a, b = scene_from_dict(timed), scene_from_dict(tabulated)
    assert _max_dq(simulate(a, REDUCED), simulate(b, REDUCED)) <= 1e-12
    mj = MujocoSettings(integrator="rk4", timestep=2e-4)
    assert _max_dq(simulate_mujoco(a, mj), simulate_mujoco(b, mj)) <= 1e-12


# -- closed form: a block pushed along its slider -------------------------------------------------

def _block(profile: dict, horizon: float) -> dict:
    """A 0.5 kg block on a slider at 0.3 rad to ground x, pushed at 0.8 rad (0.5 rad off its line)."""
    return {"linkage": {"type": "planar", "input": "S"},
            "bodies": {"ground": {"points": {"O": [0.0, 0.0]}},
                       "block": {"points": {"c": [0.0, 0.0]}, "mass": 0.5, "com": [0.0, 0.0], "inertia": 1e-3}},
            "joints": [{"name": "S", "type": "prismatic", "a": "ground.O", "direction": 0.3, "b": "block.c"}],
            "timed_forces": [{"point": "block.c", "direction": 0.8, **profile}],
            "initial": {"q": 0.1, "qdot": 0.2}, "simulation": {"horizon": horizon}}


def _pushed(t: np.ndarray, times, values, s0=0.1, v0=0.2, mass=0.5) -> np.ndarray:
    """s(t) of m s̈ = F(t) cos 0.5 with F piecewise constant (values from each time on, 0 before)."""
    s, v, t_prev, a = s0, v0, 0.0, 0.0
    out = np.empty_like(t)
    knots = list(zip(times, values))
    for j, tj in enumerate(t):
        while knots and knots[0][0] <= tj:
            tk, fk = knots.pop(0)
            dt = tk - t_prev
            s, v, t_prev = s + v * dt + 0.5 * a * dt * dt, v + a * dt, tk
            a = fk * math.cos(0.5) / mass
        dt = tj - t_prev
        out[j] = s + v * dt + 0.5 * a * dt * dt
    return out


@pytest.mark.parametrize("profile, times, values", [
    ({"type": "pulse", "value": 3.0, "start": 0.2, "duration": 0.3}, [0.2, 0.5], [3.0, 0.0]),
    ({"type": "table", "times": [0.0, 0.25, 0.6], "values": [2.0, -4.0, 1.0]}, [0.0, 0.25, 0.6], [2.0, -4.0, 1.0]),
])
def test_pushed_block_follows_its_closed_form(profile, times, values):
    """A quadratic on each piece: DOP853 and RK4 (edges on its grid) are exact to round-off.
    Measured 8.9e-16 and 7.2e-16 m (reduced; pulse, table), 1.4e-14 and 8.4e-15 m (MuJoCo, 1000
    steps); bounds 5e-15 and 1e-13 m. A pulse applied one 1 ms step late is 1e-4 m off."""
    scene = scene_from_dict(_block(profile, 1.0))
    for result, bound in ((simulate(scene, REDUCED), 5e-15),
                          (simulate_mujoco(scene, MujocoSettings(integrator="rk4", timestep=1e-3)), 1e-13)):
        tr = result.trajectory
        assert np.max(np.abs(tr.q - _pushed(tr.t, times, values))) <= bound, result.engine
        # q̈ = F cos 0.5 / m on each piece; an edge inside the run is a repeated sample holding
        # the value before it, then after it (measured exact to 4e-15 m/s² in both engines)
        def force(t):  # F(t), right-continuous; MuJoCo's times carry round-off (0.2 is 0.2 + 1.5e-16)
            i = np.searchsorted(times, t + 1e-9, side="right") - 1
            return np.where(i < 0, 0.0, np.asarray(values)[np.maximum(i, 0)])
        repeated = np.append(np.diff(tr.t) == 0.0, False)  # the first of a repeated time: before the edge
        expected = np.where(repeated, force(tr.t - 2e-9), force(tr.t)) * math.cos(0.5) / 0.5
        assert np.max(np.abs(tr.qddot - expected)) <= 1e-12, result.engine
        assert np.count_nonzero(repeated) == len([tk for tk in times if 0.0 < tk < 1.0]), result.engine


def test_bad_timed_force_is_refused_naming_its_key():
    data = _block({"type": "pulse", "value": 3.0, "start": 0.2}, 1.0)
    with pytest.raises(SceneError, match=r"missing key 'timed_forces\[0\]\.duration'"):
        scene_from_dict(data)
    data = _block({"type": "ramp", "value": 3.0}, 1.0)
    with pytest.raises(SceneError, match=r"'timed_forces\[0\]\.type' must be"):
        scene_from_dict(data)
    data = _block({"type": "constant", "value": 3.0}, 1.0)
    data["timed_forces"][0]["point"] = "ground.O"
    with pytest.raises(SceneError, match="acts on the ground"):
        scene_from_dict(data)
