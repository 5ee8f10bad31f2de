"""The MuJoCo model of any planar linkage (issue 11): slider-cranks, a two-loop six-bar, the seed.

Oracles independent of the MuJoCo builder and of the reduced engine's dynamics: the loop
kinematics of :mod:`loopcheck.kinematics` (positions, K = dx/dq on ``system.centres``) give the
kinetic energy ½ 𝔍 q̇² with 𝔍 = Σ m |K_G|² + I K_θ², summed here by hand, and the exported
MJCF is read by MuJoCo alone (``MjModel.from_xml_string``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib

import mujoco
import numpy as np
import pytest

from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck import kinematics as loops
from loopcheck.reduced.dynamics import MechanismModel
from loopcheck.reference_models import (HOME_KEY, MujocoSettings, build_model, coordinate_map, joint_order, mjcf_text,
                              simulate_mujoco)
from loopcheck.mujoco_model.build import joint_rates_matrix

from helpers import ROOT, SEED_SCENE

STEP = 1e-3  # s: explicit timestep, so exporting runs no simulation
GAS = [0.0, 0.0, 40.0, 120.0, 60.0, 10.0, 0.0]  # N over one crank turn (a gas-force shape)


def slider_crank(*, slider_input: bool = False) -> dict:
    """An offset slider-crank (offset 0.05 m): crank 0.1 m, rod 0.35 m, piston on a line of
    ground; a damper ground–rod, a spring crank–piston (body–body), a gas force on the
    piston tabulated over crank angle, gravity; driven by a crank torque, or by a force on
    the slider (then the gas force is tabulated over the slider's displacement). With the
    crank torque a second point force, a side load on a point of the rod (a rotating body)."""
    data = {
        "name": "offset_slider_crank", "gravity": [0.0, -9.81],
        "linkage": {"type": "planar", "input": "slide" if slider_input else "O"},
        "bodies": {
            "ground": {"points": {"O": [0.0, 0.0], "P": [0.0, 0.05], "anchor": [0.3, 0.4]}},
            "crank": {"points": {"O": [0.0, 0.0], "A": [0.1, 0.0]}, "pivot_inertia": 0.02, "pivot": "O"},
            "rod": {"points": {"A": [0.0, 0.0], "B": [0.35, 0.0], "mid": [0.2, 0.03]}, "mass": 1.2,
                    "com": [0.12, 0.01],
                    "inertia": 0.015},
            "piston": {"points": {"B": [0.0, 0.0], "top": [0.02, 0.03]}, "mass": 0.8, "com": [0.01, 0.0],
                       "inertia": 1e-3},
        },
        "joints": [{"name": "O", "type": "revolute", "a": "ground.O", "b": "crank.O"},
                   {"name": "A", "type": "revolute", "a": "crank.A", "b": "rod.A"},
                   {"name": "B", "type": "revolute", "a": "rod.B", "b": "piston.B"},
                   {"name": "slide", "type": "prismatic", "a": "ground.P", "b": "piston.B", "direction": 0.0}],
        "dampers": [{"a": "ground.anchor", "b": "rod.B", "coefficient": 2.0}],
        "springs": [{"a": "crank.A", "b": "piston.top", "stiffness": 300.0, "rest_length": 0.3}],
        "simulation": {"horizon": 0.2},
    }
    if slider_input:
        data["force"] = {"type": "constant", "value": -30.0}
        data["point_forces"] = [{"point": "piston.top", "direction": math.pi, "q": [0.25, 0.3, 0.35, 0.4, 0.45],
                                 "values": [0.0, 10.0, 30.0, 15.0, 5.0]}]
        data["initial"] = {"q": 0.43, "qdot": -1.0, "guess": {"crank": 0.5, "rod": -0.1}}
    else:
        data["torque"] = {"type": "pulse", "value": 3.0, "start": 0.0, "duration": 0.1}
        data["point_forces"] = [{"point": "piston.top", "direction": math.pi, "q": list(np.linspace(0, 6, 7)),
                                 "values": GAS, "period": 2 * math.pi},
                                {"name": "side_load", "point": "rod.mid", "direction": 1.2, "q": [0.0, 3.0, 6.0],
                                 "values": [5.0, -4.0, 5.0], "period": 2 * math.pi}]
        data["initial"] = {"q": 0.3, "qdot": 20.0, "guess": {"rod": 0.06, "slide": 0.44}}
    return data


def watt_six_bar() -> dict:
    """A Watt II six-bar: two four-bars in series sharing the ternary rocker (loops cut at B
    and D); masses on every body, a damper rocker2–ground, a spring coupler–coupler2."""
    return {
        "name": "watt_ii", "gravity": [0.0, -9.81],
        "linkage": {"type": "planar", "input": "O1"},
        "bodies": {
            "ground": {"points": {"O1": [0.0, 0.0], "O3": [1.0, 0.0], "O5": [1.9, 0.6], "E": [2.2, -0.2]}},
            "crank": {"points": {"O1": [0.0, 0.0], "A": [0.35, 0.0]}, "pivot_inertia": 0.05, "pivot": "O1"},
            "coupler": {"points": {"A": [0.0, 0.0], "B": [1.0, 0.0], "S": [0.5, 0.1]}, "mass": 2.0,
                        "com": [0.5, 0.05], "inertia": 0.2},
            "rocker": {"points": {"O3": [0.0, 0.0], "B": [0.8, 0.0], "C": [0.6, 0.5]}, "mass": 1.5,
                       "com": [0.4, 0.2], "inertia": 0.1},
            "coupler2": {"points": {"C": [0.0, 0.0], "D": [0.9, 0.0]}, "mass": 1.0, "com": [0.45, 0.0],
                         "inertia": 0.07},
            "rocker2": {"points": {"O5": [0.0, 0.0], "D": [0.6, 0.0]}, "pivot_inertia": 0.04, "pivot": "O5"},
        },
        "joints": [{"name": "O1", "type": "revolute", "a": "ground.O1", "b": "crank.O1"},
                   {"name": "A", "type": "revolute", "a": "crank.A", "b": "coupler.A"},
                   {"name": "B", "type": "revolute", "a": "coupler.B", "b": "rocker.B"},
                   {"name": "O3", "type": "revolute", "a": "ground.O3", "b": "rocker.O3"},
                   {"name": "C", "type": "revolute", "a": "rocker.C", "b": "coupler2.C"},
                   {"name": "D", "type": "revolute", "a": "coupler2.D", "b": "rocker2.D"},
                   {"name": "O5", "type": "revolute", "a": "ground.O5", "b": "rocker2.O5"}],
        "dampers": [{"a": "ground.E", "b": "rocker2.D", "coefficient": 3.0}],
        "springs": [{"a": "coupler.S", "b": "coupler2.D", "stiffness": 50.0, "rest_length": 1.0}],
        "torque": {"type": "constant", "value": 2.0},
        "initial": {"q": 0.5, "qdot": 3.0,
                    "guess": {"coupler": 0.6, "rocker": 1.9, "coupler2": 0.3, "rocker2": -1.0}},
        "simulation": {"horizon": 0.2},
    }


def slider_reversed() -> dict:
    """The slider-crank with its prismatic joint written the other way round (a on the piston,
    b on ground, direction π): the slide's child is its body_a, so its axis is reversed."""
    data = slider_crank()
    data["joints"][3] = {"name": "slide", "type": "prismatic", "a": "piston.B", "b": "ground.P", "direction": math.pi}
    data["initial"]["guess"] = {"rod": 0.06, "slide": 0.44}
    return data


def seed_driven_at_a() -> dict:
    """The planar seed driven at its coupler joint A (q = coupler angle − crank angle, a revolute
    between two moving bodies: its hinge acceleration is the child's minus the parent's)."""
    with open(ROOT / "scenes" / "mechanisms" / "seed_fourbar.toml", "rb") as f:
        data = tomllib.load(f)
    data["linkage"]["input"] = "A"
    data["initial"] = {"q": 0.5, "qdot": 2.0, "guess": {"crank": 0.2, "coupler": 0.7, "rocker": 1.3}}
    data["torque"] = {"type": "constant", "value": 20.0}
    data["simulation"] = {"horizon": 0.2}
    return data


SCENES = {
    "seed": lambda: load_scene(SEED_SCENE),
    "seed_general": lambda: load_scene(ROOT / "scenes" / "mechanisms" / "seed_fourbar.toml"),
    "slider_crank": lambda: scene_from_dict(slider_crank()),
    "slider_driven": lambda: scene_from_dict(slider_crank(slider_input=True)),
    "watt_ii": lambda: scene_from_dict(watt_six_bar()),
    "slider_reversed": lambda: scene_from_dict(slider_reversed()),
    "seed_driven_at_a": lambda: scene_from_dict(seed_driven_at_a()),
}
# Every catalogue scene too (the issue: each catalogue mechanism's exported MJCF closes its loops,
# and MuJoCo's kinetic energy is the reduced model's).
CATALOGUE = sorted((ROOT / "scenes" / "mechanisms").glob("*.toml"))
SCENES.update({f"catalogue:{path.stem}": (lambda path=path: load_scene(path)) for path in CATALOGUE})


@pytest.fixture(params=sorted(SCENES), scope="module")
def scene(request):
    return SCENES[request.param]()


def test_inline_scenes_are_what_they_say(scene):
    """Guards the fixtures: the loops, the slides and the input's kind are as described."""
    linkage = scene.mechanism.linkage
    expected = {"offset_slider_crank": 1, "watt_ii": 2, "watt2_sixbar": 2, "stephenson3_sixbar": 2,
                "stephenson3_near_toggle": 2, "andrews_squeezer": 3, "parallelogram_redundant": 2,
                    "three_rrr": 2}.get(scene.name, 1)
    assert len(linkage.cut_joints) == expected
    if scene.name == "watt_ii":
        assert set(linkage.cut_joints) == {"B", "D"}


# Measured over SCENES at the default state and at home: MuJoCo's equality residual ≤ 2.2e-16 m,
# the sites on both sides of each cut joint ≤ 4.6e-16 m apart (seed driven at A), the home key's
# equality velocity residual ≤ 4.4e-16 m/s where q̇0 ≤ 2, and 2.8e-14 m/s in drag_link, started at
# 25 rad/s (1.1e-15 per rad/s): velocities are rounded in proportion to the speed, so that bound is
# per rad/s (or m/s) of q̇0, at least 1. The issue asks 1e-9 m;
# these bounds (4–9x round-off) keep a 6-digit export (~1e-6 m) or an unposed model (0.1–0.3 m)
# failing by orders of magnitude.
CLOSURE_ATOL = 2e-15  # m
VELOCITY_ATOL = 4e-15  # m/s per rad/s (or m/s) of q̇0, at least 1


def test_exported_mjcf_loads_with_every_loop_closed(scene):
    text = mjcf_text(scene, MujocoSettings(timestep=STEP))
    model = mujoco.MjModel.from_xml_string(text)
    data = mujoco.MjData(model)
    linkage = scene.mechanism.linkage
    for key in (None, HOME_KEY):
        if key is None:
            mujoco.mj_resetData(model, data)
        else:
            mujoco.mj_resetDataKeyframe(model, data, model.key(key).id)
        mujoco.mj_forward(model, data)
        rows = np.flatnonzero(data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        assert len(rows) == 3 * len(linkage.cut_joints) + len(linkage.couplings)  # a coupling: one row
        assert np.max(np.abs(data.efc_pos[rows]), initial=0.0) < CLOSURE_ATOL
        for name in linkage.cut_joints:
            jt = linkage.joint_map[name]
            gap = data.site(f"{jt.body_a}.{jt.point_a}").xpos - data.site(f"{jt.body_b}.{jt.point_b}").xpos
            assert np.linalg.norm(gap) < CLOSURE_ATOL, name
        if key is not None:
            assert np.max(np.abs(data.efc_vel[rows]), initial=0.0) < VELOCITY_ATOL * max(1.0, abs(scene.qdot0))
            _, T = coordinate_map(scene)  # the input turns or slides at q̇0
            system = loops.compile_linkage(linkage)
            assert system.drive @ T @ data.qvel == pytest.approx(scene.qdot0, rel=1e-15, abs=1e-15)
    # Every tree joint, also at the assembly: each named point where the loop kinematics put it.
    mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)
    system = loops.compile_linkage(linkage)
    where = loops.positions(system.points, np.asarray(scene.x0))
    for k, (body, point) in enumerate(system.point_names):
        assert np.linalg.norm(data.site(f"{body}.{point}").xpos[:2] - where[k]) < CLOSURE_ATOL, (body, point)


def _states(scene, count: int = 7) -> list[np.ndarray]:
    """Assembled configurations near x0, by continuation in q (Newton from the last one)."""
    system = loops.compile_linkage(scene.mechanism.linkage)
    # rad, or for a slider a tenth of its offset towards the crank (inside the stroke, away from
    # the dead centre the catalogue's slider-driven scene starts near)
    span = -0.1 * abs(scene.q0) if scene.input_is_prismatic else 0.4
    out, x = [], np.asarray(scene.x0, dtype=float)
    if scene.dof > 1:  # several inputs: the first moves by span, the others by −span/2 each (rad)
        steps = np.array([1.0] + [-0.5] * (scene.dof - 1))
        for s in np.linspace(0.0, span, count):
            x = loops.assemble_inputs(system, np.array(scene.initial_q()) + s * steps, x)
            out.append(x)
        return out
    for q in scene.q0 + np.linspace(0.0, span, count):
        x = loops.assemble(system, q, x)
        out.append(x)
    return out


def _inertia_matrix(scene, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """With several inputs: 𝔍 = Σ m K_Gᵀ K_G + I K_θᵀ K_θ (k×k) and K (n, k) at x, K's columns
    the rates of every coordinate with one input at unit rate and the others held
    (:func:`loopcheck.kinematics.input_rates`), from the loop kinematics alone."""
    linkage = scene.mechanism.linkage
    system = loops.compile_linkage(linkage)
    K = np.column_stack([loops.input_rates(system, x, e) for e in np.eye(scene.dof)])
    kg = np.stack([loops.rates(system.centres, x, K[:, j])[0] for j in range(scene.dof)], axis=-1)  # (bodies, 2, k)
    inertia = np.zeros((scene.dof, scene.dof))
    for i, name in enumerate(linkage.moving):
        b = linkage.body_map[name]
        inertia += b.mass * kg[i].T @ kg[i] + b.inertia * np.outer(K[i], K[i])
    return inertia, K


def _generalized_inertia(scene, x: np.ndarray) -> tuple[float, np.ndarray]:
    """𝔍 = Σ m |K_G|² + I K_θ² (kg·m² or kg) and K at x, from the loop kinematics alone; a
    body of mass 0 turns about its fixed pivot with its pivot inertia."""
    linkage = scene.mechanism.linkage
    system = loops.compile_linkage(linkage)
    K, _ = loops.coefficients(system, x)
    kg, _ = loops.rates(system.centres, x, K)
    bodies = linkage.body_map
    inertia = 0.0
    for i, name in enumerate(linkage.moving):
        b = bodies[name]
        inertia += b.mass * float(kg[i] @ kg[i]) + b.inertia * K[i] ** 2
    return inertia, K


def test_kinetic_energy_equals_generalized_inertia(scene):
    """½ q̇ᵀ M q̇ (mj_fullM) at assembled states equals ½ 𝔍 q̇², 𝔍 summed from loops' K.

    Both sides are a few dozen float64 products of the same geometry: measured agreement
    ≤ 5.1e-15 relative over SCENES (Watt II); the bound 5e-14 is 10x that, well inside the
    issue's 1e-10, and catches a wrong ipos, inertia or joint axis by orders of magnitude.
    """
    handles = build_model(scene, MujocoSettings(timestep=STEP))
    m, d = handles.model, mujoco.MjData(handles.model)
    x0, T = coordinate_map(scene)
    P = joint_rates_matrix(scene)
    M = np.zeros((m.nv, m.nv))
    worst = 0.0
    for x in _states(scene):
        if scene.dof > 1:  # several inputs: ½ q̇ᵀ 𝔍 q̇ (k×k); the reduced engine's own 𝔍 is its tests'
            inertia, K = _inertia_matrix(scene, x)
            qdot = np.linspace(1.7, -0.9, scene.dof)
            d.qpos[:] = P @ (x - x0)
            d.qvel[:] = P @ (K @ qdot)
            mujoco.mj_forward(m, d)
            rows = np.flatnonzero(d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
            assert np.max(np.abs(d.efc_vel[rows]), initial=0.0) < 1e-12  # the rates keep the loops closed
            mujoco.mj_fullM(m, d, M)
            worst = max(worst, abs((d.qvel @ M @ d.qvel) / (qdot @ inertia @ qdot) - 1.0))
            continue
        inertia, K = _generalized_inertia(scene, x)
        qdot = 1.7
        d.qpos[:] = P @ (x - x0)
        d.qvel[:] = P @ (K * qdot)
        mujoco.mj_forward(m, d)
        rows = np.flatnonzero(d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        assert np.max(np.abs(d.efc_pos[rows]), initial=0.0) < 1e-12  # the state closes the loops
        np.testing.assert_allclose(x0 + T @ d.qpos, x, rtol=0, atol=1e-14)
        mujoco.mj_fullM(m, d, M)
        kinetic = 0.5 * d.qvel @ M @ d.qvel
        worst = max(worst, abs(kinetic / (0.5 * inertia * qdot ** 2) - 1.0))
        # The reduced model's own 𝔍 (loopcheck.reduced.dynamics, the engine's path) is the same sum.
        engine = MechanismModel(scene).coefficients_at(x).generalized_inertia
        worst = max(worst, abs(kinetic / (0.5 * engine * qdot ** 2) - 1.0))
    assert worst < 5e-14


def test_coordinate_map_inverts_the_joint_map(scene):
    _, T = coordinate_map(scene)
    P = joint_rates_matrix(scene)
    np.testing.assert_array_equal(P @ T, np.eye(len(joint_order(scene.mechanism.linkage))))


# Measured at 0.5 ms (RK4, default hard constraint): loop gap ≤ 1.2e-7 m (slider-crank), energy
# residual ≤ 4.6e-5 of the energy scale (slider-crank with its gas force; Watt II 3.4e-6). Bounds
# 8x and 6.5x above: a point force applied with the wrong sign or at the wrong point, or a body
# left out of the audit, breaks the balance by far more.
@functools.cache
def _run(name: str):
    """(scene, its MuJoCo run at 0.5 ms): one run per scene for the tests that read it (results
    are frozen, their arrays read-only)."""
    scene = SCENES[name]()
    return scene, simulate_mujoco(scene, MujocoSettings(timestep=5e-4))


@pytest.mark.parametrize("name", ["slider_crank", "slider_driven", "watt_ii", "slider_reversed", "seed_driven_at_a"])
def test_general_scene_runs_gated_and_balanced(name):
    scene, result = _run(name)
    assert result.constraint_violation.max < 1e-6
    assert result.audit.relative_residual < 3e-4
    joints = result.joints
    system = loops.compile_linkage(scene.mechanism.linkage)
    assert joints.names == system.coordinate_names
    assert joints.x.shape == joints.xdot.shape == (len(joints.t), system.n)
    np.testing.assert_array_equal(joints.t, result.constraint_violation.t)
    np.testing.assert_allclose(joints.x @ system.drive, result.details.grid_q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(joints.xdot @ system.drive, result.details.grid_qdot, rtol=0, atol=1e-12)
    assert np.all(joints.coordinate == -1)
    mode = getattr(joints, dataclasses.fields(joints)[5].name)  # "mode" (contract), "branch" before
    assert mode.shape == (len(joints.t), len(scene.mechanism.linkage.cut_joints))
    assert tuple(mode[0]) == tuple(scene.mode)
    assert result.trajectory.q[0] == pytest.approx(scene.q0, abs=1e-15)
    assert result.trajectory.qdot[0] == pytest.approx(scene.qdot0, rel=1e-12)


# The seed's MuJoCo run at 1 ms before the general model (commit 7054af1, the four-bar-only
# builder; MuJoCo 4.0.1): peak (rad/s, s) and (t, q, q̇) at nine of its 2002 samples.
BEFORE_PEAK = (34.2646726666546, 1.1544637201716292)
BEFORE_INDEX = [0, 250, 500, 750, 1000, 1250, 1500, 1750, 2001]
BEFORE_T = [0.0, 0.25000000000000017, 0.5000000000000003, 0.7500000000000006, 1.0000000000000007,
            1.2489999999999732, 1.4989999999999457, 1.7489999999999182, 1.9999999999998905]
BEFORE_Q = [0.2, 1.203406799777244, 3.5268631203671577, 7.601559150422674, 12.81491397125157,
            18.79526675764433, 24.751892076156917, 30.496808657437853, 35.68769217543426]
BEFORE_QDOT = [-0.0, 6.848985883472782, 16.884804159228395, 17.56756318496341, 24.75501946855413,
               14.737093609041326, 13.780359752811345, 20.738457145065325, 30.79783836825654]


def test_seed_run_is_the_four_bar_only_models():
    """The shorthand seed is authored at the four-bar's closed form, the same pose, joints,
    bodies and elements as before: the run is bit-identical on the same MuJoCo build (measured:
    every sample, the peak and the energy residual exactly equal). 1e-12 is the brief's bound."""
    result = simulate_mujoco(load_scene(SEED_SCENE), MujocoSettings(timestep=1e-3))
    t = result.trajectory
    assert len(t.t) == 2002
    np.testing.assert_allclose(t.t[BEFORE_INDEX], BEFORE_T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(t.q[BEFORE_INDEX], BEFORE_Q, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(t.qdot[BEFORE_INDEX], BEFORE_QDOT, rtol=1e-12, atol=1e-12)
    assert result.peak.omega == pytest.approx(BEFORE_PEAK[0], rel=1e-12)
    assert result.peak.time == pytest.approx(BEFORE_PEAK[1], rel=1e-12)


def test_general_seed_agrees_with_the_shorthand():
    """The planar description of the seed is assembled by Newton's method, 4e-16 rad from the
    closed form; the stiff loop constraint carries that to ≤ 3.5e-11 rad in q and 1.1e-9 rad/s in
    q̇ over the run (measured against the 7054af1 run, all 2002 samples); bounds ~8x above."""
    general = simulate_mujoco(load_scene(ROOT / "scenes" / "mechanisms" / "seed_fourbar.toml"),
                              MujocoSettings(timestep=1e-3))
    t = general.trajectory
    np.testing.assert_allclose(t.q[BEFORE_INDEX], BEFORE_Q, rtol=0, atol=3e-10)
    np.testing.assert_allclose(t.qdot[BEFORE_INDEX], BEFORE_QDOT, rtol=0, atol=9e-9)


@pytest.mark.parametrize("name", ["slider_crank", "slider_driven"])
def test_point_force_is_the_tabulated_force_at_every_rk4_stage(name):
    """The callback's generalized force does the virtual power F(q) u·K_P of the loop kinematics
    (K_P = dP/dq from loopcheck.kinematics on the point, not MuJoCo), and RK4 calls it once per stage
    (four times per step) at that stage's own state (four different q).

    Measured: the two virtual powers agree to 5.4e-17 of Σ max|F|·|K_P|; bound 1e-15 (20x).
    """
    from loopcheck.loads import TabulatedForce
    from loopcheck.reference_models import point_force_callback
    from loopcheck.mujoco_model.layout import Layout as _Layout

    scene = SCENES[name]()
    handles = build_model(scene, MujocoSettings(timestep=STEP))
    m, d = handles.model, mujoco.MjData(handles.model)
    layout = _Layout.of(scene, m)
    callback = point_force_callback(scene, m, layout)
    system = loops.compile_linkage(scene.mechanism.linkage)
    x0, _ = coordinate_map(scene)
    P = joint_rates_matrix(scene)
    for x in _states(scene, 4):
        K, _ = loops.coefficients(system, x)
        kp, _ = loops.rates(system.points, x, K)
        expected, scale = 0.0, 0.0
        for pf in scene.mechanism.point_forces:
            f = float(TabulatedForce(pf.coordinate, pf.values, pf.period)(system.drive @ x))
            u = np.array([math.cos(pf.direction), math.sin(pf.direction)])
            expected += f * float(kp[system.point_index(pf.body, pf.point)] @ u)
            scale += np.max(np.abs(pf.values)) * np.linalg.norm(kp[system.point_index(pf.body, pf.point)])
        d.qpos[:] = P @ (x - x0)
        mujoco.mj_forward(m, d)
        callback(m, d)
        power = float(d.qfrc_applied @ (P @ K))  # joint rates with q̇ = 1
        assert abs(power - expected) <= 1e-15 * scale

    seen: list[float] = []

    def counting(model, data):
        seen.append(float(layout.input_row @ data.qpos))
        callback(model, data)
    previous = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(counting)
    try:
        mujoco.mj_resetDataKeyframe(m, d, m.key(HOME_KEY).id)
        mujoco.mj_step(m, d)
    finally:
        mujoco.set_mjcb_control(previous)
    assert len(seen) == 4 and len(set(seen)) == 4


def test_slider_input_acceleration_is_the_rate_of_its_speed():
    """A slide input's q̈ comes from MuJoCo's qacc (no sensor reads a slide's acceleration):
    against central differences of q̇ (constant force: no jumps), measured 2.6e-3 of max |q̈|
    (the differences' O(h²) error at 0.5 ms); bound 1e-2. A wrong sign or dof is off by ~2."""
    _, result = _run("slider_driven")
    t = result.trajectory
    fd = np.gradient(t.qdot, t.t)[1:-1]
    assert np.max(np.abs(fd - t.qddot[1:-1])) < 1e-2 * np.max(np.abs(t.qddot))


def test_unit_rate_inertia_from_mujocos_null_space_is_the_generalized_inertia(scene):
    """The energy gate's floor: uᵀ M u over the null space of every equality row, scaled to a
    unit input rate, is 𝔍(x0) from the loop kinematics (measured ≤ 1.6e-15 relative, Watt II;
    bound 1e-14)."""
    from loopcheck.reference_models import check_initial_state, initial_qpos_qvel

    handles = build_model(scene, MujocoSettings(timestep=STEP))
    data = mujoco.MjData(handles.model)
    data.qpos[:], data.qvel[:] = initial_qpos_qvel(scene)
    found = check_initial_state(scene, handles.model, data)["unit_rate_inertia"]
    if scene.dof > 1:  # several inputs: the lightest input's, each at unit rate with the others held
        expected = float(np.min(np.diag(_inertia_matrix(scene, np.asarray(scene.x0))[0])))
    else:
        expected, _ = _generalized_inertia(scene, np.asarray(scene.x0))
    assert found == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize("name", ["slider_crank", "watt_ii"])
def test_exported_mjcf_reruns_the_same_motion(name, tmp_path):
    """The file, compiled alone and run with the scene (its point forces applied again by the
    runner), gives the in-memory model's run: same model, same arithmetic, so bit-identical."""
    from loopcheck.reference_models import handles_from_mjcf

    scene, direct = _run(name)
    settings = MujocoSettings(timestep=5e-4)
    path = tmp_path / "model.xml"
    path.write_text(mjcf_text(scene, settings), encoding="utf-8")
    reloaded = simulate_mujoco(scene, settings, handles=handles_from_mjcf(path))
    np.testing.assert_array_equal(reloaded.trajectory.q, direct.trajectory.q)
    np.testing.assert_array_equal(reloaded.trajectory.qdot, direct.trajectory.qdot)
