"""The general description of a planar one-degree-of-freedom linkage, and its joint graph.

A linkage is rigid bodies with named points and mass properties in their own frames,
revolute and prismatic joints between two bodies' points, and the input joint whose
coordinate is q. Ground is the body named ``"ground"`` (:data:`GROUND`): it does not move,
its points are fixed points of the plane, and it is not counted as a moving body. A
:class:`Mechanism` adds what acts on the bodies: dampers and springs between two points
(:class:`LineElement`), dampers and springs on a joint's coordinate (:class:`JointElement`)
point forces tabulated over the input coordinate (:class:`PointForce`) and point forces
given over time (:class:`TimedForce`), and actuators as MuJoCo applies them (:class:`Actuator`). Both engines build from a :class:`Mechanism`; neither is known here.

:class:`Linkage` checks the description as a graph on construction (names, connectivity,
Grübler's count at most 1, loops that a MuJoCo ``connect`` equality can close) and holds its
spanning tree from ground and the cut joints, one per independent loop. The numeric loop
kinematics built from it are in :mod:`loopcheck.kinematics`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

GROUND = "ground"


class MechanismError(ValueError):
    """A linkage description that is malformed or not a one-degree-of-freedom mechanism."""


class GrublerCountWarning(UserWarning):
    """A linkage accepted with one degree of freedom by the rank of its loop equations whose
    Grübler count differs (a redundantly closed loop): one line naming the scene and both counts."""


def _finite_pair(value, what: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise MechanismError(f"{what} must be a pair of numbers (x, y) in m, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise MechanismError(f"{what} must be finite, got ({x}, {y})")
    return x, y


def _name(value, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise MechanismError(f"{what} must be a non-empty string, got {value!r}")
    return value


@dataclass(frozen=True)
class Body:
    """A rigid body, its named points and its mass properties.

    Parameters
    ----------
    name : str
        Unique among the bodies; ``"ground"`` is the fixed frame (no mass properties).
    points : mapping str → (x, y)
        Named points in the body's own frame (m). Stored read-only.
    mass : float
        kg, ≥ 0. Zero only for a body given by its inertia about a fixed pivot (``com`` is
        then that pivot, a point of a revolute joint to ground: :class:`Linkage` checks it).
    com : (x, y)
        Centre of mass in the body's frame (m).
    inertia : float
        Moment of inertia about the centre of mass, about z (kg·m²), ≥ 0.
    gravcomp : float
        Gravity compensation, as MuJoCo's body ``gravcomp``: the body's weight is scaled by
        (1 − gravcomp) (0: its full weight, 1: none, above 1: it floats up), ≥ 0. Its mass and
        inertia are unchanged.
    """

    name: str
    points: Mapping[str, tuple[float, float]] = field(hash=False)
    mass: float = 0.0
    com: tuple[float, float] = (0.0, 0.0)
    inertia: float = 0.0
    gravcomp: float = 0.0

    def __post_init__(self):
        _name(self.name, "body name")
        for f in ("mass", "inertia", "gravcomp"):
            value = getattr(self, f)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value >= 0.0):
                raise MechanismError(f"body {self.name!r}: {f} must be a finite number ≥ 0, got {value!r}")
            object.__setattr__(self, f, float(value))
        object.__setattr__(self, "com", _finite_pair(self.com, f"body {self.name!r}: com"))
        if self.name == GROUND and (self.mass or self.inertia or self.gravcomp):
            raise MechanismError("the ground does not move: it has no mass, inertia or gravcomp")
        if self.gravcomp and not self.mass:
            raise MechanismError(f"body {self.name!r}: gravcomp needs a mass (a body given by its inertia about a "
                                 "pivot has no weight that moves)")

        if not isinstance(self.points, Mapping):
            raise MechanismError(f"body {self.name!r}: points must be a mapping name → (x, y), "
                                 f"got {type(self.points).__name__}")
        if not self.points:
            raise MechanismError(f"body {self.name!r} has no points")
        pts = {}
        for key, value in self.points.items():
            _name(key, f"body {self.name!r}: point name")
            pts[key] = _finite_pair(value, f"body {self.name!r}: point {key!r}")
        object.__setattr__(self, "points", MappingProxyType(pts))

    def __reduce__(self):
        # The read-only points view does not pickle (a scene is sent to worker processes).
        return (Body, (self.name, dict(self.points), self.mass, self.com, self.inertia, self.gravcomp))


def _check_joint_ends(joint) -> None:
    """A joint's name and the names of its two bodies and points; the bodies must differ."""
    _name(joint.name, "joint name")
    for f in ("body_a", "point_a", "body_b", "point_b"):
        _name(getattr(joint, f), f"joint {joint.name!r}: {f}")
    if joint.body_a == joint.body_b:
        raise MechanismError(f"joint {joint.name!r} joins body {joint.body_a!r} to itself")


def _check_range(joint, unit: str) -> None:
    """A joint's ``range``: None, or two finite numbers lo < hi (``unit``), stored as floats."""
    if joint.range is None:
        return
    try:
        lo, hi = (float(v) for v in joint.range)
    except (TypeError, ValueError):
        raise MechanismError(f"joint {joint.name!r}: range must be two numbers [lo, hi] in {unit}, "
                             f"got {joint.range!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise MechanismError(f"joint {joint.name!r}: range must be finite with lo < hi ({unit}), got [{lo}, {hi}]")
    object.__setattr__(joint, "range", (lo, hi))


@dataclass(frozen=True)
class RevoluteJoint:
    """A pin: point ``point_a`` of ``body_a`` and point ``point_b`` of ``body_b`` coincide.

    Its coordinate is the angle of body_b's frame relative to body_a's (rad). ``range``: the
    interval (lo, hi) of that coordinate the joint may reach (rad; whole turns count, as for a
    joint spring), or None; a run that reaches a bound ends there (MuJoCo's joint ``range``).
    """

    name: str
    body_a: str
    point_a: str
    body_b: str
    point_b: str
    range: tuple[float, float] | None = None

    def __post_init__(self):
        _check_joint_ends(self)
        _check_range(self, "rad")


@dataclass(frozen=True)
class PrismaticJoint:
    """A planar slider between body_a and body_b.

    Point ``point_b`` of body_b slides along the line through ``point_a`` of body_a with
    direction ``direction_a`` (rad, in body_a's frame), and body_b's frame stays parallel to
    body_a's (relative angle 0). Its coordinate is the displacement s (m) of point_b from
    point_a along the line. ``range``: the interval (lo, hi) of s the joint may reach (m), or
    None; a run that reaches a bound ends there (MuJoCo's joint ``range``).
    """

    name: str
    body_a: str
    point_a: str
    direction_a: float
    body_b: str
    point_b: str
    range: tuple[float, float] | None = None

    def __post_init__(self):
        _check_joint_ends(self)
        _check_range(self, "m")
        try:
            direction = float(self.direction_a)
        except (TypeError, ValueError):
            raise MechanismError(f"joint {self.name!r}: direction_a must be an angle in rad, "
                                 f"got {self.direction_a!r}") from None
        if not math.isfinite(direction):
            raise MechanismError(f"joint {self.name!r}: direction_a must be finite, got {direction}")
        object.__setattr__(self, "direction_a", direction)


Joint = RevoluteJoint | PrismaticJoint


POLY_TERMS = 5  # a coupling's polynomial: a0 + a1 s + … + a4 s⁴ (MuJoCo's polycoef)


@dataclass(frozen=True)
class JointCoupling:
    """A closure between two joints' own coordinates (MuJoCo's ``equality/joint``): joint
    ``joint`` (y, the coupled one) follows joint ``driver`` (x) by a polynomial,

        y − y_ref = a0 + a1 (x − x_ref) + a2 (x − x_ref)² + a3 (x − x_ref)³ + a4 (x − x_ref)⁴,

    each coordinate a joint's own (:class:`JointElement`): a revolute's relative angle
    θ_b − θ_a (rad), a prismatic's displacement s (m). ``coefficients`` (a0 … a4, fewer given
    are padded with zeros) in the units that make each term y's; ``x_ref``, ``y_ref`` the
    reference values (MuJoCo's qpos0 of the two joints). A gear pair: a1 = −ratio. One more
    constraint row: an ideal, workless closure.
    """

    name: str
    joint: str
    driver: str
    coefficients: tuple[float, ...] = (0.0, 1.0)
    x_ref: float = 0.0
    y_ref: float = 0.0

    def __post_init__(self):
        _name(self.name, "coupling name")
        _name(self.joint, f"coupling {self.name!r}: joint")
        _name(self.driver, f"coupling {self.name!r}: driver")
        if self.joint == self.driver:
            raise MechanismError(f"coupling {self.name!r} couples joint {self.joint!r} to itself")
        try:
            coefficients = tuple(self.coefficients)
        except TypeError:
            raise MechanismError(f"coupling {self.name!r}: coefficients must be 1 to {POLY_TERMS} numbers "
                                 f"a0 … a4, got {self.coefficients!r}") from None
        if not 1 <= len(coefficients) <= POLY_TERMS or not all(
                isinstance(a, (int, float)) and not isinstance(a, bool) for a in coefficients):
            raise MechanismError(f"coupling {self.name!r}: coefficients must be 1 to {POLY_TERMS} numbers "
                                 f"a0 … a4, got {self.coefficients!r}")
        coefficients = tuple(float(a) for a in coefficients) + (0.0,) * (POLY_TERMS - len(coefficients))
        if not all(math.isfinite(a) for a in coefficients):
            raise MechanismError(f"coupling {self.name!r}: coefficients must be finite, got {coefficients}")
        if not any(coefficients[1:]):
            raise MechanismError(f"coupling {self.name!r}: no term in the driver {self.driver!r} (a1 … a4 all 0): "
                                 f"it locks joint {self.joint!r}, which is not a coupling")
        object.__setattr__(self, "coefficients", coefficients)
        for f in ("x_ref", "y_ref"):
            value = getattr(self, f)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise MechanismError(f"coupling {self.name!r}: {f} must be a finite number, got {value!r}")
            object.__setattr__(self, f, float(value))

    def polynomial(self, x: float) -> tuple[float, float, float]:
        """p(s), p'(s), p''(s) at s = x − x_ref: y = y_ref + p(s)."""
        a0, a1, a2, a3, a4 = self.coefficients
        s = x - self.x_ref
        return (a0 + s * (a1 + s * (a2 + s * (a3 + s * a4))),
                a1 + s * (2.0 * a2 + s * (3.0 * a3 + s * 4.0 * a4)),
                2.0 * a2 + s * (6.0 * a3 + s * 12.0 * a4))


@dataclass(frozen=True)
class TreeEdge:
    """How a moving body hangs from the spanning tree: by ``joint`` from ``parent``."""

    body: str
    joint: str
    parent: str


@dataclass(frozen=True)
class Linkage:
    """A planar linkage of revolute and prismatic joints with one degree of freedom or more.

    Parameters
    ----------
    bodies : sequence of Body
        The moving bodies, and optionally a body named ``"ground"`` holding fixed points.
    joints : sequence of RevoluteJoint or PrismaticJoint
    input_joint : str
        Name of the joint whose coordinate is the independent coordinate q (rad for a
        revolute: body_b's angle relative to body_a; m for a prismatic: its displacement);
        with several degrees of freedom, the first input.
    tree_first : tuple of str
        Joints to take into the spanning tree before the other revolute ones (after the input
        and the prismatic joints), where the loops allow: a joint inertia's joints, which
        MuJoCo holds only on a tree joint (:class:`Mechanism` passes them).
    couplings : tuple of JointCoupling
        Polynomial couplings between two joints' coordinates; each is one more closure
        equation (one fewer degree of freedom).
    inputs : tuple of str
        With several degrees of freedom, every input joint in order, the first being
        ``input_joint`` (q = (q_1, …, q_n), each its joint's own coordinate); empty (the default)
        means ``(input_joint,)``, one degree of freedom.

    Attributes (derived)
    --------------------
    moving : tuple of str
        Names of the moving bodies, in the order given.
    tree : tuple of TreeEdge
        The spanning tree from ground, in breadth-first order (a parent before its children).
        The input joint is taken first, then prismatic joints before revolute ones, so the
        input is a tree joint and a loop is cut at a revolute joint whenever it has one.
    cut_joints : tuple of str
        One joint per independent loop, not in the tree; its loop closes when it is satisfied.
    grubler_dof : int
        Grübler's count 3·moving bodies − 2·joints: at most the number of inputs (above is
        refused). Below it the loops are redundantly closed (more loop equations than the
        coordinates less the inputs); whether the linkage moves with that many DOF is decided by the rank of its loop equations at the
        assembled configuration (:func:`loopcheck.kinematics.rank_dof`), and the scene reader warns
        that the count differs (:class:`GrublerCountWarning`).
    """

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    input_joint: str
    tree_first: tuple[str, ...] = ()
    couplings: tuple[JointCoupling, ...] = ()
    inputs: tuple[str, ...] = ()
    moving: tuple[str, ...] = field(init=False, repr=False, compare=False)
    tree: tuple[TreeEdge, ...] = field(init=False, repr=False, compare=False)
    cut_joints: tuple[str, ...] = field(init=False, repr=False, compare=False)
    grubler_dof: int = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "bodies", tuple(self.bodies))
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "tree_first", tuple(self.tree_first))
        object.__setattr__(self, "couplings", tuple(self.couplings))
        object.__setattr__(self, "inputs", tuple(self.inputs) or (self.input_joint,))
        for b in self.bodies:
            if not isinstance(b, Body):
                raise MechanismError(f"bodies must be Body values, got {type(b).__name__}")
        for j in self.joints:
            if not isinstance(j, (RevoluteJoint, PrismaticJoint)):
                raise MechanismError(f"joints must be RevoluteJoint or PrismaticJoint values, "
                                     f"got {type(j).__name__}")
        _unique([b.name for b in self.bodies], "body")
        _unique([j.name for j in self.joints], "joint")
        bodies = self.body_map
        moving = tuple(b.name for b in self.bodies if b.name != GROUND)
        if not moving:
            raise MechanismError("the linkage has no moving body")
        for j in self.joints:
            for side in ("a", "b"):
                body, point = getattr(j, f"body_{side}"), getattr(j, f"point_{side}")
                if body not in bodies:
                    raise MechanismError(f"joint {j.name!r}: unknown body {body!r} (body_{side})")
                if point not in bodies[body].points:
                    raise MechanismError(f"joint {j.name!r}: body {body!r} has no point {point!r} "
                                         f"(point_{side})")
        if self.input_joint not in {j.name for j in self.joints}:
            raise MechanismError(f"input joint {self.input_joint!r} is not one of the joints")
        if self.inputs[0] != self.input_joint:
            raise MechanismError(f"inputs must start with the input joint {self.input_joint!r}, got {list(self.inputs)}")
        _unique(list(self.inputs), "input")
        for name in self.inputs:
            if name not in {j.name for j in self.joints}:
                raise MechanismError(f"input {name!r} is not one of the joints")
        for name in self.tree_first:
            if name not in {j.name for j in self.joints}:
                raise MechanismError(f"tree_first: {name!r} is not one of the joints")
        _check_couplings(self.couplings, self.joint_map)
        touched = {j.body_a for j in self.joints} | {j.body_b for j in self.joints}
        for name in moving:
            if name not in touched:
                raise MechanismError(f"body {name!r} is connected to nothing (no joint names it)")
        if GROUND not in touched:
            raise MechanismError("no joint connects the linkage to ground")
        n, j, c = len(moving), len(self.joints), len(self.couplings)
        dof = 3 * n - 2 * j - c
        tree, cut = self._spanning_tree(moving)
        # Grübler's count below 1 is not a refusal: a redundantly closed loop (dependent loop
        # equations: a parallelogram with an extra parallel crank) may still move with one DOF.
        # The rank of the loop equations at the assembled configuration decides
        # (:func:`loopcheck.kinematics.rank_dof`, when a scene is read); the count is a warning then.
        if dof > len(self.inputs):
            raise MechanismError(f"the linkage has {dof} degrees of freedom by Grübler's count "
                                 f"3·{n} moving bodies − 2·{j} joints"
                                 + (f" − {c} couplings" if c else "")
                                 + (", not 1" if len(self.inputs) == 1 else f", more than its {len(self.inputs)} inputs"))
        kinds = self.joint_map
        for name in cut:
            loop = _cycle(tree, kinds[name])
            if all(isinstance(kinds[k], PrismaticJoint) for k in loop):
                raise MechanismError(f"the loop of joints {', '.join(loop)} has only prismatic "
                                     f"joints: no revolute joint to cut it with a connect equality")
            if isinstance(kinds[name], PrismaticJoint):
                raise MechanismError(f"the loop of joints {', '.join(loop)} can only be cut at its "
                                     f"prismatic joint {name!r} once the input joint is kept whole: "
                                     f"no revolute joint to close it with a connect equality")
        object.__setattr__(self, "moving", moving)
        object.__setattr__(self, "tree", tree)
        object.__setattr__(self, "cut_joints", cut)
        object.__setattr__(self, "grubler_dof", dof)

    @property
    def body_map(self) -> dict[str, Body]:
        """Bodies by name."""
        return {b.name: b for b in self.bodies}

    @property
    def joint_map(self) -> dict[str, Joint]:
        """Joints by name."""
        return {j.name: j for j in self.joints}

    @property
    def dof(self) -> int:
        """The degrees of freedom the linkage is driven with: one per input."""
        return len(self.inputs)

    def loop_of(self, cut_joint: str) -> tuple[str, ...]:
        """The joints of the loop that ``cut_joint`` closes: its tree path and itself."""
        return _cycle(self.tree, self.joint_map[cut_joint])

    def _spanning_tree(self, moving: tuple[str, ...]) -> tuple[tuple[TreeEdge, ...], tuple[str, ...]]:
        """Breadth-first tree from ground taking the input joint first, then prismatic joints,
        then the joints of ``tree_first`` (a maximum spanning tree with prismatic joints weighted
        above revolute ones): the
        input joints (all of them, in order) are never cut (an engine can drive it as a tree joint), and a cut joint
        is prismatic only if its loop is all prismatic (or it closes the input's loop that way,
        which :class:`Linkage` refuses like an all-prismatic loop)."""
        adjacent: dict[str, list[Joint]] = {}
        for jt in self.joints:
            adjacent.setdefault(jt.body_a, []).append(jt)
            adjacent.setdefault(jt.body_b, []).append(jt)
        reached = {GROUND}
        frontier: deque[Joint] = deque(adjacent.get(GROUND, ()))
        tree: list[TreeEdge] = []
        used = set()
        while frontier:
            candidates = [jt for jt in frontier
                          if (jt.body_a in reached) != (jt.body_b in reached)]
            if not candidates:
                break
            driven = sorted((jt for jt in candidates if jt.name in self.inputs), key=lambda jt: self.inputs.index(jt.name))
            prismatic = [jt for jt in candidates if isinstance(jt, PrismaticJoint)]
            first = [jt for jt in candidates if jt.name in self.tree_first]
            jt = (driven or prismatic or first or candidates)[0]
            frontier.remove(jt)
            child, parent = ((jt.body_b, jt.body_a) if jt.body_a in reached
                             else (jt.body_a, jt.body_b))
            reached.add(child)
            used.add(jt.name)
            tree.append(TreeEdge(child, jt.name, parent))
            frontier.extend(k for k in adjacent[child] if k.name not in used and k not in frontier)
        missing = [b for b in moving if b not in reached]
        if missing:
            raise MechanismError(f"bodies {', '.join(map(repr, missing))} form a group not "
                                 f"connected to ground")
        return tuple(tree), tuple(jt.name for jt in self.joints if jt.name not in used)


def _check_couplings(couplings, joints) -> None:
    """Couplings are JointCoupling values with unique names, between known joints."""
    for c in couplings:
        if not isinstance(c, JointCoupling):
            raise MechanismError(f"couplings must be JointCoupling values, got {type(c).__name__}")
    _unique([c.name for c in couplings], "coupling")
    for c in couplings:
        if c.name in joints:
            raise MechanismError(f"coupling {c.name!r} has a joint's name: couplings and joints share MuJoCo's "
                                 "equality names (a cut joint's connect is named after it)")
    for c in couplings:
        for role, name in (("joint", c.joint), ("driver", c.driver)):
            if name not in joints:
                raise MechanismError(f"coupling {c.name!r}: unknown joint {name!r} ({role})")


def _check_mass(body: Body, joints) -> None:
    """A moving body has mass and inertia, or only an inertia about a fixed pivot."""
    if body.mass > 0.0:
        if body.inertia <= 0.0:
            raise MechanismError(f"body {body.name!r} has mass but no inertia: give its "
                                 f"moment of inertia about the centre of mass")
        return
    if body.inertia <= 0.0:
        raise MechanismError(f"body {body.name!r} has neither mass nor inertia")
    for j in joints:
        if isinstance(j, RevoluteJoint) and GROUND in (j.body_a, j.body_b) and body.name in (j.body_a, j.body_b):
            own = j.point_b if j.body_b == body.name else j.point_a
            if body.points[own] == body.com:
                return
    raise MechanismError(f"body {body.name!r} has no mass: only a body turning about a fixed "
                         f"pivot may be given by its inertia about it alone (its com must be "
                         f"the point of a revolute joint to ground)")


def _unique(names: list[str], kind: str) -> None:
    seen = set()
    for n in names:
        if n in seen:
            raise MechanismError(f"duplicate {kind} name {n!r}")
        seen.add(n)


def _path_to_ground(tree: tuple[TreeEdge, ...], body: str) -> list[str]:
    """Tree joints from ``body`` down to ground, nearest first."""
    up = {e.body: e for e in tree}
    path = []
    while body != GROUND:
        e = up[body]
        path.append(e.joint)
        body = e.parent
    return path


def _cycle(tree: tuple[TreeEdge, ...], joint: Joint) -> tuple[str, ...]:
    """The tree joints on the path between the joint's two bodies, and the joint itself."""
    pa = _path_to_ground(tree, joint.body_a)
    pb = _path_to_ground(tree, joint.body_b)
    common = set(pa) & set(pb)
    return tuple([k for k in pa if k not in common] + [k for k in pb if k not in common]
                 + [joint.name])


def point_ref(text, what: str) -> tuple[str, str]:
    """(body, point) from a ``"body.point"`` reference."""
    if not isinstance(text, str) or text.count(".") != 1 or not all(text.split(".")):
        raise MechanismError(f"{what} must be a point reference \"body.point\", got {text!r}")
    body, point = text.split(".")
    return body, point


@dataclass(frozen=True)
class LineElement:
    """A damper or a spring along the line between two points.

    ``kind`` is ``"damper"`` (force −b Ḋ along the line, ``coefficient`` b in N·s/m) or
    ``"spring"`` (V = ½ k (D − D0)², ``coefficient`` k in N/m, ``rest_length`` D0 in m).
    """

    kind: str
    name: str
    body_a: str
    point_a: str
    body_b: str
    point_b: str
    coefficient: float
    rest_length: float = 0.0

    def __post_init__(self):
        _name(self.name, "line element name")
        if self.kind not in LINE_ELEMENT_KINDS:
            raise MechanismError(f"line element {self.name!r}: kind must be one of "
                                 f"{', '.join(LINE_ELEMENT_KINDS)}, got {self.kind!r}")
        if not (math.isfinite(self.coefficient) and self.coefficient > 0.0):
            raise MechanismError(f"{self.kind} {self.name!r}: coefficient must be positive "
                                 f"and finite, got {self.coefficient}")
        if not (math.isfinite(self.rest_length) and self.rest_length >= 0.0):
            raise MechanismError(f"{self.kind} {self.name!r}: rest_length must be ≥ 0 m, "
                                 f"got {self.rest_length}")
        if self.body_a == self.body_b:
            raise MechanismError(f"{self.kind} {self.name!r} joins two points of body "
                                 f"{self.body_a!r}: its length never changes")


LINE_ELEMENT_KINDS = ("damper", "spring")
JOINT_ELEMENT_KINDS = ("damper", "spring", "inertia", "friction")


@dataclass(frozen=True)
class JointElement:
    """A damper, a spring or an inertia on one joint's own coordinate u: a revolute joint's
    relative angle θ_b − θ_a (rad), a prismatic joint's displacement s (m); the joint may be a
    cut joint.

    ``kind`` is ``"damper"`` (generalized force −c u̇ on u: a torque in N·m with c in
    N·m·s/rad, or a force in N with c in N·s/m), ``"spring"`` (V = ½ k (u − u0)², k in
    N·m/rad or N/m, ``rest`` u0 in rad or m) or ``"inertia"`` (kinetic energy ½ I u̇², I in
    kg·m² or kg: a rotor geared to the joint, MuJoCo's ``armature``) or ``"friction"`` (dry
    Coulomb friction of f = c, N·m or N, static equal to kinetic: −f sign(u̇) while the joint
    slips, up to f while it sticks; MuJoCo's ``frictionloss``). The relative angle counts
    whole turns: a torsion spring wound by one turn stores ½ k (2π)².
    """

    kind: str
    name: str
    joint: str
    coefficient: float
    rest: float = 0.0

    def __post_init__(self):
        _name(self.name, "joint element name")
        _name(self.joint, f"joint {self.kind} {self.name!r}: joint")
        if self.kind not in JOINT_ELEMENT_KINDS:
            raise MechanismError(f"joint element {self.name!r}: kind must be one of "
                                 f"{', '.join(JOINT_ELEMENT_KINDS)}, got {self.kind!r}")
        if not (math.isfinite(self.coefficient) and self.coefficient > 0.0):
            raise MechanismError(f"joint {self.kind} {self.name!r}: coefficient must be positive "
                                 f"and finite, got {self.coefficient}")
        if not math.isfinite(self.rest):
            raise MechanismError(f"joint {self.kind} {self.name!r}: rest must be finite, got {self.rest}")
        object.__setattr__(self, "coefficient", float(self.coefficient))
        object.__setattr__(self, "rest", float(self.rest))


@dataclass(frozen=True)
class PointForce:
    """A force of magnitude F(q) along a fixed direction of the plane, applied at a point.

    F is tabulated over the input coordinate q (rad or m) and interpolated by a degree-5
    spline (periodic with ``period`` when given; else held at its end values outside the
    table); a gas force over crank angle, a punch-press load over ram travel.

    direction : rad, in the ground frame; the force is F(q) (cos, sin)(direction) (N).
    coordinate, values : (k,) the table, k ≥ 2, coordinate strictly increasing.
    period : the table repeats every ``period`` (rad or m), or None.
    """

    name: str
    body: str
    point: str
    direction: float
    coordinate: tuple[float, ...]
    values: tuple[float, ...]
    period: float | None = None

    def __post_init__(self):
        _name(self.name, "point force name")
        q = tuple(float(v) for v in self.coordinate)
        f = tuple(float(v) for v in self.values)
        if len(q) != len(f) or len(q) < 2:
            raise MechanismError(f"point force {self.name!r}: the table needs two or more "
                                 f"(coordinate, value) pairs of equal length")
        if not all(math.isfinite(v) for v in q + f + (float(self.direction),)):
            raise MechanismError(f"point force {self.name!r}: the table and direction must be finite")
        if any(b <= a for a, b in zip(q, q[1:])):
            raise MechanismError(f"point force {self.name!r}: the coordinates must increase strictly")
        if self.period is not None:
            if not (math.isfinite(self.period) and self.period > 0.0):
                raise MechanismError(f"point force {self.name!r}: period must be positive, got {self.period}")
            if q[-1] - q[0] > self.period:
                raise MechanismError(f"point force {self.name!r}: the table spans {q[-1] - q[0]:g}, "
                                     f"more than its period {self.period:g}")
            # A table spanning one period (loads.TabulatedForce's closing rule) gives its last
            # point twice: F(q0 + period) must be F(q0), or one of the two would be dropped.
            if (q[-1] - q[0] >= self.period * (1 - 1e-12)
                    and not math.isclose(f[-1], f[0], rel_tol=1e-12, abs_tol=1e-12 * max(map(abs, f)))):
                raise MechanismError(f"point force {self.name!r}: the table spans its period {self.period:g} and "
                                     f"its ends disagree (F = {f[0]:g} N at {q[0]:g}, {f[-1]:g} N at {q[-1]:g}): "
                                     "a periodic table ends on its first value, or one period short of it")
        object.__setattr__(self, "coordinate", q)
        object.__setattr__(self, "values", f)
        object.__setattr__(self, "direction", float(self.direction))


@dataclass(frozen=True)
class TimedForce:
    """A force of magnitude F(t) along a fixed direction of the plane, applied at a point: a
    pressure history on a piston while the crank is the input.

    ``profile`` is one of the input load's profiles (:mod:`loopcheck.loads`: constant, pulse,
    table; piecewise constant in t, its values in N), ``direction`` rad in the ground frame; the
    force is F(t) (cos, sin)(direction) (N). Its edges are load edges: the reduced integrators
    stop at them and MuJoCo's automatic timestep puts them on its step grid.
    """

    name: str
    body: str
    point: str
    direction: float
    profile: object  # loopcheck.loads.LoadProfile (not imported here: loads needs numpy only)

    def __post_init__(self):
        _name(self.name, "timed force name")
        if not math.isfinite(float(self.direction)):
            raise MechanismError(f"timed force {self.name!r}: direction must be finite, got {self.direction}")
        if not hasattr(self.profile, "edges") or not hasattr(self.profile, "sample"):
            raise MechanismError(f"timed force {self.name!r}: profile must be a load profile (loopcheck.loads), "
                                 f"got {type(self.profile).__name__}")
        object.__setattr__(self, "direction", float(self.direction))



def _finite_number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MechanismError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _range(value, what: str) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise MechanismError(f"{what} must be a pair (lo, hi), got {value!r}") from None
    lo, hi = _finite_number(lo, f"{what} lo"), _finite_number(hi, f"{what} hi")
    if not lo < hi:
        raise MechanismError(f"{what} must have lo < hi, got ({lo:g}, {hi:g})")
    return lo, hi


@dataclass(frozen=True)
class Actuator:
    """An actuator as MuJoCo applies it (``<general>`` with fixed gain and affine bias; ``motor``,
    ``position`` and ``velocity`` are its special cases).

    Transmission: ``joint`` (its own coordinate u, as :class:`JointElement` defines it: a
    revolute joint's relative angle, a prismatic joint's displacement) or ``tendon``, a fixed
    tendon: pairs (joint, c) with l = Σ c_j u_j (coefficients finite and nonzero). Exactly one.
    With l the transmission's length, the actuator's length is L = gear·l (MuJoCo's
    ``actuator_length``), its force (N·m or N, MuJoCo's ``actuator_force``)

        f = clamp(gain·clamp(ctrl(t), ctrlrange) + b0 + b1·L + b2·L̇, forcerange)

    and its generalized force gear·f·dl/dq; its power f·L̇. A position servo (kp, kv) is gain
    kp, bias (0, −kp, −kv). ``control`` is the control over time, one of the input load's
    profiles (:mod:`loopcheck.loads`: piecewise constant in t; None: zero); its edges are load edges.
    """

    name: str
    joint: str | None = None
    tendon: tuple[tuple[str, float], ...] | None = None
    gain: float = 1.0
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gear: float = 1.0
    ctrlrange: tuple[float, float] | None = None
    forcerange: tuple[float, float] | None = None
    control: object = None  # loopcheck.loads.LoadProfile, or None (zero)

    def __post_init__(self):
        _name(self.name, "actuator name")
        what = f"actuator {self.name!r}"
        if (self.joint is None) == (self.tendon is None):
            raise MechanismError(f"{what}: give its transmission, a joint or a tendon (one of the two)")
        if self.joint is not None:
            _name(self.joint, f"{what}: joint")
        else:
            pairs = tuple(self.tendon.items()) if isinstance(self.tendon, Mapping) else self.tendon
            try:
                pairs = tuple((j, c) for j, c in pairs)
            except (TypeError, ValueError):
                raise MechanismError(f"{what}: tendon must be pairs (joint, coefficient), got {self.tendon!r}") from None
            if not pairs:
                raise MechanismError(f"{what}: tendon has no joint")
            out = []
            for j, c in pairs:
                _name(j, f"{what}: tendon joint")
                c = _finite_number(c, f"{what}: tendon coefficient of joint {j!r}")
                if c == 0.0:
                    raise MechanismError(f"{what}: tendon coefficient of joint {j!r} must be nonzero")
                out.append((j, c))
            _unique([j for j, _ in out], f"{what}: tendon joint")
            object.__setattr__(self, "tendon", tuple(out))
        object.__setattr__(self, "gain", _finite_number(self.gain, f"{what}: gain"))
        try:
            bias = tuple(self.bias)
        except TypeError:
            bias = ()
        if len(bias) != 3:
            raise MechanismError(f"{what}: bias must be three numbers (b0, b1, b2), got {self.bias!r}")
        object.__setattr__(self, "bias", tuple(_finite_number(b, f"{what}: bias") for b in bias))
        gear = _finite_number(self.gear, f"{what}: gear")
        if gear == 0.0:
            raise MechanismError(f"{what}: gear must be nonzero")
        object.__setattr__(self, "gear", gear)
        object.__setattr__(self, "ctrlrange", _range(self.ctrlrange, f"{what}: ctrlrange"))
        object.__setattr__(self, "forcerange", _range(self.forcerange, f"{what}: forcerange"))
        if self.control is not None and (not hasattr(self.control, "edges") or not hasattr(self.control, "sample")):
            raise MechanismError(f"{what}: control must be a load profile (loopcheck.loads), "
                                 f"got {type(self.control).__name__}")

    @property
    def terms(self) -> tuple[tuple[str, float], ...]:
        """The transmission as (joint, coefficient) pairs: l = Σ c_j u_j."""
        return ((self.joint, 1.0),) if self.joint is not None else self.tendon

    @property
    def state_dependent(self) -> bool:
        """Whether the force depends on the state (b1 or b2 nonzero)."""
        return self.bias[1] != 0.0 or self.bias[2] != 0.0

    def control_values(self, times):
        """The control at each time, clamped to ctrlrange (zero without a control)."""
        import numpy as np
        values = (np.zeros(np.shape(times)) if self.control is None
                  else np.asarray(self.control.sample(np.asarray(times, dtype=float)), dtype=float))
        return values if self.ctrlrange is None else np.clip(values, *self.ctrlrange)

    def force(self, ctrl, length, velocity):
        """f (N·m or N) at a clamped control, the transmission's length l and rate l̇ (arrays or
        numbers): clamp(gain·ctrl + b0 + b1·gear·l + b2·gear·l̇, forcerange)."""
        import numpy as np
        b0, b1, b2 = self.bias
        f = self.gain * ctrl + b0 + b1 * (self.gear * length) + b2 * (self.gear * velocity)
        return f if self.forcerange is None else np.clip(f, *self.forcerange)


@dataclass(frozen=True)
class Mechanism:
    """A checked linkage with mass properties, and the dampers, springs and point forces
    acting on it (every moving body has mass and inertia, or an inertia about a fixed pivot),
    and the dampers, springs and inertias on joints (:class:`JointElement`). Dampers, springs
    and joint inertias share one namespace, line and joint elements alike (each is one tendon
    in MuJoCo)."""

    linkage: Linkage
    elements: tuple[LineElement, ...] = ()
    point_forces: tuple[PointForce, ...] = ()
    joint_elements: tuple[JointElement, ...] = ()
    timed_forces: tuple[TimedForce, ...] = ()
    actuators: tuple[Actuator, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "actuators", tuple(self.actuators))
        for a in self.actuators:
            if not isinstance(a, Actuator):
                raise MechanismError(f"actuators must be Actuator values, got {type(a).__name__}")
        object.__setattr__(self, "elements", tuple(self.elements))
        object.__setattr__(self, "point_forces", tuple(self.point_forces))
        object.__setattr__(self, "joint_elements", tuple(self.joint_elements))
        object.__setattr__(self, "timed_forces", tuple(self.timed_forces))
        bodies = self.linkage.body_map
        for name in self.linkage.moving:
            _check_mass(bodies[name], self.linkage.joints)
        _unique([e.name for e in self.elements] + [e.name for e in self.joint_elements], "damper, spring or inertia")
        joints = self.linkage.joint_map
        for e in self.joint_elements:
            if e.joint not in joints:
                raise MechanismError(f"joint {e.kind} {e.name!r}: unknown joint {e.joint!r}")
        _unique([p.name for p in self.point_forces] + [p.name for p in self.timed_forces], "point force")
        _unique([a.name for a in self.actuators], "actuator")
        for a in self.actuators:
            for j, _ in a.terms:
                if j not in joints:
                    raise MechanismError(f"actuator {a.name!r}: unknown joint {j!r}")

        def check(body, point, what):
            if body not in bodies:
                raise MechanismError(f"{what}: unknown body {body!r}")
            if point not in bodies[body].points:
                raise MechanismError(f"{what}: body {body!r} has no point {point!r}")
        for e in self.elements:
            check(e.body_a, e.point_a, f"{e.kind} {e.name!r}")
            check(e.body_b, e.point_b, f"{e.kind} {e.name!r}")
        for p in self.point_forces:
            check(p.body, p.point, f"point force {p.name!r}")
            if p.body == GROUND:
                raise MechanismError(f"point force {p.name!r} acts on the ground: it does no work")
        for p in self.timed_forces:
            check(p.body, p.point, f"timed force {p.name!r}")
            if p.body == GROUND:
                raise MechanismError(f"timed force {p.name!r} acts on the ground: it does no work")

    @property
    def dampers(self) -> tuple[LineElement, ...]:
        return tuple(e for e in self.elements if e.kind == "damper")

    @property
    def springs(self) -> tuple[LineElement, ...]:
        return tuple(e for e in self.elements if e.kind == "spring")

    @property
    def joint_dampers(self) -> tuple[JointElement, ...]:
        return tuple(e for e in self.joint_elements if e.kind == "damper")

    @property
    def joint_springs(self) -> tuple[JointElement, ...]:
        return tuple(e for e in self.joint_elements if e.kind == "spring")

    @property
    def joint_inertias(self) -> tuple[JointElement, ...]:
        return tuple(e for e in self.joint_elements if e.kind == "inertia")

    @property
    def joint_frictions(self) -> tuple[JointElement, ...]:
        return tuple(e for e in self.joint_elements if e.kind == "friction")
