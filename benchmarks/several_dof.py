"""The several-DOF chart's cost per evaluation of q̈ for n = 1, 2, 3 degrees of freedom (issue 40).

For each scene, the states (t, q, q̇) of its run's samples in the inputs' own coordinates, up to
its first coordinate switch (successive samples are close: each evaluation walks a short jump, as
inside an integration), are evaluated in order by the compiled chart
(:class:`loopcheck.reduced.kernels.several.Several`) in a loop in C (``accelerations``), the chart
reset before each repeat. Printed: ns per evaluation (median of the repeats) and, counted by the
chart, per evaluation: LU factorizations of A (n_x × n_x, n_x the linkage's coordinates), solves
with them (Newton's steps, k for K, one for ẍ0: the velocity-squared terms), k×k solves (𝔍 q̈ = Q − c)
and loop closures. For n = 1 the one-DOF kernel (:class:`loopcheck.reduced.kernels.physics.Chart`,
today's engine) on the same states beside it, called from Python (its ``acceleration`` takes
scalars; the call adds ~0.1 µs); its solves are not counted (its docstring: 3 factorizations, 2
Newton steps from the quadratic predictor where no closed-form dyad applies, and 2 solves for K
and L).

Then the whole runs: each scene of several DOF over its horizon by the methods of the reduced
engine, the integration's wall time (``EngineResult.wall_s``: the run of the charts and their
switches, not the scene's loading nor RKN4's error estimate) as the median of the repeats, with
its steps and evaluations of q̈: the compiled DOP853 (the default: the chart called from the
compiled integrator), scipy's DOP853 on the same chart (the same steps, through Python) and the
compiled RKN4 at its default step. The load average is printed with them (the machine is shared).

    python benchmarks/several_dof.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import loopcheck  # noqa: E402
from loopcheck.reduced.dynamics import MechanismModel  # noqa: E402
from loopcheck.reduced.kernels.several import CLOSURES, EVALUATIONS, FACTORS, SMALL_SOLVES, SOLVES  # noqa: E402
from loopcheck.reduced.settings import ReducedSettings  # noqa: E402
from loopcheck.reduced.several import SeveralModel, integrate, start_chart  # noqa: E402
from loopcheck.scenefile import load_scene  # noqa: E402

SCENES = ((1, ROOT / "scenes/seed_fourbar.toml"), (2, ROOT / "scenes/mechanisms/five_bar_robot.toml"),
          (3, ROOT / "tests/data/five_bar_pendulum.toml"))


def states(scene):
    """(t, q, q̇) of the run's samples in the inputs' coordinates before its first switch."""
    model = SeveralModel(scene)
    record, switches, *_ = integrate(model, ReducedSettings())
    t = np.concatenate(record.t)
    x, xdot = np.concatenate(record.x), np.concatenate(record.xdot)
    end = switches[0].time if switches and switches[0].time > 0 else t[-1]
    keep = t < end
    keep[1:] &= np.diff(t) > 0  # one sample per time
    R = model.input_rows
    return model, np.ascontiguousarray(t[keep]), np.ascontiguousarray(x[keep] @ R.T), \
        np.ascontiguousarray(xdot[keep] @ R.T)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    print(f"{'n':>2} {'scene':<20} {'evals':>6} {'ns/eval':>9} {'LU/eval':>8} {'solves/eval':>11} "
          f"{'kxk/eval':>8} {'closures/eval':>13}")
    for k, path in SCENES:
        scene = load_scene(path)
        if k == 1:
            scene = replace(scene, horizon=1.0)
        model, t, q, v = states(scene)
        out = np.zeros_like(q)
        times = []
        for _ in range(args.repeats):
            chart = start_chart(model, model.inputs, np.array(scene.x0))
            before = np.array(chart.counts)
            start = time.perf_counter()
            done = chart.accelerations(0, t, q, v, out)
            times.append(time.perf_counter() - start)
            assert done == len(t), f"{path.name}: evaluation {done} failed"
            counts = np.array(chart.counts) - before
        m = counts[EVALUATIONS]
        print(f"{k:>2} {scene.name:<20} {m:>6} {np.median(times) / m * 1e9:>9.0f} {counts[FACTORS] / m:>8.2f} "
              f"{counts[SOLVES] / m:>11.2f} {counts[SMALL_SOLVES] / m:>8.2f} {counts[CLOSURES] / m:>13.2f}")
        if k == 1:
            one = MechanismModel(scene)
            times = []
            for _ in range(args.repeats):
                chart1 = one.new_chart()
                chart1.start(np.array(scene.x0), one.input_coordinate)
                acceleration = chart1.acceleration
                qs, vs, ts = q[:, 0].tolist(), v[:, 0].tolist(), t.tolist()
                start = time.perf_counter()
                for tt, qq, vv in zip(ts, qs, vs):
                    acceleration(0, tt, qq, vv)
                times.append(time.perf_counter() - start)
            print(f"{1:>2} {'(one-DOF kernel)':<20} {len(t):>6} {np.median(times) / len(t) * 1e9:>9.0f} "
                  f"{'3':>8} {'2+2':>11} {'-':>8} {'1':>13}   (documented counts; called from Python)")
    runs(args.repeats)


def runs(repeats: int) -> None:
    """The whole runs' wall times by method (module docstring)."""
    print(f"\nwhole runs, median of {repeats} (load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}):")
    print(f"{'n':>2} {'scene':<20} {'horizon':>8} {'method':<13} {'wall_s':>9} {'steps':>6} {'evals':>7} {'µs/eval':>8}")
    for k, path in SCENES[1:]:
        scene = load_scene(path)
        for method in ("dop853", "scipy-dop853", "rkn4"):
            walls = []
            for _ in range(repeats):
                result = loopcheck.simulate(scene, ReducedSettings(method=method))
                walls.append(result.wall_s)
            wall = float(np.median(walls))
            print(f"{k:>2} {scene.name:<20} {scene.horizon:>7g}s {method:<13} {wall:>9.4f} {result.n_steps:>6} "
                  f"{result.n_evaluations:>7} {wall / result.n_evaluations * 1e6:>8.2f}")
    print(f"(load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())})")


if __name__ == "__main__":
    main()
