"""Dampers and springs on a joint's own coordinate ([[joint_dampers]], [[joint_springs]]):
a revolute joint's relative angle θ_b − θ_a (cut joints included), a prismatic joint's
displacement. Both engines: the reduced kernel's terms (loopcheck/reduced/kernels/physics.py) and
MuJoCo's fixed tendons (loopcheck/reference_models/build.py, joint_tendons).

Oracles: each element split into two halves on the same joint gives the whole's motion (a
four-bar, a slider-crank and a six-bar, both engines); closed forms of a one-body oscillator
(a bar on a torsion spring and damper, a block on a slider spring and damper); the energy
audit with the springs' potential and the dampers' dissipation; both engines agree.
"""

from __future__ import annotations

import math
import re
import tomllib

import numpy as np
import pytest

from loopcheck import kinematics as loops
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scenefile import scene_from_dict
from loopcheck.scene import SceneError
from loopcheck.reference_models import MujocoSettings, simulate_mujoco

from helpers import ROOT

REDUCED = ReducedSettings(method="dop853", rtol=1e-12)
MECHANISMS = {"four_bar": "seed_fourbar.toml", "slider_crank": "slider_crank_gas.toml",
              "six_bar": "stephenson3_sixbar.toml"}
HORIZON = {"four_bar": 0.5, "slider_crank": 0.05, "six_bar": 0.5}
MUJOCO_STEP = {"four_bar": 2e-4, "slider_crank": 1e-4, "six_bar": 2e-4}


def _data(name: str) -> dict:
    with open(ROOT / "scenes" / "mechanisms" / MECHANISMS[name], "rb") as f:
        data = tomllib.load(f)
    data["simulation"] = {"horizon": HORIZON[name]}
    data.pop("tolerances", None)
    return data


def _elements(name: str) -> tuple[list[dict], list[dict]]:
    """(springs, dampers) for a mechanism: a spring on a cut joint and a damper on a tree joint
    (not the input); on the slider-crank also a spring and a damper on its prismatic joint.
    Each spring rests 0.2 rad (or 5 mm) away from its joint's coordinate at q0, so it acts."""
    scene = scene_from_dict(_data(name))
    linkage = scene.mechanism.linkage
    system = loops.compile_linkage(linkage)
    x0 = np.asarray(scene.x0)
    cut = linkage.cut_joints[0]
    tree = next(e.joint for e in linkage.tree if e.joint != linkage.input_joint)
    stiffness = {"four_bar": 200.0, "slider_crank": 20.0, "six_bar": 5.0}[name]
    damping = {"four_bar": 5.0, "slider_crank": 0.05, "six_bar": 0.2}[name]
    springs = [{"joint": cut, "stiffness": stiffness, "rest_angle": float(system.joint_row(cut) @ x0) + 0.2}]
    dampers = [{"joint": tree, "coefficient": damping}]
    if name == "slider_crank":
        springs.append({"joint": "cyl", "stiffness": 2e4, "rest_displacement": float(system.joint_row("cyl") @ x0) - 0.005})
        dampers.append({"joint": "cyl", "coefficient": 20.0})
    return springs, dampers


def _with(name: str, halves: bool, springs=None, dampers=None):
    data = _data(name)
    if springs is None:
        springs, dampers = _elements(name)
    if halves:
        springs = [{**e, "stiffness": 0.5 * e["stiffness"], "name": f"s{k}{h}"} for k, e in enumerate(springs) for h in "ab"]
        dampers = [{**e, "coefficient": 0.5 * e["coefficient"], "name": f"d{k}{h}"} for k, e in enumerate(dampers)
                   for h in "ab"]
    data["joint_springs"], data["joint_dampers"] = springs, dampers
    return scene_from_dict(data)


@pytest.fixture(scope="module", params=list(MECHANISMS))
def runs(request):
    """Both engines on the mechanism with its elements whole and split, and without them."""
    name = request.param
    mujoco = MujocoSettings(integrator="rk4", timestep=MUJOCO_STEP[name])
    out = {"name": name}
    for label, scene in (("whole", _with(name, False)), ("halves", _with(name, True)),
                         ("without", scene_from_dict(_data(name)))):
        out[label] = (simulate(scene, REDUCED), simulate_mujoco(scene, mujoco))
    return out


def _max_diff(a, b) -> tuple[float, float]:
    """max |Δq| and max |Δq̇| of run b (its quintic interpolant) on run a's samples."""
    t = a.trajectory.t
    q, qdot, _ = b.trajectory.interpolate(t)
    return float(np.max(np.abs(q - a.trajectory.q))), float(np.max(np.abs(qdot - a.trajectory.qdot)))


def test_two_halves_move_as_the_whole(runs):
    # Measured max |Δq|: reduced 8.9e-16, 7.1e-15, 4.6e-14 rad (four-bar, slider-crank, six-bar;
    # round-off of the summed terms, carried by DOP853's step choices), MuJoCo 0, 7.1e-15, 0.
    # Bounds 3e-13 and 5e-14 rad. The elements move the input by 0.18-2.3 rad (asserted ≥ 0.1),
    # so a half that is lost or counted twice is caught by twelve decades.
    for engine, bound in ((0, 3e-13), (1, 5e-14)):
        whole, halves, without = runs["whole"][engine], runs["halves"][engine], runs["without"][engine]
        dq, _ = _max_diff(whole, halves)
        effect, _ = _max_diff(whole, without)
        assert dq <= bound, (runs["name"], engine, dq)
        assert effect >= 0.1, (runs["name"], engine, effect)


def test_both_engines_agree_with_joint_elements(runs):
    # MuJoCo RK4 at 0.1-0.2 ms against DOP853 at rtol 1e-12: measured max |Δq| 1.0e-8, 1.9e-7,
    # 2.9e-6 rad (four-bar, slider-crank, six-bar; the six-bar's soft loop constraints); bounds
    # about 5x. Without its elements each run moves 0.18-2.3 rad away.
    reduced, mujoco = runs["whole"]
    dq, dv = _max_diff(mujoco, reduced)
    bound = {"four_bar": 5e-8, "slider_crank": 1e-6, "six_bar": 1.5e-5}[runs["name"]]
    assert dq <= bound, (runs["name"], dq, dv)


def test_energy_audits_hold_the_joint_elements(runs):
    # The springs' potential and the dampers' dissipation are in both audits: measured relative
    # residuals reduced 6.2e-12, 3.6e-13, 7.5e-12, MuJoCo 9.1e-7, 9.5e-6, 2.2e-6 (its trapezoid
    # rule); bounds 5e-11 and 5e-5. The dampers dissipate 3-19 % of the energy scale (asserted
    # ≥ 1 %), so dropping either term leaves a residual thousands of times the bound.
    reduced, mujoco = runs["whole"]
    assert reduced.audit.relative_residual <= 5e-11, reduced.audit.relative_residual
    assert mujoco.audit.relative_residual <= 5e-5, mujoco.audit.relative_residual
    for result in (reduced, mujoco):
        assert result.audit.damper_dissipation[-1] > 1e-2 * result.audit.scale


# -- closed forms: a one-body oscillator ------------------------------------------------------

def _oscillator(prismatic: bool, k: float, c: float | None, rest: float, start: float, horizon: float) -> dict:
    """A bar of inertia J = 0.02 kg·m² about a fixed pin, or a block of 0.5 kg on a slider at
    0.3 rad to ground x, with a joint spring (and damper) on that joint; no gravity."""
    joint = ({"name": "S", "type": "prismatic", "a": "ground.O", "direction": 0.3, "b": "block.c"} if prismatic else
             {"name": "P", "type": "revolute", "a": "ground.O", "b": "bar.O"})
    body = ({"block": {"points": {"c": [0.0, 0.0]}, "mass": 0.5, "com": [0.0, 0.0], "inertia": 1e-3}} if prismatic else
            {"bar": {"points": {"O": [0.0, 0.0], "T": [0.4, 0.0]}, "pivot_inertia": 0.02, "pivot": "O"}})
    spring = {"joint": joint["name"], "stiffness": k, ("rest_displacement" if prismatic else "rest_angle"): rest}
    data = {"linkage": {"type": "planar", "input": joint["name"]}, "bodies": {"ground": {"points": {"O": [0.0, 0.0]}}, **body},
            "joints": [joint], "joint_springs": [spring], "initial": {"q": start}, "simulation": {"horizon": horizon}}
    if c is not None:
        data["joint_dampers"] = [{"joint": joint["name"], "coefficient": c}]
    return data


def _closed_form(t, inertia: float, k: float, c: float, rest: float, start: float) -> np.ndarray:
    """u(t) of J ü + c u̇ + k (u − rest) = 0 from rest at u = start (underdamped)."""
    omega = math.sqrt(k / inertia)
    zeta = c / (2.0 * math.sqrt(k * inertia))
    wd = omega * math.sqrt(1.0 - zeta * zeta)
    return rest + (start - rest) * np.exp(-zeta * omega * t) * (np.cos(wd * t) + zeta * omega / wd * np.sin(wd * t))


CASES = {"torsion_spring": (False, 8.0, None, 0.1, 0.6), "torsion_spring_damper": (False, 8.0, 0.05, -0.2, 0.6),
         "slider_spring": (True, 200.0, None, 0.05, 0.12), "slider_spring_damper": (True, 200.0, 1.5, 0.05, 0.12)}


@pytest.mark.parametrize("case", CASES)
def test_oscillator_on_a_joint_element_follows_its_closed_form(case):
    prismatic, k, c, rest, start = CASES[case]
    inertia = 0.5 if prismatic else 0.02
    period = 2 * math.pi * math.sqrt(inertia / k)
    scene = scene_from_dict(_oscillator(prismatic, k, c, rest, start, 3 * period))
    # Over three periods, of the amplitude: reduced DOP853 at rtol 1e-12 measured 7.5e-12, 3.1e-12,
    # 3.2e-11, 1.1e-11 (the cases in order), bound 1e-10; MuJoCo RK4 at period/400 (error O(h⁴))
    # measured 8.8e-9, 3.0e-9, 8.8e-9, 2.5e-9, bound 3e-8. A spring of the wrong stiffness by
    # 1e-6 already shifts the phase by 1e-5 of the amplitude after three periods.
    for result, bound in ((simulate(scene, REDUCED), 1e-10),
                          (simulate_mujoco(scene, MujocoSettings(integrator="rk4", timestep=period / 400)), 3e-8)):
        tr = result.trajectory
        error = np.max(np.abs(tr.q - _closed_form(tr.t, inertia, k, c or 0.0, rest, start)))
        assert error <= bound * abs(start - rest), (case, result.engine, error / abs(start - rest))


# -- the scene file ---------------------------------------------------------------------------

@pytest.mark.parametrize("change, message", [
    ({"joint": "nope"}, "'joint_springs[0].joint' = \"nope\" is not one of the joints"),
    ({"rest_displacement": 0.1}, "'joint_springs[0].rest_displacement' does not fit the revolute joint 'P'"),
    ({"stiffness": -1.0}, "'joint_springs[0].stiffness' must be positive"),
    ({"extra": 1}, "unknown key 'joint_springs[0].extra'"),
])
def test_bad_joint_spring_is_refused_naming_its_key(change, message):
    data = _oscillator(False, 8.0, None, 0.1, 0.6, 1.0)
    data["joint_springs"][0].update(change)
    with pytest.raises(SceneError, match=re.escape(message)):
        scene_from_dict(data)


def test_joint_element_names_share_the_line_elements_namespace():
    data = _oscillator(False, 8.0, 0.05, 0.1, 0.6, 1.0)
    data["joint_springs"][0]["name"] = "x"
    data["joint_dampers"][0]["name"] = "x"
    with pytest.raises(SceneError, match="duplicate damper, spring or inertia name 'x'"):
        scene_from_dict(data)


def test_exported_mjcf_keeps_the_joint_tendons(tmp_path):
    """The six-bar with a spring on a cut joint and a damper on a tree joint: the exported file,
    compiled alone, reruns the in-memory model's motion bit for bit (the fixed tendons' numbers
    written to full precision)."""
    from loopcheck.reference_models import handles_from_mjcf, mjcf_text

    scene = _with("six_bar", False)
    settings = MujocoSettings(integrator="rk4", timestep=MUJOCO_STEP["six_bar"])
    path = tmp_path / "model.xml"
    path.write_text(mjcf_text(scene, settings), encoding="utf-8")
    assert path.read_text().count("<fixed ") == 2
    direct = simulate_mujoco(scene, settings)
    reloaded = simulate_mujoco(scene, settings, handles=handles_from_mjcf(path))
    np.testing.assert_array_equal(reloaded.trajectory.q, direct.trajectory.q)
