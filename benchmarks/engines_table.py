"""Every engine against the exact reduced solution on the mechanism catalogue, and each engine's
time per variant on the seed.

1. For each scene of scenes/mechanisms/ (the nine mechanisms), ``loopcheck check --engines`` with every
   engine installed (reduced, MuJoCo C, Pinocchio, MJX, MJWarp; the optional ones skipped with a
   note when their extra is missing), each at its defaults and judged by the scene's own
   ``[tolerances]`` (or ``[tolerances.ENGINE]``): peak ω, its relative difference from the reduced
   peak (DOP853, rtol 1e-12, the exact reference), max |Δq|, max |Δq̇|, the gate, the engine's
   wall time. MJX and MJWarp refuse scenes with point forces (one line, printed).
2. The seed over its 2 s: time per variant. The reduced engine, MuJoCo C and Pinocchio run one
   variant at a time (median of --repeats); MJX and MJWarp run --batch variants (the damper
   swept over 20–80 N·s/m) as one vmap / one nworld launch, and the time per variant is the batch's
   run divided by its size (compilation reported apart).

    python benchmarks/engines_table.py [--scenes A.toml ...] [--batch 64] [--repeats 3]

Prints Markdown tables; the date, machine and command go with them (docs/performance.md).
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import sys
import time
from dataclasses import replace
from datetime import date
from pathlib import Path

import numpy as np

from loopcheck.compare.engines import check_engines
from loopcheck.compare.settings import engine_settings
from loopcheck.mujoco_model.steps import grid_timestep, step_count
from loopcheck.registry import ENGINES
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.toml_reader import parse_toml

ROOT = Path(__file__).resolve().parents[1]
EXTRAS = {"pin": "pinocchio", "mjx": "jax", "mjwarp": "warp"}
MJWARP_STEP_S = 0.047  # s per MJWarp step on this project's CPU (seed, measured), for the skip message


def installed() -> tuple[str, ...]:
    names = ["reduced", "mujoco"]
    for name, module in EXTRAS.items():
        if name in ENGINES and importlib.util.find_spec(module) is not None:
            names.append(name)
        else:
            print(f"note: {name} skipped (its extra is not installed)", file=sys.stderr)
    return tuple(names)


def table(paths: list[Path], engines: tuple[str, ...], max_port_steps: int) -> None:
    """The ports run with their own loop-gap and energy gates opened, so that a run those gates
    would stop still shows its figures; the "own audit" column says whether it meets the
    defaults' bounds (the gap and the energy residual relative to its scale)."""
    print("| scene | engine | peak (rad/s or m/s) | Δpeak rel. | max abs Δq | max abs Δq̇ | loop gap (m) | "
          "energy residual | own audit | gate | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for path in paths:
        scene = load_scene(path)
        settings = {name: engine_settings(name, scene) for name in engines}
        run_here = engines
        if "mjwarp" in engines:
            steps = step_count(scene, settings["mjwarp"].timestep or grid_timestep(scene))
            if steps > max_port_steps:
                run_here = tuple(e for e in engines if e != "mjwarp")
                print(f"| {scene.name} | mjwarp | not run here: {steps} steps at the scene's step, about "
                      f"{steps * MJWARP_STEP_S / 60:.0f} min of MJWarp on this CPU | | | | | | | | |")
        defaults = dict(settings)
        for port in set(engines) & {"mjx", "mjwarp"}:
            settings[port] = replace(settings[port], max_constraint_violation=1.0, max_energy_residual=1.0)
        check = check_engines(scene, run_here, settings, None)
        print(f"| {scene.name} | reduced | {check.reference.peak.omega:.10g} | – | – | – | – | "
              f"{check.reference.audit.relative_residual:.1e} | – | – | {check.reference.wall_s:.3f} |")
        for v in check.verdicts:
            if v.comparison is None:
                print(f"| {scene.name} | {v.engine} | {v.failure} | | | | | | | no | |")
                continue
            d, run = v.comparison.diff, v.comparison.other
            gap, energy = run.constraint_violation.max, run.audit.relative_residual
            bounds = defaults[v.engine]
            own = gap <= bounds.max_constraint_violation and energy <= bounds.max_energy_residual
            note = " (known defect)" if run.caveats else ""
            print(f"| {scene.name} | {v.engine} | {d.peak_omega_other:.10g} | {d.peak_omega_rel:.2e} | "
                  f"{d.q_max_abs:.2e} | {d.omega_max_abs:.2e} | {gap:.1e} | {energy:.1e} | {'pass' if own else 'FAIL'} | "
                  f"{'pass' if v.passed and own else 'FAIL'}{note} | {run.wall_s:.3f} |")
        sys.stdout.flush()


def seed_variants(n: int) -> list:
    text = (ROOT / "scenes" / "seed_fourbar.toml").read_text()
    data = parse_toml(text, ROOT / "scenes" / "seed_fourbar.toml")
    out = []
    for b in np.linspace(20.0, 80.0, n):
        data["dampers"][0]["coefficient"] = float(b)
        out.append(scene_from_dict(data, source=f"seed, B = {b:.3g} N·s/m"))
    return out


def per_variant(engines: tuple[str, ...], batch: int, repeats: int) -> None:
    variants = seed_variants(batch)
    print()
    print(f"Time per variant on the seed (2 s), {platform.processor() or platform.machine()}, {date.today()}:")
    print("| engine | variants per run | compile (s) | run per variant (s) |")
    print("|---|---|---|---|")
    for name in engines:
        settings = engine_settings(name, variants[0])
        if name in ("mjx", "mjwarp"):  # timing only: their own gates opened (MJX's loops open by ~3.5 mm here)
            settings = replace(settings, max_constraint_violation=1.0, max_energy_residual=1.0)
            module = __import__(ENGINES[name].package, fromlist=["simulate_batch"])
            results = module.simulate_batch(variants, settings)
            compile_s = results[0].details.compile_s
            print(f"| {name} | {batch} | {compile_s:.1f} | {results[0].wall_s:.3g} |")
        else:
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                ENGINES[name].simulate(variants[0], settings)
                times.append(time.perf_counter() - start)
            print(f"| {name} | 1 | – | {float(np.median(times)):.3g} |")
        sys.stdout.flush()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="*", type=Path, default=sorted((ROOT / "scenes" / "mechanisms").glob("*.toml")))
    p.add_argument("--engines", default=None, help="comma-separated (default: every engine installed)")
    p.add_argument("--batch", type=int, default=64)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-table", action="store_true")
    p.add_argument("--max-port-steps", type=int, default=5000,
                   help="skip MJWarp runs of more steps (on a CPU it takes ~50 ms a step)")
    a = p.parse_args(argv)
    engines = tuple(a.engines.split(",")) if a.engines else installed()
    print(f"# engines_table.py on {platform.node()}, {date.today()}, engines {', '.join(engines)}")
    if not a.no_table:
        table(a.scenes, engines, a.max_port_steps)
    per_variant(engines, a.batch, a.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
