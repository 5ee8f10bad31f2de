"""RKN4 against DOP853 on the seed scene at equal peak-ω accuracy.

Truth: DOP853 at rtol 1e-12. For a target relative peak-ω error (1e-8 by default), find the
largest RKN4 step and the loosest DOP853 rtol that reach it, time the integration alone
(median of repeated runs, model built once), and print both medians and their ratio.
Target (issue 2): RKN4 at least 5x faster than DOP853 at equal accuracy.

    python benchmarks/reduced_rkn_vs_dop853.py [--targets 1e-4 1e-6 1e-8] [--repeats 7]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import largest_passing, median_time  # noqa: E402

from loopcheck.reduced import MechanismModel, ReducedSettings  # noqa: E402
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path
from loopcheck.reduced.engine import integrate  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=float, nargs="+", default=[1e-4, 1e-6, 1e-8])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()

    scene = load_scene(default_scene_path())
    model = MechanismModel(scene)
    truth = integrate(model, ReducedSettings(method="dop853", rtol=1e-12)).trajectory.peak_rate()

    def peak_error(settings: ReducedSettings) -> float:
        peak = integrate(model, settings).trajectory.peak_rate()
        return abs(peak.omega - truth.omega) / abs(truth.omega)

    print(f"seed scene (truth: DOP853 rtol 1e-12, peak {truth.omega:.12g} rad/s); integration only, "
          f"median of {args.repeats} runs")
    for target in args.targets:
        compare_at(model, peak_error, target, args.repeats)


def compare_at(model, peak_error, target: float, repeats: int) -> None:
    steps = np.geomspace(2e-2, 5e-5, 50)
    step, rkn_err = largest_passing(steps, lambda h: peak_error(ReducedSettings(method="rkn4", step=h)), target)
    rtols = np.geomspace(1e-3, 1e-12, 46)
    rtol, dop_err = largest_passing(rtols, lambda r: peak_error(ReducedSettings(method="dop853", rtol=r)), target)
    print(f"\ntarget relative peak-omega error {target:g}")
    if step is None or rtol is None:
        print(f"  not reached: RKN4 step {step}, DOP853 rtol {rtol}")
        return
    rkn = ReducedSettings(method="rkn4", step=step)
    dop = ReducedSettings(method="dop853", rtol=rtol)
    t_rkn = median_time(lambda: integrate(model, rkn), repeats)
    t_dop = median_time(lambda: integrate(model, dop), repeats)
    n_rkn = integrate(model, rkn).n_evaluations
    n_dop = integrate(model, dop).n_evaluations
    print(f"  RKN4    step {step:.3e} s   error {rkn_err:.2e}   {n_rkn:6d} f-evals   median {t_rkn * 1e3:8.2f} ms")
    print(f"  DOP853  rtol {rtol:.3e}     error {dop_err:.2e}   {n_dop:6d} f-evals   median {t_dop * 1e3:8.2f} ms")
    print(f"  speed-up of RKN4 over DOP853 (DOP853 time / RKN4 time): {t_dop / t_rkn:.2f}"
          + ("   (issue 2 target: >= 5)" if target == 1e-8 else ""))
    print(f"  f-evaluation ratio DOP853 / RKN4: {n_dop / n_rkn:.2f}")


if __name__ == "__main__":
    main()
