"""Seeded generator of valid scenes a mechanism engineer would write, for loopcheck's own gate.

The project's rule (issue 24): loopcheck's own defaults must pass loopcheck's own gate on every valid
scene. This module draws such scenes from a seeded random generator, in both scene forms:

- ``four_bar``: the shorthand ``[linkage] type = "four_bar"``, Grashof (crank-rocker,
  drag-link) and non-Grashof (a crank that swings), with line dampers and springs to ground
  and joint dampers and springs;
- ``slider_crank``: ``type = "planar"``, an offset slider-crank driven by a crank torque
  (optionally with a gas-like force table over crank angle) or by a force on the slider;
- ``watt2`` and ``stephenson3``: ``type = "planar"`` six-bars whose second dyad assembles over
  the whole crank turn, some of them near (0.05–1 % from) the dyad's toggle.

Each draw takes plausible numbers: link lengths 0.05–2 m, masses 0.1–50 kg (bars of
0.5–20 kg/m, inertia m L²/12), horizons 0.3–3 s, loads sized so that the input's speed stays
at a few to a few tens of rad/s; with or without gravity, springs, dampers, point forces
(over q, and timed), constant, pulse or table loads. The scene carries no ``[mujoco]`` table
and, in most draws, no ``[tolerances]`` (the defaults); some carry tolerances a user might
write. Assembly is computed here in closed form (dyad by dyad) and handed over as the exact
``initial.guess``; a draw that :func:`reduced.scene_from_dict` refuses for its assembly is
drawn again (any other refusal is a bug of the generator and raises).

Usage: ``python tests/valid_scenes.py OUTDIR [--seed S] [--n N]`` writes N TOML files (what
tests/compare/test_valid_scene_family.py runs through ``compare_engines``; the full draw was run through
``loopcheck check`` one file at a time).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from loopcheck.scene import SceneError
from loopcheck.scene_writer import toml_text
from loopcheck.scenefile import scene_from_dict

KINDS = ("four_bar", "four_bar_swing", "slider_crank", "slider_driven", "watt2", "stephenson3")
# six-bars started just before their dyad's near-toggle, turning towards it (not in KINDS: ask for them)
TOGGLE_KINDS = ("watt2_toggle", "stephenson3_toggle")
G = 9.81  # m/s²


# -- small geometry ---------------------------------------------------------------------

def _dyad(p1, r1, p2, r2, sign):
    """The point X with |X − p1| = r1 and |X − p2| = r2 on the side ``sign`` of p1→p2, or None."""
    d = math.dist(p1, p2)
    if d == 0.0 or d > r1 + r2 or d < abs(r1 - r2):
        return None
    a = (r1 * r1 - r2 * r2 + d * d) / (2 * d)
    h = math.sqrt(max(r1 * r1 - a * a, 0.0))
    ex, ey = (p2[0] - p1[0]) / d, (p2[1] - p1[1]) / d
    return (p1[0] + a * ex - sign * h * ey, p1[1] + a * ey + sign * h * ex)


def _angle(p, q):
    return math.atan2(q[1] - p[1], q[0] - p[0])


def _frame_point(origin, angle, local):
    c, s = math.cos(angle), math.sin(angle)
    return (origin[0] + c * local[0] - s * local[1], origin[1] + s * local[0] + c * local[1])


def _r(x, digits=5):
    """A number as an engineer writes it (5 significant digits)."""
    return float(f"{x:.{digits}g}")


def _bar(rng, length, *, com=None):
    """Mass properties of a bar of ``length`` (m): 0.5–20 kg/m, clipped to 0.1–50 kg."""
    mass = _r(min(max(rng.uniform(0.5, 20.0) * length, 0.1), 50.0), 3)
    inertia = _r(mass * length ** 2 / 12 * rng.uniform(1.0, 1.5), 4)
    return {"mass": mass, "com": com if com is not None else [_r(length / 2), _r(rng.uniform(-0.05, 0.05) * length)],
            "inertia": inertia}


def _profile(rng, scale, horizon, *, kind=None):
    """A load profile (constant, pulse or table) of magnitude ~``scale`` over the horizon."""
    kind = kind or rng.choice(["constant", "pulse", "table"])
    sign = float(rng.choice([-1.0, 1.0]))
    if kind == "constant":
        return {"type": "constant", "value": _r(sign * scale)}
    if kind == "pulse":
        start = _r(rng.choice([0.0, rng.uniform(0.0, 0.3) * horizon]), 3)
        return {"type": "pulse", "value": _r(sign * scale), "start": start,
                "duration": _r(rng.uniform(0.2, 0.7) * horizon, 3)}
    n = int(rng.integers(3, 6))
    times = sorted({_r(t, 3) for t in rng.uniform(0.05, 0.9, n - 1) * horizon})
    values = [_r(sign * scale * v) for v in rng.uniform(-0.5, 1.0, len(times) + 1)]
    return {"type": "table", "times": [0.0] + times, "values": values}


def _tolerances(rng):
    """Most draws keep the defaults; some carry tolerances a user might write."""
    u = rng.uniform()
    if u < 0.7:
        return None
    if u < 0.85:
        return {"peak_omega_rtol": 1e-3, "q_atol": 1e-2, "omega_atol": 0.5}
    return {"peak_omega_rtol": 1e-4, "q_atol": 1e-4, "omega_atol": 1e-2}


# -- the four-bar shorthand ----------------------------------------------------------------

def _four_bar_lengths(rng, grashof: bool):
    while True:
        c4 = rng.uniform(0.1, 1.5)
        c1, c2, c3 = rng.uniform(0.15, 0.45) * c4, rng.uniform(0.6, 1.6) * c4, rng.uniform(0.5, 1.4) * c4
        if not grashof:
            c1 = rng.uniform(0.6, 1.3) * c4
        lengths = [c1, c2, c3, c4]
        if max(lengths) > 2.0 or min(lengths) < 0.05:
            continue
        s, l = min(lengths), max(lengths)
        is_grashof = s + l < sum(lengths) - s - l - 0.02 * c4
        if grashof and is_grashof and s == c1:
            return [_r(v, 3) for v in lengths]
        if not grashof and s + l > sum(lengths) - s - l + 0.02 * c4:
            return [_r(v, 3) for v in lengths]


def _four_bar(rng, swing: bool) -> dict:
    c1, c2, c3, c4 = _four_bar_lengths(rng, grashof=not swing)
    gravity = rng.uniform() < 0.5
    horizon = _r(rng.uniform(0.3, 3.0), 2)
    lo, hi = abs(c2 - c3), c2 + c3
    qs = [q for q in np.linspace(0.0, 2 * np.pi, 721, endpoint=False)
          if lo + 0.05 * c4 < math.hypot(c1 * math.cos(q) - c4, c1 * math.sin(q)) < hi - 0.05 * c4]
    q0 = _r(float(rng.choice(qs)), 4)
    coupler = _bar(rng, c2)
    rocker = _bar(rng, c3)
    if gravity or rng.uniform() < 0.5:
        crank = _bar(rng, c1)
        crank["pivot_inertia"] = _r(crank.pop("inertia") + crank["mass"] * (c1 / 2) ** 2 + rng.uniform(0, 0.05), 4)
    else:
        crank = {"pivot_inertia": _r(rng.uniform(0.002, 0.5), 3)}
    J = crank["pivot_inertia"] + (coupler["mass"] * c1 ** 2) + rocker["inertia"] + rocker["mass"] * c3 ** 2 / 4
    w = rng.uniform(3.0, 30.0)  # the speed (rad/s) the load is sized for
    data = {"name": "fourbar_swing" if swing else "fourbar", "linkage": {
        "type": "four_bar", "c1": c1, "c2": c2, "c3": c3, "c4": c4, "branch": int(rng.choice([-1, 1]))},
        "bodies": {"crank": crank, "coupler": coupler, "rocker": rocker}}
    if gravity:
        data["gravity"] = [0.0, -G]
    data["torque"] = _profile(rng, _r(J * w / min(horizon, 1.0) * rng.uniform(0.3, 1.5), 3), horizon)
    if rng.uniform() < 0.6:
        data["dampers"] = [{"coefficient": _r(J * rng.uniform(1.0, 10.0) / c3 ** 2, 3),
                            "ground_point": [_r(c4 * rng.uniform(0.8, 1.3)), _r(c4 * rng.uniform(-0.3, 0.5))],
                            "body": str(rng.choice(["coupler", "rocker"])), "body_point": [_r(c3 * 0.8), 0.0]}]
    if rng.uniform() < 0.4:
        rest = _r(c4 * rng.uniform(0.3, 0.8))
        data["springs"] = [{"stiffness": _r(J * rng.uniform(20.0, 400.0) / c3 ** 2, 3), "rest_length": rest,
                            "ground_point": [_r(c4 * rng.uniform(0.0, 1.0)), _r(-c4 * rng.uniform(0.2, 0.6))],
                            "body": "rocker", "body_point": [c3, 0.0]}]
    if rng.uniform() < 0.3:
        data["joint_dampers"] = [{"joint": str(rng.choice(["A", "B", "O3"])),
                                  "coefficient": _r(J * rng.uniform(0.5, 5.0), 3)}]
    if rng.uniform() < 0.2:
        data["joint_springs"] = [{"joint": "O3", "stiffness": _r(J * rng.uniform(10.0, 200.0), 3),
                                  "rest_angle": _r(rng.uniform(0.5, 2.5), 3)}]
    data["initial"] = {"q": q0, "qdot": 0.0 if swing or rng.uniform() < 0.5 else _r(rng.uniform(-1, 1) * w, 3)}
    data["simulation"] = {"horizon": horizon}
    return data


# -- slider-crank ----------------------------------------------------------------------------

def _slider_crank(rng, slider_input: bool) -> dict:
    r = _r(rng.uniform(0.02, 0.3), 3)
    l = _r(r * rng.uniform(2.5, 5.0), 3)
    e = _r(r * rng.uniform(-0.3, 0.3), 3)
    gravity = rng.uniform() < 0.4
    horizon = _r(rng.uniform(0.3, 3.0), 2)
    while True:
        theta = float(rng.uniform(0.0, 2 * math.pi))
        # away from the dead centres (crank and rod collinear) for a slider input
        if not slider_input or abs(math.sin(theta + math.asin((e - r * math.sin(theta)) / l))) > 0.3:
            break
    theta = _r(theta, 4)
    A = (r * math.cos(theta), r * math.sin(theta))
    s = A[0] + math.sqrt(l * l - (e - A[1]) ** 2)
    rod_angle = _angle(A, (s, e))
    rod = _bar(rng, l, com=[_r(l * rng.uniform(0.25, 0.4)), 0.0])
    piston = {"points": {"pin": [0.0, 0.0]}, "mass": _r(rng.uniform(0.1, 5.0) * r / 0.05 if r < 0.1 else rng.uniform(1, 20), 3),
              "com": [0.0, 0.0], "inertia": 1e-3}
    flywheel = _r(rng.uniform(0.002, 0.5) * (r / 0.05) ** 2, 3)
    crank = {"points": {"O": [0.0, 0.0], "A": [r, 0.0]}}
    if gravity:
        crank.update(mass=_r(flywheel / r ** 2 * 0.2, 3), com=[0.0, 0.0], inertia=flywheel)
    else:
        crank.update(pivot_inertia=flywheel, pivot="O")
    rod["points"] = {"A": [0.0, 0.0], "P": [l, 0.0]}
    data = {"name": "slider_driven" if slider_input else "slider_crank", "linkage": {
        "type": "planar", "input": "cyl" if slider_input else "O"},
        "bodies": {"ground": {"points": {"O": [0.0, 0.0], "cyl": [0.0, e], "S": [_r(r + l * 1.5), e]}},
                   "crank": crank, "rod": rod, "piston": piston},
        "joints": [{"name": "O", "type": "revolute", "a": "ground.O", "b": "crank.O"},
                   {"name": "A", "type": "revolute", "a": "crank.A", "b": "rod.A"},
                   {"name": "P", "type": "revolute", "a": "rod.P", "b": "piston.pin"},
                   {"name": "cyl", "type": "prismatic", "a": "ground.cyl", "direction": 0.0, "b": "piston.pin"}]}
    if gravity:
        data["gravity"] = [0.0, -G]
    J = flywheel + (rod["mass"] + piston["mass"]) * r ** 2
    w = rng.uniform(5.0, 40.0)  # crank speed (rad/s) the loads are sized for
    if slider_input:
        data["force"] = _profile(rng, _r(J * w / min(horizon, 1.0) / r * rng.uniform(0.3, 1.0), 3), horizon,
                                 kind=str(rng.choice(["constant", "pulse"])))
        q0, qdot0 = _r(s, 6), 0.0
        data["initial"] = {"q": q0, "qdot": qdot0, "guess": {"crank": theta, "rod": _r(rod_angle, 4)}}
        # the input is s: q0 is rounded, so the guess gives the crank; the loop closes from it
    else:
        data["torque"] = _profile(rng, _r(J * w / min(horizon, 1.0) * rng.uniform(0.3, 1.0), 3), horizon)
        if rng.uniform() < 0.5:  # a gas-like force over crank angle, repeating every turn
            qs = [_r(v, 4) for v in np.linspace(0.0, 2 * math.pi, 13)[:-1]]
            peak = J * w * w / r * rng.uniform(0.05, 0.3)
            values = [_r(peak * max(math.cos(v / 2), 0.0) ** 4 + 0.02 * peak, 4) for v in qs]
            data["point_forces"] = [{"name": "gas", "point": "piston.pin", "direction": math.pi,
                                     "q": qs, "values": values, "period": 2 * math.pi}]
        data["initial"] = {"q": theta, "qdot": _r(rng.choice([0.0, rng.uniform(0.3, 1.0) * w]), 3),
                           "guess": {"rod": _r(rod_angle, 4), "cyl": _r(s, 4)}}
    if rng.uniform() < 0.5:
        data["dampers"] = [{"a": "ground.S", "b": "piston.pin",
                            "coefficient": _r(J * rng.uniform(1.0, 10.0) / r ** 2, 3)}]
    if rng.uniform() < 0.3:
        data["springs"] = [{"a": "ground.S", "b": "piston.pin", "stiffness": _r(J * rng.uniform(20, 300) / r ** 2, 3),
                            "rest_length": _r(l * 1.5 - r + rng.uniform(-0.5, 0.5) * r)}]
    if rng.uniform() < 0.3:
        data["joint_dampers"] = [{"joint": "O", "coefficient": _r(J * rng.uniform(0.5, 3.0), 3)}]
    if rng.uniform() < 0.3:
        data["timed_forces"] = [{"point": "piston.pin", "direction": math.pi,
                                 **_profile(rng, _r(J * w / r * rng.uniform(0.2, 1.0), 3), horizon,
                                            kind=str(rng.choice(["pulse", "table"])))}]
    data["simulation"] = {"horizon": horizon}
    return data


# -- six-bars ----------------------------------------------------------------------------------

def _six_bar(rng, kind: str, near_toggle: bool, approach: bool = False) -> dict | None:
    """Watt II (second dyad on the rocker) or Stephenson III (on the coupler) with a Grashof
    crank-rocker first loop; None when the draw's second dyad cannot be placed. ``approach``:
    the crank starts 0.15–0.6 rad before the angle of the dyad's near-toggle and turns towards
    it (a positive constant torque and speed), so that the run passes it."""
    scale = rng.uniform(0.15, 1.0)
    a, b, c, g = _four_bar_lengths(rng, grashof=True)
    k = scale / g
    a, b, c, g = (_r(v * k, 4) for v in (a, b, c, g))
    if min(a, b, c, g) < 0.03:
        return None
    O2, O4 = (0.0, 0.0), (g, 0.0)
    sign1 = int(rng.choice([-1, 1]))
    host_len = b if kind == "stephenson3" else c
    C_local = (_r(host_len * rng.uniform(0.2, 0.8), 4), _r(host_len * rng.uniform(0.2, 0.6) * rng.choice([-1, 1]), 4))
    O6 = (_r(g * rng.uniform(0.3, 1.8), 4), _r(g * rng.uniform(0.4, 1.2) * rng.choice([-1, 1]), 4))

    def pose(theta):
        A = (a * math.cos(theta), a * math.sin(theta))
        B = _dyad(A, b, O4, c, sign1)
        if B is None:
            return None
        host_origin, host_angle = (A, _angle(A, B)) if kind == "stephenson3" else (O4, _angle(O4, B))
        return A, B, _frame_point(host_origin, host_angle, C_local)

    thetas = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    poses = [pose(t) for t in thetas]
    if any(p is None for p in poses):
        return None
    d = [math.dist(p[2], O6) for p in poses]
    dmin, dmax = min(d), max(d)
    total = dmax * (1 + (rng.uniform(0.0005, 0.01) if near_toggle else rng.uniform(0.1, 0.5)))
    diff = rng.uniform(0.0, 0.7) * dmin
    l5, l6 = _r((total + diff) / 2, 5), _r((total - diff) / 2, 5)
    if near_toggle:  # keep the gap after rounding
        l6 = _r(dmax * (1 + rng.uniform(0.0005, 0.01)) - l5, 5)
    if not (abs(l5 - l6) < dmin * 0.97 and l5 + l6 > dmax * 1.0003) or min(l5, l6) < 0.05 or max(l5, l6) > 2.0:
        return None
    sign2 = int(rng.choice([-1, 1]))
    theta0 = _r(float(rng.uniform(0, 2 * math.pi)), 4)
    if approach:
        theta0 = _r(float(thetas[int(np.argmax(d))] - rng.uniform(0.15, 0.6)), 4)
    A, B, C = pose(theta0)
    D = _dyad(C, l5, O6, l6, sign2)
    gravity = rng.uniform() < 0.5
    horizon = _r(rng.uniform(0.3, 3.0) if not near_toggle else rng.uniform(0.3, 1.5), 2)
    host = "coupler" if kind == "stephenson3" else "rocker"
    bodies = {
        "ground": {"points": {"O2": [0.0, 0.0], "O4": [g, 0.0], "O6": list(O6),
                              "R": [_r(O6[0] + l6 * 0.8), _r(O6[1] + 0.5 * l6)]}},
        "crank": {"points": {"O2": [0.0, 0.0], "A": [a, 0.0]}},
        "coupler": {"points": {"A": [0.0, 0.0], "B": [b, 0.0]}},
        "rocker": {"points": {"O4": [0.0, 0.0], "B": [c, 0.0]}},
        "link": {"points": {"C": [0.0, 0.0], "D": [l5, 0.0]}},
        "output": {"points": {"O6": [0.0, 0.0], "D": [l6, 0.0]}},
    }
    bodies[host]["points"]["C"] = list(C_local)
    for name, length in (("coupler", b), ("rocker", c), ("link", l5), ("output", l6)):
        bodies[name].update(_bar(rng, length))
    flywheel = _r(rng.uniform(0.005, 0.3) * scale ** 2, 3)
    if gravity:
        m = _bar(rng, a)
        bodies["crank"].update(mass=m["mass"], com=[_r(a / 2), 0.0], inertia=_r(m["inertia"] + flywheel, 4))
    else:
        bodies["crank"].update(pivot_inertia=flywheel, pivot="O2")
    names = ("O2", "A", "B", "O4", "C", "D", "O6")
    pairs = (("ground.O2", "crank.O2"), ("crank.A", "coupler.A"), ("coupler.B", "rocker.B"),
             ("ground.O4", "rocker.O4"), (f"{host}.C", "link.C"), ("link.D", "output.D"),
             ("ground.O6", "output.O6"))
    data = {"name": f"{kind}{'_near_toggle' if near_toggle else ''}", "linkage": {"type": "planar", "input": "O2"},
            "bodies": bodies,
            "joints": [{"name": n, "type": "revolute", "a": p, "b": q} for n, (p, q) in zip(names, pairs)]}
    if gravity:
        data["gravity"] = [0.0, -G]
    J = flywheel + sum(bodies[n]["mass"] * a ** 2 for n in ("coupler", "link")) + 0.3 * bodies["output"]["mass"] * l6 ** 2
    w = rng.uniform(3.0, 20.0)
    data["torque"] = _profile(rng, _r(J * w / min(horizon, 1.0) * rng.uniform(0.3, 1.0), 3), horizon)
    if approach:
        data["torque"] = {"type": "constant", "value": abs(data["torque"].get("value", 1.0) or 1.0)}
    if rng.uniform() < 0.6:
        data["dampers"] = [{"a": "ground.R", "b": "output.D", "coefficient": _r(J * rng.uniform(1.0, 10.0) / l6 ** 2, 3)}]
    if rng.uniform() < 0.4:
        rest = _r(math.dist(bodies["ground"]["points"]["R"], D) * rng.uniform(0.7, 1.0))
        data["springs"] = [{"a": "ground.R", "b": "output.D", "stiffness": _r(J * rng.uniform(20, 300) / l6 ** 2, 3),
                            "rest_length": rest}]
    if rng.uniform() < 0.25:
        data["joint_springs"] = [{"joint": "O6", "stiffness": _r(J * rng.uniform(5.0, 50.0), 3),
                                  "rest_angle": _r(_angle(O6, D), 3)}]
    if rng.uniform() < 0.25:
        data["timed_forces"] = [{"point": "link.D", "direction": _r(rng.uniform(0, 2 * math.pi), 3),
                                 **_profile(rng, _r(J * w / l6 * rng.uniform(0.2, 1.0), 3), horizon,
                                            kind=str(rng.choice(["pulse", "table"])))}]
    qdot0 = _r(rng.choice([0.0, rng.uniform(0.5, 1.0) * w]), 3)
    if approach:
        qdot0 = _r(rng.uniform(0.5, 1.0) * w, 3)
    data["initial"] = {"q": theta0, "qdot": qdot0,
                       "guess": {"coupler": _r(_angle(A, B), 5), "rocker": _r(_angle(O4, B), 5),
                                 "link": _r(_angle(C, D), 5), "output": _r(_angle(O6, D), 5)}}
    data["simulation"] = {"horizon": horizon}
    if approach:
        toggle = float(thetas[int(np.argmax(d))])
        data["description"] = (f"dyad C-D-O6 {100 * (l5 + l6 - dmax) / dmax:.2g} % longer than its reach: "
                               f"near its toggle at q = {toggle:.6f} rad")
    return data


# -- the family ----------------------------------------------------------------------------

def draw(rng, kind: str) -> dict | None:
    """One scene of ``kind`` (one of KINDS) as parsed TOML data, or None for a draw to redo."""
    if kind == "four_bar":
        data = _four_bar(rng, swing=False)
    elif kind == "four_bar_swing":
        data = _four_bar(rng, swing=True)
    elif kind in ("slider_crank", "slider_driven"):
        data = _slider_crank(rng, slider_input=kind == "slider_driven")
    elif kind.endswith("_toggle"):
        data = _six_bar(rng, kind.removesuffix("_toggle"), near_toggle=True, approach=True)
    else:
        data = _six_bar(rng, kind, near_toggle=rng.uniform() < 0.35)
    if data is None:
        return None
    tolerances = _tolerances(rng)
    if tolerances:
        data["tolerances"] = tolerances
    return data


def generate(seed: int, n: int, kinds: tuple[str, ...] = KINDS) -> list[dict]:
    """``n`` valid scenes, the kinds in turn, from ``numpy.random.default_rng(seed)``; each
    named ``<kind>_<index>``. A draw whose linkage does not assemble at q0 (or sits at a dead
    centre) is drawn again."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        kind = kinds[len(out) % len(kinds)]
        data = draw(rng, kind)
        if data is None:
            continue
        try:
            scene_from_dict(data)
        except SceneError as exc:
            text = str(exc)
            if not any(w in text for w in ("assembl", "dead", "singular", "converge", "close")):
                raise
            continue
        data["name"] = f"{data['name']}_{len(out):02d}"
        out.append(data)
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("outdir", type=Path)
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--n", type=int, default=42)
    p.add_argument("--toggle", action="store_true", help="only six-bars that pass near their toggle")
    args = p.parse_args(argv)
    args.outdir.mkdir(parents=True, exist_ok=True)
    for data in generate(args.seed, args.n, TOGGLE_KINDS if args.toggle else KINDS):
        (args.outdir / f"{data['name']}.toml").write_text(toml_text(data))


if __name__ == "__main__":
    main()
