"""MJWarp's float32 share on the mechanism catalogue: MJWarp with its J̇·q̇ lag patched out, against
the reduced engine (docs/engines.md, "The MJWarp engine").

MJWarp 4.0.0's ``make_constraint`` (inside ``fwd_position``) reads ``cvel`` and ``cdof_dot`` for
the loops' J̇·q̇ before ``fwd_velocity`` recomputes them. The patch runs ``smooth.com_vel`` first,
so what is left of MJWarp's difference from the exact solution is its float32 arithmetic (and
MuJoCo's own discretisation at the step, which MuJoCo C's row of benchmarks/results/engines_table.md
shows to be far smaller). For each scene of scenes/mechanisms/ that MJWarp runs: loopcheck's mjwarp
engine at its defaults (the scene's [mujoco] timestep, else the grid step), patched, against the reduced engine (DOP853, rtol 1e-12):
the relative peak difference, max |Δq|, max |Δq̇|, the loop gap and the energy residual.

    python benchmarks/gpu_ports/mjwarp_patched_catalogue.py [--scenes A.toml ...]

Needs loopcheck with the mjwarp extra.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def patch_mjwarp_jdotv() -> None:
    """Make MJWarp compute the body velocities (cvel, cdof_dot) before the loop constraints'
    J̇·q̇, as MuJoCo C's order of evaluation has them."""
    from mujoco_warp._src import constraint, smooth

    original = constraint.make_constraint

    def make_constraint(m, d, *args, **kwargs):
        smooth.com_vel(m, d)
        return original(m, d, *args, **kwargs)

    constraint.make_constraint = make_constraint


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="*", type=Path, default=sorted((ROOT / "scenes" / "mechanisms").glob("*.toml")))
    p.add_argument("--max-steps", type=int, default=5000, help="skip runs of more steps (~50 ms a step on a CPU)")
    a = p.parse_args(argv)
    from loopcheck.compare.run import judge
    from loopcheck.compare.settings import engine_settings
    from loopcheck.mjwarp import simulate_mjwarp
    from loopcheck.mujoco_model.steps import grid_timestep, step_count
    from loopcheck.mujoco_model.port import PortRefusal
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.scenefile import load_scene

    patch_mjwarp_jdotv()
    print("MJWarp 4.0.0 with its J̇·q̇ lag patched out (float32 alone) against the reduced engine")
    print("| scene | step (s) | peak | peak rel. | max abs Δq | max abs Δq̇ | loop gap (m) | energy residual |")
    print("|---|---|---|---|---|---|---|---|")
    for path in a.scenes:
        scene = load_scene(path)
        settings = replace(engine_settings("mjwarp", scene), max_constraint_violation=1.0, max_energy_residual=1.0)
        steps = step_count(scene, settings.timestep or grid_timestep(scene))
        if steps > a.max_steps:
            print(f"| {scene.name} | not run here: {steps} steps at the scene's step | | | | | | |")
            continue
        try:
            run = simulate_mjwarp(scene, settings)
        except PortRefusal as exc:
            print(f"| {scene.name} | refused: {exc} | | | | | | |")
            continue
        reference = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12))
        d = judge(scene, reference, run, scene.tolerances).diff
        print(f"| {scene.name} | {run.settings.timestep:g} | {run.peak.omega:.10g} | {d.peak_omega_rel:.2e} | "
              f"{d.q_max_abs:.2e} | {d.omega_max_abs:.2e} | {run.constraint_violation.max:.1e} | "
              f"{run.audit.relative_residual:.1e} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
