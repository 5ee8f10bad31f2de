"""Minimal reproduction: MJX leaves J̇·q̇ out of a connect constraint's reference acceleration.

Issue 28 (docs/engines-gpu-research.md). A planar plate (slides x, y and a hinge) is pinned to the
world by one ``connect`` at a point 0.5 m from its centre of mass and spins about the pin at
ω = 10 rad/s: no load, no damper, no gravity, no contact. The exact motion keeps ω.

1. One forward pass at the initial state, where the pin's position and velocity errors are 0.
   MuJoCo C's reference acceleration of the connect rows is ``-b·J·q̇ - k·i·e - J̇·q̇``
   (``mj_referenceConstraint``, with ``mj_Jdotv`` in src/engine/engine_core_constraint.c), and
   J̇·q̇ here is the centripetal acceleration of the body's anchor point at zero q̈, ω²·r = 50 m/s²
   toward the centre of mass (+x): C's aref is (-50, 0, 0), exactly. MJX
   (mjx/_src/constraint.py, ``make_constraint``) computes ``aref = -b·(J @ qvel) - k·imp·pos``
   only: (0, 0, 0). The constraint force then lacks the centripetal part, which the softness
   (solref, Baumgarte stabilisation) supplies late: the pin stretches and its damping term
   dissipates energy.
2. The spin over ``--horizon`` s (RK4, 0.5 ms): C keeps ω to ~4e-8; MJX loses it steadily.

    python mjx_jdotv_repro.py [--horizon 1.0]

Needs mujoco, jax and mujoco.mjx (float64). Measured numbers are in the research note.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from common import SPINNER

OMEGA, R = 10.0, 0.5  # rad/s, m (the keyframe's spin, the anchor's distance from the centre of mass)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--horizon", type=float, default=1.0)
    a = p.parse_args(argv)
    import jax
    jax.config.update("jax_enable_x64", True)
    import mujoco
    from mujoco import mjx

    m = mujoco.MjModel.from_xml_string(SPINNER)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    mx = mjx.put_model(m)
    dx = jax.jit(mjx.forward)(mx, mjx.put_data(m, d))
    print(f"MuJoCo {mujoco.__version__}, jax {jax.__version__}")
    print(f"aref of the pin's rows at t = 0 (pin error 0, pin velocity {np.abs(d.efc_vel).max():.1e}):")
    print(f"  exact -J̇·q̇ = -ω²·r along +x: {np.array([-OMEGA ** 2 * R, 0.0, 0.0])}")
    print(f"  MuJoCo C:                    {np.round(d.efc_aref, 9)}")
    print(f"  MJX:                         {np.round(np.asarray(dx._impl.efc_aref), 9)}")

    n = round(a.horizon / m.opt.timestep)
    dc = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, dc, 0)
    for _ in range(n):
        mujoco.mj_step(m, dc)
    step = jax.jit(mjx.step)
    dx = mjx.put_data(m, d)
    for _ in range(n):
        dx = step(mx, dx)
    wc, wx = dc.qvel[2], float(dx.qvel[2])
    print(f"spin after {a.horizon:g} s ({n} RK4 steps of {m.opt.timestep:g} s), exact {OMEGA:g} rad/s:")
    print(f"  MuJoCo C: {wc:.10f} rad/s (rel. error {abs(wc - OMEGA) / OMEGA:.2e})")
    print(f"  MJX:      {wx:.10f} rad/s (rel. error {abs(wx - OMEGA) / OMEGA:.2e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
