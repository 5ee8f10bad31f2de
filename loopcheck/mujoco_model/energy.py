"""The energy audit of a MuJoCo run, from MuJoCo's own quantities (body and tendon sensors, the
model's masses, inertias, stiffnesses and damping) at every stored state."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from loopcheck.loads import TabulatedForce
from loopcheck.results import EnergyAudit

from .build import sensor_name


def squares_by_row(v: np.ndarray) -> np.ndarray:
    """Σ_j v[:, j]² of each row of v (samples, 3), the columns added in order: the same sums as
    ``np.sum(v * v, axis=1)`` (and ``np.linalg.norm(v, axis=1)²``), without numpy's slow
    reduction along a short row."""
    total = v[:, 0] * v[:, 0]
    for j in range(1, v.shape[1]):
        total = total + v[:, j] * v[:, j]
    return total


def _cumulative_trapezoid(power: np.ndarray, dt: np.ndarray) -> np.ndarray:
    return np.concatenate([np.zeros(1), np.cumsum(0.5 * (power[:-1] + power[1:]) * dt)])


def actuator_work(scene, model, sl, sensors, ctrl, dt) -> np.ndarray:
    """The scene actuators' work ∫ Σ f L̇ dt (J) at every stored state, from MuJoCo's own actuator
    length L and velocity L̇ (sensors) and the model's gain, bias, ctrlrange and forcerange: over
    step k, the trapezoid of f·L̇ at its two ends with step k's control (f is affine in the state and
    the control, clamped: MuJoCo's force law)."""
    zero = np.zeros(1)
    work = np.zeros(len(dt) + 1)
    first = 1 if scene.load is not None else 0
    for k, a in enumerate(scene.mechanism.actuators):
        i = first + k
        length = sensors[:, sl[sensor_name(a.name, "length")]][:, 0]
        velocity = sensors[:, sl[sensor_name(a.name, "velocity")]][:, 0]
        c = ctrl[:, i]
        if model.actuator_ctrllimited[i]:
            c = np.clip(c, *model.actuator_ctrlrange[i])
        gain, (b0, b1, b2) = model.actuator_gainprm[i, 0], model.actuator_biasprm[i, 0:3]

        def force(rows, control):
            f = gain * control + b0 + b1 * length[rows] + b2 * velocity[rows]
            return np.clip(f, *model.actuator_forcerange[i]) if model.actuator_forcelimited[i] else f

        steps = np.arange(len(dt))
        c = c[:len(dt)]
        power_dt = 0.5 * (force(steps, c) * velocity[steps] + force(steps + 1, c) * velocity[steps + 1]) * dt
        work = work + np.concatenate([zero, np.cumsum(power_dt)])
    return work


def energy_audit(scene, model, handles, layout, times, states, sensors, ctrl, q, timed) -> EnergyAudit:
    """The energy balance from MuJoCo's own quantities at every stored state.

    Kinetic Σ ½ m |v_G|² + ½ I_zz ω_z² over every moving body, and ½ I u̇² over every joint
    inertia (a fixed tendon's armature), and potential −Σ (1 − gravcomp) m g·r_G (the work of
    MuJoCo's gravity compensation counted with the weight it compensates) +
    Σ ½ k (l − l0)² over every spring tendon, from the body and tendon sensors with the model's
    masses, inertias, stiffnesses (kinetic energy agrees with ½ q̇ᵀM q̇); the work of the motor
    ∫ u q̇_input dt (the input joint's rate; the control is constant within each step) plus the
    work of the point forces ∫ Σ F(q) u·v_p dt and of the timed forces ∫ Σ F(t) u·v_p dt (F held
    over each step, ``timed`` (steps, forces)) and of the actuators (:func:`actuator_work`; in
    ``torque_work``: the work of the external loads), and the damper dissipation ∫ Σ b l̇² dt, by the trapezoid rule.
    """
    sl = handles.sensor_slices
    n = len(times)
    kinetic, potential = np.zeros(n), np.zeros(n)
    gravity = model.opt.gravity
    for name in scene.mechanism.linkage.moving:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        mass, izz = model.body_mass[body], model.body_inertia[body, 2]
        v, w = sensors[:, sl[sensor_name(name, "com_vel")]], sensors[:, sl[sensor_name(name, "ang_vel")]]
        kinetic += 0.5 * mass * squares_by_row(v) + 0.5 * izz * w[:, 2] ** 2
        # gravcomp's force (−gravcomp·m·g at the centre of mass, conservative) counted with the
        # weight: mj_energyPos leaves it out
        potential -= (1.0 - model.body_gravcomp[body]) * mass * sensors[:, sl[sensor_name(name, "com_pos")]] @ gravity
    for tendon in range(model.ntendon):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, tendon)
        if model.tendon_armature[tendon] > 0.0:  # a joint inertia: ½ I u̇²
            kinetic += 0.5 * model.tendon_armature[tendon] * sensors[:, sl[sensor_name(name, "rate")]][:, 0] ** 2
        if sensor_name(name, "length") in sl:
            stretch = sensors[:, sl[sensor_name(name, "length")]][:, 0] - model.tendon_lengthspring[tendon, 0]
            potential += 0.5 * model.tendon_stiffness[tendon] * stretch * stretch
    dt = np.diff(times)
    zero = np.zeros(1)
    if scene.load is not None:  # the input motor, the first actuator
        rate = states[:, 1 + model.nq + layout.input_dof]
        power_dt = ctrl[:, 0] * 0.5 * (rate[:-1] + rate[1:]) * dt
        load_work = np.concatenate([zero, np.cumsum(power_dt)])
    else:
        load_work = np.zeros(n)
    if scene.mechanism.point_forces:
        power = np.zeros(n)
        for pf in scene.mechanism.point_forces:
            u = np.array([math.cos(pf.direction), math.sin(pf.direction), 0.0])
            force = TabulatedForce(pf.coordinate, pf.values, pf.period)
            power += np.asarray(force(q), dtype=float) * (sensors[:, sl[sensor_name(pf.name, "vel")]] @ u)
        load_work = load_work + _cumulative_trapezoid(power, dt)
    for k, tf in enumerate(scene.mechanism.timed_forces):  # F constant over each step (timed_values)
        u = np.array([math.cos(tf.direction), math.sin(tf.direction), 0.0])
        along = sensors[:, sl[sensor_name(tf.name, "vel")]] @ u
        load_work = load_work + np.concatenate([zero, np.cumsum(timed[:, k] * 0.5 * (along[:-1] + along[1:]) * dt)])
    if scene.mechanism.actuators:
        load_work = load_work + actuator_work(scene, model, sl, sensors, ctrl, dt)
    rate = np.zeros(n)
    for name in handles.damper_tendons:
        b = model.tendon_damping[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, name)]
        ldot = sensors[:, sl[sensor_name(name, "rate")]][:, 0]
        rate += b * ldot * ldot
    dissipation = np.concatenate([zero, np.cumsum(0.5 * (rate[:-1] + rate[1:]) * dt)])
    return EnergyAudit(t=times, kinetic=kinetic, potential=potential, torque_work=load_work,
                       damper_dissipation=dissipation)
