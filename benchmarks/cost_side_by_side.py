"""What accuracy costs on the seed scene, both engines side by side, and our MuJoCo overhead.

1. For relative peak-ω errors 1e-4, 1e-6 and 1e-8 (truth: DOP853 rtol 1e-12), the cheapest
   configuration of each engine that reaches it (reduced: RKN4 steps and DOP853 tolerances;
   MuJoCo: every integrator with the hard loop constraint over a ladder of timesteps), with
   median wall times measured in this one run, or "not reached".
2. MuJoCo's cost per step: ``simulate_mujoco`` (control sequence, rollout, sensors, edge
   samples, constraint check, energy audit; model built beforehand) against a bare
   ``mujoco.rollout.rollout`` of the same compiled model with the arrays prepared in advance,
   and against the same model without our read-out sensors. Target: our wrapping adds less
   than 10 % to MuJoCo's own stepping cost.

    python benchmarks/cost_side_by_side.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import median_time  # noqa: E402

from loopcheck.compare.cost import Config, ground_truth, measure  # noqa: E402
from loopcheck.mujoco_model.options import HARD  # noqa: E402
from loopcheck.reduced import ReducedSettings  # noqa: E402
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path
from loopcheck.reference_models import (MujocoSettings, build_model, compile_model, control_sequence,  # noqa: E402
                              initial_qpos_qvel, simulate_mujoco)

TARGETS = (1e-4, 1e-6, 1e-8)


def candidates() -> list[Config]:
    configs = [Config("reduced", "RKN4", h, ReducedSettings(method="rkn4", step=h))
               for h in np.geomspace(1e-2, 5e-5, 14)]
    configs += [Config("reduced", "DOP853", r, ReducedSettings(method="dop853", rtol=r), "rtol")
                for r in np.geomspace(1e-3, 1e-12, 19)]
    # Timesteps that divide the pulse edges (1 s): an off-grid edge adds an error of its own.
    for integrator in ("euler", "implicit", "implicitfast", "rk4"):
        for h in (2e-3, 1e-3, 5e-4, 2.5e-4, 2e-4, 1.25e-4, 1e-4, 5e-5, 2.5e-5, 1e-5):
            configs.append(Config("mujoco", f"MuJoCo {integrator}", h,
                                  MujocoSettings(integrator=integrator, timestep=float(h),
                                                 max_constraint_violation=0.1, **HARD)))
    return configs


def accuracy_cost(scene, repeats: int) -> None:
    truth = ground_truth(scene)
    print(f"1. time to reach a relative peak-omega error (truth DOP853 rtol 1e-12, accurate to "
          f"{truth.error['peak_omega_rel']:.1e}); median of {repeats} runs, simulation only")
    measured = [measure(scene, c, truth, repeats) for c in candidates()]
    print(f"{'target':>8s}  {'reduced':46s} {'MuJoCo':46s} {'MuJoCo/reduced':>14s}")
    for target in TARGETS:
        best = {}
        for engine in ("reduced", "mujoco"):
            ok = [m for m in measured if m.config.engine == engine and m.ok and m.peak_omega_rel <= target]
            best[engine] = min(ok, key=lambda m: m.wall_median_s) if ok else None

        def cell(m):
            return "not reached" if m is None else f"{m.config.label} {m.wall_median_s * 1e3:8.2f} ms"

        ratio = (f"{best['mujoco'].wall_median_s / best['reduced'].wall_median_s:14.2f}"
                 if best["reduced"] and best["mujoco"] else f"{'-':>14s}")
        print(f"{target:8.0e}  {cell(best['reduced']):46s} {cell(best['mujoco']):46s} {ratio}")
    finest = [m for m in measured if m.config.engine == "mujoco" and m.ok]
    if finest:
        m = min(finest, key=lambda m: m.peak_omega_rel)
        print(f"   smallest MuJoCo error measured: {m.peak_omega_rel:.2e} ({m.config.label})")


def overhead(scene, repeats: int) -> None:
    settings = MujocoSettings(timestep=1e-4)
    handles = build_model(scene, settings)
    model, data = handles.model, mujoco.MjData(handles.model)
    n = int(round(scene.horizon / settings.timestep))
    ctrl, _ = control_sequence(scene, settings.timestep, n)
    qpos, qvel = initial_qpos_qvel(scene)
    data.qpos[:], data.qvel[:] = qpos, qvel
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)

    bare_spec = handles.spec.copy()
    for sensor in list(bare_spec.sensors):
        bare_spec.delete(sensor)
    bare = compile_model(bare_spec).model

    def bare_rollout(m):
        d = mujoco.MjData(m)
        return lambda: rollout.rollout(m, d, state0[None], ctrl[None], nstep=n)

    def ours():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            simulate_mujoco(scene, settings, handles=handles)

    t_bare = median_time(bare_rollout(bare), repeats)
    t_sensed = median_time(bare_rollout(model), repeats)
    t_ours = median_time(ours, repeats)
    print(f"\n2. MuJoCo cost per step, seed scene, RK4, timestep {settings.timestep:g} s, {n} steps, "
          f"median of {repeats} runs")
    print(f"   bare rollout, physics only (no sensors): {t_bare / n * 1e6:7.3f} us/step")
    print(f"   bare rollout of our model (with sensors): {t_sensed / n * 1e6:7.3f} us/step "
          f"({(t_sensed / t_bare - 1) * 100:+.1f} % for the read-out sensors)")
    print(f"   simulate_mujoco (all our wrapping):       {t_ours / n * 1e6:7.3f} us/step")
    print(f"   our wrapping over MuJoCo's own stepping of the same model: {(t_ours / t_sensed - 1) * 100:+.1f} % "
          f"(target < 10 %); over physics-only stepping: {(t_ours / t_bare - 1) * 100:+.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--skip-accuracy", action="store_true", help="only the overhead measurement")
    args = parser.parse_args()
    scene = load_scene(default_scene_path())
    if not args.skip_accuracy:
        accuracy_cost(scene, args.repeats)
    overhead(scene, args.repeats)


if __name__ == "__main__":
    main()
