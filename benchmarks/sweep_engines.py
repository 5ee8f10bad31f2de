"""The per-variant cost of each installed engine in a sweep, measured in one run (issue 39,
"Batches in the interface").

The sweep: ``scenes/seed_fourbar.toml`` over a short horizon (``--horizon``, default 0.2 s) with
``dampers.0.coefficient`` on a grid of ``--variants`` values (default 32) from 40 to 70 N·s/m, made
as ``loopcheck sweep`` makes them (``load_sweep``, ``spec_from_args``, ``variant_values``,
``apply``, ``scene_from_dict``). Every registered engine whose extra is installed runs the
variants the way the sweep runs them, in this process:

- variant by variant: ``Engine.simulate(scene, settings)`` on each (the sweep's process pool runs
  the same call per variant, and so does ``--batch-size 1`` for a batch engine; one process
  here, so the figure is one core's), the scene and the engine's settings as the sweep gives
  them (``judged_scene``, ``engine_settings``);
- an engine that declares a batch size (MJX, MJWarp) also in batches:
  :func:`loopcheck.compare.sweep.run_batches`, the sweep's own function (chunks of the batch size,
  the last padded, each variant's failure its own), at its ``BATCH_SIZE`` (or ``--batch`` N).

Each engine's first call (MJX's compilation of a shape, warp's kernel load, imports) is made once
before the timing and printed apart ("first call"); the timing is one pass over the variants
(wall, ``time.perf_counter``), divided by their number. The yardstick: one ``simulate`` of the
nominal scene by the reduced reference at its scene settings, timed in the same run (median of
5), and every per-variant figure is printed as a ratio to it.

Runs as it is on a GPU machine: JAX and warp pick their device (the GPU when they see one; the
device is printed); give ``--batch 4096 --variants 32768`` there. On a CPU keep
``XLA_FLAGS=--xla_cpu_multi_thread_eigen=false`` as the tests do (one thread per process).

    python benchmarks/sweep_engines.py [--variants 32] [--horizon 0.2] [--batch N] [--engines a,b]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from loopcheck.compare.settings import engine_settings  # noqa: E402
from loopcheck.compare.sweep import _member, run_batches  # noqa: E402
from loopcheck.compare.sweep_scene import load_sweep  # noqa: E402
from loopcheck.registry import ENGINES, REFERENCE  # noqa: E402
from loopcheck.scenefile import scene_from_dict  # noqa: E402
from loopcheck.sweep_spec import apply, spec_from_args, variant_values  # noqa: E402

SEED = ROOT / "scenes" / "seed_fourbar.toml"


def _device(name: str) -> str:
    """Where an engine runs: JAX's backend, warp's device, else the CPU."""
    package = ENGINES[name].package
    if package.endswith("mjx"):
        import jax

        return f"JAX {jax.default_backend()}"
    if package.endswith("mjwarp"):
        import warp as wp

        wp.init()
        return f"warp {wp.get_device()}"
    return "CPU"


def _installed(names) -> list[str]:
    out = []
    for name in names:
        try:
            ENGINES[name].load()
        except ImportError as exc:
            print(f"  {name}: not installed ({str(exc).splitlines()[0][:80]})")
            continue
        out.append(name)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variants", type=int, default=32)
    parser.add_argument("--horizon", type=float, default=0.2)
    parser.add_argument("--batch", type=int, default=None, help="the batch size of the batch engines "
                                                                "(default: each one's BATCH_SIZE)")
    parser.add_argument("--engines", default=",".join(ENGINES), help="engines to time (default: all registered)")
    args = parser.parse_args()

    data, _ = load_sweep(SEED)
    data = {**data, "simulation": {**data["simulation"], "horizon": args.horizon}}
    spec = spec_from_args([f"dampers.0.coefficient=40:70:{args.variants}"])
    values = list(variant_values(spec))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenes = [scene_from_dict(apply(data, v), str(SEED)) for v in values]
        nominal = scene_from_dict(data, str(SEED))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"benchmarks/sweep_engines.py: {len(values)} variants of {SEED.name} (dampers.0.coefficient 40..70), "
          f"horizon {args.horizon:g} s; {os.cpu_count()} cores, load average {load:.2f} at start")

    reference = ENGINES[REFERENCE]
    ref_settings = engine_settings(REFERENCE, nominal)
    reference.simulate(nominal, ref_settings)  # imports, compiled kernels
    times = []
    for _ in range(5):
        start = time.perf_counter()
        reference.simulate(nominal, ref_settings)
        times.append(time.perf_counter() - start)
    yardstick = statistics.median(times)
    print(f"yardstick: one simulate of the nominal scene by {REFERENCE} at its scene settings, "
          f"{yardstick * 1e3:.2f} ms (median of 5)\n")

    rows = []
    names = _installed([n.strip() for n in args.engines.split(",") if n.strip()])
    for name in names:
        engine = ENGINES[name]
        device = _device(name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            runs = [(s if name == REFERENCE else _judged(s, name), engine_settings(name, s)) for s in scenes]
            start = time.perf_counter()
            first = _outcome(lambda: engine.simulate(*runs[0]))
            first_s = time.perf_counter() - start
            start = time.perf_counter()
            failed = sum(isinstance(_outcome(lambda r=r: engine.simulate(*r)), BaseException) for r in runs)
            each = (time.perf_counter() - start) / len(runs)
        rows.append((name, "variant by variant", 1, device, first_s, each, failed, first))
        declared = engine.batch_size
        size = args.batch or declared
        if declared > 1 and size > 1:
            sizes = {name: size}
            members = [_member(i, v, data, str(SEED), sizes) for i, v in enumerate(values)]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                start = time.perf_counter()
                run_batches(members[:1], sizes)  # the compiled shape of this size (one padded batch)
                first_s = time.perf_counter() - start
                start = time.perf_counter()
                outcomes = run_batches(members, sizes)
                each = (time.perf_counter() - start) / len(members)
            failed = sum(isinstance(o[name], BaseException) for o in outcomes)
            rows.append((name, "batches (run_batches)", size, device, first_s, each, failed, None))

    print(f"{'engine':8s} {'how':22s} {'batch':>6s} {'device':14s} {'first call (s)':>14s} "
          f"{'per variant (ms)':>16s} {'/ yardstick':>11s} {'failed':>6s}")
    for name, how, size, device, first_s, each, failed, _ in rows:
        print(f"{name:8s} {how:22s} {size:6d} {device:14s} {first_s:14.2f} {each * 1e3:16.2f} "
              f"{each / yardstick:11.2f} {failed:6d}")
    print("\nfailed: variants whose run failed (a port's known defect fails its own audits on some scenes; "
          "the cost is the run's either way)")
    return 0


def _judged(scene, name):
    from loopcheck.compare.sweep import judged_scene

    return judged_scene(scene, name)


def _outcome(call):
    try:
        return call()
    except Exception as exc:  # noqa: BLE001 - a variant's failure is counted, not the benchmark's
        return exc


if __name__ == "__main__":
    sys.exit(main())
