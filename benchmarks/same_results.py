"""Whether two trees of the code give the same reduced-engine results, bit for bit.

For a change meant to be a pure speed-up (the compiled kernels' arithmetic order kept, work not
redone): every array of ``loopcheck.reduced.engine.simulate``'s result (the trajectory, the
joints, the energy audit, the details: switches, events, RKN4's error estimate; every number
of it as a 0-d array; the times of the run, ``wall_s``, left out) for

- every shipped scene under ``scenes/`` (one-DOF and several-DOF), at its own settings (DOP853,
  rtol 1e-12), at DOP853 rtol 1e-10 (full and ``summary=True``), RKN4 at a fixed step
  (the scene's default 5e-4 s, its error estimate included) and Radau (scipy's; a scene it
  refuses is compared by its refusal);
- twelve variants of the seed of the sweep benchmark's grid (``benchmarks/sweep.py``: the damper's
  coefficient and the coupler's mass) and a few of its geometry and loads, at the sweep's settings
  (DOP853 rtol 1e-12) and rtol 1e-10, full and ``summary=True``,

each run with ``check_error`` off (a run beyond its energy bound keeps its arrays); a run that
raises is compared by its exception's type and text. Each tree runs in a process of its own
(``PYTHONPATH``: the package of that tree, its compiled kernels built in place); the arrays are
compared with ``np.array_equal`` (NaN equal to NaN), dtypes and shapes too.

    python benchmarks/same_results.py --before /tmp/base_tree [--after TREE] [--quick]

Exit status 0 when every array is equal, 1 otherwise (each difference printed).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
SEED = SCENES / "seed_fourbar.toml"

# (damper coefficient, coupler mass) of the sweep benchmark's grid: corners, centre, inside
SEED_GRID = [(40.0, 35.0), (40.0, 45.0), (70.0, 35.0), (70.0, 45.0), (55.0, 40.0), (43.75, 36.28),
             (51.25, 41.41), (62.5, 38.85), (66.25, 44.74), (47.5, 39.1), (58.75, 35.51), (68.75, 42.3)]
# other keys of the seed: its geometry, its inertias, its pulse
SEED_OTHERS = [{"linkage.c2": 0.95}, {"linkage.c3": 0.72, "bodies.rocker.pivot_inertia": 2.0},
               {"torque.value": 400.0}, {"initial.q": 1.1, "initial.qdot": -2.0}]


def cases():
    """(name, scene, settings, summary) of every run compared."""
    from loopcheck.reduced.settings import ReducedSettings
    from loopcheck.scenefile import load_scene, scene_from_dict
    from loopcheck.sweep_spec import apply
    from loopcheck.toml_reader import parse_toml, read_text

    for path in sorted(SCENES.rglob("*.toml")):
        name = str(path.relative_to(SCENES))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load_scene(path)
        yield name, "own", scene, ReducedSettings(check_error=False), False
        yield name, "own-summary", scene, ReducedSettings(check_error=False), True
        yield name, "dop853-1e-10", scene, ReducedSettings(rtol=1e-10, check_error=False), False
        yield name, "dop853-1e-10-summary", scene, ReducedSettings(rtol=1e-10, check_error=False), True
        yield name, "rkn4", scene, ReducedSettings(method="rkn4", check_error=False), False
        yield name, "radau", scene, ReducedSettings(method="radau", rtol=1e-8, check_error=False), False
    data = parse_toml(read_text(SEED), SEED)
    variants = [{"dampers.0.coefficient": c, "bodies.coupler.mass": m} for c, m in SEED_GRID] + SEED_OTHERS
    for k, values in enumerate(variants):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = scene_from_dict(apply(data, values), str(SEED))
        name = f"seed-variant-{k}"
        for rtol in (1e-12, 1e-10):
            yield name, f"dop853-{rtol:g}", scene, ReducedSettings(rtol=rtol, check_error=False), False
            yield name, f"dop853-{rtol:g}-summary", scene, ReducedSettings(rtol=rtol, check_error=False), True


def flatten(value, prefix: str, out: dict) -> None:
    """Every array and number of ``value`` (dataclasses, tuples, dicts) into ``out`` by path;
    the run's times (a key with "wall") left out, settings and texts as text."""
    if isinstance(value, np.ndarray):
        out[prefix] = value
    elif isinstance(value, (bool, int, float, np.number, np.bool_)) or value is None:
        out[prefix] = np.array(np.nan if value is None else value)
    elif isinstance(value, str):
        out[prefix] = np.array(value)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        if type(value).__name__.endswith("Settings"):
            out[prefix] = np.array(repr(value))
            return
        for f in dataclasses.fields(value):
            if "wall" not in f.name:
                flatten(getattr(value, f.name), f"{prefix}.{f.name}", out)
    elif isinstance(value, dict):
        for k, v in value.items():
            if "wall" not in str(k):
                flatten(v, f"{prefix}.{k}", out)
    elif isinstance(value, (tuple, list)):
        out[f"{prefix}.len"] = np.array(len(value))
        for k, v in enumerate(value):
            flatten(v, f"{prefix}[{k}]", out)
    else:
        out[prefix] = np.array(repr(value))


def dump(path: Path, quick: bool) -> None:
    """Run every case with the package on the path and save its arrays into ``path`` (npz)."""
    from loopcheck.reduced.engine import simulate

    out: dict[str, np.ndarray] = {}
    for name, label, scene, settings, summary in cases():
        if quick and not name.startswith(("seed", "hard/dead", "mechanisms/five_bar_robot")):
            continue
        key = f"{name}|{label}"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = simulate(scene, settings, summary=summary)
        except Exception as exc:  # noqa: BLE001 - a refusal or a failure is a result to compare too
            out[f"{key}|raised"] = np.array(f"{type(exc).__name__}: {exc}")
            continue
        flatten(result, key, out)
    np.savez(path, **out)


def run_tree(tree: Path, path: Path, quick: bool) -> None:
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--dump", str(path)] + (["--quick"] if quick else [])
    done = subprocess.run(cmd, cwd=tree, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{tree}: {done.stderr[-3000:]}")


def compare(a_path: Path, b_path: Path, ignore: tuple[str, ...] = ()) -> int:
    import fnmatch

    a, b = np.load(a_path), np.load(b_path)
    differ = []
    keys = sorted(set(a.files) | set(b.files))
    ignored = [k for k in keys if any(fnmatch.fnmatchcase(k, p) for p in ignore)]
    if ignored:
        print(f"{len(ignored)} arrays ignored (--ignore {' '.join(ignore)}): {len(set(ignored) & set(a.files))} of "
              f"before, {len(set(ignored) & set(b.files))} of after")
    for key in (k for k in keys if k not in set(ignored)):
        if key not in a.files or key not in b.files:
            differ.append(f"{key}: only in {'before' if key in a.files else 'after'}")
            continue
        x, y = a[key], b[key]
        same = x.dtype == y.dtype and x.shape == y.shape and (
            np.array_equal(x, y, equal_nan=True) if x.dtype.kind in "fc" else np.array_equal(x, y))
        if not same:
            differ.append(f"{key}: {x!r:.200} != {y!r:.200}")
    runs = {k.split("|")[0] + "|" + k.split("|")[1].split(".")[0] for k in a.files}
    scenes = {k.split("|")[0] for k in a.files}
    raised = sum(k.endswith("|raised") for k in a.files)
    print(f"{len(a.files)} arrays of {len(runs)} runs ({raised} of them a refusal or failure compared by its text) "
          f"of {len(scenes)} scenes and variants: {len(differ)} differ")
    for line in differ[:50]:
        print("  ", line)
    return 1 if differ else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="a tree of the code before (its kernels built in place)")
    parser.add_argument("--after", type=Path, default=ROOT, help="the tree after (default: this one)")
    parser.add_argument("--quick", action="store_true", help="the seed, its variants and two scenes only")
    parser.add_argument("--ignore", nargs="*", default=[], metavar="GLOB",
                        help="keys to leave out of the comparison (fnmatch patterns, e.g. '*-summary.joints*' for what "
                             "one tree no longer makes)")
    parser.add_argument("--dump", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.dump:
        dump(args.dump, args.quick)
        return 0
    if args.before is None:
        parser.error("--before TREE is required")
    with tempfile.TemporaryDirectory() as tmp:
        paths = Path(tmp) / "before.npz", Path(tmp) / "after.npz"
        run_tree(args.before.resolve(), paths[0], args.quick)
        run_tree(args.after.resolve(), paths[1], args.quick)
        return compare(*paths, tuple(args.ignore))


if __name__ == "__main__":
    sys.exit(main())
