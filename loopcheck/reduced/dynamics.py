"""Eksergian's equation for a one-DOF linkage, built only from the effects a scene declares.

    𝔍(x_i) ẍ_i + ζ(x_i) ẋ_i² + dV/dx_i = Q_i(t, x_i, ẋ_i)

    𝔍 = Σ m |K_G|² + I_G K_θ²
    ζ = ½ d𝔍/dx_i = Σ m K_G·L_G + I_G K_θ L_θ
    V = −Σ m g·r_G + Σ ½ k_s (D_s − D0_s)² + Σ ½ k_j (u_j − u0_j)²
    Q_i = load(t)·dq/dx_i + Σ F_p(q) e_p·K_P + Σ F_r(t) e_r·K_R − Σ b_d K_Dd² ẋ_i − Σ c_j K_uj² ẋ_i
          + Σ_a gear_a f_a K_la     (an actuator's force f_a on its transmission l_a, K_la = dl_a/dx_i:
                                     :class:`loopcheck.mechanism.Actuator`)

(D = |r_a − r_b| between a line element's points, K_D = dD/dx_i; u = row·x a joint element's
joint coordinate, relative angle or displacement, K_u = row·K: :class:`loopcheck.mechanism.JointElement`.)

x_i is the chart's independent coordinate (any joint coordinate: a body angle or a slider
displacement, :mod:`loopcheck.reduced.charts`); every K and L is a derivative with respect to it.
The input q = drive·x; dq/dx_i = drive·K. Units: with x_i an angle 𝔍, ζ in kg·m², dV/dx_i and
Q_i in N·m; with a displacement, kg and N.

The arithmetic is compiled (:mod:`loopcheck.reduced.kernels.physics`, one implementation for every
linkage); this module builds its arrays from a scene (:class:`MechanismModel`) and gives
Python callers the results as values (:class:`Kinematics`, :class:`Coefficients`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from loopcheck import kinematics as loops
from loopcheck.kinematics import Kinematics
from loopcheck.errors import NumericalFailure
from .kernels import physics
from .kernels.physics import Model
from loopcheck.loads import TabulatedForce
from loopcheck.scene import Scene


@dataclass(frozen=True)
class Coefficients:
    """The reduced model's coefficients at one configuration, with respect to the chart's
    coordinate x_i (rad or m)."""

    kinematics: Kinematics
    generalized_inertia: float  # 𝔍 (kg·m² or kg)
    centrifugal: float  # ζ
    potential_gradient: float  # dV/dx_i (N·m or N)
    damping: float  # Σ b K_D² (N·m·s or N·s/m)
    potential: float  # V (J)
    input_rate: float = 1.0  # dq/dx_i: 1 when the input q is the coordinate
    point_force: float = 0.0  # Σ F(q) e·K_P, the point forces' generalized force (N·m or N)

    def acceleration(self, load: float, rate: float) -> float:
        """ẍ_i from Eksergian's equation at coordinate rate ẋ_i and input load (N·m or N)."""
        Q = load * self.input_rate + self.point_force - self.damping * rate
        return (Q - self.centrifugal * rate * rate - self.potential_gradient) / self.generalized_inertia


def coefficients_from(fields: np.ndarray, kin: np.ndarray) -> Coefficients:
    """A :class:`Coefficients` value from a kernel's fields (N_FIELDS,) and kinematics (3, n)."""
    f = fields.tolist()
    return Coefficients(Kinematics(kin[0].copy(), kin[1].copy(), kin[2].copy()), f[physics.INERTIA],
                        f[physics.CENTRIFUGAL], f[physics.POTENTIAL_GRADIENT], f[physics.DAMPING],
                        f[physics.POTENTIAL], f[physics.INPUT_RATE], f[physics.POINT_FORCE])


def _splines(forces: tuple[TabulatedForce, ...]):
    """Each F(q) as a B-spline: knots, coefficients, degree, range and period."""
    out = []
    for f in forces:
        spline = f._spline
        if spline is None:  # two points: the straight line (a degree-1 B-spline)
            q0, q1 = f._knots[0], f._knots[-1]
            values = f.values if f.period is None else (f.values[0], f.values[0])
            knots, coef, k = np.array([q0, q0, q1, q1]), np.array(values[:2], dtype=float), 1
        else:
            knots, coef, k = spline.t, spline.c, spline.k
        out.append((np.asarray(knots, dtype=float), np.asarray(coef, dtype=float), int(k), float(f._knots[0]),
                    float(f._knots[-1]), float(f.period) if f.period is not None else 0.0))
    return out


def dyad_plans(n: int, loop_table, n_linear: int) -> tuple[list[int], list[int], list[float]]:
    """For each coordinate i as the chart's, a plan to close the loops by closed form
    (:func:`loopcheck.reduced.kernels.physics._dyads`): loops in an order where each has exactly two unknown
    angles and only fixed-length terms (an RRR dyad: four-bars, their chains, the squeezer's
    loops), or none (a slider's length, a linear row, a loop of more unknowns: Newton alone).
    Returns the first step of each plan (−1: none), the steps (loop, a, b) and their
    (W_a, W_b, φ_a, φ_b), φ the angle of W (rad): the closed form's constants. n_linear counts the
    linear rows and the couplings: a coupling is not a dyad, so with one there is no plan."""
    offset, w, row, mag, angle = loop_table
    # per loop of fixed-length terms: W_c = Σ w_t over its terms turning with angle c
    # (R(θ_c) W_c is their sum); loops with a slider's length take no part
    turning: dict[int, dict[int, np.ndarray]] = {}
    for k in range(len(offset)):
        terms = np.flatnonzero(row == k)
        if np.all(mag[terms] < 0):
            turning[k] = {int(c): w[terms[angle[terms] == c]].sum(axis=0) for c in set(angle[terms]) if c >= 0}
    plans, steps, weights = [], [], []
    for i in range(n):
        known, order = {i}, []
        while n_linear == 0 and len(order) < len(offset):
            ready = [(k, *sorted(set(W) - known)) for k, W in turning.items()
                     if k not in {o[0] for o in order} and len(set(W) - known) == 2]
            if not ready:
                break
            order.append(ready[0])
            known.update(ready[0][1:])
        if len(order) != len(offset) or known != set(range(n)):
            plans.append(-1)
            continue
        plans.append(len(steps) // 3)
        for k, a, b in order:
            steps += [k, a, b]
            wa, wb = turning[k][a], turning[k][b]
            weights += [*wa, *wb, math.atan2(wa[1], wa[0]), math.atan2(wb[1], wb[0])]
    return plans, steps, [float(v) for v in weights]


def piece_edges(scene: Scene) -> np.ndarray:
    """The edges (p+1,) of the run's load pieces, s: 0, every load edge inside the horizon
    (:attr:`loopcheck.scene.Scene.load_edges`), the horizon."""
    horizon = scene.horizon
    return np.array([0.0, *[b for b in scene.load_edges if 0.0 < b < horizon], horizon])


def piece_values(scene: Scene, edges: np.ndarray) -> np.ndarray:
    """The loads on each piece (p, 1 + timed forces): the input load (N·m or N; 0 without one),
    then each timed force's value (N), all constant on the piece (taken at its midpoint)."""
    mid = 0.5 * (edges[:-1] + edges[1:])
    columns = [np.array([float(scene.load.on_piece(a, b)(m)) for a, b, m in zip(edges[:-1], edges[1:], mid)])
               if scene.load is not None else np.zeros(len(mid))]
    columns += [np.asarray(f.profile.sample(mid), dtype=float) for f in scene.mechanism.timed_forces]
    return np.column_stack(columns)


def actuator_piece_values(scene: Scene, edges: np.ndarray) -> np.ndarray:
    """The actuators' state-independent force on each piece (p, actuators), N·m or N:
    gain·clamp(ctrl, ctrlrange) + b0, the control taken at the piece's midpoint."""
    mid = 0.5 * (edges[:-1] + edges[1:])
    acts = scene.mechanism.actuators
    out = np.zeros((len(mid), len(acts)))
    for k, a in enumerate(acts):
        out[:, k] = a.gain * a.control_values(mid) + a.bias[0]
    return out


def clamped_actuators(mechanism) -> tuple:
    """The actuators whose forcerange clamps a force that depends on the state (b1 or b2 nonzero):
    the clamp's switching is an event of the reduced engine (:meth:`physics.Chart.set_clamps`)."""
    return tuple(a for a in mechanism.actuators if a.forcerange is not None and a.state_dependent)


def ranged_joints(linkage) -> tuple:
    """The joints with a range, in the linkage's order: range r of the kernel is the r-th."""
    return tuple(j for j in linkage.joints if j.range is not None)


def build_arrays(scene: Scene, system: loops.LoopSystem) -> Model:
    """The kernel arrays of a scene (:mod:`loopcheck.reduced.kernels.physics` documents the layout, after
    the kinematics' of :mod:`loopcheck.kernels.loops`): only the effects it declares have rows."""
    mech = scene.mechanism
    linkage = mech.linkage
    bodies = linkage.body_map
    elements = list(mech.dampers) + list(mech.springs)
    ends = []
    for e in elements:
        ends += [system.point_index(e.body_a, e.point_a), system.point_index(e.body_b, e.point_b)]
    pf = mech.point_forces
    splines = _splines(tuple(TabulatedForce(p.coordinate, p.values, p.period) for p in pf))
    tf = mech.timed_forces
    packed, plans = _kinematic_tables(system, len(linkage.moving), ends,
                                      [system.point_index(p.body, p.point) for p in pf + tf])
    P = packed.copy()
    h = P.header
    h[physics.N_DAMPERS] = len(mech.dampers)
    h[physics.N_ELEMENTS], h[physics.N_FORCES] = len(elements), len(pf)
    h[physics.HAS_GRAVITY] = scene.gravity is not None
    h[physics.DRIVE] = P.float(system.drive)
    h[physics.MASSES] = P.float([bodies[b].mass for b in linkage.moving])
    h[physics.INERTIAS] = P.float([bodies[b].inertia for b in linkage.moving])
    g = np.asarray(scene.gravity if scene.gravity is not None else (0.0, 0.0), dtype=float)
    h[physics.GRAVITY] = P.float([g * (1.0 - bodies[b].gravcomp) for b in linkage.moving])  # each body's weight
    h[physics.ELEMENT_COEF] = P.float([e.coefficient for e in elements])
    h[physics.ELEMENT_REST] = P.float([e.rest_length for e in elements])
    h[physics.FORCE_DIR] = P.float([[math.cos(p.direction), math.sin(p.direction)] for p in pf])
    joint_elements = list(mech.joint_dampers) + list(mech.joint_springs) + list(mech.joint_inertias)
    h[physics.N_JOINT_ELEMENTS], h[physics.N_JOINT_DAMPERS] = len(joint_elements), len(mech.joint_dampers)
    h[physics.N_JOINT_INERTIAS] = len(mech.joint_inertias)
    h[physics.JOINT_ROWS] = P.float([system.joint_row(e.joint) for e in joint_elements])
    h[physics.JOINT_COEF] = P.float([e.coefficient for e in joint_elements])
    h[physics.JOINT_REST] = P.float([e.rest for e in joint_elements])
    frictions: dict[str, float] = {}  # the events' (physics.Chart.stop_margin): one per joint, f summed
    for e in mech.joint_frictions:
        frictions[e.joint] = frictions.get(e.joint, 0.0) + e.coefficient
    h[physics.N_FRICTION] = len(frictions)
    h[physics.FRICTION_ROWS] = P.float([system.joint_row(joint) for joint in frictions])
    h[physics.FRICTION_COEF] = P.float(list(frictions.values()))
    ranged = ranged_joints(linkage)
    h[physics.N_RANGES] = len(ranged)
    h[physics.RANGE_ROWS] = P.float([system.joint_row(j.name) for j in ranged])
    h[physics.RANGE_BOUNDS] = P.float([j.range for j in ranged])
    h[physics.N_TIMED] = len(tf)
    h[physics.TIMED_DIR] = P.float([[math.cos(p.direction), math.sin(p.direction)] for p in tf])
    h[physics.PIECE_VALUES] = P.float(piece_values(scene, piece_edges(scene)))
    h[physics.SPLINE_KNOTS] = P.float(np.concatenate([s[0] for s in splines]) if splines else [])
    h[physics.SPLINE_COEF] = P.float(np.concatenate([s[1] for s in splines]) if splines else [])
    h[physics.SPLINE_LO] = P.float([s[3] for s in splines])
    h[physics.SPLINE_HI] = P.float([s[4] for s in splines])
    h[physics.SPLINE_PERIOD] = P.float([s[5] for s in splines])
    h[physics.KNOT_START] = P.int(np.cumsum([0] + [len(s[0]) for s in splines]))
    h[physics.COEF_START] = P.int(np.cumsum([0] + [len(s[1]) for s in splines]))
    h[physics.SPLINE_DEGREE] = P.int([s[2] for s in splines])
    acts = mech.actuators
    h[physics.N_ACTUATORS] = len(acts)
    h[physics.ACT_ROWS] = P.float([sum(c * system.joint_row(j) for j, c in a.terms) for a in acts])
    h[physics.ACT_PARAMS] = P.float([[a.bias[1] * a.gear, a.bias[2] * a.gear, a.gear,
                                      *(a.forcerange if a.forcerange is not None else (-math.inf, math.inf))]
                                     for a in acts])
    h[physics.ACT_PIECE] = P.float(actuator_piece_values(scene, piece_edges(scene)))
    h[physics.N_CLAMPED] = len(clamped_actuators(mech))
    plans, steps, weights = plans
    h[physics.DYAD_PLAN], h[physics.DYAD_STEPS], h[physics.DYAD_W] = P.int(plans), P.int(steps), P.float(weights)
    return Model(*P.arrays())


def _kinematic_tables(system: loops.LoopSystem, n_moving: int, ends: list[int],
                      forces: list[int]) -> tuple[loops.Packer, tuple]:
    """The kinematics' tables (:mod:`loopcheck.kernels.loops`: LOOPS, then physics' CENTRES, ENDS
    of the elements' points ``ends``, FORCE_POINTS of the forces' points ``forces``) packed with
    the kinematics' header (:meth:`loopcheck.kinematics.Packer.kinematics`; copy the packer to
    append the rest), and the closed form's plans (:func:`dyad_plans`), made once per system,
    moving bodies and points (kept with the system, as its kernels are: a sweep's variants of one
    geometry share them; read-only arrays)."""
    cache = system.__dict__.setdefault("_physics_tables", {})
    key = (n_moving, tuple(ends), tuple(forces))
    if key not in cache:
        tables = (loops.kernel_table(system.loops), loops.kernel_table(system.centres),
                  loops.kernel_table(system.points, ends), loops.kernel_table(system.points, forces))
        for table in tables:
            for a in table:
                a.setflags(write=False)
        plans = dyad_plans(system.n, tables[0], len(system.linear) + len(system.coupling_rows))
        packed = loops.Packer(physics.HEADER)
        packed.kinematics(system.n, n_moving, tables, system.linear, system.couplings)
        for a in packed.F + packed.I[1:]:
            a.setflags(write=False)
        cache[key] = packed, plans
    return cache[key]


class MechanismModel:
    """Eksergian's equation for one scene, as compiled arrays (:attr:`arrays`).

    Parameters
    ----------
    scene : Scene
        The validated scene.
    """

    def __init__(self, scene: Scene):
        self.scene = scene
        self.system = loops.compile_linkage(scene.mechanism.linkage)
        self.effects: tuple[str, ...] = scene.effects
        self.load = scene.load
        # the edges of the load pieces (:func:`piece_edges`): the kernels' ``load`` is a piece's index
        self.piece_edges = piece_edges(scene)
        self.arrays = build_arrays(scene, self.system)
        self.x0 = np.array(scene.x0, dtype=float)
        drive = self.system.drive
        unit = np.flatnonzero(drive)
        # the input's coordinate, or None when q = θ_b − θ_a of two moving bodies
        self.input_coordinate = int(unit[0]) if len(unit) == 1 and drive[unit[0]] == 1.0 else None
        self.angle_columns = np.array([name.endswith(".angle") for name in self.system.coordinate_names])

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return self.system.coordinate_names

    def new_chart(self) -> physics.Chart:
        """An empty compiled chart of this model (:meth:`physics.Chart.start` starts it), with the
        singular-position threshold of :mod:`loopcheck.kinematics`."""
        return physics.Chart(self.arrays, loops.SINGULAR_CONDITIONING)

    def assemble(self, q: float) -> np.ndarray:
        """The configuration at input q (rad or m): the scene's own at q0, else Newton from it."""
        if q == float(self.system.drive @ self.x0):
            return self.x0.copy()
        return loops.assemble(self.system, q, self.x0)

    def coefficients_at(self, x, row: np.ndarray | None = None) -> Coefficients:
        """The coefficients at an assembled configuration x (shape (n,)) with respect to the
        input q (or to p = row·x): ½ 𝔍 q̇² is the kinetic energy there.

        Raises NumericalFailure(SINGULAR) where q cannot drive the linkage.
        """
        chart = self.new_chart()
        chart.S[physics.INDEPENDENT] = -1
        x = np.ascontiguousarray(x, dtype=float)
        row = np.ascontiguousarray(self.system.drive if row is None else row, dtype=float)
        if not chart.kinematics_at(x, row):
            raise NumericalFailure("singular", f"dead-centre position: the input coordinate cannot drive the "
                                               f"linkage at q = {self.system.drive @ x:.15g} {self.scene.input_unit}")
        views = chart.arrays()
        return coefficients_from(views["fields"], views["kin"])

    def coefficients(self, q: float) -> Coefficients:
        """The coefficients at input q (rad or m) on the scene's assembly, q the coordinate:
        the input's chart walked from the scene's configuration at q0 to q (Newton from x0
        alone, as :meth:`assemble` does, does not reach half a turn away)."""
        i = self.input_coordinate
        chart = self.new_chart()
        if i is None or not chart.start(np.ascontiguousarray(self.x0, dtype=float), i):
            return self.coefficients_at(self.assemble(q))
        if not chart.evaluate(float(q)):
            raise NumericalFailure("singular", f"the input's chart cannot be followed from q0 to q = {q:.15g} "
                                               f"{self.scene.input_unit}: a dead centre or an unreachable position")
        views = chart.arrays()
        return coefficients_from(views["fields"], views["kin"])

    def generalized_inertia(self, q: float) -> float:
        """𝔍(q) (kg·m² or kg)."""
        return self.coefficients(q).generalized_inertia

    def load_on_piece(self, start: float, end: float) -> Callable[[float], float]:
        """The input load on one smooth piece of its history (N·m or N), zero without one."""
        return self.load.on_piece(start, end) if self.load is not None else (lambda t: 0.0)

    @property
    def load_edges(self) -> tuple[float, ...]:
        """Times (s) where the applied loads jump: the input's and the timed forces'."""
        return self.scene.load_edges

