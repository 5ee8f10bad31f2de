"""MJWarp's one-step difference from MuJoCo C along C's trajectory: noise or bias?

Research script for issue 28 (docs/engines-gpu-research.md). From C's state every ``--every`` s
(the seed's control), C and MJWarp each take one step; the script prints the difference of the
input speed after the step (MJWarp − C, rad/s), and the mean and spread over the states. A bias
(mean comparable to the spread) accumulates linearly over the steps; noise as their square root.

    python local_error_mjwarp.py MODEL.xml [--every 0.05] [--horizon 2]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from common import load


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--every", type=float, default=0.05)
    p.add_argument("--horizon", type=float, default=2.0)
    a = p.parse_args(argv)
    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    m, d = load(a.model)
    wp.init()
    mw = mjw.put_model(m)
    h = m.opt.timestep
    n = round(a.horizon / h)
    stride = round(a.every / h)
    diffs = []
    for k in range(n):
        d.ctrl[:] = 250.0 if (k + 0.5) * h < 1.0 else 0.0
        if k % stride == 0:
            dw = mjw.put_data(m, d)
            mjw.step(mw, dw)
            c = mujoco.MjData(m)
            c.qpos[:], c.qvel[:], c.ctrl[:], c.time = d.qpos, d.qvel, d.ctrl, d.time
            mujoco.mj_step(m, c)
            diffs.append(float(dw.qvel.numpy()[0][0]) - c.qvel[0])
        mujoco.mj_step(m, d)
    x = np.array(diffs)
    print(f"{len(x)} states; one-step difference of qvel[0] (rad/s): mean {x.mean():+.3e}, std {x.std():.3e}, "
          f"max |.| {np.abs(x).max():.3e}; h = {h:g} s, {n} steps")
    print("per state:", np.array2string(x, precision=2, max_line_width=120))
    return 0


if __name__ == "__main__":
    sys.exit(main())
