"""MJX with J̇·q̇ added against MuJoCo C on the mechanism catalogue: is the missing term the whole
of MJX's difference on every mechanism, not only on the seed? (docs/engines.md, "MJX and the
connect constraint").

For each scene of scenes/mechanisms/ that MJX runs (no point forces): loopcheck's mjx engine at its
defaults (the grid step, float64) with MJX's ``make_constraint`` patched to subtract J̇·q̇ from
the connect rows' reference acceleration (``mjx_jdotv_study.patch_mjx_jdotv``, what MuJoCo C's
``mj_Jdotv`` does), against loopcheck's MuJoCo engine on the same model at the same step. Prints the
relative difference of the peaks and the largest |Δq̇| relative to the peak.

    python benchmarks/gpu_ports/mjx_patched_catalogue.py [--scenes A.toml ...]

Needs loopcheck with the mjx extra (JAX and MJX).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="*", type=Path, default=sorted((ROOT / "scenes" / "mechanisms").glob("*.toml")))
    a = p.parse_args(argv)
    import jax

    from mjx_jdotv_study import patch_mjx_jdotv
    from loopcheck.mjx import MjxSettings, simulate_mjx
    from loopcheck.mujoco_model.port import PortRefusal
    from loopcheck.reference_models import MujocoSettings, simulate_mujoco
    from loopcheck.scenefile import load_scene

    patch_mjx_jdotv()
    open_gates = dict(max_constraint_violation=1.0, max_energy_residual=1.0)
    print(f"MJX patched with J̇·q̇ (jax {jax.__version__}) against MuJoCo C, same model, same step")
    print("| scene | step (s) | C peak | patched MJX peak | peaks apart, rel. | max abs Δq̇ / peak |")
    print("|---|---|---|---|---|---|")
    for path in a.scenes:
        scene = load_scene(path)
        try:
            x = simulate_mjx(scene, MjxSettings(**open_gates))
        except PortRefusal as exc:
            print(f"| {scene.name} | refused: {exc} | | | | |")
            continue
        h = x.settings.timestep
        c = simulate_mujoco(scene, MujocoSettings(timestep=h, **open_gates))
        peak = abs(c.peak.omega)
        n = min(len(x.trajectory.qdot), len(c.trajectory.qdot))  # the same grid (and the same load-edge samples)
        dv = np.max(np.abs(x.trajectory.qdot[:n] - c.trajectory.qdot[:n]))
        print(f"| {scene.name} | {h:g} | {c.peak.omega:.10g} | {x.peak.omega:.10g} | "
              f"{abs(x.peak.omega - c.peak.omega) / peak:.1e} | {dv / peak:.1e} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
