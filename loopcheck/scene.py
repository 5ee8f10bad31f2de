"""A scene's value types: what a user asks to simulate (no parsing, no engine).

Every length is in m, angle in rad, mass in kg, inertia in kg·m², torque in N·m, force in N,
damping in N·s/m, stiffness in N/m, time in s; the input coordinate q is an angle (rad) or a
slider displacement (m), as its joint says. The README documents the format; the parser is
:mod:`loopcheck.scenefile`, the mechanism description :mod:`loopcheck.mechanism`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

from .loads import LoadProfile
from .mechanism import Mechanism, PrismaticJoint


class SceneError(ValueError):
    """A scene that cannot be simulated; the message names the key and the reason."""


# ---------------------------------------------------------------------------
# Physical ranges
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Range:
    """Allowed magnitudes of one kind of quantity in a scene.

    A quantity that must be positive lies in [low, high]; a signed one (a coordinate, a
    torque) has |value| ≤ high, and ``low`` is 0.
    """

    kind: str
    unit: str
    low: float
    high: float
    why: str
    keys: tuple[str, ...] = ()  # the scene keys of this kind (the reference lists them; engines' steps add theirs)

    def __post_init__(self):
        if not 0.0 <= self.low < self.high < math.inf:
            raise ValueError(f"range of {self.kind}: need 0 ≤ low < high < inf, got [{self.low}, {self.high}]")

    def text(self) -> str:
        return f"[{self.low:g}, {self.high:g}] {self.unit}" if self.low else f"±{self.high:g} {self.unit}"


def _ranges(*items: Range) -> Mapping[str, Range]:
    return MappingProxyType({r.kind: r for r in items})


# One table for both engines. The bounds are wide (every shipped scene sits two or more decades
# inside each) and keep the arithmetic of validation finite: mass·|com|² ≤ 1e6·2e6 kg·m², the
# assembly discriminant is of order length⁴ ≤ 1e12 m⁴, spring energy k·D² ≤ 1e8·1e6 J.
LIMITS: Mapping[str, Range] = _ranges(
    Range("length", "m", 1e-3, 1e3, "link lengths c1…c4; lengths⁴ in the assembly discriminant stay ≤ 1e12",
          keys=("linkage.c1 … c4",)),
    Range("position", "m", 0.0, 1e3, "points, centres of mass and spring rest lengths",
          keys=("points", "com", "ground_point", "body_point", "rest_length", "rest_displacement",
                "initial.q (prismatic input)", "couplings.reference (prismatic joints)", "joints.range (prismatic)")),
    Range("mass", "kg", 1e-6, 1e6, "MuJoCo refuses a mass below mjMINVAL = 1e-15 kg; 1e-6 leaves nine decades",
          keys=("bodies.*.mass", "joint_inertias.inertia (prismatic)")),
    Range("inertia", "kg·m²", 1e-9, 1e6, "MuJoCo refuses an inertia below mjMINVAL = 1e-15 kg·m² (a pivot "
          "inertia becomes I_zz of a 1 kg point body); 1e-9 leaves six decades",
          keys=("inertia", "pivot_inertia", "pivot_inertia − mass·|com|²", "joint_inertias.inertia (revolute)")),
    Range("damping", "N·s/m", 1e-9, 1e7, "stiff_damper uses 1e6; the seed with 1e7 ran in 2.6 s (DOP853, 9675 steps)",
          keys=("dampers.coefficient", "joint_dampers.coefficient (prismatic)")),
    Range("stiffness", "N/m", 1e-9, 1e8, "a 1e8 N/m spring on a 1 kg·m² link at 1 m swings in 0.6 ms",
          keys=("springs.stiffness", "joint_springs.stiffness (prismatic)")),
    Range("rotational damping", "N·m·s/rad", 1e-9, 1e7, "a joint damper on a revolute joint: as a line damper "
          "of the same coefficient acting 1 m from the pin",
          keys=("joint_dampers.coefficient (revolute)",)),
    Range("rotational stiffness", "N·m/rad", 1e-9, 1e8, "a joint spring on a revolute joint: as a line spring "
          "of the same stiffness acting 1 m from the pin",
          keys=("joint_springs.stiffness (revolute)",)),
    Range("torque", "N·m", 0.0, 1e6, "fast_crank reaches ~1000 rad/s with 7300 N·m",
          keys=("torque.value(s)", "joint_frictions.friction (revolute)")),
    Range("force", "N", 0.0, 1e7, "a force on a slider, or a tabulated point force (a gas force of 1e5 N is a "
          "large engine's)",
          keys=("force.value(s)", "point_forces.values", "timed_forces.value(s)", "joint_frictions.friction (prismatic)")),
    Range("angle", "rad", 0.0, 1e3, "q0 is an angle; beyond a few turns it only loses digits",
          keys=("initial.q (revolute input)", "direction", "guessed angles", "rest_angle",
                "couplings.reference (revolute joints)", "joints.range (revolute)")),
    Range("speed", "rad/s", 0.0, 1e4, "q̇0; fast_crank peaks near 1000 rad/s, and the work grows with speed",
          keys=("initial.qdot",)),
    Range("time", "s", 0.0, 1e3, "torque start, duration and table times (s)",
          keys=("torque, timed-force and actuator-control start, duration, times",)),
    Range("horizon", "s", 1e-3, 1e3, "at MuJoCo's 1 ms default a 1000 s run is already 1e6 steps",
          keys=("simulation.horizon",)),
    Range("gravity", "m/s²", 0.0, 1e3, "about 100 g",
          keys=("gravity",)),
    Range("gravity compensation", "(× the body's weight)", 0.0, 100.0, "MuJoCo's body gravcomp, ≥ 0: 1 "
          "compensates the weight, above 1 the body floats up (buoyancy)", keys=("bodies.*.gravcomp",)),
    Range("actuator value", "(its own units)", 0.0, 1e9, "an actuator's gain, bias terms, gear, tendon coefficients, "
          "controls and ranges (units follow its transmission and control): wide, and keeps gain·ctrl + b1·L finite",
          keys=("actuators.gain", "actuators.bias", "actuators.gear", "actuators.tendon", "actuators.ctrlrange",
                "actuators.forcerange", "actuators.control value(s)")),
    Range("step", "s", 1e-6, 1.0, "an engine's time step (its settings' options of this kind, at most the horizon); "
          "the hard cases use 2e-5 to 1e-3"),
)
MAX_TABLE_ENTRIES = 10_000  # entries of a torque or point-force table
MAX_BODIES = 50  # moving bodies of a linkage (Andrews' squeezer has 7); each adds a Newton column
MAX_JOINTS = 2 * MAX_BODIES
MAX_ELEMENTS = 100  # dampers, springs (line and joint) and point forces (over q or t) together
MAX_NAME_CHARS = 100  # a scene name is printed, plotted and used in file listings
MAX_DESCRIPTION_CHARS = 1000
MAX_SCENE_BYTES = 1 << 20  # 1 MiB: a scene is a short text file (the seed is 2 kB)


# ---------------------------------------------------------------------------
# Values
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class FourBarGeometry:
    """Link lengths of the four-bar O1-A-B-O3 (m) and its assembly branch.

    ``branch`` is the sign of the ± in the seed's φ1 = 2 atan[(−A ± √(A²+B²−C²))/(C − B)];
    +1 puts B above the ground line O1O3 for the seed example.
    """

    c1: float
    c2: float
    c3: float
    c4: float
    branch: int


@dataclass(frozen=True)
class Tolerances:
    """Agreement tolerances between the engines (used by ``loopcheck check``).

    The peak passes when |Δ peak ω| ≤ peak_omega_rtol·|peak ω| + peak_omega_atol: the
    absolute floor keeps a relative figure of a motion that barely moves from judging
    round-off.
    """

    peak_omega_rtol: float = field(default=1e-4, metadata={
        "unit": "", "help": "relative difference allowed in the peak input speed"})
    peak_omega_atol: float = field(default=1e-9, metadata={
        "unit": "rad/s (m/s)", "help": "absolute floor of the peak's bound: |Δ peak| ≤ rtol·|peak| + atol"})
    q_atol: float = field(default=1e-3, metadata={
        "unit": "rad (m)", "help": "largest |Δq| of the input coordinate over the run"})
    omega_atol: float = field(default=1e-1, metadata={
        "unit": "rad/s (m/s)", "help": "largest |Δq̇| over the run"})
    omega_vs_q_atol: float | None = field(default=None, metadata={
        "unit": "rad/s (m/s)", "help": "largest |Δq̇| at equal input position (phase-free); not checked when "
                                       "absent"})

    def peak_bound(self, peak: float) -> float:
        """The largest |Δ peak ω| allowed for a peak of magnitude ``peak`` (rad/s)."""
        return self.peak_omega_rtol * peak + self.peak_omega_atol


@dataclass(frozen=True)
class Scene:
    """One simulation request: mechanism, loads, initial state and horizon.

    Parameters
    ----------
    mechanism : the linkage with its masses, dampers, springs and point forces.
    load : the generalized force on the input joint over time, a torque (N·m) on a
        revolute input or a force (N) on a prismatic one; None without one.
    gravity : (gx, gy) m/s², or None.
    q0, qdot0 : the input coordinate and its rate at t = 0 (rad or m; per s); with several
        inputs, the first input's.
    x0 : the configuration assembled at q0 (the coordinates of
        :class:`loopcheck.kinematics.LoopSystem`: body angles in rad, slider displacements in m).
    mode : its assembly mode, one sign per loop (:func:`loopcheck.kinematics.assembly_mode`).
    tolerances : the gate's tolerances: MuJoCo's, and every engine's where its own table does not
        say otherwise.
    engine_tolerances : each engine's own tolerances by engine name (``[tolerances.pin]``): the
        keys given, each already checked; a key not given is ``tolerances``' (:meth:`tolerances_for`).
    inputs_q0, inputs_qdot0 : with several inputs, every input's coordinate and rate at t = 0, in
        the linkage's inputs order (:attr:`loopcheck.mechanism.Linkage.inputs`), the first being q0
        and qdot0; empty with one input (:meth:`initial_q` gives both cases).
    engine_tables : the settings the scene asks each engine for, by engine name (its table of
        the scene file, ``[reduced]``, ``[mujoco]``): the keys given, each already checked.
    four_bar : the four-bar shorthand's geometry when the scene used it (enables the
        closed-form fast path, checked against the general one); else None.
    """

    name: str
    description: str
    mechanism: Mechanism
    load: LoadProfile | None
    gravity: tuple[float, float] | None
    q0: float
    qdot0: float
    x0: tuple[float, ...]
    mode: tuple[int, ...]
    horizon: float
    tolerances: Tolerances = field(default_factory=Tolerances)
    engine_tables: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    source: str = "<memory>"
    four_bar: FourBarGeometry | None = None
    engine_tolerances: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    inputs_q0: tuple[float, ...] = ()
    inputs_qdot0: tuple[float, ...] = ()

    def __post_init__(self):
        k = len(self.mechanism.linkage.inputs)
        q0s, qdot0s = tuple(map(float, self.inputs_q0)), tuple(map(float, self.inputs_qdot0))
        if k == 1 and (q0s or qdot0s):
            raise ValueError("inputs_q0 and inputs_qdot0 are for several inputs: one input's are q0 and qdot0")
        if k > 1 and (len(q0s) != k or len(qdot0s) != k or (q0s[0], qdot0s[0]) != (self.q0, self.qdot0)):
            raise ValueError(f"inputs_q0 and inputs_qdot0 need one value per input ({k}), the first q0 and qdot0; "
                             f"got {list(q0s)} and {list(qdot0s)}")
        object.__setattr__(self, "inputs_q0", q0s)
        object.__setattr__(self, "inputs_qdot0", qdot0s)
        keys = {f.name for f in dataclasses.fields(Tolerances)}
        for engine, given in self.engine_tolerances.items():
            unknown = sorted(set(given) - keys)
            if unknown:
                raise ValueError(f"engine_tolerances[{engine!r}]: {unknown[0]!r} is not a field of Tolerances")
        object.__setattr__(self, "engine_tolerances", MappingProxyType(
            {engine: MappingProxyType(dict(given)) for engine, given in self.engine_tolerances.items()}))

    def __reduce__(self):
        # The read-only views do not pickle (a scene is sent to worker processes).
        return (Scene, tuple({k: dict(v) for k, v in self.engine_tolerances.items()} if f.name == "engine_tolerances"
                             else getattr(self, f.name) for f in dataclasses.fields(self)))

    def tolerances_for(self, engine: str) -> Tolerances:
        """The tolerances the engine named ``engine`` is judged by against the reduced reference:
        its own table's keys (``[tolerances.ENGINE]``) over the scene's ``tolerances``."""
        return dataclasses.replace(self.tolerances, **self.engine_tolerances.get(engine, {}))

    def engine_table(self, engine: str) -> Mapping[str, Any]:
        """The settings this scene asks the engine ``engine`` for (its table of the scene file:
        the keys given, each checked on its own; the engine's ``Settings`` resolve them)."""
        return self.engine_tables.get(engine, {})

    @property
    def inputs(self) -> tuple[str, ...]:
        """The input joints, in order (one for a one-DOF linkage)."""
        return self.mechanism.linkage.inputs

    @property
    def dof(self) -> int:
        """The degrees of freedom: one per input."""
        return len(self.mechanism.linkage.inputs)

    def initial_q(self) -> tuple[float, ...]:
        """Every input's coordinate at t = 0 (rad or m), in the inputs' order."""
        return self.inputs_q0 or (self.q0,)

    def initial_qdot(self) -> tuple[float, ...]:
        """Every input's rate at t = 0 (rad/s or m/s), in the inputs' order."""
        return self.inputs_qdot0 or (self.qdot0,)

    def input_units(self) -> tuple[str, ...]:
        """Each input coordinate's unit, "rad" or "m", in the inputs' order."""
        joints = self.mechanism.linkage.joint_map
        return tuple("m" if isinstance(joints[name], PrismaticJoint) else "rad" for name in self.inputs)

    @property
    def input_is_prismatic(self) -> bool:
        linkage = self.mechanism.linkage
        return isinstance(linkage.joint_map[linkage.input_joint], PrismaticJoint)

    @property
    def input_unit(self) -> str:
        """Unit of q: "rad" or "m"."""
        return "m" if self.input_is_prismatic else "rad"

    @property
    def load_name(self) -> str:
        """"force" on a prismatic input, "torque" on a revolute one."""
        return "force" if self.input_is_prismatic else "torque"

    @property
    def load_edges(self) -> tuple[float, ...]:
        """Times (s) where a load over time jumps, the input's, the timed forces' and the actuators'
        controls', sorted
        without repeats: the reduced integrators stop at them, MuJoCo's steps fall on them."""
        edges = set(self.load.edges) if self.load is not None else set()
        for force in self.mechanism.timed_forces:
            edges.update(force.profile.edges)
        for actuator in self.mechanism.actuators:  # their controls, piecewise constant in t
            if actuator.control is not None:
                edges.update(actuator.control.edges)
        return tuple(sorted(edges))

    @property
    def effects(self) -> tuple[str, ...]:
        """The physical effects the scene declares, in a fixed order (:data:`EFFECTS`)."""
        m = self.mechanism
        present = {"torque": self.load is not None and not self.input_is_prismatic,
                   "force": self.load is not None and self.input_is_prismatic,
                   "damper": bool(m.dampers), "spring": bool(m.springs),
                   "joint-damper": bool(m.joint_dampers), "joint-spring": bool(m.joint_springs),
                   "joint-inertia": bool(m.joint_inertias), "joint-friction": bool(m.joint_frictions),
                   "joint-range": any(j.range is not None for j in m.linkage.joints),
                   "point-force": bool(m.point_forces), "timed-force": bool(m.timed_forces), "actuator": bool(m.actuators),
                   "gravity": self.gravity is not None}
        return tuple(name for name in EFFECTS if present[name])


# Every effect a scene can declare, in the order reports list them.
EFFECTS = ("torque", "force", "damper", "spring", "joint-damper", "joint-spring", "joint-inertia", "joint-friction",
           "joint-range", "point-force", "timed-force", "actuator", "gravity")
