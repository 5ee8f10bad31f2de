"""Compare one forward pass of MJX with MuJoCo C at the same state, stage by stage.

Research script for issue 28 (docs/engines-gpu-research.md). MuJoCo C steps the model to time
``--at`` (s) with the seed's control (250 N·m while t < 1 s); at that state both engines run
``forward`` (MJX float64) and the script prints, per quantity, the largest absolute difference
and the C value's size: the first quantity that differs beyond round-off is where MJX departs.

    python forward_diff.py MODEL.xml [--at 0.6] [--ctrl 250]
"""

from __future__ import annotations

import sys

import numpy as np

from common import state_arguments, state_at


def main(argv=None) -> int:
    a = state_arguments(__doc__.splitlines()[0], argv)

    import jax
    jax.config.update("jax_enable_x64", True)
    import mujoco
    from mujoco import mjx

    m, d = state_at(a.model, a.at, a.ctrl)

    mx = mjx.put_model(m)
    dx = mjx.put_data(m, d)
    dx = jax.jit(mjx.forward)(mx, dx)

    from mujoco.mjx._src.support import full_m

    qm_c = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, qm_c)  # MuJoCo 4: mj_fullM(m, d, dst), d.qM is gone
    nefc = d.nefc
    rows = [
        ("qvel (input)", d.qvel, dx.qvel),
        ("ten_length", d.ten_length, dx.ten_length),
        ("ten_velocity", d.ten_velocity, getattr(dx, "ten_velocity", np.full(m.ntendon, np.nan))),
        ("M (dense)", qm_c, full_m(mx, dx)),
        ("qfrc_bias", d.qfrc_bias, dx.qfrc_bias),
        ("qfrc_passive", d.qfrc_passive, dx.qfrc_passive),
        ("qfrc_actuator", d.qfrc_actuator, dx.qfrc_actuator),
        ("qacc_smooth", d.qacc_smooth, dx.qacc_smooth),
        ("efc_J", d.efc_J.reshape(nefc, m.nv), np.asarray(dx.efc_J)[:nefc]),
        ("efc_pos", d.efc_pos, np.asarray(dx.efc_pos)[:nefc]),
        ("efc_aref", d.efc_aref, np.asarray(dx.efc_aref)[:nefc]),
        ("efc_D", d.efc_D, np.asarray(dx.efc_D)[:nefc]),
        ("efc_force", d.efc_force, np.asarray(dx.efc_force)[:nefc]),
        ("qfrc_constraint", d.qfrc_constraint, dx.qfrc_constraint),
        ("qacc", d.qacc, dx.qacc),
    ]
    print(f"state at t = {d.time:.4f} s, ctrl {a.ctrl}; MuJoCo {mujoco.__version__}; nefc C {nefc}")
    print(f"{'quantity':16s} {'max |MJX - C|':>14s} {'max |C|':>12s}  C / MJX (first entries)")
    for name, c, x in rows:
        c = np.asarray(c, dtype=float)
        x = np.asarray(x, dtype=float)
        if c.shape != x.shape:
            print(f"{name:16s} shapes differ: C {c.shape}, MJX {x.shape}")
            continue
        diff = float(np.max(np.abs(x - c))) if c.size else 0.0
        size = float(np.max(np.abs(c))) if c.size else 0.0
        print(f"{name:16s} {diff:14.3e} {size:12.4e}  {np.array2string(c.ravel()[:3], precision=8)} / "
              f"{np.array2string(x.ravel()[:3], precision=8)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
