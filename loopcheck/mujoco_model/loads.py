"""The scene's loads as MuJoCo applies them: the input motor's control over each step
(:func:`control_sequence`), the timed forces' values over each step (:func:`timed_values`), and
the point and timed forces applied through ``mjcb_control`` at every integrator stage
(:func:`point_force_callback`)."""

from __future__ import annotations

import contextlib
import math

import mujoco
import numpy as np

from loopcheck.loads import TabulatedForce
from loopcheck.scene import Scene

from .build import actuator_controls, site_name
from .layout import Layout


def control_sequence(scene: Scene, timestep: float, n_steps: int) -> tuple[np.ndarray, list[str]]:
    """Every control for each step, shape (n_steps, nu): the input motor's T, then each actuator's
    control (:func:`loopcheck.mujoco_model.build.actuator_controls`), at the step's midpoint t_k + h/2,
    so a load edge inside a step is applied at the nearest step boundary.

    Returns the controls and one warning per load edge that falls inside a step.
    """
    notes = []
    for edge in scene.load_edges:  # the input's and the timed forces' (timed_values)
        k = edge / timestep
        if 0.0 < edge < scene.horizon and abs(k - round(k)) > 1e-6:
            notes.append(f"load edge at t = {edge:g} s is not a multiple of the timestep {timestep:g} s: "
                         f"the jump is applied at t = {round(k) * timestep:g} s, up to "
                         f"{0.5 * timestep:g} s late or early")
    starts = np.arange(n_steps) * timestep
    return actuator_controls(scene, starts + 0.5 * timestep), notes


def timed_values(scene: Scene, timestep: float, n_steps: int) -> np.ndarray:
    """Each timed force's value over each step (n_steps, timed forces), N: F(t) at the step's
    midpoint, as :func:`control_sequence` samples the input load (an edge on the step grid is
    applied exactly there)."""
    mid = np.arange(n_steps) * timestep + 0.5 * timestep
    return np.array([f.profile.sample(mid) for f in scene.mechanism.timed_forces], dtype=float).reshape(-1, n_steps).T


def point_force_callback(scene: Scene, model: mujoco.MjModel, layout: "Layout"):
    """The ``mjcb_control`` callback that applies the scene's point forces, or None without any.

    How: MuJoCo calls ``mjcb_control`` in every ``mj_forward`` after the position and velocity
    stages, before actuation and acceleration, so also in each of RK4's four stages at that
    stage's state. The callback sets ``qfrc_applied`` = Σ J_pᵀ F(q) u (J_p the site's
    translational Jacobian ``mj_jacSite``, u the force's fixed ground direction, q the input
    coordinate from that stage's qpos): the force is exactly F(q(t)) at every stage, so RK4
    keeps its order. Scenes with point forces are stepped by a Python loop of ``mj_step``
    (:func:`loopcheck.reference_models.run._step_loop`) rather than ``mujoco.rollout``: single-threaded rollout does call a
    Python ``mjcb_control`` (measured with MuJoCo 4.0.1: 1600 calls in 400 RK4 steps, states
    identical to the loop's) but the documented callback contract does not cover its threads, and
    the callback (~65 µs, mostly the spline) dominates either way.
    """
    def site_of(force, what):
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name(force.body, force.point))
        if site < 0:
            raise ValueError(f"the model has no site {site_name(force.body, force.point)!r} for {what} {force.name!r}")
        return site, np.array([math.cos(force.direction), math.sin(force.direction), 0.0])

    forces = [(TabulatedForce(pf.coordinate, pf.values, pf.period), *site_of(pf, "point force"))
              for pf in scene.mechanism.point_forces]
    timed = [site_of(tf, "timed force") for tf in scene.mechanism.timed_forces]
    if not forces and not timed:
        return None
    q0 = float(layout.system.drive @ layout.x0)
    row = layout.input_row
    jac = np.zeros((3, model.nv))
    step_values = np.zeros(len(timed))  # the timed forces' values over the current step

    def callback(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        q = q0 + float(row @ d.qpos)
        total = np.zeros(m.nv)
        for force, site, u in forces:
            mujoco.mj_jacSite(m, d, jac, None, site)
            total += float(force(q)) * (u @ jac)
        for value, (site, u) in zip(step_values, timed):
            mujoco.mj_jacSite(m, d, jac, None, site)
            total += float(value) * (u @ jac)
        d.qfrc_applied[:] = total

    callback.step_values = step_values  # set by the step loop before each step (timed_values)
    return callback


@contextlib.contextmanager
def point_forces_installed(scene: Scene, model: mujoco.MjModel, layout: "Layout"):
    """Install :func:`point_force_callback` for the block; yields it (None without point forces)."""
    callback = point_force_callback(scene, model, layout)
    if callback is None:
        yield None
        return
    previous = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(callback)
    try:
        yield callback
    finally:
        mujoco.set_mjcb_control(previous)
