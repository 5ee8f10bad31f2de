"""The two catalogue scenes of several inputs added by issue 41, described for the multibody oracle
(:mod:`oracles.multibody`) from their own physics (the numbers of the scenes' files, not their
loopcheck objects): the adaptive finger (scenes/mechanisms/adaptive_finger.toml) and the 3-RRR
planar parallel manipulator (scenes/mechanisms/three_rrr.toml). Each one's inputs, in the scene's
order, are angles the oracle reads from its own coordinates: a body's angle, or a pin's relative
angle θ_b − θ_a. Not shipped."""

from __future__ import annotations

import math

import numpy as np

from oracles.multibody import GROUND, Body, Model, Pin, Torque, TorsionSpring, integrate, pulse


def finger(spring_sign: float = 1.0) -> Model:
    """The adaptive finger: palm pivots O (0, 0) and D (0, −0.02); driver 2 cm, coupler 2.6 cm,
    proximal phalanx 5 cm, distal phalanx with the lever E (−5, −15) mm behind its joint J; a
    torsion spring 0.02 N·m/rad on J (rest 0); the motor's −2 mN·m over [0, 0.1) s on D; no gravity.
    ``spring_sign`` −1 is a plant (a spring that pushes away from its rest)."""
    return Model(
        bodies=(Body("driver", 0.008, (0.01, 0.0), 4.0e-7), Body("coupler", 0.005, (0.013, 0.0), 3.5e-7),
                Body("proximal", 0.03, (0.025, 0.0), 7.0e-6), Body("distal", 0.02, (0.016, -0.002), 2.6e-6)),
        pins=(Pin("D", GROUND, (0.0, -0.02), "driver", (0.0, 0.0)),
              Pin("C", "driver", (0.02, 0.0), "coupler", (0.0, 0.0)),
              Pin("E", "coupler", (0.026, 0.0), "distal", (-0.005, -0.015)),
              Pin("J", "proximal", (0.05, 0.0), "distal", (0.0, 0.0)),
              Pin("O", GROUND, (0.0, 0.0), "proximal", (0.0, 0.0))),
        torques=(Torque("D", pulse(-0.002, 0.0, 0.1)),),
        springs=(TorsionSpring("J", spring_sign * 0.02, 0.0),),
        gravity=0.0, edges=(0.1,))


FINGER_INPUTS = ("D", "J")  # the driver's angle (pin D's, from the ground), J's relative angle
FINGER_GUESS = {"driver": -0.3, "coupler": 0.2, "proximal": 0.0, "distal": 0.0}


def three_rrr() -> Model:
    """The 3-RRR: ground pivots A_k at the corners of an equilateral triangle of circumradius 0.3 m
    (at 90°, 210°, 330°), cranks 0.15 m (0.6 kg), distal links 0.2 m (0.4 kg), a platform of
    circumradius 0.06 m (0.8 kg) with its corners B_k at the same bearings; motor pulses 0.6 N·m
    over [0, 0.2), −0.4 N·m over [0.05, 0.25), 0.3 N·m over [0.1, 0.25) s; no gravity."""
    bodies, pins = [], []
    for k in range(3):
        bearing = math.radians(90.0 + 120.0 * k)
        corner = (0.3 * math.cos(bearing), 0.3 * math.sin(bearing))
        apex = (0.06 * math.cos(bearing), 0.06 * math.sin(bearing))
        bodies += [Body(f"crank{k + 1}", 0.6, (0.075, 0.0), 1.2e-3), Body(f"link{k + 1}", 0.4, (0.1, 0.0), 1.4e-3)]
        pins += [Pin(f"A{k + 1}", GROUND, corner, f"crank{k + 1}", (0.0, 0.0)),
                 Pin(f"C{k + 1}", f"crank{k + 1}", (0.15, 0.0), f"link{k + 1}", (0.0, 0.0)),
                 Pin(f"B{k + 1}", f"link{k + 1}", (0.2, 0.0), "platform", apex)]
    bodies.append(Body("platform", 0.8, (0.0, 0.0), 1.5e-3))
    return Model(bodies=tuple(bodies), pins=tuple(pins),
                 torques=(Torque("A1", pulse(0.6, 0.0, 0.2)), Torque("A2", pulse(-0.4, 0.05, 0.2)),
                          Torque("A3", pulse(0.3, 0.1, 0.15))),
                 gravity=0.0, edges=(0.05, 0.1, 0.2, 0.25))


RRR_INPUTS = ("A1", "A2", "A3")
RRR_GUESS = {"crank1": -0.59, "link1": -2.24, "crank2": 1.5, "link2": -0.15, "crank3": -2.68, "link3": 1.94,
             "platform": 0.0}


def inputs(model: Model, names, guess: dict, q0, qdot0, times, rtol: float):
    """Every input's (q, q̇) at ``times`` (sorted) from the inputs' q0 and q̇0 (the angles of the
    pins named: a crank's from the ground, a joint's relative angle), by name; the run at ``rtol``
    (its energy balance); and the oracle's accuracy on these inputs: the largest differences of
    their angles (rad) and rates (rad/s) from the run at rtol / 2."""
    y0, yd0 = model.assemble(guess, dict(zip(names, q0)), dict(zip(names, qdot0)))
    times = np.asarray(times, dtype=float)
    run, half = integrate(model, y0, yd0, times, rtol), integrate(model, y0, yd0, times, rtol / 2.0)

    def angles(r):
        return {name: (r.q @ model.angle_row(name), r.qd @ model.angle_row(name)) for name in names}

    out, other = angles(run), angles(half)
    accuracy = (max(float(np.max(np.abs(out[n][0] - other[n][0]))) for n in names),
                max(float(np.max(np.abs(out[n][1] - other[n][1]))) for n in names))
    return out, run, accuracy
