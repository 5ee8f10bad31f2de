"""Time per evaluation of q̈ = f(t, q, q̇): the general description against the four-bar closed
form on the seed scene, and the general description on every catalogue mechanism.

Three rows per scene, whichever can run:

- ``engine``: the reduced engine's own right-hand side, a :class:`loopcheck.reduced.charts.Chart` of a
  :class:`loopcheck.reduced.dynamics.MechanismModel` in the input coordinate (the compiled kernel, called
  once per f from Python, as scipy's integrators call it);
- ``closed form``: Eksergian's equation written here from the four-bar closed form
  (:meth:`loopcheck.four_bar.FourBar.kinematics`) and the bodies' geometry (``scene.four_bar``
  scenes only: the shorthand seed, scenes/seed_fourbar.toml; no point forces);
- ``loops``: Eksergian's equation written here directly on :mod:`loopcheck.kinematics` (Newton from the
  previous configuration, K and L, masses, springs, dampers, gravity, point forces and the input
  load: everything on plain arrays, no model object), a floor for what the general path costs
  in Python and a check of the engine row's value (the two must agree).

Each f is called along a short path back and forth, q_k = q0 + j·Δq with j going 0…200…0…
(Δq = q̇0·1 µs, or 1e-5 of the input's unit when q̇0 = 0), as an integrator's stages do, so every
call re-solves the loops; the figure is the best of ``--repeats`` timeit runs of ``--calls``
calls, per call.

    python benchmarks/general_vs_closed_form.py [--calls 2000] [--repeats 5]

Every f is taken on the first smooth piece of the load history, (0, first load edge), so the
load at t = 0 is the one the integrators see there.
"""

from __future__ import annotations

import argparse
import math
import timeit
from pathlib import Path
from typing import Callable

import numpy as np

from loopcheck import kinematics as loops
from loopcheck.loads import TabulatedForce
from loopcheck.scenefile import load_scene
from loopcheck.shipped_scenes import default_scene_path

ROOT = Path(__file__).resolve().parent.parent
CATALOGUE = sorted((ROOT / "scenes" / "mechanisms").glob("*.toml"))
F = Callable[[float, float, float], float]


def engine_f(scene) -> F:
    """The reduced engine's q̈ = f(t, q, q̇) in the input coordinate (index 0 of a chart)."""
    from loopcheck.reduced.dynamics import MechanismModel
    from loopcheck.reduced.charts import Chart

    model = MechanismModel(scene)
    i = model.input_coordinate  # the input is a coordinate in every catalogue scene
    return Chart(model, i, model.x0).rhs_on_piece(0.0, first_piece_end(scene))


def first_piece_end(scene) -> float:
    """The end of the load history's first smooth piece (s)."""
    edges = [e for e in (scene.load.edges if scene.load is not None else ()) if e > 0.0]
    return min(edges + [scene.horizon])


def closed_form_f(scene) -> F:
    """The four-bar closed form's f (scene.four_bar scenes only): body frames crank at O1 turning
    with q, coupler at A = c1 e(q) turning with φ1, rocker at O3 = (c4, 0) turning with φ2 + π;
    a body point p is r = o + R(θ) p, K_r = K_o + θ' (R p)⊥, L_r = L_o + θ'' (R p)⊥ − θ'² R p."""
    from loopcheck.four_bar import FourBar

    if scene.four_bar is None or scene.mechanism.point_forces:
        raise ValueError("not a four-bar shorthand scene without point forces")
    g = scene.four_bar
    fourbar = FourBar(g)
    mech = scene.mechanism
    bodies = mech.linkage.body_map
    gravity = np.zeros(2) if scene.gravity is None else np.asarray(scene.gravity, dtype=float)
    load = scene.load.on_piece(0.0, first_piece_end(scene)) if scene.load is not None else (lambda t: 0.0)
    zero = np.zeros(2)

    def f(t: float, q: float, qdot: float) -> float:
        kin = fourbar.kinematics(q)
        x, K, L = kin.x, kin.K, kin.L
        a = g.c1 * np.array([math.cos(x[0]), math.sin(x[0])])
        ap = np.array([-a[1], a[0]])
        frames = {"ground": (zero, zero, zero, 0.0, 0.0, 0.0), "crank": (zero, zero, zero, x[0], K[0], L[0]),
                  "coupler": (a, K[0] * ap, L[0] * ap - K[0] ** 2 * a, x[1], K[1], L[1]),
                  "rocker": (np.array([g.c4, 0.0]), zero, zero, x[2] + math.pi, K[2], L[2])}

        def point(body, p):
            o, ko, lo, th, kt, lt = frames[body]
            c, s_ = math.cos(th), math.sin(th)
            rp = np.array([c * p[0] - s_ * p[1], s_ * p[0] + c * p[1]])
            rpp = np.array([-rp[1], rp[0]])
            return o + rp, ko + kt * rpp, lo + lt * rpp - kt * kt * rp

        J = zeta = Q = 0.0
        for name in ("crank", "coupler", "rocker"):
            b = bodies[name]
            _, k, l = point(name, b.com)
            kt, lt = frames[name][4], frames[name][5]
            J += b.mass * (k @ k) + b.inertia * kt * kt
            zeta += b.mass * (k @ l) + b.inertia * kt * lt
            Q += b.mass * (gravity @ k)
        Q += load(t)
        for e in (*mech.dampers, *mech.springs):
            ra, ka, _ = point(e.body_a, bodies[e.body_a].points[e.point_a])
            rb, kb, _ = point(e.body_b, bodies[e.body_b].points[e.point_b])
            d = rb - ra
            length = math.hypot(d[0], d[1])
            k_d = float(d @ (kb - ka)) / length
            Q -= e.coefficient * k_d * k_d * qdot if e.kind == "damper" else e.coefficient * (length - e.rest_length) * k_d
        return (Q - zeta * qdot * qdot) / J

    return f


def loops_f(scene) -> F:
    """Eksergian's equation on loopcheck.kinematics' plain arrays (see the module docstring)."""
    mech = scene.mechanism
    linkage = mech.linkage
    system = loops.compile_linkage(linkage)
    bodies = linkage.body_map
    mass = np.array([bodies[b].mass for b in linkage.moving])
    inertia = np.array([bodies[b].inertia for b in linkage.moving])
    n_bodies = len(linkage.moving)
    gravity = np.zeros(2) if scene.gravity is None else np.asarray(scene.gravity, dtype=float)

    def ends(element):
        return system.point_index(element.body_a, element.point_a), system.point_index(element.body_b, element.point_b)

    springs = [(ends(s), s.coefficient, s.rest_length) for s in mech.springs]
    dampers = [(ends(d), d.coefficient) for d in mech.dampers]
    forces = [(system.point_index(p.body, p.point), np.array([math.cos(p.direction), math.sin(p.direction)]),
               TabulatedForce(p.coordinate, p.values, p.period)) for p in mech.point_forces]
    load = scene.load if scene.load is not None else (lambda t: 0.0)  # T(t) (N·m) or F(t) (N)
    last = {"x": np.asarray(scene.x0, dtype=float), "K": None, "L": None, "q": scene.q0}

    def f(t: float, q: float, qdot: float) -> float:
        x, K, L = last["x"], last["K"], last["L"]
        if K is not None:  # predictor, as the engine's chart does
            dq = q - last["q"]
            x = x + K * dq + 0.5 * L * dq * dq
        x = loops.assemble(system, q, x)
        K, L = loops.coefficients(system, x)
        last.update(x=x, K=K, L=L, q=q)
        kc, lc = loops.rates(system.centres, x, K, L)
        ka = K[:n_bodies]
        J = float(mass @ np.einsum("ij,ij->i", kc, kc) + inertia @ (ka * ka))
        zeta = float(mass @ np.einsum("ij,ij->i", kc, lc) + inertia @ (ka * L[:n_bodies]))
        Q = load(t) + float(mass @ (kc @ gravity))
        if springs or dampers or forces:
            r = loops.positions(system.points, x)
            kr, _ = loops.rates(system.points, x, K)
            for (a, b), k, rest in springs:
                d = r[b] - r[a]
                length = math.hypot(d[0], d[1])
                Q -= k * (length - rest) * float(d @ (kr[b] - kr[a])) / length
            for (a, b), c in dampers:
                d = r[b] - r[a]
                rate = float(d @ (kr[b] - kr[a])) / math.hypot(d[0], d[1])
                Q -= c * rate * rate * qdot
            for i, direction, table in forces:
                Q += table(q) * float(direction @ kr[i])
        return (Q - zeta * qdot * qdot) / J

    return f


def time_per_call(f: F, scene, calls: int, repeats: int) -> tuple[float, float]:
    """(best seconds per call, f at the last point) along the path of the module docstring."""
    step = scene.qdot0 * 1e-6 if scene.qdot0 else 1e-5
    qs = [scene.q0 + step * (k % 200 if k % 400 < 200 else 200 - k % 200) for k in range(calls)]
    qdot = scene.qdot0

    def run():
        for k, q in enumerate(qs):
            f(k * 1e-7, q, qdot)

    best = min(timeit.repeat(run, number=1, repeat=repeats)) / calls
    return best, f(0.0, scene.q0, qdot)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    rows = [("seed_fourbar (shorthand)", load_scene(default_scene_path()))]
    rows += [(p.stem, load_scene(p)) for p in CATALOGUE]
    print(f"time per f-evaluation (µs), best of {args.repeats} × {args.calls} calls along a short path")
    print(f"{'scene':32s} {'bodies':>6s} {'loops':>5s} {'closed form':>12s} {'engine':>12s} {'loops':>12s}  f (closed form / engine / loops)")
    notes = []
    for label, scene in rows:
        cells, values = [], []
        linkage = scene.mechanism.linkage
        for build in (closed_form_f, engine_f, loops_f):
            try:
                seconds, value = time_per_call(build(scene), scene, args.calls, args.repeats)
            except Exception as exc:  # an engine not yet ported to general linkages
                cells.append("n/a")
                values.append(None)
                if build is not closed_form_f or scene.four_bar is not None:
                    notes.append(f"  {label}: {build.__name__} not available: {type(exc).__name__}: {exc}"[:160])
                continue
            cells.append(f"{seconds * 1e6:.1f}")
            values.append(value)
        shown = " / ".join("-" if v is None else f"{v:.12g}" for v in values)
        print(f"{label:32s} {len(linkage.moving):6d} {len(linkage.cut_joints):5d} "
              f"{cells[0]:>12s} {cells[1]:>12s} {cells[2]:>12s}  {shown}")
    print("f at (t, q, q̇) = (0, q0, q̇0): rad/s² or m/s²; every row must agree")
    print("\n".join(notes))


if __name__ == "__main__":
    main()
