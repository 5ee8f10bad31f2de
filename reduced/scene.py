"""Scenes: what a user asks to simulate, read from TOML into frozen dataclasses.

Every length is in m, angle in rad, mass in kg, inertia in kg·m², torque in N·m,
damping in N·s/m, stiffness in N/m, time in s. The README documents the format.

A malformed scene raises :class:`SceneError` with one message that names the
offending key and the reason; nothing else in the package raises on bad input.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .loads import ConstantTorque, PiecewiseConstantTorque, PulseTorque, TorqueProfile

BODY_NAMES = ("crank", "coupler", "rocker")
GROUNDED_BODIES = ("crank", "rocker")


class SceneError(ValueError):
    """A scene that cannot be simulated; the message names the key and the reason."""


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
               nonnegative: bool = False) -> float:
        value = self.raw(name, default)
        if value is default and default is not ...:
            return value
        return _number(value, self.key(name), positive=positive, nonnegative=nonnegative)

    def point(self, name: str, default: Any = ...) -> tuple[float, float]:
        value = self.raw(name, default)
        if value is default and default is not ...:
            return value
        return _point(value, self.key(name))

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


def _number(value: Any, key: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"'{key}' must be a number, got {_type_name(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise SceneError(f"'{key}' must be finite, got {value}")
    if positive and value <= 0.0:
        raise SceneError(f"'{key}' must be positive, got {value}")
    if nonnegative and value < 0.0:
        raise SceneError(f"'{key}' must not be negative, got {value}")
    return value


def _point(value: Any, key: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise SceneError(f"'{key}' must be an array of two numbers [x, y]")
    return (_number(value[0], f"{key}[0]"), _number(value[1], f"{key}[1]"))


def _parse_linkage(t: _Table) -> FourBarGeometry:
    kind = t.string("type", "four_bar")
    if kind != "four_bar":
        raise SceneError(f"'{t.key('type')}' must be \"four_bar\", got \"{kind}\"")
    lengths = [t.number(f"c{i}", positive=True) for i in (1, 2, 3, 4)]
    branch = t.raw("branch")
    if isinstance(branch, bool) or branch not in (1, -1):
        raise SceneError(f"'{t.key('branch')}' must be 1 or -1 (the sign of ± in the φ1 formula)")
    t.close()
    return FourBarGeometry(*lengths, branch=int(branch))


def _parse_body(t: _Table, name: str, needs_mass: bool) -> BodyInertia:
    grounded = name in GROUNDED_BODIES
    mass = t.number("mass", None, positive=True)
    com = t.point("com", None)
    centroidal = t.number("inertia", None, positive=True)
    pivot = t.number("pivot_inertia", None, positive=True) if grounded else None
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
    if needs_mass and (mass is None or com is None):
        raise SceneError(f"missing key '{t.key('mass' if mass is None else 'com')}':"
                         " gravity needs the mass and centre of mass of every moving link")
    return BodyInertia(mass=mass, com=com, centroidal_inertia=centroidal, pivot_inertia=pivot)


def _parse_torque(t: _Table) -> TorqueProfile:
    kind = t.string("type")
    if kind == "constant":
        profile = ConstantTorque(t.number("value"))
    elif kind == "pulse":
        profile = PulseTorque(amplitude=t.number("value"), start=t.number("start", 0.0, nonnegative=True),
                              duration=t.number("duration", nonnegative=True))
    elif kind == "table":
        times = t.raw("times")
        values = t.raw("values")
        if not isinstance(times, list) or not isinstance(values, list):
            raise SceneError(f"'{t.key('times')}' and '{t.key('values')}' must be arrays")
        if len(times) != len(values) or not times:
            raise SceneError(f"'{t.key('times')}' and '{t.key('values')}' must have the same, non-zero length")
        ts = tuple(_number(v, f"{t.key('times')}[{i}]") for i, v in enumerate(times))
        vs = tuple(_number(v, f"{t.key('values')}[{i}]") for i, v in enumerate(values))
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
    name = top.string("name", Path(source).stem if source != "<memory>" else "scene")
    description = top.string("description", "")
    linkage = _parse_linkage(top.table("linkage"))

    gravity = top.point("gravity", None)
    bodies_t = top.table("bodies")
    bodies = {}
    for body in BODY_NAMES:
        bodies[body] = _parse_body(bodies_t.table(body), body, needs_mass=gravity is not None)
    bodies_t.close()

    torque = _parse_torque(top.table("torque")) if top.has("torque") else None
    top.used.add("torque")

    dampers = []
    for t in _array_of_tables(top, "dampers"):
        coefficient = t.number("coefficient", positive=True)
        dampers.append(LinearDamper(coefficient=coefficient, **_parse_attachment(t)))
        t.close()
    springs = []
    for t in _array_of_tables(top, "springs"):
        stiffness = t.number("stiffness", positive=True)
        rest = t.number("rest_length", nonnegative=True)
        springs.append(LinearSpring(stiffness=stiffness, rest_length=rest, **_parse_attachment(t)))
        t.close()

    init = top.table("initial")
    q0 = init.number("q")
    qdot0 = init.number("qdot", 0.0)
    init.close()

    sim = top.table("simulation")
    horizon = sim.number("horizon", positive=True)
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
    _check_assembly(scene)
    return scene


MUJOCO_INTEGRATORS = ("euler", "implicit", "implicitfast", "rk4")


def _parse_mujoco(t: _Table) -> dict[str, Any]:
    """Optional [mujoco] table: integrator, timestep (s), solref (2 numbers), solimp (5 numbers),
    iterations, tolerance, refsafe and diagexact (booleans)."""
    out: dict[str, Any] = {}
    if t.has("integrator"):
        out["integrator"] = t.choice("integrator", MUJOCO_INTEGRATORS)
    if t.has("timestep"):
        out["timestep"] = t.number("timestep", positive=True)
    if t.has("tolerance"):
        out["tolerance"] = t.number("tolerance", positive=True)
    if t.has("iterations"):
        value = t.raw("iterations")
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise SceneError(f"'{t.key('iterations')}' must be a whole number of at least 1")
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
    for name in ("rtol", "step"):
        if t.has(name):
            out[name] = t.number(name, positive=True)
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


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file.

    Raises
    ------
    SceneError
        If the file is missing, is not valid TOML, or describes an invalid scene.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(f"cannot read scene file '{path}': {exc.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"'{path}' is not valid TOML: {exc}") from None
    return scene_from_dict(data, source=str(path))


def scenes_dir() -> Path:
    """Folder of the scenes shipped with the project (``seed_fourbar.toml``, ``hard/``)."""
    return Path(__file__).resolve().parent.parent / "scenes"


def default_scene_path() -> Path:
    """Path of the seed four-bar scene shipped with the project."""
    return scenes_dir() / "seed_fourbar.toml"


def hard_scene_dir() -> Path:
    """Folder of the hard-case catalogue (``xval stress``)."""
    return scenes_dir() / "hard"
