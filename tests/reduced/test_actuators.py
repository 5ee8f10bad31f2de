"""Actuators as MuJoCo applies them (loopcheck.mechanism.Actuator) in the reduced engine.

Oracles: a rotor on a pivot held by a position servo (kp, kv) is a damped harmonic oscillator,
I θ̈ = kp (c − θ) − kv θ̇, in closed form; the energy audit balances with the actuators' power
f·L̇ in the work; the scene format reads and writes what the value holds.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from loopcheck.api import reduced_settings, scene_from_string, simulate
from loopcheck.mechanism import Actuator, MechanismError
from loopcheck.scene import SceneError
from loopcheck.scene_writer import scene_toml

ROTOR = """
name = "servo_rotor"
[linkage]
type = "planar"
input = "O"
[bodies.ground]
points = {{ O = [0.0, 0.0] }}
[bodies.rotor]
points = {{ O = [0.0, 0.0] }}
pivot_inertia = 0.5
pivot = "O"
[[joints]]
name = "O"
type = "revolute"
a = "ground.O"
b = "rotor.O"
[[actuators]]
name = "servo"
{transmission}
gain = {kp}
bias = [0.0, -{kp}, -{kv}]
{extra}
[actuators.control]
type = "constant"
value = {c}
[initial]
q = 0.2
qdot = 1.0
[simulation]
horizon = 2.0
"""


def rotor(kp=8.0, kv=0.6, c=0.7, transmission='joint = "O"', extra=""):
    return scene_from_string(ROTOR.format(kp=kp, kv=kv, c=c, transmission=transmission, extra=extra))


def oscillator(t, inertia, kp, kv, target, q0=0.2, v0=1.0):
    """θ(t) of I θ̈ = kp (target − θ) − kv θ̇ (underdamped)."""
    alpha = kv / (2 * inertia)
    wd = math.sqrt(kp / inertia - alpha * alpha)
    e0 = q0 - target
    return target + np.exp(-alpha * t) * (e0 * np.cos(wd * t) + (v0 + alpha * e0) / wd * np.sin(wd * t))


def residual(audit):
    r = audit.kinetic + audit.potential - audit.torque_work + audit.damper_dissipation
    return float(np.max(np.abs(r - r[0])))


def test_position_servo_on_a_rotor_is_the_damped_oscillator():
    """DOP853 at its default rtol (1e-12 here: the scene's defaults) against the closed form: measured
    3.7e-12 rad; 1e-9 leaves the integrator's own error room. Planted: b2 dropped from the kernel's
    parameters (dynamics.build_arrays): this test, the tendon's and the table's fail."""
    result = simulate(rotor(), reduced_settings(rotor()))
    t = result.trajectory.t
    assert np.max(np.abs(result.trajectory.q - oscillator(t, 0.5, 8.0, 0.6, 0.7))) < 1e-9
    # the servo's work is what the rotor lost: the audit balances (measured 1.2e-11 J of 0.18 J of work)
    assert residual(result.audit) < 1e-9 and abs(result.audit.torque_work[-1]) > 0.1


def test_servo_on_a_fixed_tendon_and_its_ctrlrange():
    """l = 0.5 θ (a tendon of one joint): I θ̈ = 0.5 kp (c − 0.5 θ) − 0.25 kv θ̇, about θ = 2c; the control 3
    clamped to the ctrlrange's 1. Planted: the tendon's coefficient taken as 1 in build_arrays: fails."""
    scene = rotor(c=3.0, transmission="tendon = { O = 0.5 }", extra="ctrlrange = [0.0, 1.0]")
    result = simulate(scene, reduced_settings(scene))
    t = result.trajectory.t
    assert np.max(np.abs(result.trajectory.q - oscillator(t, 0.5, 2.0, 0.15, 2.0))) < 1e-9
    assert residual(result.audit) < 1e-9


def test_a_control_table_steps_the_target():
    """A table of set-points is piecewise constant: its edge is a load edge, and on each piece the
    motion is the oscillator from the state at the edge (closed form, 1e-9)."""
    scene = scene_from_string(ROTOR.format(kp=8.0, kv=0.6, c=0.0, transmission='joint = "O"', extra="").replace(
        'type = "constant"\nvalue = 0.0', 'type = "table"\ntimes = [0.0, 0.8]\nvalues = [0.7, -0.3]'))
    assert 0.8 in scene.load_edges
    result = simulate(scene, reduced_settings(scene))
    t, q, v = result.trajectory.t, result.trajectory.q, result.trajectory.qdot
    first = t <= 0.8
    assert np.max(np.abs(q[first] - oscillator(t[first], 0.5, 8.0, 0.6, 0.7))) < 1e-9
    k = np.flatnonzero(t >= 0.8)[0]
    assert t[k] == 0.8
    later = t >= 0.8
    exact = oscillator(t[later] - 0.8, 0.5, 8.0, 0.6, -0.3, q0=q[k], v0=v[k])
    assert np.max(np.abs(q[later] - exact)) < 1e-9
    assert residual(result.audit) < 1e-9


def test_forcerange_on_a_constant_force_clamps_it():
    """b1 = b2 = 0: the clamp is on the control, exact. A motor of gain 1, control 5 clamped to 2 by its
    forcerange, on a free rotor of 0.5 kg·m²: θ = 0.2 + t + ½ (2 / 0.5) t²."""
    scene = scene_from_string(ROTOR.format(kp=1.0, kv=0.0, c=5.0, transmission='joint = "O"',
                                           extra="forcerange = [-2.0, 2.0]").replace("bias = [0.0, -1.0, -0.0]", ""))
    assert scene.mechanism.actuators[0].bias == (0.0, 0.0, 0.0)
    result = simulate(scene, reduced_settings(scene))
    t = result.trajectory.t
    assert np.max(np.abs(result.trajectory.q - (0.2 + t + 2.0 * t * t))) < 1e-9


def test_the_scene_file_round_trip():
    scene = rotor(c=3.0, transmission="tendon = { O = 0.5 }", extra="ctrlrange = [0.0, 1.0]\ngear = 2.0")
    back = scene_from_string(scene_toml(scene))
    assert back.mechanism.actuators == scene.mechanism.actuators
    assert back.mechanism.actuators[0].gear == 2.0 and back.mechanism.actuators[0].tendon == (("O", 0.5),)


@pytest.mark.parametrize("extra, key", [
    ('ctrlrange = [1.0, 0.0]', "actuators[0].ctrlrange"),
    ('gear = 0.0', "actuators[0].gear"),
    ('colour = 1', "actuators[0].colour"),
    ('forcerange = [0.0]', "actuators[0].forcerange"),
])
def test_bad_actuator_keys_are_named(extra, key):
    with pytest.raises(SceneError, match=re.escape(key)):
        rotor(extra=extra)


def test_a_duplicate_actuator_name_is_named_by_its_key():
    """Two actuators named alike: the second's name key (planted: the Mechanism's own check, which
    the scene reader attributed to 'bodies')."""
    with pytest.raises(SceneError, match=re.escape("'actuators[1].name' = \"servo\": duplicate actuator name")):
        rotor(extra='\n[[actuators]]\nname = "servo"\njoint = "O"')


def test_bad_transmissions_are_named():
    with pytest.raises(SceneError, match=r"actuators\[0\].joint' = \"X\" is not one of the joints"):
        rotor(transmission='joint = "X"')
    with pytest.raises(SceneError, match=r"actuators\[0\].tendon.O' must be nonzero"):
        rotor(transmission="tendon = { O = 0.0 }")
    with pytest.raises(SceneError, match=r"actuators\[0\]' needs its transmission"):
        rotor(transmission="")
    with pytest.raises(MechanismError, match="actuator 'a': give its transmission"):
        Actuator("a")
    with pytest.raises(MechanismError, match="bias must be three numbers"):
        Actuator("a", joint="O", bias=(1.0, 2.0))



@pytest.mark.parametrize("name, table, joint", [("seed_fourbar", "torque", "O1"),
                                                ("slider_crank_driven_slider", "force", "cyl")])
def test_the_input_load_as_an_actuator_is_the_same_run(name, table, joint):
    """The catalogue's input load ([torque] on a revolute input, [force] on a prismatic one) written as a
    motor actuator on the input joint with that profile as its control (gear 2, gain ½): the same
    generalized force, rounded otherwise (T·dq/dx against gear·f·dl/dx), so DOP853's steps differ by
    round-off: compared through the reference's interpolant at the other's samples (1e-9 of the scale)
    and at the horizon (1e-10); measured 1.1e-12 rad of 36 rad on the seed, equal on the slider. Planted:
    the actuator's gear left out of its generalized force (build_arrays' ACT_PARAMS) → both fail."""
    from loopcheck.scenefile import load_scene
    from loopcheck.scene_writer import scene_data, toml_text
    from helpers import ROOT

    scene = load_scene(ROOT / "scenes" / "mechanisms" / f"{name}.toml")
    data = scene_data(scene)
    profile = data.pop(table)
    data["actuators"] = [{"name": "drive", "joint": joint, "gain": 0.5, "gear": 2.0, "control": profile}]
    as_actuator = scene_from_string(toml_text(data))
    assert as_actuator.load is None and as_actuator.load_edges == scene.load_edges
    a = simulate(scene, reduced_settings(scene))
    b = simulate(as_actuator, reduced_settings(as_actuator))
    scale = max(1.0, np.max(np.abs(a.trajectory.q)))
    q, _, _ = a.trajectory.interpolate(b.trajectory.t)
    assert np.max(np.abs(q - b.trajectory.q)) < 1e-9 * scale
    assert a.trajectory.t[-1] == b.trajectory.t[-1] and abs(a.trajectory.q[-1] - b.trajectory.q[-1]) < 1e-10 * scale
    assert abs(a.audit.torque_work[-1] - b.audit.torque_work[-1]) < 1e-9 * abs(a.audit.torque_work[-1])


@pytest.mark.parametrize("method", ["scipy-dop853", "radau"])
def test_scipys_runs_count_the_actuators_work_by_quadrature(method):
    """scipy's runs have no integrated power: the audit takes the actuators' f·L̇ by Gauss-Legendre
    quadrature (loopcheck.reduced.energy.quadrature_energy). On servo_fourbar (a servo and an affine
    actuator on a tendon, controls that jump) measured 9.6e-12 (scipy-dop853), 2.1e-12 (radau) relative,
    and the runs agree with the compiled DOP853's to 1e-12 rad; bound 1e-9. Planted: the actuators' term
    left out of the quadrature → the run itself fails its energy gate (residual 1.0 of its scale)."""
    import dataclasses

    from loopcheck.scenefile import load_scene
    from helpers import ROOT

    scene = load_scene(ROOT / "scenes" / "mechanisms" / "servo_fourbar.toml")
    result = simulate(scene, dataclasses.replace(reduced_settings(scene), method=method))
    assert result.audit.relative_residual < 1e-9


def test_an_actuator_value_out_of_its_range_is_named():
    with pytest.raises(SceneError, match=r"'actuators\[0\].gain' = 1e\+12 is out of range: actuator value"):
        rotor(kp=1e12)
