"""Compare one forward pass of MJWarp (float32) with MuJoCo C at the same state.

Research script for issue 28 (docs/engines-gpu-research.md), the MJWarp twin of
``forward_diff.py``: C steps the model to ``--at`` s with the seed's control; at that state both
run ``forward`` and the script prints, per quantity, the largest absolute and relative difference.

    python forward_diff_mjwarp.py MODEL.xml [--at 0.6] [--ctrl 250]
"""

from __future__ import annotations

import sys

import numpy as np

from common import state_arguments, state_at


def main(argv=None) -> int:
    a = state_arguments(__doc__.splitlines()[0], argv)
    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    m, d = state_at(a.model, a.at, a.ctrl)
    wp.init()
    mw = mjw.put_model(m)
    dw = mjw.put_data(m, d)
    mjw.forward(mw, dw)
    wp.synchronize()
    ne = d.nefc
    rows = [("qfrc_bias", d.qfrc_bias, dw.qfrc_bias.numpy()[0]),
            ("qfrc_passive", d.qfrc_passive, dw.qfrc_passive.numpy()[0]),
            ("qacc_smooth", d.qacc_smooth, dw.qacc_smooth.numpy()[0]),
            ("efc_pos", d.efc_pos, dw.efc.pos.numpy()[0][:ne]),
            ("efc_vel", d.efc_vel, dw.efc.vel.numpy()[0][:ne]),
            ("efc_aref", d.efc_aref, dw.efc.aref.numpy()[0][:ne]),
            ("efc_force", d.efc_force, dw.efc.force.numpy()[0][:ne]),
            ("qfrc_constraint", d.qfrc_constraint, dw.qfrc_constraint.numpy()[0]),
            ("qacc", d.qacc, dw.qacc.numpy()[0])]
    print(f"state at t = {d.time:.4f} s; MuJoCo {mujoco.__version__}, warp {wp.__version__}; "
          f"solver iterations C {d.solver_niter[0]}, MJWarp {dw.solver_niter.numpy()[0]}")
    for name, c, w in rows:
        c, w = np.asarray(c, float), np.asarray(w, float)
        diff = float(np.max(np.abs(w - c)))
        size = float(np.max(np.abs(c)))
        print(f"{name:16s} max |MJWarp - C| {diff:10.3e}  relative {diff / size if size else 0:10.3e}  "
              f"C {np.array2string(c[:3], precision=6)}  MJWarp {np.array2string(w[:3], precision=6)}")
    # The aref difference that the pos and vel differences explain through C's own K, B, I
    kbip = d.efc_KBIP
    dpos = dw.efc.pos.numpy()[0][:ne] - d.efc_pos
    dvel = dw.efc.vel.numpy()[0][:ne] - d.efc_vel
    explained = -kbip[:, 1] * dvel - kbip[:, 0] * kbip[:, 2] * dpos
    print(f"aref difference explained by -B*dvel - K*I*dpos: {np.array2string(explained, precision=6)}; "
          f"measured {np.array2string(dw.efc.aref.numpy()[0][:ne] - d.efc_aref, precision=6)}; "
          f"float32 spacing at 1 m: {np.spacing(np.float32(1.0)):.2e} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
