"""The compiled reduced core on the seed scene: four measured ratios, all in one run.

1. Evaluation cost, general path vs bound. A straight-line numba implementation of the
   seed's closed form, q̈ = (Q − ζ q̇² − dV/dq)/𝔍 (positions by the closed-form angle
   formulas, K and L analytically, 𝔍 and ζ summed over the three bodies, the damper's and
   the load's generalized forces), written here, is checked against the general compiled
   path ``reduced.kernels.physics.acceleration`` at points of an RKN4 run of the seed
   (relative agreement ≤ 1e-12 or the script exits 1). Both are then timed in compiled loops
   of N calls (an @njit loop calling the function: no Python call overhead), q advancing by
   1e-3 rad per call so the general chart's Newton starts from the last point, as in a run.
   Printed: ns per evaluation of each, their ratio (target: general ≤ 1.5× the bound), and a
   breakdown of the general path (the chart walk: Newton, K and L; the coefficients).
2. Reduced RKN4 vs MuJoCo at equal accuracy. Truth: DOP853 rtol 1e-12
   (``compare.cost.ground_truth``). Every RKN4 step and MuJoCo configuration of
   ``compare.cost.ladder`` is run once for its errors (``compare.cost.measure``: peak-ω
   relative error, and max |Δq(t)| with the truth interpolated at the run's sample times);
   the ladder is 1-2-5 per decade, so for each target and series four geometric steps are
   added between its cheapest passing step and the next coarser one (``refinements``);
   those that meet a target are timed again (median of the repeats) and the cheapest of each
   engine is printed, for peak-ω error 1e-6 and for max |Δq| 1e-6 rad, with the ratio
   MuJoCo / reduced (target ≥ 30×). Wall times: reduced, ``EngineResult.wall_s`` of
   ``reduced.simulate`` = the call to ``reduced.engine.integrate`` (the compiled RKN4 run
   and its output assembly; not the error estimate or energy audit); MuJoCo,
   ``simulate_mujoco``'s ``wall_s`` = the rollout only.
3. The adaptive reference: median wall time of
   ``reduced.engine.integrate(model, ReducedSettings(method="dop853", rtol=1e-12))`` on the
   seed, model built beforehand (target < 10 ms). Whatever that call runs is measured. The
   same with ``method="scipy-dop853"`` (scipy's driver on the compiled equation) beside it.
4. ``xval run`` on the seed end to end: wall time of the ``xval run --out TMP`` subprocess,
   warm (median of 3 after one run that fills the numba cache) and cold (``NUMBA_CACHE_DIR``
   set to a fresh empty temporary directory, once) (targets: 2 s warm, 6 s cold).

Every timing is a median of at least 3 runs (the machine is small and shared). No timing is
asserted: the exit status is 1 only when part 1's agreement check fails.

    python benchmarks/compiled_core.py [--quick] [--repeats 5] [--parts 1,2,3,4]

``--quick`` is a smoke run: fewer calls, the small ladder, one MuJoCo integrator, no cold run
of ``xval run``.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import median_time  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from reduced import ReducedSettings, default_scene_path, load_scene  # noqa: E402
from reduced.dynamics import MechanismModel  # noqa: E402
from reduced.kernels import physics  # noqa: E402

AGREEMENT = 1e-12  # relative, part 1
STEP_Q = 1e-3  # rad per call in the timing loops
RATE = 5.0  # rad/s: q̇ handed to every timed call


# -- part 1: the bound ---------------------------------------------------------------------

def closed_form(scene):
    """The seed's q̈(load, q, q̇) in closed form as one straight-line @njit function, its
    constants (link lengths, masses, inertias, centres, the damper) frozen from the scene."""
    g = scene.four_bar
    c1, c2, c3, c4, branch = g.c1, g.c2, g.c3, g.c4, float(g.branch)
    bodies = {b.name: b for b in scene.mechanism.linkage.bodies}
    crank, coupler, rocker = bodies["crank"], bodies["coupler"], bodies["rocker"]
    m1, i1, g1x, g1y = crank.mass, crank.inertia, crank.com[0], crank.com[1]
    m2, i2, g2x, g2y = coupler.mass, coupler.inertia, coupler.com[0], coupler.com[1]
    m3, i3, g3x, g3y = rocker.mass, rocker.inertia, rocker.com[0], rocker.com[1]
    (damper,) = scene.mechanism.elements
    assert damper.kind == "damper" and damper.body_a == "ground" and damper.body_b == "coupler"
    px, py = bodies["ground"].points[damper.point_a]
    bx, by = bodies["coupler"].points[damper.point_b]  # on the coupler, frame origin A
    cd = damper.coefficient
    k0 = c1 * c1 + c2 * c2 - c3 * c3 + c4 * c4

    @njit(error_model="numpy")
    def accel(load, q, qd):
        cq, sq = math.cos(q), math.sin(q)
        # positions: A sin φ1 + B cos φ1 + C = 0 on the scene's branch, φ2 from the loop
        a = 2.0 * c1 * c2 * sq
        b = 2.0 * c2 * (c1 * cq - c4)
        c = k0 - 2.0 * c1 * c4 * cq
        p1 = math.atan2(a, b) - branch * math.acos(max(-1.0, min(1.0, -c / math.sqrt(a * a + b * b))))
        c1p, s1p = math.cos(p1), math.sin(p1)
        p2 = math.atan2(-(c1 * sq + c2 * s1p), c4 - c1 * cq - c2 * c1p)
        c2p, s2p = math.cos(p2), math.sin(p2)
        # velocity and acceleration coefficients K = dφ/dq, L = d²φ/dq²
        s21 = s2p * c1p - c2p * s1p  # sin(φ2 − φ1)
        k1 = c1 * (sq * c2p - cq * s2p) / (c2 * s21)
        k2 = c1 * (s1p * cq - c1p * sq) / (c3 * s21)
        X = c1 * cq + k1 * k1 * c2 * c1p + k2 * k2 * c3 * c2p
        Y = c1 * sq + k1 * k1 * c2 * s1p + k2 * k2 * c3 * s2p
        l1 = (X * c2p + Y * s2p) / (c2 * s21)
        l2 = -(X * c1p + Y * s1p) / (c3 * s21)
        # crank: angle q about O1 = (0, 0); centre R(q) g1
        ux, uy = cq * g1x - sq * g1y, sq * g1x + cq * g1y
        kx, ky = -uy, ux
        lx, ly = -ux, -uy
        J = m1 * (kx * kx + ky * ky) + i1
        zeta = m1 * (kx * lx + ky * ly)
        # coupler: angle φ1 about A = c1 e(q); centre A + R(φ1) g2
        ux, uy = c1p * g2x - s1p * g2y, s1p * g2x + c1p * g2y
        kax, kay = -c1 * sq, c1 * cq  # K_A
        kx, ky = kax - k1 * uy, kay + k1 * ux
        lx = -c1 * cq - l1 * uy - k1 * k1 * ux
        ly = -c1 * sq + l1 * ux - k1 * k1 * uy
        J += m2 * (kx * kx + ky * ky) + i2 * k1 * k1
        zeta += m2 * (kx * lx + ky * ly) + i2 * k1 * l1
        # rocker: angle φ2 + π about O3 = (c4, 0); centre O3 + R(φ2 + π) g3
        ux, uy = -(c2p * g3x - s2p * g3y), -(s2p * g3x + c2p * g3y)
        kx, ky = -k2 * uy, k2 * ux
        lx = -l2 * uy - k2 * k2 * ux
        ly = l2 * ux - k2 * k2 * uy
        J += m3 * (kx * kx + ky * ky) + i3 * k2 * k2
        zeta += m3 * (kx * lx + ky * ly) + i3 * k2 * l2
        # damper between the ground point P and the coupler point (at A + R(φ1) b)
        ux, uy = c1p * bx - s1p * by, s1p * bx + c1p * by
        dx, dy = c1 * cq + ux - px, c1 * sq + uy - py
        kdx, kdy = kax - k1 * uy, kay + k1 * ux
        kd = (dx * kdx + dy * kdy) / math.sqrt(dx * dx + dy * dy)
        # no gravity, no spring: dV/dq = 0; the input load's rate dq/dq = 1
        Q = load - cd * kd * kd * qd
        return (Q - zeta * qd * qd) / J

    return accel


def make_bound_loop(accel):
    @njit(error_model="numpy")
    def loop(load, q0, dq, rate, n):
        s = 0.0
        for k in range(n):
            s += accel(load, q0 + k * dq, rate)
        return s
    return loop


@njit(error_model="numpy")  # not cached: a cached caller keeps the physics it was compiled with
def general_loop(model, chart, load, q0, dq, rate, n):
    """n calls of the general path along q = q0 + k dq, from the chart's start."""
    physics.reset(model, chart)
    s = 0.0
    for k in range(n):
        s += physics.acceleration(model, chart, load, 0.0, q0 + k * dq, rate)
    return s


@njit(error_model="numpy")  # not cached: a cached caller keeps the physics it was compiled with
def walk_loop(model, chart, q0, dq, n):
    """The chart walk alone (Newton from the predictor, K, L, conditioning) along the same q."""
    F, I = model
    S, W = chart
    physics.reset(model, chart)
    s = 0.0
    for k in range(n):
        physics._walk(F, I, S, W, q0 + k * dq)
        s += W[1]
    return s


@njit(error_model="numpy")  # not cached: a cached caller keeps the physics it was compiled with
def coefficients_loop(model, chart, n):
    """The Eksergian coefficients alone, n times at the chart's current configuration."""
    F, I = model
    S, W = chart
    s = 0.0
    for k in range(n):
        physics._coefficients(F, I, S, W)
        s += W[1]
    return s


@njit(error_model="numpy")  # not cached: a cached caller keeps the physics it was compiled with
def views_loop(model, chart, n):
    """physics._views alone (the chart's 14 array views), n times."""
    s = 0.0
    for k in range(n):
        s += physics._views(model[1], chart[1])[4][0]
    return s


def median_of(run, repeats):
    run()  # warm-up (compilation)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        run()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def part1(scene, quick: bool, repeats: int) -> bool:
    from reduced.engine import integrate

    model = MechanismModel(scene)
    x0 = np.ascontiguousarray(model.assemble(scene.q0), dtype=float)
    chart = model.new_chart()
    if not physics.start_chart(model.arrays, chart, x0, 0):
        raise RuntimeError("the crank cannot drive the seed at its start")
    accel = closed_form(scene)

    # agreement at points along the motion (an RKN4 run's samples, in time order)
    run = integrate(model, ReducedSettings(method="rkn4", step=1e-3)).trajectory
    picks = np.linspace(0, len(run.t) - 1, 9).astype(int)
    print("1. q̈ on the seed: general compiled path vs a straight-line closed form (numba)")
    print(f"   {'t (s)':>6s} {'q (rad)':>10s} {'q̇ (rad/s)':>10s} {'load':>6s} {'general q̈':>22s} "
          f"{'closed form q̈':>22s} {'rel diff':>9s}")
    physics.reset(model.arrays, chart)
    worst = 0.0
    for k in picks:
        t, q, qd = float(run.t[k]), float(run.q[k]), float(run.qdot[k])
        load = 250.0 if t < 1.0 else 0.0  # the seed's pulse: 250 N·m on [0, 1) s
        general = physics.acceleration(model.arrays, chart, load, t, q, qd)
        bound = accel(load, q, qd)
        rel = abs(general - bound) / max(abs(bound), 1e-300)
        worst = max(worst, rel)
        print(f"   {t:6.3f} {q:10.5f} {qd:10.5f} {load:6.1f} {general:22.15e} {bound:22.15e} {rel:9.1e}")
    ok = worst <= AGREEMENT
    print(f"   largest relative difference {worst:.2e} (check ≤ {AGREEMENT:g}: {'ok' if ok else 'FAILED'})")

    n = 20_000 if quick else 200_000
    bound_loop = make_bound_loop(accel)
    load, q0 = 250.0, scene.q0
    checksum_general = general_loop(model.arrays, chart, load, q0, STEP_Q, RATE, n)
    checksum_bound = bound_loop(load, q0, STEP_Q, RATE, n)
    same = abs(checksum_general - checksum_bound) <= 1e-9 * abs(checksum_bound)
    t_general = median_of(lambda: general_loop(model.arrays, chart, load, q0, STEP_Q, RATE, n), repeats)
    t_bound = median_of(lambda: bound_loop(load, q0, STEP_Q, RATE, n), repeats)
    t_walk = median_of(lambda: walk_loop(model.arrays, chart, q0, STEP_Q, n), repeats)
    t_coef = median_of(lambda: coefficients_loop(model.arrays, chart, n), repeats)
    t_views = median_of(lambda: views_loop(model.arrays, chart, n), repeats)
    ns = 1e9 / n
    print(f"\n   timed: @njit loops of N = {n} calls, q = {q0} + k·{STEP_Q:g} rad (about {n * STEP_Q / (2 * math.pi):.0f} "
          f"crank turns), q̇ = {RATE:g} rad/s, load 250 N·m; median of {repeats} loops "
          f"(sums of the two loops agree: {'yes' if same else 'NO'})")
    print(f"   {'function':58s} {'ns/eval':>9s}")
    print(f"   {'closed form, straight line (the bound)':58s} {t_bound * ns:9.1f}")
    print(f"   {'general: physics.acceleration (walk + coefficients)':58s} {t_general * ns:9.1f}")
    print(f"   {'  of which the chart walk (Newton, K, L, conditioning)':58s} {t_walk * ns:9.1f}")
    print(f"   {'  of which the coefficients (𝔍, ζ, damper, load rate)':58s} {t_coef * ns:9.1f}")
    print(f"   {'  physics._views alone (5 calls per evaluation)':58s} {t_views * ns:9.1f}")
    print(f"   ratio general / bound: {t_general / t_bound:.2f}x (target ≤ 1.5x)")
    return ok


# -- part 2: RKN4 vs MuJoCo at equal accuracy ----------------------------------------------

def part2(scene, quick: bool, repeats: int) -> None:
    from compare.cost import ground_truth, ladder, measure

    targets = (("peak-ω rel error", "peak_omega_rel", 1e-6), ("max |Δq(t)| (rad)", "q_max_abs", 1e-6))
    truth = ground_truth(scene)
    configs = ladder(quick=True, integrators=("rk4",)) if quick else ladder()
    configs = [c for c in configs if c.series != "DOP853"]
    if quick:
        configs = [c for c in configs if c.engine == "reduced" or "hard" in c.series]
    print(f"\n2. reduced RKN4 vs MuJoCo at equal accuracy on the seed (truth DOP853 rtol 1e-12, "
          f"itself within {truth.error['peak_omega_rel']:.1e} peak, {truth.error['q_max_abs']:.1e} rad "
          f"of rtol 1e-11)")
    print(f"   {len(configs)} configurations from compare.cost.ladder({'quick=True' if quick else ''}) run "
          f"once for errors; those meeting a target timed again, median of {repeats}")
    first = [measure(scene, c, truth.trajectory, 1) for c in configs]
    timed: dict[str, object] = {}
    rkn4_steps = set()

    def retimed(m):
        if key(m.config) not in timed:
            timed[key(m.config)] = measure(scene, m.config, truth.trajectory, repeats)
        return timed[key(m.config)]

    print(f"   {'target':24s} {'engine':8s} {'cheapest configuration':34s} {'error':>9s} "
          f"{'wall (ms)':>10s} {'steps':>7s}")
    first += refinements(scene, first, targets, truth, quick)
    for name, attr, target in targets:
        best = {}
        for engine in ("reduced", "mujoco"):
            meeting = [m for m in first if m.config.engine == engine and m.ok and getattr(m, attr) <= target]
            if not meeting:
                best[engine] = None
                continue
            # re-time the ones within 3x of the cheapest single run (the rest cannot win)
            floor = min(m.wall_median_s for m in meeting)
            again = [retimed(m) for m in meeting if m.wall_median_s <= 3.0 * floor]
            again = [m for m in again if m.ok]
            best[engine] = min(again, key=lambda m: m.wall_median_s) if again else None
        for engine in ("reduced", "mujoco"):
            m = best[engine]
            heading = f"{name} ≤ {target:g}"
            if m is None:
                print(f"   {heading:24s} {engine:8s} {'not reached':34s}")
            else:
                if engine == "reduced":
                    rkn4_steps.add(m.config.parameter)
                print(f"   {heading:24s} {engine:8s} {label(m.config):34s} {getattr(m, attr):9.2e} "
                      f"{m.wall_median_s * 1e3:10.3f} {m.n_steps:7d}")
        if best["reduced"] and best["mujoco"]:
            print(f"   ratio MuJoCo / reduced at {name} ≤ {target:g}: "
                  f"{best['mujoco'].wall_median_s / best['reduced'].wall_median_s:.1f}x (target ≥ 30x)")
        else:
            print(f"   ratio MuJoCo / reduced at {name} ≤ {target:g}: not measured (a target not reached)")
    for h in sorted(rkn4_steps):
        run_only, whole = rkn4_breakdown(scene, h, repeats)
        print(f"   RKN4 h={h:.1e}: the compiled run alone (kernels.partition.run_rkn4) {run_only * 1e3:.3f} ms "
              f"of integrate()'s {whole * 1e3:.3f} ms (the rest: start, output assembly in Python)")
    mj = [m for m in first if m.config.engine == "mujoco" and m.ok]
    if mj:
        print(f"   smallest MuJoCo errors measured: peak {min(m.peak_omega_rel for m in mj):.2e}, "
              f"max |Δq| {min(m.q_max_abs for m in mj):.2e} rad")


REFINE_POINTS = 4  # steps inserted between a ladder's passing step and the next coarser one


def key(config) -> tuple[str, float]:
    return config.series, config.parameter


def label(config) -> str:
    return f"{config.series} h={config.parameter:.3g}"


def with_step(config, step: float):
    """``config`` at another step (RKN4) or timestep (MuJoCo)."""
    from dataclasses import replace

    if config.engine == "reduced":
        return replace(config, parameter=step, reduced=replace(config.reduced, step=step))
    return replace(config, parameter=step, mujoco=replace(config.mujoco, timestep=step))


def refinements(scene, first, targets, truth, quick: bool) -> list:
    """The ladder is 1-2-5 per decade: its cheapest passing step can sit far inside a target
    (RKN4 at 1 ms: 1.6e-7 for 1e-6), which favours whichever engine lands closer. For each
    target and series, the cheapest passing step and the next coarser one (which failed) get
    ``REFINE_POINTS`` geometric steps between them (MuJoCo's moved down onto the load edges'
    grid, as the ladder's are: off it the pulse's edge costs MuJoCo 1e-4 of peak error), run
    once for errors like the ladder's."""
    from compare.cost import measure
    from reference_models.run import grid_timestep

    if quick:
        return []
    extra, seen = [], {key(m.config) for m in first}
    for _, attr, target in targets:
        for series in sorted({m.config.series for m in first}):
            runs = sorted((m for m in first if m.config.series == series), key=lambda m: m.config.parameter)
            passing = [m for m in runs if m.ok and getattr(m, attr) <= target]
            if not passing:
                continue
            cheapest = max(m.config.parameter for m in passing)
            coarser = [m for m in runs if m.config.parameter > cheapest]
            if not coarser:
                continue
            lo, hi = cheapest, coarser[0].config.parameter
            for k in range(1, REFINE_POINTS + 1):
                step = lo * (hi / lo) ** (k / (REFINE_POINTS + 1))
                if coarser[0].config.engine == "mujoco":  # on the load edges' grid, as the ladder's steps
                    step = grid_timestep(scene, ceiling=step)
                config = with_step(coarser[0].config, step)
                if lo < step < hi and key(config) not in seen:
                    seen.add(key(config))
                    extra.append(measure(scene, config, truth.trajectory, 1))
    print(f"   refined: {len(extra)} more configurations between each series' cheapest passing step and the "
          f"next coarser one ({REFINE_POINTS} geometric steps)")
    return extra


def rkn4_breakdown(scene, step: float, repeats: int) -> tuple[float, float]:
    """Median wall times (s) of the compiled RKN4 run alone and of the whole
    ``reduced.engine.integrate`` call at ``step``."""
    from reduced.integrators import SPEED_LIMIT
    from reduced.kernels import partition as compiled
    from reduced.partition import MAX_SWITCHES, _start, load_pieces
    from reduced.engine import integrate

    model = MechanismModel(scene)
    x0, i, rate = _start(model)
    edges, loads = load_pieces(model)
    chart = model.new_chart()

    def run_only():
        compiled.run_rkn4(model.arrays, chart, edges, loads, x0, i, rate, float(step), SPEED_LIMIT, True,
                          MAX_SWITCHES)

    settings = ReducedSettings(method="rkn4", step=step)
    return median_time(run_only, repeats), median_time(lambda: integrate(model, settings), repeats)


# -- part 3: the adaptive reference --------------------------------------------------------

def part3(scene, repeats: int) -> None:
    from reduced.engine import integrate

    model = MechanismModel(scene)
    settings = ReducedSettings(method="dop853", rtol=1e-12)
    solution = integrate(model, settings)
    t = median_time(lambda: integrate(model, settings), repeats)
    print(f"\n3. adaptive reference on the seed: reduced.engine.integrate(model, "
          f"ReducedSettings(method='dop853', rtol=1e-12)), model built beforehand, median of {repeats}")
    print(f"   {'solver':28s} {'steps':>7s} {'f evals':>8s} {'wall (ms)':>10s}")
    print(f"   {solution.method:28s} {solution.n_steps:7d} {solution.n_evaluations:8d} {t * 1e3:10.2f}")
    # scipy's solve_ivp driving the same compiled equation: the independent cross-check
    cross = ReducedSettings(method="scipy-dop853", rtol=1e-12)
    by_scipy = integrate(model, cross)
    t_scipy = median_time(lambda: integrate(model, cross), repeats)
    print(f"   {'scipy-dop853 (cross-check)':28s} {by_scipy.n_steps:7d} {by_scipy.n_evaluations:8d} "
          f"{t_scipy * 1e3:10.2f}   ({t_scipy / t:.1f}x the compiled driver)")
    print(f"   ratio to the target: {t / 10e-3:.2f}x of 10 ms (target < 1)")


# -- part 4: xval run end to end -----------------------------------------------------------

def xval_command() -> list[str]:
    exe = Path(sys.executable).with_name("xval")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "compare.cli"]


def timed_run(env: dict) -> float:
    out = tempfile.mkdtemp(prefix="xval-bench-")
    try:
        start = time.perf_counter()
        done = subprocess.run([*xval_command(), "run", "--out", out], cwd=ROOT, env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall = time.perf_counter() - start
    finally:
        shutil.rmtree(out, ignore_errors=True)
    if done.returncode not in (0, 1):  # 1: a gate failed, still a full run
        raise RuntimeError(f"xval run exited {done.returncode}: {done.stderr[-2000:]}")
    return wall


def part4(quick: bool, repeats: int) -> None:
    env = dict(os.environ)
    timed_run(env)  # fills the cache
    warm = [timed_run(env) for _ in range(max(3, repeats if not quick else 3))]
    print(f"\n4. `xval run --out TMP` on the seed, subprocess wall time (imports, both engines, report, plots)")
    print(f"   {'run':44s} {'wall (s)':>9s} {'target (s)':>10s}")
    print(f"   {f'warm cache, median of {len(warm)} (after one fill)':44s} {statistics.median(warm):9.2f} {2.0:10.1f}"
          f"   (runs: {', '.join(f'{w:.2f}' for w in warm)})")
    if quick:
        print("   cold cache: skipped (--quick)")
        print(f"   ratio warm / target: {statistics.median(warm) / 2.0:.2f}")
        return
    cache = tempfile.mkdtemp(prefix="numba-cold-")
    try:
        cold = timed_run({**env, "NUMBA_CACHE_DIR": cache})
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    print(f"   {'cold cache (fresh empty NUMBA_CACHE_DIR), once':44s} {cold:9.2f} {6.0:10.1f}")
    print(f"   ratio warm / target: {statistics.median(warm) / 2.0:.2f}, cold / target: {cold / 6.0:.2f} "
          f"(< 1 meets the target)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a fast smoke run")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats (at least 3)")
    parser.add_argument("--parts", default="1,2,3,4", help="which parts to run, e.g. 1,3")
    args = parser.parse_args()
    repeats = max(3, args.repeats)
    parts = {int(p) for p in args.parts.split(",")}
    scene = load_scene(default_scene_path())
    ok = True
    if 1 in parts:
        ok = part1(scene, args.quick, repeats)
    if 2 in parts:
        part2(scene, args.quick, repeats)
    if 3 in parts:
        part3(scene, repeats)
    if 4 in parts:
        part4(args.quick, repeats)
    if not ok:
        print("FAILED: the general path and the closed form disagree (part 1)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
