"""Scenes: what a user asks to simulate, read from TOML into frozen dataclasses.

Every length is in m, angle in rad, mass in kg, inertia in kg·m², torque in N·m,
damping in N·s/m, stiffness in N/m, time in s. The README documents the format.

A malformed scene raises :class:`SceneError` with one message that names the
offending key and the reason; nothing else in the package raises on bad input.
Every number lies in the range of its kind (:data:`LIMITS`, one table for both
engines), and a scene whose crank could turn more than :data:`MAX_SWEPT_ANGLE`
over its horizon (:func:`speed_bound`) is refused before any work.
"""

from __future__ import annotations

import importlib.resources
import math
import os
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

from .loads import ConstantTorque, PiecewiseConstantTorque, PulseTorque, TorqueProfile

BODY_NAMES = ("crank", "coupler", "rocker")
GROUNDED_BODIES = ("crank", "rocker")


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
    Range("length", "m", 1e-3, 1e3, "link lengths c1…c4; lengths⁴ in the assembly discriminant stay ≤ 1e12"),
    Range("position", "m", 0.0, 1e3, "points, centres of mass and spring rest lengths"),
    Range("mass", "kg", 1e-6, 1e6, "MuJoCo refuses a mass below mjMINVAL = 1e-15 kg; 1e-6 leaves nine decades"),
    Range("inertia", "kg·m²", 1e-9, 1e6, "MuJoCo refuses an inertia below mjMINVAL = 1e-15 kg·m² (a pivot "
          "inertia becomes I_zz of a 1 kg point body); 1e-9 leaves six decades"),
    Range("damping", "N·s/m", 1e-9, 1e7, "stiff_damper uses 1e6; the seed with 1e7 ran in 2.6 s (DOP853, 9675 steps)"),
    Range("stiffness", "N/m", 1e-9, 1e8, "a 1e8 N/m spring on a 1 kg·m² link at 1 m swings in 0.6 ms"),
    Range("torque", "N·m", 0.0, 1e6, "fast_crank reaches ~1000 rad/s with 7300 N·m"),
    Range("angle", "rad", 0.0, 1e3, "q0 is an angle; beyond a few turns it only loses digits"),
    Range("speed", "rad/s", 0.0, 1e4, "q̇0; fast_crank peaks near 1000 rad/s, and the work grows with speed"),
    Range("time", "s", 0.0, 1e3, "torque start, duration and table times (s)"),
    Range("horizon", "s", 1e-3, 1e3, "at MuJoCo's 1 ms default a 1000 s run is already 1e6 steps"),
    Range("gravity", "m/s²", 0.0, 1e3, "about 100 g"),
    Range("step", "s", 1e-6, 1.0, "a scene's [mujoco] timestep or [reduced] step; the hard cases use 2e-5 to 1e-3"),
)
MAX_TABLE_ENTRIES = 10_000  # entries of a torque table
MAX_NAME_CHARS = 100  # a scene name is printed, plotted and used in file listings
MAX_DESCRIPTION_CHARS = 1000
MAX_SCENE_BYTES = 1 << 20  # 1 MiB: a scene is a short text file (the seed is 2 kB)
# Largest crank angle a scene may sweep by the bound of speed_bound (rad, ~3 200 turns): the work
# of every engine grows with it. The seed started at q̇0 = 1000 rad/s has a bound of 5.2e3 rad,
# really turns ~3e3 rad and takes DOP853 (default rtol) 32 726 steps, ~45 s; the hard cases
# fast_crank and long_conservative have bounds of 5.8e3 and 3.7e3 rad.
MAX_SWEPT_ANGLE = 2e4


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
class BodyInertia:
    """Mass properties of one moving link, in its body frame.

    Body frames: crank origin O1, x along O1→A; coupler origin A, x along A→B;
    rocker origin O3, x along O3→B. ``pivot_inertia`` is the inertia about the
    frame origin (only meaningful for a link that turns about a fixed pivot);
    ``mass``/``com``/``centroidal_inertia`` may be None when not needed.
    """

    mass: float | None
    com: tuple[float, float] | None
    centroidal_inertia: float | None
    pivot_inertia: float

    @property
    def has_mass_distribution(self) -> bool:
        return self.mass is not None and self.com is not None


@dataclass(frozen=True)
class LinearDamper:
    """Viscous damper between a fixed point and a point of a body: F = −b Ḋ along the line."""

    coefficient: float
    ground_point: tuple[float, float]
    body: str
    body_point: tuple[float, float]


@dataclass(frozen=True)
class LinearSpring:
    """Linear spring between a fixed point and a point of a body: V = ½ k (D − D0)²."""

    stiffness: float
    rest_length: float
    ground_point: tuple[float, float]
    body: str
    body_point: tuple[float, float]


@dataclass(frozen=True)
class Tolerances:
    """Agreement tolerances between the engines (used by ``xval check``).

    The peak passes when |Δ peak ω| ≤ peak_omega_rtol·|peak ω| + peak_omega_atol: the
    absolute floor keeps a relative figure of a motion that barely moves from judging
    round-off.
    """

    peak_omega_rtol: float = 1e-4
    peak_omega_atol: float = 1e-9  # rad/s
    q_atol: float = 1e-3
    omega_atol: float = 1e-1
    omega_vs_q_atol: float | None = None  # max |Δω| at equal q (rad/s); None: not checked

    def peak_bound(self, peak: float) -> float:
        """The largest |Δ peak ω| allowed for a peak of magnitude ``peak`` (rad/s)."""
        return self.peak_omega_rtol * peak + self.peak_omega_atol


@dataclass(frozen=True)
class Scene:
    """One simulation request: mechanism, loads, initial state and horizon."""

    name: str
    description: str
    linkage: FourBarGeometry
    bodies: Mapping[str, BodyInertia]
    torque: TorqueProfile | None
    dampers: tuple[LinearDamper, ...]
    springs: tuple[LinearSpring, ...]
    gravity: tuple[float, float] | None
    q0: float
    qdot0: float
    horizon: float
    tolerances: Tolerances = field(default_factory=Tolerances)
    mujoco: Mapping[str, Any] = field(default_factory=dict)  # settings this scene asks MuJoCo for
    reduced: Mapping[str, Any] = field(default_factory=dict)  # settings for the reduced reference
    source: str = "<memory>"

    @property
    def effects(self) -> tuple[str, ...]:
        """The physical effects the scene declares, in a fixed order."""
        names = []
        if self.torque is not None:
            names.append("torque")
        if self.dampers:
            names.append("damper")
        if self.springs:
            names.append("spring")
        if self.gravity is not None:
            names.append("gravity")
        return tuple(names)


# ---------------------------------------------------------------------------
# Parsing
# ---------------------------------------------------------------------------


class _Table:
    """A TOML table being read: tracks used keys so unknown ones can be reported."""

    def __init__(self, data: Any, path: str):
        if not isinstance(data, dict):
            raise SceneError(f"'{path}' must be a table, got {_type_name(data)}")
        self.data = data
        self.path = path
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = ...) -> Any:
        self.used.add(name)
        if name not in self.data:
            if default is ...:
                raise SceneError(f"missing key '{self.key(name)}'")
            return default
        return self.data[name]

    def number(self, name: str, default: Any = ..., *, positive: bool = False,
               nonnegative: bool = False, kind: str | None = None) -> float:
        value = self.raw(name, default)
        if value is default and default is not ...:
            return value
        return _number(value, self.key(name), positive=positive, nonnegative=nonnegative, kind=kind)

    def point(self, name: str, default: Any = ..., *, kind: str = "position") -> tuple[float, float]:
        value = self.raw(name, default)
        if value is default and default is not ...:
            return value
        return _point(value, self.key(name), kind=kind)

    def string(self, name: str, default: Any = ...) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise SceneError(f"'{self.key(name)}' must be a string, got {_type_name(value)}")
        return value

    def choice(self, name: str, options: tuple[str, ...]) -> str:
        """A string that must be one of ``options``."""
        value = self.string(name)
        if value not in options:
            raise SceneError(f"'{self.key(name)}' must be one of {', '.join(options)}, got \"{value}\"")
        return value

    def table(self, name: str) -> "_Table":
        return _Table(self.raw(name), self.key(name))

    def close(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise SceneError(f"unknown key '{self.key(unknown[0])}'")


def _type_name(value: Any) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "an array", dict: "a table"}.get(type(value), type(value).__name__)


def _number(value: Any, key: str, *, positive: bool = False, nonnegative: bool = False,
            kind: str | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"'{key}' must be a number, got {_type_name(value)}")
    try:
        value = float(value)
    except OverflowError:  # a TOML integer beyond the float range
        raise SceneError(f"'{key}' must be finite, got an integer of about"
                         f" {int(value.bit_length() * math.log10(2)) + 1} digits") from None
    if not math.isfinite(value):
        raise SceneError(f"'{key}' must be finite, got {value}")
    if positive and value <= 0.0:
        raise SceneError(f"'{key}' must be positive, got {value}")
    if nonnegative and value < 0.0:
        raise SceneError(f"'{key}' must not be negative, got {value}")
    if kind is not None:
        _check_range(value, key, LIMITS[kind])
    return value


def _check_range(value: float, key: str, r: Range, what: str = "") -> None:
    inside = r.low <= value <= r.high if r.low else abs(value) <= r.high
    if not inside:
        raise SceneError(f"'{key}'{what} = {value:g} is out of range: {r.kind} must be in {r.text()}")


def _point(value: Any, key: str, *, kind: str = "position") -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise SceneError(f"'{key}' must be an array of two numbers [x, y]")
    return (_number(value[0], f"{key}[0]", kind=kind), _number(value[1], f"{key}[1]", kind=kind))


def _text(t: "_Table", name: str, default: str, limit: int) -> str:
    """A one-line, printable string of at most ``limit`` characters (names stay plain text)."""
    value = t.string(name, default)
    if len(value) > limit:
        raise SceneError(f"'{t.key(name)}' has {len(value)} characters; at most {limit}")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise SceneError(f"'{t.key(name)}' must be printable text, got the control character {bad!r}")
    return value


def _parse_linkage(t: _Table) -> FourBarGeometry:
    kind = t.string("type", "four_bar")
    if kind != "four_bar":
        raise SceneError(f"'{t.key('type')}' must be \"four_bar\", got \"{kind}\"")
    lengths = [t.number(f"c{i}", positive=True, kind="length") for i in (1, 2, 3, 4)]
    branch = t.raw("branch")
    if isinstance(branch, bool) or branch not in (1, -1):
        raise SceneError(f"'{t.key('branch')}' must be 1 or -1 (the sign of ± in the φ1 formula)")
    t.close()
    return FourBarGeometry(*lengths, branch=int(branch))


def _parse_body(t: _Table, name: str, needs_mass: bool) -> BodyInertia:
    grounded = name in GROUNDED_BODIES
    mass = t.number("mass", None, positive=True, kind="mass")
    com = t.point("com", None)
    centroidal = t.number("inertia", None, positive=True, kind="inertia")
    pivot = t.number("pivot_inertia", None, positive=True, kind="inertia") if grounded else None
    if not grounded and t.has("pivot_inertia"):
        raise SceneError(f"'{t.key('pivot_inertia')}' is not allowed: the {name} has no fixed pivot;"
                         " give mass, inertia and com")
    t.close()
    if pivot is None:
        missing = [k for k, v in (("mass", mass), ("inertia", centroidal), ("com", com)) if v is None]
        if missing:
            hint = " (or pivot_inertia)" if grounded else ""
            raise SceneError(f"missing key '{t.key(missing[0])}'{hint}")
        pivot = centroidal + mass * (com[0] ** 2 + com[1] ** 2)
    else:
        if centroidal is not None:
            raise SceneError(f"'{t.key('inertia')}' conflicts with '{t.key('pivot_inertia')}': give one")
        if (mass is None) != (com is None):
            raise SceneError(f"'{t.key('mass')}' and '{t.key('com')}' go together")
        if mass is not None:
            centroidal = pivot - mass * (com[0] ** 2 + com[1] ** 2)
            if centroidal <= 0.0:
                raise SceneError(f"'{t.key('pivot_inertia')}' = {pivot} is smaller than mass·|com|²;"
                                 " the centroidal inertia would not be positive")
            _check_range(centroidal, t.key("pivot_inertia"), LIMITS["inertia"], " − mass·|com|²")
    if needs_mass and (mass is None or com is None):
        missing = " and ".join(f"'{t.key(k)}'" for k, v in (("mass", mass), ("com", com)) if v is None)
        raise SceneError(f"missing {'keys' if ' and ' in missing else 'key'} {missing}:"
                         " gravity needs the mass and centre of mass of every moving link")
    return BodyInertia(mass=mass, com=com, centroidal_inertia=centroidal, pivot_inertia=pivot)


def _parse_torque(t: _Table) -> TorqueProfile:
    kind = t.string("type")
    if kind == "constant":
        profile = ConstantTorque(t.number("value", kind="torque"))
    elif kind == "pulse":
        profile = PulseTorque(amplitude=t.number("value", kind="torque"),
                              start=t.number("start", 0.0, nonnegative=True, kind="time"),
                              duration=t.number("duration", nonnegative=True, kind="time"))
    elif kind == "table":
        times = t.raw("times")
        values = t.raw("values")
        if not isinstance(times, list) or not isinstance(values, list):
            raise SceneError(f"'{t.key('times')}' and '{t.key('values')}' must be arrays")
        if len(times) != len(values) or not times:
            raise SceneError(f"'{t.key('times')}' and '{t.key('values')}' must have the same, non-zero length")
        if len(times) > MAX_TABLE_ENTRIES:
            raise SceneError(f"'{t.key('times')}' has {len(times)} entries; at most {MAX_TABLE_ENTRIES}")
        ts = tuple(_number(v, f"{t.key('times')}[{i}]", kind="time") for i, v in enumerate(times))
        vs = tuple(_number(v, f"{t.key('values')}[{i}]", kind="torque") for i, v in enumerate(values))
        if any(b <= a for a, b in zip(ts, ts[1:])):
            raise SceneError(f"'{t.key('times')}' must be strictly increasing")
        profile = PiecewiseConstantTorque(times=ts, values=vs)
    else:
        raise SceneError(f"'{t.key('type')}' must be \"constant\", \"pulse\" or \"table\", got \"{kind}\"")
    t.close()
    return profile


def _parse_attachment(t: _Table) -> dict[str, Any]:
    body = t.string("body")
    if body not in BODY_NAMES:
        raise SceneError(f"'{t.key('body')}' must be one of {', '.join(BODY_NAMES)}, got \"{body}\"")
    return {"ground_point": t.point("ground_point"), "body": body, "body_point": t.point("body_point")}


def _array_of_tables(top: _Table, name: str) -> list[_Table]:
    items = top.raw(name, [])
    if not isinstance(items, list):
        raise SceneError(f"'{name}' must be an array of tables ([[{name}]])")
    return [_Table(item, f"{name}[{i}]") for i, item in enumerate(items)]


def scene_from_dict(data: Mapping[str, Any], source: str = "<memory>") -> Scene:
    """Build and validate a :class:`Scene` from parsed TOML data."""
    top = _Table(dict(data), "")
    stem = "".join(c if c.isprintable() else "?" for c in Path(source).stem[:MAX_NAME_CHARS])
    name = _text(top, "name", stem if source != "<memory>" else "scene", MAX_NAME_CHARS)
    description = _text(top, "description", "", MAX_DESCRIPTION_CHARS)
    linkage = _parse_linkage(top.table("linkage"))

    gravity = top.point("gravity", None, kind="gravity")
    bodies_t = top.table("bodies")
    bodies = {}
    for body in BODY_NAMES:
        bodies[body] = _parse_body(bodies_t.table(body), body, needs_mass=gravity is not None)
    bodies_t.close()

    torque = _parse_torque(top.table("torque")) if top.has("torque") else None
    top.used.add("torque")

    dampers = []
    for t in _array_of_tables(top, "dampers"):
        coefficient = t.number("coefficient", positive=True, kind="damping")
        dampers.append(LinearDamper(coefficient=coefficient, **_parse_attachment(t)))
        t.close()
    springs = []
    for t in _array_of_tables(top, "springs"):
        stiffness = t.number("stiffness", positive=True, kind="stiffness")
        rest = t.number("rest_length", nonnegative=True, kind="position")
        springs.append(LinearSpring(stiffness=stiffness, rest_length=rest, **_parse_attachment(t)))
        t.close()

    init = top.table("initial")
    q0 = init.number("q", kind="angle")
    qdot0 = init.number("qdot", 0.0, kind="speed")
    init.close()

    sim = top.table("simulation")
    horizon = sim.number("horizon", positive=True, kind="horizon")
    sim.close()

    tolerances = Tolerances()
    if top.has("tolerances"):
        tol = top.table("tolerances")
        tolerances = Tolerances(
            peak_omega_rtol=tol.number("peak_omega_rtol", Tolerances.peak_omega_rtol, positive=True),
            peak_omega_atol=tol.number("peak_omega_atol", Tolerances.peak_omega_atol, positive=True),
            q_atol=tol.number("q_atol", Tolerances.q_atol, positive=True),
            omega_atol=tol.number("omega_atol", Tolerances.omega_atol, positive=True),
            omega_vs_q_atol=tol.number("omega_vs_q_atol", None, positive=True),
        )
        tol.close()
    mujoco = _parse_mujoco(top.table("mujoco")) if top.has("mujoco") else {}
    reduced = _parse_reduced(top.table("reduced")) if top.has("reduced") else {}
    top.used.update(("mujoco", "reduced"))
    top.close()

    scene = Scene(name=name, description=description, linkage=linkage, bodies=bodies,
                  torque=torque, dampers=tuple(dampers), springs=tuple(springs), gravity=gravity,
                  q0=q0, qdot0=qdot0, horizon=horizon, tolerances=tolerances, mujoco=mujoco, reduced=reduced,
                  source=source)
    for key, table in (("mujoco.timestep", mujoco), ("reduced.step", reduced)):
        step = table.get(key.split(".")[1])
        if step is not None and step > horizon:
            raise SceneError(f"'{key}' = {step:g} s is longer than 'simulation.horizon' = {horizon:g} s")
    _check_assembly(scene)
    _check_motion(scene)
    return scene


MUJOCO_INTEGRATORS = ("euler", "implicit", "implicitfast", "rk4")


# MuJoCo's constraint-solver iterations per step: Newton on a loop's rows converges in a handful;
# 10 000 already means a solver that is not converging, and keeps the binding's C int (2**31
# raises a TypeError there) far away. One limit for the scene file, the CLI and MujocoSettings.
MUJOCO_MAX_ITERATIONS = 10_000


def _parse_mujoco(t: _Table) -> dict[str, Any]:
    """Optional [mujoco] table: integrator, timestep (s), solref (2 numbers), solimp (5 numbers),
    iterations, tolerance, refsafe and diagexact (booleans)."""
    out: dict[str, Any] = {}
    if t.has("integrator"):
        out["integrator"] = t.choice("integrator", MUJOCO_INTEGRATORS)
    if t.has("timestep"):
        out["timestep"] = t.number("timestep", positive=True, kind="step")
    if t.has("tolerance"):
        out["tolerance"] = t.number("tolerance", positive=True)
    if t.has("iterations"):
        value = t.raw("iterations")
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MUJOCO_MAX_ITERATIONS:
            raise SceneError(f"'{t.key('iterations')}' must be a whole number from 1 to {MUJOCO_MAX_ITERATIONS}")
        out["iterations"] = value
    for name in ("refsafe", "diagexact"):
        if t.has(name):
            value = t.raw(name)
            if not isinstance(value, bool):
                raise SceneError(f"'{t.key(name)}' must be true or false, got {_type_name(value)}")
            out[name] = value
    for name, size in (("solref", 2), ("solimp", 5)):
        if t.has(name):
            value = t.raw(name)
            if not isinstance(value, list) or len(value) != size:
                raise SceneError(f"'{t.key(name)}' must be an array of {size} numbers")
            out[name] = tuple(_number(v, f"{t.key(name)}[{i}]") for i, v in enumerate(value))
    t.close()
    return out


REDUCED_METHODS = ("dop853", "rkn4", "radau")


def _parse_reduced(t: _Table) -> dict[str, Any]:
    """Optional [reduced] table: the reference method, rtol, step (s)."""
    out: dict[str, Any] = {}
    if t.has("method"):
        out["method"] = t.choice("method", REDUCED_METHODS)
    if t.has("rtol"):
        out["rtol"] = t.number("rtol", positive=True)
    if t.has("step"):
        out["step"] = t.number("step", positive=True, kind="step")
    t.close()
    return out


def _check_assembly(scene: Scene) -> None:
    # Imported here: the linkage module needs the geometry type defined above.
    from .linkage import FourBar, AssemblyError

    from .linkage import SINGULAR_DETERMINANT

    linkage = FourBar(scene.linkage)
    try:
        x = linkage.assemble(scene.q0)
    except AssemblyError as exc:
        raise SceneError(f"'initial.q' = {scene.q0}: {exc}") from None
    if scene.qdot0 != 0.0 and linkage.conditioning(x)[0] < SINGULAR_DETERMINANT:
        raise SceneError(f"'initial.qdot' = {scene.qdot0}: the input link is at a dead centre at "
                         f"q = {scene.q0} rad, where its speed must be zero")


def speed_bound(scene: Scene) -> dict[str, float]:
    """An upper bound of the crank's speed |q̇| (rad/s) over the horizon, split by cause (the
    scene key or effect, quoted as in messages; the parts add up to the bound).

    𝔍(q) ≥ I_O1, the crank's pivot inertia (every other term of 𝔍 is ≥ 0). With K = E − V_min
    (E the mechanical energy), dK/dt ≤ |T||q̇| ≤ |T|·√(2K/I_O1), so √K grows at most by
    ∫|T|dt/√(2 I_O1), and |q̇| ≤ √(2K/I_O1) ≤ √(𝔍(q0)/I_O1)·|q̇0| + √(2ΔV/I_O1) + ∫|T|dt / I_O1,
    where ΔV bounds the potential energy the springs and gravity can release (over the reach of
    each point, c1 + c4 + |point|). Dampers only take energy out.
    """
    from .dynamics import MechanismModel

    j_low = scene.bodies["crank"].pivot_inertia
    g = scene.linkage
    reach = g.c1 + g.c4
    initial = 0.0
    if scene.qdot0:  # not at a dead centre (checked before), so 𝔍(q0) is defined
        initial = math.sqrt(MechanismModel(scene).generalized_inertia(scene.q0) / j_low) * abs(scene.qdot0)
    released = 0.0
    for sp in scene.springs:
        longest = math.hypot(*sp.ground_point) + reach + math.hypot(*sp.body_point)
        released += 0.5 * sp.stiffness * max(longest - sp.rest_length, sp.rest_length) ** 2
    if scene.gravity is not None:
        weight = math.hypot(*scene.gravity)
        released += sum(2.0 * b.mass * weight * (reach + math.hypot(*b.com)) for b in scene.bodies.values())
    torque = scene.torque
    impulse = 0.0 if torque is None else torque.impulse_bound(scene.horizon)
    torque_key = "'torque.values'" if isinstance(torque, PiecewiseConstantTorque) else "'torque.value'"
    return {"'initial.qdot'": initial, "the springs and gravity": math.sqrt(2.0 * released / j_low),
            torque_key: impulse / j_low}


def _check_motion(scene: Scene) -> None:
    """Refuse a scene whose crank could sweep more than MAX_SWEPT_ANGLE over its horizon."""
    parts = speed_bound(scene)
    swept = sum(parts.values()) * scene.horizon
    if swept > MAX_SWEPT_ANGLE:
        cause = max(parts, key=parts.get)
        raise SceneError(f"the crank could turn up to {swept:.3g} rad in 'simulation.horizon' = {scene.horizon:g} s"
                         f" (|q̇| ≤ {sum(parts.values()):.3g} rad/s, mostly from {cause}), more than"
                         f" {MAX_SWEPT_ANGLE:g} rad: lower {cause} or the horizon, or raise the crank's"
                         " inertia ('bodies.crank')")


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file.

    The file must be a regular file of at most ``MAX_SCENE_BYTES`` bytes of UTF-8 text (a
    byte-order mark is accepted). Every message starts with the file's path.

    Raises
    ------
    SceneError
        If the file is missing, too large, not UTF-8, not valid TOML, or describes an invalid scene.
    """
    path = Path(path)
    data = _parse_toml(_read_text(path), path)
    try:
        return scene_from_dict(data, source=str(path))
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None


def _read_text(path: Path) -> str:
    """The file's text: regular files only, at most MAX_SCENE_BYTES read, UTF-8 with or without BOM."""
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer; it is refused below.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise SceneError(f"cannot read scene file '{path}': {exc.strerror}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        what = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise SceneError(f"cannot read scene file '{path}': it is {what}")
    with os.fdopen(fd, "rb") as f:
        try:
            raw = f.read(MAX_SCENE_BYTES + 1)
        except OSError as exc:
            raise SceneError(f"cannot read scene file '{path}': {exc.strerror}") from None
    if len(raw) > MAX_SCENE_BYTES:
        raise SceneError(f"'{path}' is larger than {MAX_SCENE_BYTES} bytes; a scene is a short text file")
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise SceneError(f"'{path}' is UTF-16 text (byte-order mark); save it as UTF-8")
    try:
        return raw.decode("utf-8-sig")  # strips a UTF-8 byte-order mark
    except UnicodeDecodeError as exc:
        raise SceneError(f"'{path}' is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start});"
                         " save it as UTF-8") from None


def _parse_toml(text: str, path: Path) -> dict[str, Any]:
    """``tomllib.loads`` with its errors as one-line SceneErrors naming the file."""
    try:
        return tomllib.loads(text)
    except ValueError as exc:  # TOMLDecodeError, or an integer past Python's 4300-digit limit
        raise SceneError(f"'{path}' is not valid TOML: {exc}") from None
    except RecursionError:
        raise SceneError(f"'{path}' is not a usable scene: its arrays or tables are nested too deeply") from None


def scenes_dir() -> Path:
    """Folder of the scenes shipped with the project (``seed_fourbar.toml``, ``hard/``).

    The scenes are the package data of the ``scenes`` package, found with importlib.resources,
    so an installed wheel finds them as well as a source checkout.
    """
    root = importlib.resources.files("scenes")
    if not isinstance(root, Path):  # e.g. imported from a zip file
        raise SceneError(f"the shipped scenes are not files on disk ({root}); install xval unzipped")
    return root


def default_scene_path() -> Path:
    """Path of the seed four-bar scene shipped with the project."""
    return scenes_dir() / "seed_fourbar.toml"


def hard_scene_dir() -> Path:
    """Folder of the hard-case catalogue (``xval stress``)."""
    return scenes_dir() / "hard"
