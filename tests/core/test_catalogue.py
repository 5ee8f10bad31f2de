"""The catalogue of classic mechanisms (scenes/mechanisms/): every scene loads, says what it is
and where it comes from, assembles in the mode it asks for and keeps it over its motion, and its
kinematic coefficients K = dx/dq and L = d²x/dq² (loopcheck.kinematics, no finite differences) agree
with central differences of the Newton assembly. These need only the scene layer and
loopcheck.kinematics; the engines' checks of the catalogue (energy balance, MuJoCo's ½ q̇ᵀMq̇, exported
MJCF) live with the engines.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from loopcheck import kinematics as loops
from loopcheck.errors import NumericalFailure
from loopcheck.mechanism import PrismaticJoint
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path

from helpers import ROOT

FOLDER = ROOT / "scenes" / "mechanisms"
EXPECTED = {  # scene: (moving bodies, loops, effects)
    "seed_fourbar": (3, 1, ("torque", "damper")),
    "friction_fourbar": (3, 1, ("torque", "damper", "joint-friction")),
    "slider_crank_gas": (3, 1, ("torque", "point-force")),
    "slider_crank_driven_slider": (3, 1, ("force",)),
    "oscillating_slotted_lever": (3, 1, ("torque", "damper", "gravity")),
    "drag_link": (3, 1, ("torque", "damper")),
    "watt2_sixbar": (5, 2, ("torque", "damper", "gravity")),
    "stephenson3_sixbar": (5, 2, ("torque", "spring")),
    "stephenson3_near_toggle": (5, 2, ("torque", "spring")),
    "andrews_squeezer": (7, 3, ("torque", "spring")),
    "parallelogram_redundant": (4, 2, ("torque",)),  # a redundantly closed loop: Grübler 0, rank 1 DOF
    "seed_fourbar_geared_flywheel": (4, 1, ("torque", "damper")),
    "servo_fourbar": (3, 1, ("actuator",)),
    "five_bar_robot": (4, 1, ("actuator", "gravity")),  # two DOF (issue 40)
    "adaptive_finger": (4, 1, ("joint-spring", "actuator")),  # two DOF, one motor (issue 41)
    "three_rrr": (7, 2, ("actuator",)),  # three DOF (issue 41)
}
# Scenes of several inputs: the one-input checks below (a full turn of the crank, K and L of the one
# input by finite differences) do not apply; tests/reduced/test_several_dof.py holds them to the
# independent multibody oracle (tests/reduced/test_catalogue_several_dof.py the finger and the 3-RRR).
SEVERAL_DOF = ("five_bar_robot", "adaptive_finger", "three_rrr")
# whole turns each other angle makes per turn of the crank (0 where it comes back): the drag link's
# coupler and follower turn with it, the geared flywheel turns twice the other way (its coupling)
TURNS = {"drag_link": 1, "seed_fourbar_geared_flywheel": {"flywheel.angle": -2}}
NAMES = sorted(EXPECTED)
TURN_SAMPLES = 720


def _load(name):
    scene = load_scene(FOLDER / f"{name}.toml")
    return scene, loops.compile_linkage(scene.mechanism.linkage)


def _crank(scene, system) -> int:
    """The coordinate that turns fully: the input's for a revolute input, else the body at the
    other fixed revolute joint (the slider-driven slider-crank's crank)."""
    linkage = scene.mechanism.linkage
    if scene.input_unit == "rad":
        return int(np.argmax(system.drive))
    for j in linkage.joints:
        if not isinstance(j, PrismaticJoint) and "ground" in (j.body_a, j.body_b):
            return system.coordinate(f"{j.body_b if j.body_a == 'ground' else j.body_a}.angle")
    raise AssertionError("no crank")


def _turn(scene, system, samples=TURN_SAMPLES):
    """Configurations over one full turn of the crank from x0, by continuation, shape (samples + 1, n)."""
    i = _crank(scene, system)
    by_crank = system.driven_by(i)
    x = np.array(scene.x0)
    out = [x]
    for value in np.linspace(x[i], x[i] + 2 * math.pi, samples + 1)[1:]:
        x = loops.assemble(by_crank, value, x)
        out.append(x)
    return np.array(out)


def test_the_catalogue_is_complete():
    assert sorted(p.stem for p in FOLDER.glob("*.toml")) == NAMES


@pytest.mark.parametrize("name", NAMES)
def test_each_scene_loads_and_says_where_it_comes_from(name):
    text = (FOLDER / f"{name}.toml").read_text(encoding="utf-8")
    header = [line for line in text.splitlines()[:12] if line.startswith("#")]
    assert len(header) >= 4, "a header comment saying what the mechanism is and where it comes from"
    scene, system = _load(name)
    bodies, n_loops, effects = EXPECTED[name]
    linkage = scene.mechanism.linkage
    assert (len(linkage.moving), len(linkage.cut_joints), scene.effects) == (bodies, n_loops, effects)
    assert len(scene.mode) == n_loops
    assert np.max(np.abs(loops.constraint_residual(system, np.array(scene.x0)))) < 1e-12
    assert loops.jacobian_rank(system, np.array(scene.x0)) == system.n - scene.dof


# ~1 s each: a Newton assembly at each of the turn's samples. The fast suite keeps a four-bar, a
# six-bar and the slider-driven slider-crank (its modes flip at the dead centres); the rest are slow.
FAST_TURNS = ("seed_fourbar", "watt2_sixbar", "slider_crank_driven_slider")


# A parallelogram's flat positions (crank angle 0, π) are change points: there the rank of its loop
# equations drops, it may fold into an anti-parallelogram, and its dyads' elbow signs (the assembly
# mode) flip as the crank passes them even on the parallelogram branch. Its scene stays between them.
NO_FULL_TURN = ("parallelogram_redundant",)


@pytest.mark.parametrize("name", [n if n in FAST_TURNS else pytest.param(n, marks=pytest.mark.slow)
                                  for n in NAMES if n not in NO_FULL_TURN + SEVERAL_DOF])
def test_the_crank_turns_fully_in_the_scenes_assembly_mode(name):
    """A full turn of the crank closes every loop, keeps the scene's assembly mode throughout and
    returns to x0 (plus one turn of the crank). The mode is a property of the input: it may
    change only where the input cannot drive the loop, so with the slider as input it changes
    exactly at the two dead centres (the extremes of s), and nowhere for a crank input (the
    oscillating slotted lever's extremes are not singular for the crank: needs the mode_pairs fix in
    loopcheck/kinematics.py, see the catalogue report). The other angles come back too, the drag link's
    a whole turn on (its coupler and follower turn with the crank), every other's where it was."""
    scene, system = _load(name)
    X = _turn(scene, system)
    modes = loops.assembly_modes(system, X)
    assert modes[0].tolist() == list(scene.mode)
    if scene.input_unit == "m":
        s = X[:, system.coordinate("cyl.s")]
        dead_centres = np.flatnonzero(np.diff(np.sign(np.diff(s)))) + 1  # samples at the extremes
        flips = np.flatnonzero(np.any(np.diff(modes, axis=0) != 0, axis=1))
        assert len(flips) == 2 and np.all(np.abs(flips - dead_centres) <= 1), (flips, dead_centres)
    else:
        assert np.all(modes == np.array(scene.mode)), name
    shift = X[-1] - X[0]
    i = _crank(scene, system)
    assert shift[i] == pytest.approx(2 * math.pi, abs=1e-12)
    # the other coordinates return, an angle possibly a whole turn on (the drag link's all turn)
    turns = np.array([round(d / (2 * math.pi)) if coordinate.endswith(".angle") else 0
                      for d, coordinate in zip(shift, system.coordinate_names)])
    assert np.max(np.abs(np.delete(shift - 2 * math.pi * turns, i))) < 1e-9
    expected = TURNS.get(name, 0)
    if isinstance(expected, dict):
        expected = np.array([expected.get(c, 0) for c in system.coordinate_names])
        expected = np.delete(expected, i)
    assert np.all(np.delete(turns, i) == expected)


def _states(scene, system):
    """Five assembled states along the crank's turn where the input coordinate drives the linkage."""
    X = _turn(scene, system, 100)
    states = [x for x in X[::20] if loops.conditioning(system, x)[int(np.argmax(np.abs(system.drive)))] > 0.05]
    return states


# Central differences of the Newton assembly with one Richardson step (error O(h⁴) plus
# round-off ~1e-16/h for K, ~1e-16/h² for L). Steps (K, L) per input unit: 1e-3 rad; for the
# slider-driven slider-crank, whose x(s) has steep higher derivatives near the dead centres,
# 3e-6 m and 1e-5 m (a scan of h from 1e-4 to 1e-6 m gave the least error there). Bounds relative
# to the largest |K|, |L| at the state; measured worst over the catalogue: K 1e-10
# (stephenson3_near_toggle), L 9e-8 (slider-driven; 3e-8 for the others).
STEPS = {"rad": (1e-3, 1e-3), "m": (3e-6, 1e-5)}
K_RTOL, L_RTOL = 1e-9, 3e-7


def _differences(system, x, q, h):
    """(dx/dq, d²x/dq²) by central differences with step h, Richardson-extrapolated."""
    def central(step):
        xp, xm = loops.assemble(system, q + step, x), loops.assemble(system, q - step, x)
        return (xp - xm) / (2 * step), (xp - 2 * x + xm) / step ** 2
    k1, l1 = central(h)
    k2, l2 = central(h / 2)
    return (4 * k2 - k1) / 3, (4 * l2 - l1) / 3


@pytest.mark.parametrize("name", [n for n in NAMES if n not in SEVERAL_DOF])
def test_k_and_l_agree_with_finite_differences(name):
    scene, system = _load(name)
    k_step, l_step = STEPS[scene.input_unit]
    worst_k = worst_l = 0.0
    for x in _states(scene, system):
        q = float(system.drive @ x)
        K, L = loops.coefficients(system, x)
        k_fd, _ = _differences(system, x, q, k_step)
        _, l_fd = _differences(system, x, q, l_step)
        worst_k = max(worst_k, np.max(np.abs(K - k_fd)) / np.max(np.abs(K)))
        # the parallelogram's L is 0 (every crank turns as the input, the coupler translates): relative to K then
        scale_l = np.max(np.abs(L)) if np.max(np.abs(L)) > 1e-12 * np.max(np.abs(K)) else np.max(np.abs(K))
        worst_l = max(worst_l, np.max(np.abs(L - l_fd)) / scale_l)
    assert worst_k < K_RTOL and worst_l < L_RTOL, (worst_k, worst_l)


@pytest.mark.slow  # ~1 s: a turn assembled by Newton, and a bisection at each dead centre
def test_the_slider_driven_slider_crank_must_pass_dead_centres():
    """The piston's displacement cannot drive the linkage at two crank angles per turn (the
    dead centres: coefficients raise SINGULAR there), and the flywheel's kinetic energy at the
    start exceeds the work the constant force can take out over a stroke, so the crank turns
    through them (the scene is a test of coordinate partitioning)."""
    scene, system = _load("slider_crank_driven_slider")
    X = _turn(scene, system)
    s = X[:, system.coordinate("cyl.s")]
    turning = np.flatnonzero(np.diff(np.sign(np.diff(s))))  # extrema of s over the turn
    assert len(turning) == 2
    by_crank = system.driven_by(_crank(scene, system))
    i_s = system.coordinate("cyl.s")
    for k in turning:  # bisect on the sign of ds/dθ for the crank angle of the extremum
        a, b = X[k][0], X[k + 2][0]
        x = X[k + 1]
        sign_a = np.sign(loops.coefficients(by_crank, loops.assemble(by_crank, a, x))[0][i_s])
        for _ in range(60):
            mid = 0.5 * (a + b)
            x = loops.assemble(by_crank, mid, x)
            if np.sign(loops.coefficients(by_crank, x)[0][i_s]) == sign_a:
                a = mid
            else:
                b = mid
        assert abs(loops.coefficients(by_crank, x)[0][i_s]) < 1e-12  # ds/dθ = 0: a dead centre
        with pytest.raises(NumericalFailure, match="dead-centre"):
            loops.coefficients(system, x)  # K = dx/ds does not exist there
    stroke = float(np.max(s) - np.min(s))
    x0 = np.array(scene.x0)
    K, L = loops.coefficients(system, x0)
    linkage = scene.mechanism.linkage
    kc, _ = loops.rates(system.centres, x0, K, L)
    bodies = linkage.body_map
    J = sum(bodies[b].mass * (kc[i] @ kc[i]) + bodies[b].inertia * K[i] ** 2 for i, b in enumerate(linkage.moving))
    assert stroke == pytest.approx(0.05, rel=0.01)  # 2r, slightly more with the offset
    assert 0.5 * J * scene.qdot0 ** 2 > 10 * scene.load.amplitude * stroke


def test_the_gas_force_table_spans_one_four_stroke_cycle():
    scene, _ = _load("slider_crank_gas")
    (gas,) = scene.mechanism.point_forces
    assert gas.period == pytest.approx(4 * math.pi, rel=1e-15)
    assert gas.coordinate[-1] - gas.coordinate[0] < gas.period
    peak = gas.coordinate[int(np.argmax(gas.values))]
    assert 0.0 < peak < math.radians(40)  # just after firing top dead centre
    assert max(gas.values) == pytest.approx(6051.6)


def test_the_planar_seed_is_the_shorthand_seed():
    """scenes/mechanisms/seed_fourbar.toml and the shorthand scenes/seed_fourbar.toml: the same
    assembly and the same 𝔍 (to 1e-12) around a turn."""
    planar, sp = _load("seed_fourbar")
    short = load_scene(default_scene_path())
    ss = loops.compile_linkage(short.mechanism.linkage)
    assert np.max(np.abs(np.array(planar.x0) - np.array(short.x0))) < 1e-12
    assert planar.mode == short.mode
    xp, xs = np.array(planar.x0), np.array(short.x0)

    def inertia(scene, system, x):
        linkage = scene.mechanism.linkage
        K, L = loops.coefficients(system, x)
        kc, _ = loops.rates(system.centres, x, K, L)
        bodies = linkage.body_map
        return sum(bodies[b].mass * (kc[i] @ kc[i]) + bodies[b].inertia * K[i] ** 2
                   for i, b in enumerate(linkage.moving))

    for q in np.linspace(planar.q0, planar.q0 + 2 * math.pi, 13):
        xp, xs = loops.assemble(sp, q, xp), loops.assemble(ss, q, xs)
        assert inertia(planar, sp, xp) == pytest.approx(inertia(short, ss, xs), rel=1e-12)
