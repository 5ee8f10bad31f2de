"""Run an exported loopcheck MJCF on MuJoCo C, MJX or MJWarp and print the peak input speed.

Research script for issue 28 (docs/engines-gpu-research.md). Stand-alone on purpose: it needs
only ``mujoco`` (and ``jax`` + ``mujoco.mjx`` or ``warp`` + ``mujoco_warp`` for those engines),
not loopcheck, so it runs in the ports' own scratch environments.

The run is the one loopcheck's MuJoCo engine makes of the seed: the MJCF from ``loopcheck export-mjcf``,
the energy flag cleared (MJX refuses ``mjENBL_ENERGY``), the model's own integrator and timestep
unless overridden, the state of keyframe 0, the motor's control held at the pulse's value over
every step whose midpoint lies inside the pulse (250 N·m for t < 1 s) and 0 after. The peak is
max |qvel[0]| over the step boundaries (the crank's hinge, the seed's input).

    python run_port.py MODEL.xml --engine c|c32state|mjx|mjwarp [--f32] [--integrator rk4|euler]
        [--timestep H] [--horizon T] [--pulse VALUE DURATION] [--every N]

Prints one line ``engine precision integrator h peak rel_err wall_s`` and with ``--every N``
the running peak's error every N steps (the error's growth over the horizon).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from common import controls, load

EXACT_PEAK = 34.26441306  # rad/s: the seed's exact peak (loopcheck reduced, DOP853 at rtol 1e-12)


def run_c(m, d, ctrl, round_state: bool = False):
    """MuJoCo C; with ``round_state`` the state (qpos, qvel) is rounded to float32 after every
    step (float32 storage of the state, every computation still in float64)."""
    import mujoco
    out = np.empty((len(ctrl), m.nv))
    for k, u in enumerate(ctrl):
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        if round_state:
            d.qpos[:] = d.qpos.astype(np.float32)
            d.qvel[:] = d.qvel.astype(np.float32)
        out[k] = d.qvel
    return out


def run_mjx(m, d, ctrl, f32: bool):
    import jax
    jax.config.update("jax_enable_x64", not f32)
    from mujoco import mjx
    mx = mjx.put_model(m)
    dx = mjx.put_data(m, d)

    def body(dx, u):
        new = mjx.step(mx, dx.replace(ctrl=u))
        # put_data's integer fields are int32 and a step's int64 under x64: keep the carry's types
        new = jax.tree_util.tree_map(lambda n, o: n.astype(o.dtype) if hasattr(o, "dtype") else n, new, dx)
        return new, new.qvel

    dtype = np.float32 if f32 else np.float64
    scan = jax.jit(lambda dx, us: jax.lax.scan(body, dx, us))
    _, qv = scan(dx, jax.numpy.asarray(ctrl, dtype=dtype))
    return np.asarray(jax.block_until_ready(qv), dtype=float)


def run_mjwarp(m, d, ctrl):
    import mujoco_warp as mjw
    import warp as wp
    wp.init()
    mw = mjw.put_model(m)
    dw = mjw.put_data(m, d)
    out = np.empty((len(ctrl), m.nv))
    for k, u in enumerate(ctrl):
        wp.copy(dw.ctrl, wp.array(np.asarray(u, dtype=np.float32)[None, :], dtype=float))
        mjw.step(mw, dw)
        out[k] = dw.qvel.numpy()[0]
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--engine", choices=("c", "c32state", "mjx", "mjwarp"), default="c",
                   help="c32state: MuJoCo C with the state rounded to float32 after every step")
    p.add_argument("--f32", action="store_true", help="MJX in float32 (MJWarp is float32 always)")
    p.add_argument("--integrator", choices=("rk4", "euler", "implicitfast"))
    p.add_argument("--timestep", type=float)
    p.add_argument("--iterations", type=int)
    p.add_argument("--horizon", type=float, default=2.0)
    p.add_argument("--pulse", type=float, nargs=2, default=(250.0, 1.0), metavar=("VALUE", "DURATION"))
    p.add_argument("--every", type=int, default=0, help="print the running peak every N steps")
    p.add_argument("--exact", type=float, default=EXACT_PEAK)
    a = p.parse_args(argv)
    m, d = load(a.model, a.integrator, a.timestep, a.iterations)
    n = round(a.horizon / m.opt.timestep)
    ctrl = controls(m, n, *a.pulse)
    t0 = time.perf_counter()
    if a.engine in ("c", "c32state"):
        qv = run_c(m, d, ctrl, round_state=a.engine == "c32state")
        prec = "float64" if a.engine == "c" else "float64, state rounded to float32"
    elif a.engine == "mjx":
        qv = run_mjx(m, d, ctrl, a.f32)
        prec = "float32" if a.f32 else "float64"
    else:
        qv = run_mjwarp(m, d, ctrl)
        prec = "float32"
    wall = time.perf_counter() - t0
    w = np.abs(qv[:, 0])
    integ = {0: "euler", 1: "rk4", 2: "implicit", 3: "implicitfast"}[int(m.opt.integrator)]
    if a.every:
        running = np.maximum.accumulate(w)
        for k in range(a.every - 1, n, a.every):
            print(f"  t={(k + 1) * m.opt.timestep:.4f} omega={qv[k, 0]:.10f} running_peak={running[k]:.10f}")
    peak = float(w.max())
    print(f"{a.engine} ({prec}) {integ} h={m.opt.timestep:g} steps={n} peak={peak:.10f} "
          f"at_t={(int(w.argmax()) + 1) * m.opt.timestep:.4f} rel_err={abs(peak - a.exact) / a.exact:.3e} wall_s={wall:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
