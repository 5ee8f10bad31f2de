"""MJX against MuJoCo C, one model element dropped at a time, and MJX with the missing J̇·q̇ term.

Research script for issue 28 (docs/engines-gpu-research.md). Needs ``mujoco`` (C), ``jax`` and
``mujoco.mjx`` in one environment (float64). For each variant of the seed's exported MJCF it runs
MuJoCo C (``mj_step``) and MJX (``jax.jit(mjx.step)`` in a Python loop, so each variant compiles
one step, not a scan) over the horizon with the seed's control (250 N·m while the step's midpoint
is before 1 s) and prints both peaks of |qvel[0]| and their relative difference. With ``--patched``
MJX's ``constraint.make_constraint`` is wrapped to subtract J̇·q̇ from the connect rows' reference
acceleration, as MuJoCo C's ``mj_referenceConstraint`` does (``mj_Jdotv``); J̇·q̇ is taken as the
second derivative of the connect's position error along q(t) = q + t·q̇ (exact for hinge and slide
joints, whose qpos is linear in t), by two nested ``jax.jvp``.

    python mjx_jdotv_study.py SEED.xml [--horizon 2] [--variants base,nodamper,...] [--patched]

Also the minimal reproduction: ``--variants spinner`` is a planar body pinned to the world by one
connect, spinning at 10 rad/s with no load, no damper, no gravity: the exact motion keeps the speed.
"""

from __future__ import annotations

import argparse
import re
import sys
import time

import numpy as np

from common import SPINNER as PINNED

# the solver's tolerance as the seed's exported model sets it
SPINNER = PINNED.replace('gravity="0 0 0">', 'gravity="0 0 0" tolerance="1e-12">')



def variants(seed_xml: str) -> dict[str, str]:
    """MJCF text of each variant (names say what is dropped or changed from the seed)."""
    s = seed_xml.replace('energy="enable"', 'energy="disable"')
    out = {"base": s}
    out["nodamper"] = s.replace('damping="55"', 'damping="0"')
    out["nosensors"] = re.sub(r"<sensor>.*?</sensor>", "", s, flags=re.DOTALL)
    out["euler"] = s.replace('integrator="RK4"', 'integrator="Euler"')
    out["solimp_default"] = s.replace(' solimp="0.9999 0.9999 0.001 0.5 2"', "")
    out["solref_0.004"] = s.replace('solref="0.001 1"', 'solref="0.004 1"')
    out["solref_0.016"] = s.replace('solref="0.001 1"', 'solref="0.016 1"')
    out["iterations_1"] = s.replace('tolerance="1e-12"', 'tolerance="1e-12" iterations="1"')
    out["h_0.00025"] = s.replace('timestep="0.0005"', 'timestep="0.00025"')
    out["spinner"] = SPINNER
    out["spinner_euler"] = SPINNER.replace('integrator="RK4"', 'integrator="Euler"')
    return out


def patch_mjx_jdotv():
    """Make MJX subtract J̇·q̇ from the connect rows' aref (what MuJoCo C's mj_Jdotv does)."""
    import jax
    from mujoco.mjx._src import constraint, smooth

    original = constraint.make_constraint

    def make_constraint(m, d):
        d = original(m, d)
        if constraint._efc_equality_connect(m, d) is None:
            return d

        def pos_err(q):  # the connect rows' position error at qpos q
            dq = smooth.kinematics(m, d.replace(qpos=q))
            return constraint._efc_equality_connect(m, dq).pos_aref

        def vel(q):
            return jax.jvp(pos_err, (q,), (d.qvel,))[1]

        jdv = jax.jvp(vel, (d.qpos,), (d.qvel,))[1]  # d²/dt² of the error along q + t·q̇ = J̇·q̇
        aref = d._impl.efc_aref
        return d.tree_replace({"_impl.efc_aref": aref.at[: jdv.shape[0]].add(-jdv)})

    constraint.make_constraint = make_constraint


def run(xml: str, horizon: float, pulse: tuple[float, float]):
    import jax
    import mujoco
    from mujoco import mjx

    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    n = round(horizon / m.opt.timestep)
    mid = (np.arange(n) + 0.5) * m.opt.timestep
    ctrl = np.where(mid < pulse[1], pulse[0], 0.0)
    input_dof = m.nv - 1 if m.nu == 0 else 0  # the spinner's hinge, the seed's crank
    dc = mujoco.MjData(m)
    dc.qpos[:], dc.qvel[:] = d.qpos, d.qvel
    c = np.empty(n)
    for k in range(n):
        if m.nu:
            dc.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, dc)
        c[k] = dc.qvel[input_dof]
    mx = mjx.put_model(m)
    dx = mjx.put_data(m, d)
    step = jax.jit(mjx.step)
    x = np.empty(n)
    t0 = time.perf_counter()
    for k in range(n):
        if m.nu:
            dx = dx.replace(ctrl=dx.ctrl.at[:].set(ctrl[k]))
        dx = step(mx, dx)
        x[k] = float(dx.qvel[input_dof])
        if not np.isfinite(x[k]):
            x[k:] = np.nan
            break
    return c, x, time.perf_counter() - t0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seed")
    p.add_argument("--horizon", type=float, default=2.0)
    p.add_argument("--variants", default="base,nodamper,nosensors,euler,solimp_default,solref_0.004,"
                                          "solref_0.016,iterations_1,h_0.00025,spinner,spinner_euler")
    p.add_argument("--patched", action="store_true", help="MJX with J̇·q̇ subtracted from aref")
    p.add_argument("--f32", action="store_true", help="MJX in float32 (default float64)")
    a = p.parse_args(argv)
    import jax
    jax.config.update("jax_enable_x64", not a.f32)
    import mujoco
    if a.patched:
        patch_mjx_jdotv()
    with open(a.seed) as f:
        all_variants = variants(f.read())
    print(f"MuJoCo {mujoco.__version__}, jax {jax.__version__}, MJX {'patched (aref - Jdot v)' if a.patched else 'as shipped'}, "
          f"{'float32' if a.f32 else 'float64'}")
    print(f"{'variant':16s} {'C peak':>16s} {'MJX peak':>16s} {'rel diff':>10s} {'C end':>14s} {'MJX end':>14s} {'end diff':>10s} {'MJX s':>6s}")
    for name in a.variants.split(","):
        c, x, wall = run(all_variants[name], a.horizon, (250.0, 1.0))
        pc, px = np.abs(c).max(), np.abs(x).max()
        print(f"{name:16s} {pc:16.10f} {px:16.10f} {abs(px - pc) / pc:10.3e} {c[-1]:14.8f} {x[-1]:14.8f} {abs(x[-1] - c[-1]) / abs(c[-1]):10.3e} {wall:6.1f}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
