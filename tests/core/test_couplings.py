"""Joint couplings (MuJoCo's equality/joint): y − y_ref = p(x − x_ref) on two joints' own coordinates,
one more closure row of the kinematics (loopcheck.kernels.loops' polynomial rows).

Oracles, each independent of the kernel:
- two rotors on their own pivots coupled by y = y_ref + p(x − x_ref): 𝔍(q) = I1 + I2 p'(s)², ζ = I2 p'(s)
  p''(s) by hand (Eksergian's equation written here, s = q − x_ref). Linear p (a gear pair): 𝔍 constant,
  q(t) = q0 + q̇0 t + ½ (τ/𝔍) t² in closed form; quadratic and cubic p: that equation integrated by
  scipy's DOP853 at rtol = atol = 1e-12;
- the catalogue's geared flywheel (scenes/mechanisms/seed_fourbar_geared_flywheel.toml) against the seed
  four-bar with the flywheel's reflected inertia c² I_F = 1 kg·m² as a joint inertia on the crank (another
  code path: a joint element, no coupling);
- K and L of the coupled coordinate against p'(s) and p''(s) (exact).
Tolerances: the reduced engine at DOP853 rtol 1e-12 against the oracles, measured (2026-11-28) at
|Δq| ≤ 1.2e-14 rad and |Δq̇| ≤ 6.4e-15 rad/s on the rotors over 1 s, 1.4e-13 rad / 4.2e-12 rad/s on the
flywheel over 2 s: bounds 1e-11 and 1e-10 (over 20x the largest, for another CPU or compiler). MuJoCo against the reduced
engine: the scene's own tolerances (its gate).

Planted (each fails the tests named): γ_c dropped (``self.phi[j] = 0.0`` in Loops._finish, run under
LOOPCHECK_PURE_PYTHON=1) fails test_k_and_l_of_the_coupled_joint (L = 0 against p'' = 0.6) and both
polynomial oracles (the run's own energy gate: residual 0.125 of its scale); the coupling's sign in Φ_x
flipped (``+ self.poly_dp``) fails every oracle and the MuJoCo tests; MuJoCo's polycoef not re-expanded
about qpos0 (``d, e = 0, 0`` in coupling_polycoef) or its hinge signs left out (``sy = sx = 1``) fails
test_mujoco_runs_the_coupling_as_written (MuJoCo's initial state then violates the coupling: 0.05 rad,
or its rate by 2.04 rad/s, and the run is refused).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import loopcheck
from loopcheck import kinematics
from loopcheck.mechanism import Body, JointCoupling, Linkage, MechanismError, RevoluteJoint
from loopcheck.mujoco_model.build import coupling_polycoef
from loopcheck.scene import SceneError
from loopcheck.scene_writer import scene_toml

from helpers import ROOT

TIGHT = loopcheck.ReducedSettings(method="dop853", rtol=1e-12)
Q_BOUND, QDOT_BOUND = 1e-11, 1e-10
FLYWHEEL = ROOT / "scenes" / "mechanisms" / "seed_fourbar_geared_flywheel.toml"
I1, I2, TORQUE = 0.5, 0.2, 1.0


def rotors(polycoef, *, reference=(0.1, 0.2), q0=0.1, qdot0=0.0, reversed_joint=False, horizon=1.0,
           extra="") -> str:
    """Two rotors on their own pivots, J2 coupled to J1 (the input) by polycoef; ``reversed_joint``
    writes J2 from the rotor to the ground (its coordinate is then θ_ground − θ_r2 = −θ_r2)."""
    a, b = ("r2.O", "ground.O2") if reversed_joint else ("ground.O2", "r2.O")
    return f"""
name = "rotors"
[linkage]
type = "planar"
input = "J1"
[bodies.ground]
points = {{ O1 = [0.0, 0.0], O2 = [1.0, 0.0] }}
[bodies.r1]
points = {{ O = [0.0, 0.0], T = [0.3, 0.0] }}
pivot_inertia = {I1}
pivot = "O"
[bodies.r2]
points = {{ O = [0.0, 0.0], T = [0.3, 0.0] }}
pivot_inertia = {I2}
pivot = "O"
[[joints]]
name = "J1"
type = "revolute"
a = "ground.O1"
b = "r1.O"
[[joints]]
name = "J2"
type = "revolute"
a = "{a}"
b = "{b}"
[[couplings]]
name = "cam"
joint = "J2"
driver = "J1"
polycoef = {list(polycoef)}
reference = {list(reference)}
{extra}
[torque]
type = "constant"
value = {TORQUE}
[initial]
q = {q0}
qdot = {qdot0}
[simulation]
horizon = {horizon}
"""


def eksergian(polycoef, x_ref, q0, qdot0, t):
    """q, q̇ at times t of 𝔍 q̈ + ζ q̇² = τ with 𝔍 = I1 + I2 p'², ζ = I2 p' p'' (by hand)."""
    a = list(polycoef) + [0.0] * (5 - len(polycoef))

    def rhs(_, y):
        s = y[0] - x_ref
        dp = a[1] + 2 * a[2] * s + 3 * a[3] * s ** 2 + 4 * a[4] * s ** 3
        ddp = 2 * a[2] + 6 * a[3] * s + 12 * a[4] * s ** 2
        return [y[1], (TORQUE - I2 * dp * ddp * y[1] ** 2) / (I1 + I2 * dp * dp)]

    sol = solve_ivp(rhs, (0.0, t[-1]), [q0, qdot0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t)
    return sol.y[0], sol.y[1]


def _errors(result, q, qdot):
    return np.max(np.abs(result.trajectory.q - q)), np.max(np.abs(result.trajectory.qdot - qdot))


def test_a_gear_pair_moves_with_the_reflected_inertia_in_closed_form():
    c = -2.5
    r = loopcheck.simulate(loopcheck.scene_from_string(rotors([0.05, c])), TIGHT)
    t = r.trajectory.t
    inertia = I1 + c * c * I2
    dq, dw = _errors(r, 0.1 + 0.5 * TORQUE / inertia * t ** 2, TORQUE / inertia * t)
    assert dq <= Q_BOUND and dw <= QDOT_BOUND, (dq, dw)
    # the coupled rotor's angle is the polynomial of the input's (r2's frame angle is J2's coordinate)
    y = r.joints.x[:, r.joints.names.index("r2.angle")]
    x = r.joints.x[:, r.joints.names.index("r1.angle")]
    np.testing.assert_allclose(y, 0.2 + 0.05 + c * (x - 0.1), rtol=0, atol=1e-12)
    assert r.audit.relative_residual <= 1e-9


@pytest.mark.parametrize("polycoef, reversed_joint", [([0.0, -1.5, 0.8], False), ([0.1, 1.2, -0.6, 0.4], True)])
def test_a_polynomial_coupling_against_eksergian_by_hand(polycoef, reversed_joint):
    """Quadratic and cubic p; the second with J2 written from the rotor to ground (its coordinate −θ_r2)."""
    scene = loopcheck.scene_from_string(rotors(polycoef, q0=0.3, qdot0=0.5, reversed_joint=reversed_joint))
    r = loopcheck.simulate(scene, TIGHT)
    dq, dw = _errors(r, *eksergian(polycoef, 0.1, 0.3, 0.5, r.trajectory.t))
    assert dq <= Q_BOUND and dw <= QDOT_BOUND, (dq, dw)
    assert r.audit.relative_residual <= 1e-9  # the coupling does no work


def test_k_and_l_of_the_coupled_joint():
    """K and L of the coupled coordinate are p'(s) and p''(s); Φ closes to round-off."""
    scene = loopcheck.scene_from_string(rotors([0.0, -2.0, 0.3], reference=(0.1, 0.2)))
    system = kinematics.compile_linkage(scene.mechanism.linkage)
    x = kinematics.assemble(system, 0.5, np.array(scene.x0))
    s = 0.4
    assert x[1] == pytest.approx(0.2 - 2.0 * s + 0.3 * s * s, abs=1e-15)
    K, L = kinematics.coefficients(system, x)
    np.testing.assert_allclose(K, [1.0, -2.0 + 0.6 * s], atol=1e-14)
    np.testing.assert_allclose(L, [0.0, 0.6], atol=1e-14)
    assert np.max(np.abs(kinematics.constraint_residual(system, x))) <= 1e-15


def test_the_geared_flywheel_moves_as_the_seed_with_its_reflected_inertia():
    scene = loopcheck.load_scene(FLYWHEEL)
    seed = loopcheck.load_scene(ROOT / "scenes" / "mechanisms" / "seed_fourbar.toml")
    c, inertia = -2.0, 0.25
    reflected = dataclasses.replace(seed.mechanism, joint_elements=(
        loopcheck.mechanism.JointElement("inertia", "flywheel", "O1", c * c * inertia),))
    linkage = dataclasses.replace(seed.mechanism.linkage, tree_first=("O1",))
    oracle = dataclasses.replace(seed, mechanism=dataclasses.replace(reflected, linkage=linkage))
    a, b = loopcheck.simulate(scene, TIGHT), loopcheck.simulate(oracle, TIGHT)
    q, qdot, _ = b.trajectory.interpolate(a.trajectory.t)
    dq, dw = _errors(a, q, qdot)
    assert dq <= Q_BOUND and dw <= QDOT_BOUND, (dq, dw)


def test_mujoco_runs_the_coupling_as_written():
    """MuJoCo's equality/joint, its polycoef re-expanded about qpos0 (the authored pose, q0 = 0.4 while
    x_ref = 0.1) and in the hinge's own sign (J2 reversed): within the scene's tolerances of the exact
    solution, and the re-expanded polynomial is the coupling at qpos = 0 and beyond."""
    scene = loopcheck.scene_from_string(rotors([0.05, -1.5, 0.8], q0=0.4, qdot0=1.0, reversed_joint=True))
    check = loopcheck.check(scene)
    assert check.passed, check.comparison("mujoco").gate
    joint1, joint2, P = coupling_polycoef(scene, scene.mechanism.linkage.couplings[0])
    assert (joint1, joint2) == ("J2", "J1")
    # MuJoCo: qpos_y = P(qpos_x) with qpos 0 at x0; the scene: u_y = −θ_r2 = y_ref + p(u_x − x_ref)
    c = scene.mechanism.linkage.couplings[0]
    for qx in (-0.3, 0.0, 0.2):
        ux = 0.4 + qx
        uy = c.y_ref + c.polynomial(ux)[0]
        qy = -uy - scene.x0[1]  # u_y = −θ_r2; qpos_y = θ_r2 − θ_r2(x0)
        assert np.polyval(P[::-1], qx) == pytest.approx(qy, abs=1e-14)


def test_the_catalogue_scene_passes_its_gate_and_mujocos_energy_balances():
    """MuJoCo's audit (its coupling's soft constraint force may do a little work): measured 1.76e-6 of
    the scale over 0.5 s, the seed without the flywheel 1.82e-6; bound 1e-5 (5x). Its coupling's own
    work over the scene's 2 s, summed from efc_force · efc_vel: −1.9e-4 J of 2950 J (measured)."""
    scene = loopcheck.load_scene(FLYWHEEL)
    short = dataclasses.replace(scene, horizon=0.5)
    check = loopcheck.check(short)
    assert check.passed, check.comparison("mujoco").gate
    mujoco_run = loopcheck.simulate(short, loopcheck.mujoco_settings(short))
    assert mujoco_run.audit.relative_residual <= 1e-5


def test_grublers_count_takes_a_coupling_as_one_equation():
    ground = Body("ground", {"O1": (0.0, 0.0), "O2": (1.0, 0.0)})
    r1, r2 = (Body(n, {"O": (0.0, 0.0)}, inertia=1.0) for n in ("r1", "r2"))
    joints = [RevoluteJoint("J1", "ground", "O1", "r1", "O"), RevoluteJoint("J2", "ground", "O2", "r2", "O")]
    with pytest.raises(MechanismError, match="2 degrees of freedom"):
        Linkage([ground, r1, r2], joints, "J1")
    linkage = Linkage([ground, r1, r2], joints, "J1", couplings=[JointCoupling("gear", "J2", "J1", (0.0, -1.0))])
    assert linkage.couplings[0].coefficients == (0.0, -1.0, 0.0, 0.0, 0.0)
    assert linkage.grubler_dof == 1
    # two couplings: Grübler's count 0, which is no refusal by itself (the rank at the assembled
    # configuration decides, when a scene is read); the count is kept for the warning
    locked = Linkage([ground, r1, r2], joints, "J1", couplings=[JointCoupling("gear", "J2", "J1", (0.0, -1.0)),
                                                               JointCoupling("gear2", "J1", "J2", (0.0, 2.0))])
    assert locked.grubler_dof == 0


@pytest.mark.parametrize("kwargs, words", [
    (dict(name="c", joint="J", driver="J"), "couples joint 'J' to itself"),
    (dict(name="c", joint="J", driver="K", coefficients=()), "coefficients must be 1 to 5 numbers"),
    (dict(name="c", joint="J", driver="K", coefficients=(0, 1, 2, 3, 4, 5)), "coefficients must be 1 to 5 numbers"),
    (dict(name="c", joint="J", driver="K", coefficients=(0, math.nan)), "coefficients must be finite"),
    (dict(name="c", joint="J", driver="K", coefficients=(0.3,)), "it locks joint 'J'"),
    (dict(name="c", joint="J", driver="K", x_ref=math.inf), "x_ref must be a finite number"),
    (dict(name="", joint="J", driver="K"), "coupling name must be a non-empty string"),
])
def test_a_malformed_coupling_is_refused(kwargs, words):
    with pytest.raises(MechanismError, match=words):
        JointCoupling(**kwargs)


@pytest.mark.parametrize("change, words", [
    (("polycoef = [0.05, -2.5]", "polycoef = [0, 1, 2, 3, 4, 5]"), r"'couplings\[0\].polycoef' must be an array of 1 to 5"),
    (("polycoef = [0.05, -2.5]", "polycoef = [0.05, \"x\"]"), r"'couplings\[0\].polycoef\[1\]'"),
    (("polycoef = [0.05, -2.5]", "polycoef = [0.05, nan]"), r"'couplings\[0\].polycoef\[1\]'"),
    (("reference = [0.1, 0.2]", "reference = [0.1]"), r"'couplings\[0\].reference' must be an array of two"),
    (("reference = [0.1, 0.2]", "reference = [0.1, 1e9]"), r"'couplings\[0\].reference\[1\]'"),
    (('driver = "J1"', 'driver = "J9"'), r"'couplings\[0\].driver' = \"J9\" is not one of the joints"),
    (('joint = "J2"', 'joint = "J2"\ncolour = 1'), r"unknown key 'couplings\[0\].colour'"),
    (("polycoef = [0.05, -2.5]", "polycoef = [0.05]"), r"'couplings\[0\]': coupling 'cam': no term in the driver"),
    (('name = "cam"', 'name = "J1"'), r"'couplings': coupling 'J1' has a joint's name"),
])
def test_a_scene_coupling_error_names_its_key(change, words):
    text = rotors([0.05, -2.5]).replace(*change)
    with pytest.raises(SceneError, match=words) as caught:
        loopcheck.scene_from_string(text)
    assert "\n" not in str(caught.value)


def test_the_writer_gives_the_same_coupling_back():
    scene = loopcheck.scene_from_string(rotors([0.05, -1.5, 0.8], q0=0.4))
    back = loopcheck.scene_from_string(scene_toml(scene))
    assert back.mechanism.linkage.couplings == scene.mechanism.linkage.couplings
    np.testing.assert_array_equal(back.x0, scene.x0)
