"""Reading a user's MJCF: the planar linkage a MuJoCo model describes (one DOF or several), as a scene.

The file is compiled by MuJoCo itself (``mujoco.MjModel``), so defaults, classes, includes,
``angle="degree"``, euler and axis-angle frames are resolved as MuJoCo resolves them. The model
is read in one configuration, the keyframe's ``qpos`` (or ``qpos0``), where its loops must
close; what becomes of each element:

- Bodies: a body with one hinge or slide is a moving body; a body without a joint is welded to
  its parent and merges into it (mass, centre of mass, inertia about the plane's normal); the
  world and every body welded to it are the ground. A body whose centre of mass sits on its pin
  to ground is written by its inertia about that pivot (``pivot_inertia``): a mass there never
  moves, so it adds nothing (the MJCF that ``loopcheck export-mjcf`` writes puts 1 kg there, since
  MuJoCo refuses a moving body without mass).
- The plane: its normal is the input hinge's axis (else the first hinge's); every hinge axis
  must be parallel to it and every slide axis in the plane. A body on a hinge has its own 2-D
  frame: its MuJoCo frame's x axis projected on the plane (its MuJoCo frame when its z is the
  normal, as in the models ``loopcheck export-mjcf`` writes). A body on a slide takes its parent's
  2-D frame, whichever way its own MuJoCo frame is turned (its points and centre of mass are
  expressed in that frame), since the description's prismatic joint keeps its child parallel to its
  parent; ground's is the world's.
- Points: every site (named after it, without a ``"<body>."`` prefix), every joint's position on
  both of its bodies and every loop-closure anchor; a point at a site's position is that site.
- Joints: hinges are revolute joints and slides prismatic ones, from the parent body (``a``) to
  the child (``b``); each ``connect`` equality (body form, with MuJoCo's second anchor, which its
  compiler places where the first one is at ``qpos0``; or site form) is a revolute joint closing a
  loop.
- Springs, dampers and inertias: a spatial tendon between two sites with ``stiffness`` or
  ``damping`` is a line spring or damper; a fixed tendon along one joint's coordinate (any joint,
  also a loop's), and a joint's own ``stiffness``, ``damping`` and ``armature``, are joint
  springs, dampers and inertias.
- Gravity compensation: a moving body's ``gravcomp`` (its weight scaled by 1 − gravcomp; one value
  for the bodies welded into it; a body welded to the world moves nothing, a body written by its
  pivot inertia has no weight that moves). A joint's ``actuatorgravcomp`` routes the same force
  through the actuator: the same motion while its ``actuatorfrcrange`` does not clamp it.
- The load: a motor on the input joint, ``gear`` × its control (the keyframe's ``ctrl`` or the
  one given, :class:`Control`); gravity: the option's, projected on the plane.
- Several degrees of freedom (the loop Jacobian's rank deficiency at the configuration read): the
  inputs are ``--input``'s joints, then the joints the actuators act on, then coordinate
  partitioning (:func:`_inputs`); every actuator is then a scene actuator, and every input's q and
  q̇ come from the configuration read and its qvel.

Anything else that acts is refused with one line naming it (:class:`MjcfError`): ball and free
joints, several joints on one body, axes off the plane, several degrees of freedom without a loop,
equalities other than connect, actuators other than one motor on one joint, friction loss,
geoms that can touch, fluid forces, tendons that wrap or have a dead band, armature along a line,
bodies welded together with different ``gravcomp``, a joint's ``actuatorfrcrange`` (limited; MuJoCo
clamps the joint's total actuator force), a joint equality open at the configuration read, an input
joint a coupling locks. The option flags ``frictionloss``, ``limit`` and ``actuation`` ="disable" leave
out the joint frictions, the ranges, the load and actuators (a warning each), as MuJoCo does.
A value that is NaN or infinite, or finite and outside what the description can hold (a negative
damping, stiffness, armature, mass, inertia or density; a spring or damper with polynomial terms),
is refused too, naming the element, the MJCF attribute and the default class it came from
(:func:`_check_values`); zero is "absent". A model path that is not a regular file is refused
before MuJoCo opens it (:func:`check_model_path`). MuJoCo's warnings while loading go through
:mod:`loopcheck.mujoco_model.warning_handler` and become the import's own warnings.
"""

from __future__ import annotations

import argparse
import math
import os
import stat
import warnings
import xml.etree.ElementTree as ET
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from loopcheck import kinematics as loops
from loopcheck.loads import ConstantLoad, LoadProfile, PiecewiseConstantLoad
from loopcheck.mechanism import (GROUND, Actuator, Body, GrublerCountWarning, JointCoupling, JointElement, LineElement,
                                 Linkage,
                                 Mechanism, MechanismError, PrismaticJoint, RevoluteJoint)
from loopcheck.scene import LIMITS, Scene, SceneError, Tolerances
from loopcheck.scene_writer import scene_data
from loopcheck.scenefile import redundancy_note, scene_from_dict
from loopcheck.settings import parse_number

from loopcheck.mujoco_model.build import (BASE_BODY, CUSTOM_ACTUATOR_CTRL, CUSTOM_CTRL, CUSTOM_HORIZON,
                                          CUSTOM_INPUTS, CUSTOM_PREFIX, CUSTOM_TOLERANCES, INPUT_MOTOR)
from loopcheck.mujoco_model.warning_handler import compile_spec, mujoco_warnings

# Loops must close at the configuration read within this fraction of the longest link (the
# issue's decision); the scene file's Newton assembly then polishes the configuration.
CLOSURE_RTOL = 1e-6
# Two axes are parallel (or a slide in the plane) when |sin| (or |cos|) of their angle is below this.
AXIS_TOL = 1e-9
# A joint's or anchor's position is a site's when they are this close, relative to the model's size.
SAME_POINT_RTOL = 1e-9
# MuJoCo's enums as plain ints: a model's arrays hold numpy integers, which `in` and dict keys do not
# match with the enums themselves.
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
_CONNECT = int(mujoco.mjtEq.mjEQ_CONNECT)
_WELD = int(mujoco.mjtEq.mjEQ_WELD)
_EQ_JOINT = int(mujoco.mjtEq.mjEQ_JOINT)
_EQ_TENDON = int(mujoco.mjtEq.mjEQ_TENDON)
_WRAP_SITE = int(mujoco.mjtWrap.mjWRAP_SITE)
_WRAP_JOINT = int(mujoco.mjtWrap.mjWRAP_JOINT)
_TRN_JOINT = int(mujoco.mjtTrn.mjTRN_JOINT)
_DYN_NONE = int(mujoco.mjtDyn.mjDYN_NONE)
_GAIN_FIXED = int(mujoco.mjtGain.mjGAIN_FIXED)
_BIAS_NONE = int(mujoco.mjtBias.mjBIAS_NONE)
_OBJ_SITE = int(mujoco.mjtObj.mjOBJ_SITE)
_NAME_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")


class MjcfError(SceneError):
    """An MJCF model loopcheck cannot read as a planar linkage; the message names the element."""


@dataclass(frozen=True)
class Control:
    """The input motor's control over time (the actuator's ``ctrl`` units): a constant, or a table
    of (time s, value) pairs, each value held from its time on (zero before the first).

    ``parse`` reads the command line's form: a number (``2.5``) or ``t:value,t:value,...``
    (``0:250,0.1:0``)."""

    times: tuple[float, ...]
    values: tuple[float, ...]

    @classmethod
    def constant(cls, value: float) -> "Control":
        return cls((0.0,), (float(value),))

    @classmethod
    def parse(cls, text: str) -> "Control":
        """The command line's form (a number, or ``t:value,t:value,...``); ValueError saying why not."""
        def number(word: str, what: str) -> float:
            try:
                return parse_number(word)
            except argparse.ArgumentTypeError as exc:
                raise ValueError(f"{what}: {exc}") from None

        text = text.strip()
        if ":" not in text:
            return cls.constant(number(text, "the control (a number, or a table t:value,t:value,...)"))
        times, values = [], []
        for pair in text.split(","):
            parts = pair.split(":")
            if len(parts) != 2:
                raise ValueError(f"'{pair}' is not a pair time:value (s and the control's units)")
            t, v = number(parts[0], f"the time of '{pair}'"), number(parts[1], f"the value of '{pair}'")
            if t < 0.0:
                raise ValueError(f"'{pair}': the time must be ≥ 0 s")
            times.append(t)
            values.append(v)
        if any(b <= a for a, b in zip(times, times[1:])):
            raise ValueError("the table's times must increase strictly")
        return cls(tuple(times), tuple(values))

    @classmethod
    def parse_named(cls, text: str) -> tuple[str | None, "Control"]:
        """``--ctrl``'s forms: ``NAME=VALUE`` or ``NAME=t:value,...`` (one actuator's), or a bare
        ``VALUE`` or table (the only actuator's, or the input motor's): (name or None, control)."""
        name, eq, rest = text.partition("=")
        if not eq:
            return None, cls.parse(text)
        if not name.strip():
            raise ValueError(f"'{text}': the actuator's name before '=' is empty")
        try:
            return name.strip(), cls.parse(rest)
        except ValueError as exc:
            raise ValueError(f"{name.strip()}: {exc}") from None

    @staticmethod
    def by_name(given: list) -> tuple["Control | None", dict]:
        """``--ctrl`` given several times ((name or None, control) each): the bare control (at most
        one) and the named ones (one per actuator); ValueError saying which is given twice."""
        bare, named = None, {}
        for name, control in given or ():
            if name is None:
                if bare is not None:
                    raise ValueError("--ctrl VALUE given twice: a bare control is the only actuator's; name each "
                                     "actuator's (--ctrl NAME=VALUE)")
                bare = control
            elif name in named:
                raise ValueError(f"--ctrl {name}=...: given twice")
            else:
                named[name] = control
        return bare, named

    def at(self, times: np.ndarray) -> np.ndarray:
        """The control at each time (s): the value of the last entry at or before it, zero before the first."""
        k = np.searchsorted(np.asarray(self.times), np.asarray(times, dtype=float), side="right") - 1
        return np.where(k < 0, 0.0, np.asarray(self.values)[np.maximum(k, 0)])

    def load(self, gear: float) -> LoadProfile | None:
        """The load on the input joint (N·m or N): gear × control; None when it is zero throughout."""
        values = tuple(gear * v for v in self.values)
        if not any(values):
            return None
        if self.times == (0.0,):
            return ConstantLoad(values[0])
        return PiecewiseConstantLoad(self.times, values)


@dataclass(frozen=True)
class ImportedModel:
    """A user's MJCF read as a scene.

    scene : the description, assembled (Newton-polished) at the configuration read.
    model : MuJoCo's compiled model of the file, as written.
    qpos, qvel : the configuration read (the keyframe's or qpos0) and its rates.
    joint_of : the scene's name of each MuJoCo hinge or slide, by MuJoCo joint name.
    qpos_map, x_read : the scene's coordinates x = x_read + qpos_map (qpos − qpos_read) (and
        ẋ = qpos_map qvel): every body turns about the normal, so x is affine in qpos.
    control, gear : the motor's control over time (ctrl units) and the load per unit control
        (gear × gain; N·m or N); None and 0 without a motor.
    closure_residual : the largest gap of a loop at the configuration read, m (before Newton).
    polish : the largest change Newton made to the configuration (rad or m).
    keyframe : the keyframe read, by name (``#1 (unnamed)`` for a model's only, unnamed one); None
        for qpos0.
    warnings : one line each: what was disabled or left out, and why.
    said : one line each for stdout: what was chosen for the user (the model's only keyframe).
    connects : each connect equality of the model, in its order (:class:`ConnectSource`).
    motor_index : the MuJoCo index of the input motor (``control`` is its), when there is one.
    actuator_index : the MuJoCo index of each of the scene's actuators, in their order.
    range_sources : for each scene joint whose range comes from a MuJoCo joint's, that range as the
        file writes it and how the scene's coordinate is made of its qpos (one line, for messages:
        the scene's bounds differ from the file's where the joint's body frame is turned).
    extraction : the loop cut out of a larger model this was read from (``--loop``:
        :class:`loopcheck.reference_models.extract.Extraction`), else None.
    """

    scene: Scene
    model: mujoco.MjModel = field(repr=False)
    qpos: np.ndarray = field(repr=False)
    qvel: np.ndarray = field(repr=False)
    joint_of: dict[str, str]
    qpos_map: np.ndarray = field(repr=False)
    x_read: np.ndarray = field(repr=False)
    control: Control | None
    gear: float
    keyframe: str | None
    closure_residual: float
    polish: float
    warnings: tuple[str, ...]
    said: tuple[str, ...] = ()
    connects: tuple["ConnectSource", ...] = ()
    motor_index: int = 0
    actuator_index: tuple[int, ...] = ()
    range_sources: dict[str, str] = field(default_factory=dict)
    extraction: object = None


@dataclass(frozen=True)
class ConnectSource:
    """A connect equality as the file writes it: ``label`` names it for a user
    (:func:`element_label`), ``name`` is its MJCF name (None without one), and ``own`` says that it
    sets its own softness (``solref``, ``solimp`` or a default ``class``, or the file could not be
    matched to the model, an ``<include>``): a new ``<default><equality>`` does not reach it, so
    new values go on it."""

    label: str
    name: str | None
    own: bool
    tag: str = "connect"  # its MJCF tag inside <equality>: connect, or joint (a coupling)


def _connect_sources(path: Path, model: mujoco.MjModel) -> tuple[ConnectSource, ...]:
    """The model's connects and joint couplings (the equalities whose softness a check sets:
    :func:`loopcheck.reference_models.user_model._closures`), matched in file order to the
    ``<equality>`` elements of the file."""
    try:
        root = ET.parse(path).getroot()
        written = [child for block in root.findall("equality") for child in block if isinstance(child.tag, str)]
    except (ET.ParseError, OSError):
        written = []
    matched = len(written) == model.neq
    out = []
    for e in range(model.neq):
        if int(model.eq_type[e]) not in (_CONNECT, _EQ_JOINT):
            continue
        own = not matched or any(written[e].get(key) is not None for key in ("solref", "solimp", "class"))
        out.append(ConnectSource(element_label(model, mujoco.mjtObj.mjOBJ_EQUALITY, e),
                                 mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e) or None, own,
                                 "joint" if int(model.eq_type[e]) == _EQ_JOINT else "connect"))
    return tuple(out)


def _object_name(model: mujoco.MjModel, kind, index: int, fallback: str) -> str:
    """The element's MJCF name, else ``fallback`` and its index (a name for the scene file, not for
    messages: :func:`element_label` names an element so that a user can find it)."""
    name = mujoco.mj_id2name(model, kind, index)
    return name if name else f"{fallback}{index}"


# an equality's MJCF tag (a <joint> or <tendon> inside <equality> is said so, not to read as a joint or tendon)
_EQUALITY_TAG = {int(mujoco.mjtEq.mjEQ_CONNECT): "connect", int(mujoco.mjtEq.mjEQ_WELD): "weld",
                 int(mujoco.mjtEq.mjEQ_JOINT): "joint equality", int(mujoco.mjtEq.mjEQ_TENDON): "tendon equality"}


def _body_text(model: mujoco.MjModel, body: int) -> str:
    """A body as a user finds it: its name, "world", or "body #k" (k its place in the file)."""
    return "world" if body == 0 else (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body #{body}")


def element_label(model: mujoco.MjModel, kind, index: int) -> str:
    """How messages name a model's element: ``joint 'crank'`` when it has a name; else its MJCF tag,
    its ordinal among the file's elements of that tag (from 1, in file order: MuJoCo numbers each
    kind in the order the file lists them) and what it joins or sits on, e.g.
    ``connect #2 (right_follower–right_coupler)``, ``geom #12 (on link2)``."""
    obj = mujoco.mjtObj
    if kind == obj.mjOBJ_EQUALITY:
        eq_type = int(model.eq_type[index])
        tag = _EQUALITY_TAG.get(eq_type, "equality")
    else:
        tag = {obj.mjOBJ_JOINT: "joint", obj.mjOBJ_GEOM: "geom", obj.mjOBJ_SITE: "site", obj.mjOBJ_BODY: "body",
               obj.mjOBJ_PAIR: "pair", obj.mjOBJ_TENDON: "tendon", obj.mjOBJ_ACTUATOR: "actuator",
               obj.mjOBJ_KEY: "key"}.get(kind, "element")
    name = mujoco.mj_id2name(model, kind, index)
    if name:
        return f"{tag} '{name}'"
    if kind == obj.mjOBJ_EQUALITY:
        ordinal = sum(1 for e in range(index + 1) if int(model.eq_type[e]) == eq_type)
        ends = []
        for o in (int(model.eq_obj1id[index]), int(model.eq_obj2id[index])):
            if int(model.eq_objtype[index]) == int(obj.mjOBJ_SITE):
                ends.append(mujoco.mj_id2name(model, obj.mjOBJ_SITE, o) or _body_text(model, int(model.site_bodyid[o])))
            elif eq_type in (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)):
                ends.append(_body_text(model, o))
        return f"{tag} #{ordinal}" + (f" ({'–'.join(ends)})" if ends else "")
    where = ""
    if kind == obj.mjOBJ_JOINT:
        body = int(model.jnt_bodyid[index])
        where = f" ({_body_text(model, int(model.body_parentid[body]))}–{_body_text(model, body)})"
    elif kind == obj.mjOBJ_GEOM:
        where = f" (on {_body_text(model, int(model.geom_bodyid[index]))})"
    elif kind == obj.mjOBJ_SITE:
        where = f" (on {_body_text(model, int(model.site_bodyid[index]))})"
    elif kind == obj.mjOBJ_BODY:
        return f"body #{index} (in {_body_text(model, int(model.body_parentid[index]))})"
    return f"{tag} #{index + 1}{where}"


def _clean(name: str) -> str:
    """A name the scene format accepts (letters, digits, '_', '-'): other characters become '_'."""
    return "".join(c if c in _NAME_CHARS else "_" for c in name) or "_"


def _unique(name: str, taken: set[str]) -> str:
    out, k = name, 1
    while out in taken:
        k += 1
        out = f"{name}_{k}"
    taken.add(out)
    return out


def _in_plane_x(n: np.ndarray) -> np.ndarray:
    """The x axis (else, when x is near the normal ``n``, the y axis) projected on the plane
    normal to the unit vector ``n``, as a unit vector: a plane's, or a body's 2-D, x axis."""
    x = np.array([1.0, 0.0, 0.0])
    if np.linalg.norm(np.cross(x, n)) < 0.5:
        x = np.array([0.0, 1.0, 0.0])
    x = x - (x @ n) * n
    return x / np.linalg.norm(x)


@dataclass
class _Group:
    """A rigid body of the description: a MuJoCo body with a joint and the bodies welded to it."""

    name: str
    root: int  # MuJoCo body id of its frame (0: the world, for ground)
    bodies: list[int]
    a_local: np.ndarray  # the 2-D frame's x and y in the root body's frame
    b_local: np.ndarray
    points: dict[str, tuple[float, float]] = field(default_factory=dict)


def first_contact(model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
    """The first active contact in ``data`` (after ``mj_forward`` or ``mj_step``: MuJoCo's own
    collision, its broad phase included), as ``geom 'a' and geom 'b' touch (distance d m, margin
    m m)``; None when there is none. Active: a contact row MuJoCo's solver acts on (not one in the
    pair's ``gap``), with distance below the pair's margin."""
    for i in range(data.ncon):
        c = data.contact[i]
        if c.exclude != 0 or c.efc_address < 0 or not c.dist < c.includemargin:
            continue
        g1, g2 = sorted((int(c.geom[0]), int(c.geom[1])))
        return (f"{element_label(model, mujoco.mjtObj.mjOBJ_GEOM, g1)} and "
                f"{element_label(model, mujoco.mjtObj.mjOBJ_GEOM, g2)} touch (distance {float(c.dist):.3g} m, "
                f"margin {float(c.includemargin):g} m)")
    return None


class _Reader:
    """One pass over a compiled model at one configuration (see the module docstring)."""

    def __init__(self, path: Path, model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray):
        self.path, self.model = path, model
        self.qpos, self.qvel = qpos, qvel
        self.warnings: list[str] = []
        self.said_inputs: tuple[str, ...] = ()  # the inputs chosen, with several DOF (:func:`_inputs`)
        self.data = mujoco.MjData(model)
        self.data.qpos[:] = qpos
        self.data.qvel[:] = qvel
        mujoco.mj_kinematics(model, self.data)

    def fail(self, message: str):
        raise MjcfError(f"{self.path}: {message}")

    def representable(self, value: float, kind: str, where: str) -> None:
        """Refuse a value of the model outside the scene format's range of ``kind``
        (:data:`loopcheck.scene.LIMITS`), naming where in the model it comes from."""
        r = LIMITS[kind]
        inside = r.low <= value <= r.high if r.low else abs(value) <= r.high
        if not inside:
            self.fail(f"{where} = {value:g} cannot be represented: {r.kind} must be in {r.text()}")

    def name(self, kind, index: int, fallback: str) -> str:
        return _object_name(self.model, kind, index, fallback)

    def label(self, kind, index: int) -> str:
        return element_label(self.model, kind, index)

    # -- what acts ---------------------------------------------------------------
    def check_options(self) -> None:
        m = self.model
        opt = m.opt
        if opt.density > 0.0 or opt.viscosity > 0.0 or np.any(opt.wind != 0.0):
            self.fail("option density, viscosity or wind: fluid forces act, and loopcheck's description has none")
        disabled = opt.disableflags
        if disabled & int(mujoco.mjtDisableBit.mjDSBL_EQUALITY) and m.neq:
            self.fail("option flag equality=\"disable\": the loops' connect equalities would not act")
        if disabled & int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT) and m.neq:
            self.fail("option flag constraint=\"disable\": the loops' connect equalities would not act")

    def check_contacts(self, qpos: np.ndarray) -> None:
        """Geoms may be collidable (``contype``/``conaffinity``, ``pair``): a contact during a run
        fails the check (:func:`first_contact`); geoms already in contact at ``qpos`` are refused.
        MuJoCo's own collision finds them (its broad phase: bounded time however many geoms)."""
        m = self.model
        if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT) or m.ngeom == 0:
            return
        data = mujoco.MjData(m)
        data.qpos[:] = qpos
        with mujoco_warnings():
            mujoco.mj_forward(m, data)
        touching = first_contact(m, data)
        if touching is not None:
            self.fail(f"{touching} at the start: loopcheck's description has no contacts; move them apart, set "
                      "their contype and conaffinity to 0, exclude the pair, or disable contacts")

    # -- the plane ---------------------------------------------------------------
    def joints(self) -> None:
        """Refuse joints the description cannot hold."""
        m = self.model
        for j in range(m.njnt):
            kind = int(m.jnt_type[j])
            if kind in (_FREE, _BALL):
                what = "free" if kind == _FREE else "ball"
                self.fail(f"{self.label(mujoco.mjtObj.mjOBJ_JOINT, j)} is a {what} joint: a planar "
                          "one-DOF linkage has hinges and slides only")
            if m.jnt_actgravcomp[j] and m.jnt_actfrclimited[j]:  # else the same force as a passive gravcomp
                self.fail(f"joint '{self.name(mujoco.mjtObj.mjOBJ_JOINT, j, 'joint')}': actuatorgravcomp=\"true\" "
                          "with actuatorfrcrange cannot be represented: MuJoCo clamps the gravity compensation "
                          "there, and loopcheck's gravcomp is not clamped")
            if (m.jnt_actgravcomp[j] and np.any(m.body_gravcomp != 0.0)
                    and m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)):
                self.fail(f"joint '{self.name(mujoco.mjtObj.mjOBJ_JOINT, j, 'joint')}': actuatorgravcomp=\"true\" "
                          "with option flag actuation=\"disable\" cannot be represented: MuJoCo drops the gravity "
                          "compensation on this joint only, and loopcheck's gravcomp acts on the whole body")
            if m.jnt_actfrclimited[j]:
                low, high = (float(v) for v in m.jnt_actfrcrange[j])
                self.fail(f"joint '{self.name(mujoco.mjtObj.mjOBJ_JOINT, j, 'joint')}': actuatorfrcrange=\"{low:g} "
                          f"{high:g}\" cannot be represented: MuJoCo clamps the total actuator force on the joint, "
                          "and loopcheck has no such clamp")
        if m.njnt == 0:
            self.fail("the model has no joints")
        for b in range(1, m.nbody):
            if m.body_jntnum[b] > 1:
                self.fail(f"{self.label(mujoco.mjtObj.mjOBJ_BODY, b)} has {m.body_jntnum[b]} joints: "
                          "loopcheck's description has one joint between two bodies (add a body between them)")

    def plane(self, input_joint: int) -> None:
        m, d = self.model, self.data
        hinges = [j for j in range(m.njnt) if m.jnt_type[j] == _HINGE]
        if not hinges:
            self.fail("the model has no hinge: a closed planar linkage turns about at least one")
        first = input_joint if m.jnt_type[input_joint] == _HINGE else hinges[0]
        n = np.array(d.xaxis[first], dtype=float)
        n /= np.linalg.norm(n)
        for j in range(m.njnt):
            axis = d.xaxis[j] / np.linalg.norm(d.xaxis[j])
            name = self.label(mujoco.mjtObj.mjOBJ_JOINT, j)
            first_name = self.label(mujoco.mjtObj.mjOBJ_JOINT, first)
            if m.jnt_type[j] == _HINGE:
                if np.linalg.norm(np.cross(axis, n)) > AXIS_TOL:
                    self.fail(f"{name}: its axis {np.round(axis, 6).tolist()} is not parallel to "
                              f"{first_name}'s {np.round(n, 6).tolist()}: the linkage is not planar")
            elif abs(axis @ n) > AXIS_TOL:
                self.fail(f"{name}: the slide's axis {np.round(axis, 6).tolist()} leaves the plane normal to "
                          f"{first_name}'s axis {np.round(n, 6).tolist()}")
        e1 = _in_plane_x(n)
        self.n, self.e1, self.e2 = n, e1, np.cross(n, e1)

    # -- bodies ------------------------------------------------------------------
    def groups(self) -> None:
        m, d = self.model, self.data
        self.group_of: dict[int, _Group] = {}
        taken = {GROUND}
        # ground's frame is the world's, in the plane's basis
        ground = _Group(GROUND, 0, [0], self.e1, self.e2)
        self.group_of[0] = ground
        self.moving: list[_Group] = []
        for b in range(1, m.nbody):  # parents come before their children
            parent = self.group_of[int(m.body_parentid[b])]
            if m.body_jntnum[b] == 0:
                parent.bodies.append(b)
                self.group_of[b] = parent
                continue
            name = self.name(mujoco.mjtObj.mjOBJ_BODY, b, "body")
            R = d.xmat[b].reshape(3, 3)
            if m.jnt_type[m.body_jntadr[b]] == _SLIDE:
                # the scene's prismatic joint keeps its child's frame parallel to its parent's, and a
                # slide never turns its child: the child takes its parent's 2-D frame, whatever way
                # its own MuJoCo frame is turned (constant in the child's frame, so read once here)
                R_parent = d.xmat[parent.root].reshape(3, 3)
                a, b_axis = R.T @ (R_parent @ parent.a_local), R.T @ (R_parent @ parent.b_local)
            else:
                n_local = R.T @ self.n
                a = _in_plane_x(n_local)
                b_axis = np.cross(n_local, a)
            group = _Group(_unique(_clean(name), taken), b, [b], a, b_axis)
            self.group_of[b] = group
            self.moving.append(group)

    def local(self, group: _Group, body: int, p_body: np.ndarray) -> tuple[float, float]:
        """The 2-D coordinates in ``group``'s frame of a point given in MuJoCo body ``body``'s frame:
        exact (no round trip through the world) when the body is the group's root."""
        if body != group.root:
            d = self.data
            return self.world_to_group(group, d.xpos[body] + d.xmat[body].reshape(3, 3) @ p_body)
        return float(p_body @ group.a_local), float(p_body @ group.b_local)

    def world_to_group(self, group: _Group, world: np.ndarray) -> tuple[float, float]:
        d = self.data
        local = d.xmat[group.root].reshape(3, 3).T @ (world - d.xpos[group.root])
        return float(local @ group.a_local), float(local @ group.b_local)

    def angle(self, group: _Group) -> float:
        """The angle of the group's 2-D x axis in the plane at the configuration read (rad)."""
        if group.root == 0:
            return 0.0
        axis = self.data.xmat[group.root].reshape(3, 3) @ group.a_local
        return math.atan2(float(axis @ self.e2), float(axis @ self.e1))

    def sites(self) -> None:
        m = self.model
        self.site_point: dict[int, tuple[_Group, str]] = {}
        taken: dict[str, set[str]] = {}
        for s in range(m.nsite):
            body = int(m.site_bodyid[s])
            group = self.group_of[body]
            name = self.name(mujoco.mjtObj.mjOBJ_SITE, s, "site")
            owner = BASE_BODY if group.root == 0 else group.name
            for prefix in (f"{owner}.", f"{self.name(mujoco.mjtObj.mjOBJ_BODY, body, 'body')}.", f"{group.name}."):
                if name.startswith(prefix) and len(name) > len(prefix):
                    name = name[len(prefix):]
                    break
            point = _unique(_clean(name), taken.setdefault(group.name, set()))
            group.points[point] = self.local(group, body, np.array(m.site_pos[s], dtype=float))
            self.site_point[s] = (group, point)
        self.taken = taken

    def point_at(self, group: _Group, xy: tuple[float, float], name: str) -> str:
        """The group's point at ``xy`` (a site's, when one is there), else a new one named ``name``."""
        for point, (px, py) in group.points.items():
            if math.hypot(px - xy[0], py - xy[1]) <= SAME_POINT_RTOL * self.scale:
                return point
        point = _unique(_clean(name), self.taken.setdefault(group.name, set()))
        group.points[point] = xy
        return point

    # -- joints ------------------------------------------------------------------
    def tree_joints(self) -> list:
        m, d = self.model, self.data
        out = []
        taken: set[str] = set()
        self.joint_of: dict[str, str] = {}
        self.joint_sign: dict[int, float] = {}
        self.ranges: dict[str, tuple[float, float]] = {}  # a joint's range on its own coordinate (_elements)
        self.range_sources: dict[str, str] = {}  # ImportedModel.range_sources
        for j in range(m.njnt):
            body = int(m.jnt_bodyid[j])
            child, parent = self.group_of[body], self.group_of[int(m.body_parentid[body])]
            name = _unique(_clean(self.name(mujoco.mjtObj.mjOBJ_JOINT, j, "joint")), taken)
            self.joint_of[self.name(mujoco.mjtObj.mjOBJ_JOINT, j, "joint")] = name
            at_child = self.point_at(child, self.local(child, body, np.array(m.jnt_pos[j], dtype=float)), name)
            anchor = np.array(d.xanchor[j], dtype=float)
            axis = d.xaxis[j] / np.linalg.norm(d.xaxis[j])
            if m.jnt_type[j] == _HINGE:
                at_parent = self.point_at(parent, self.world_to_group(parent, anchor), name)
                out.append(RevoluteJoint(name, parent.name, at_parent, child.name, at_child))
                self.joint_sign[j] = float(np.sign(axis @ self.n))
                continue
            # a slide: point_b (the child's) moves along the line through point_a (the parent's)
            R = d.xmat[parent.root].reshape(3, 3)
            direction_local = R.T @ axis
            direction = math.atan2(float(direction_local @ parent.b_local), float(direction_local @ parent.a_local))
            ux, uy = math.cos(direction), math.sin(direction)
            ax, ay = self.world_to_group(parent, anchor)
            on_line = [p for p, (px, py) in parent.points.items()
                       if abs((px - ax) * uy - (py - ay) * ux) <= SAME_POINT_RTOL * self.scale]
            if on_line:
                at_parent = min(on_line, key=lambda p: math.hypot(parent.points[p][0] - ax, parent.points[p][1] - ay))
            else:
                at_parent = self.point_at(parent, (ax, ay), name)
            out.append(PrismaticJoint(name, parent.name, at_parent, direction, child.name, at_child))
            self.joint_sign[j] = 1.0
        self.taken_joints = taken
        return out

    def loops(self) -> list[RevoluteJoint]:
        m, d = self.model, self.data
        out = []
        self.gaps: list[float] = []
        self.couplings: list[int] = []  # the active joint equalities with a joint2
        for e in range(m.neq):
            name = self.name(mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality")
            label = self.label(mujoco.mjtObj.mjOBJ_EQUALITY, e)
            kind = int(m.eq_type[e])
            if not m.eq_active0[e]:
                self.warnings.append(f"{label} is inactive at the start: left out")
                continue
            if kind == _EQ_JOINT:
                if int(m.eq_obj2id[e]) < 0:
                    locked = self.label(mujoco.mjtObj.mjOBJ_JOINT, int(m.eq_obj1id[e]))
                    self.fail(f"{label} has no joint2: it locks {locked} at a polynomial's constant, which "
                              "is not a coupling (a locked joint is no joint: weld its body to its parent instead)")
                self.couplings.append(e)  # a coupling: read once the joints' coordinates are known (_couplings)
                continue
            if kind != _CONNECT:
                what = {_WELD: "a weld", _EQ_TENDON: "a tendon coupling"}.get(kind, "an equality of another kind")
                self.fail(f"{label} is {what}, not a connect: only connect equalities (loop closures) and joint "
                          "couplings have a planar one-DOF meaning here")
            if int(m.eq_objtype[e]) == _OBJ_SITE:
                ends = []
                for site in (int(m.eq_obj1id[e]), int(m.eq_obj2id[e])):
                    ends.append((self.site_point[site], np.array(d.site_xpos[site], dtype=float)))
            else:
                ends = []
                for body, anchor in ((int(m.eq_obj1id[e]), m.eq_data[e][0:3]), (int(m.eq_obj2id[e]), m.eq_data[e][3:6])):
                    group = self.group_of[body]
                    anchor = np.array(anchor, dtype=float)
                    world = d.xpos[body] + d.xmat[body].reshape(3, 3) @ anchor
                    ends.append(((group, self.point_at(group, self.local(group, body, anchor), name)), world))
            (g1, p1), w1 = ends[0]
            (g2, p2), w2 = ends[1]
            if g1 is g2:
                self.fail(f"{label} joins two points of one rigid body ('{g1.name}')")
            gap = float(np.linalg.norm(w1 - w2))
            self.gaps.append(gap)
            if gap > CLOSURE_RTOL * self.scale:
                form = ("" if int(m.eq_objtype[e]) == _OBJ_SITE else
                        "; MuJoCo puts a body-form connect's second anchor where the first one is at qpos0, so "
                        "author the model in its assembled pose or use the site form")
                self.fail(f"{label} is open by {gap:.3g} m at the configuration read, more than "
                          f"{CLOSURE_RTOL:g} of the model's size ({self.scale:.3g} m){form}; --assemble closes them "
                          "by Newton from there (moves up to 0.1 rad or 10 mm)")
            out.append(RevoluteJoint(_unique(_clean(name), self.taken_joints), g1.name, p1, g2.name, p2))
        return out

    def size(self) -> float:
        """The model's length scale (m): the largest distance between two bodies' frames, joints and sites."""
        d = self.data
        pts = np.vstack([d.xpos[1:], d.xanchor, d.site_xpos]) if self.model.nsite else np.vstack([d.xpos[1:], d.xanchor])
        span = np.ptp(pts, axis=0)
        return float(max(np.linalg.norm(span), 1e-9))


def _gravcomp(reader: _Reader, group: _Group) -> float:
    """The group's gravity compensation: its bodies' ``gravcomp``, one value for all those with a
    mass (welded bodies with different values weigh at another centre than their mass's: refused)."""
    m = reader.model
    values = {float(m.body_gravcomp[b]): b for b in group.bodies if m.body_mass[b] > 0.0}
    if len(values) > 1:
        (a, ba), (b, bb) = list(values.items())[:2]
        reader.fail(f"{reader.label(mujoco.mjtObj.mjOBJ_BODY, ba)} (gravcomp=\"{_word(a)}\") and "
                    f"{reader.label(mujoco.mjtObj.mjOBJ_BODY, bb)} (gravcomp=\"{_word(b)}\") are welded "
                    "together: different gravcomp on one rigid body cannot be represented (loopcheck's body has one)")
    return next(iter(values), 0.0)


def _mass_properties(reader: _Reader, group: _Group) -> tuple[float, tuple[float, float], float]:
    """(mass kg, com in the group's frame m, inertia about the com and the plane's normal kg·m²)."""
    m, d = reader.model, reader.data
    n = reader.n
    masses, coms, inertias = [], [], []
    for b in group.bodies:
        mass = float(m.body_mass[b])
        if mass == 0.0:
            continue
        if b == group.root:  # exactly, from the model's numbers
            com = reader.local(group, b, np.array(m.body_ipos[b], dtype=float))
            q = np.empty(9)
            mujoco.mju_quat2Mat(q, m.body_iquat[b])
            Ri = q.reshape(3, 3)
            n_local = d.xmat[b].reshape(3, 3).T @ n
            if np.array_equal(Ri, np.eye(3)) and np.array_equal(np.abs(n_local), [0.0, 0.0, 1.0]):
                inertia = float(m.body_inertia[b][2])
            else:
                v = Ri.T @ n_local
                inertia = float(v @ (m.body_inertia[b] * v))
        else:
            com = reader.world_to_group(group, np.array(d.xipos[b], dtype=float))
            Ri = d.ximat[b].reshape(3, 3)
            v = Ri.T @ n
            inertia = float(v @ (m.body_inertia[b] * v))
        masses.append(mass)
        coms.append(com)
        inertias.append(inertia)
    if not masses:
        return 0.0, (0.0, 0.0), 0.0
    if len(masses) == 1:
        return masses[0], coms[0], inertias[0]
    total = sum(masses)
    cx = sum(mm * c[0] for mm, c in zip(masses, coms)) / total
    cy = sum(mm * c[1] for mm, c in zip(masses, coms)) / total
    inertia = sum(i + mm * ((c[0] - cx) ** 2 + (c[1] - cy) ** 2) for mm, c, i in zip(masses, coms, inertias))
    return total, (cx, cy), inertia


def _pivot_body(group: _Group, mass: float, com, inertia: float, joints, scale: float, gravcomp: float) -> Body:
    """The group as a body: by its inertia about its pin to ground when its com sits there (its
    weight, compensated or not, then does no work: ``gravcomp`` is left out)."""
    for j in joints:
        if isinstance(j, RevoluteJoint) and j.body_a == GROUND and j.body_b == group.name:
            px, py = group.points[j.point_b]
            if math.hypot(com[0] - px, com[1] - py) <= SAME_POINT_RTOL * scale:
                pivot = inertia + mass * ((com[0] - px) ** 2 + (com[1] - py) ** 2)
                return Body(group.name, group.points, 0.0, (px, py), pivot)
    return Body(group.name, group.points, mass, com, inertia, gravcomp)


def _load_model(path: Path) -> tuple[mujoco.MjModel, tuple[str, ...]]:
    """The compiled model and MuJoCo's warnings while loading it (in loopcheck's words), after
    the file is checked (:func:`check_model_path`) and its values are (:func:`_check_values`)."""
    check_model_path(path)
    with mujoco_warnings() as said:
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except ValueError as exc:  # MuJoCo's parse errors
            first = " ".join(str(exc).split())
            raise MjcfError(f"{path}: MuJoCo cannot load it: {first}") from None
        _check_values(path, spec)
        try:
            model = compile_spec(spec)
        except ValueError as exc:  # MuJoCo's compile errors
            first = " ".join(str(exc).split())
            raise MjcfError(f"{path}: MuJoCo cannot load it: {first}") from None
    return model, tuple(dict.fromkeys(said.lines))


def check_model_path(path: Path) -> None:
    """Refuse, before MuJoCo opens it, a model path that is not a readable regular file (a FIFO
    would block MuJoCo's read for ever; a folder is not an empty model)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # opening a FIFO must not wait for a writer
    except OSError as exc:
        raise MjcfError(f"cannot read MJCF file '{path}': {exc.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
    finally:
        os.close(fd)
    if not stat.S_ISREG(mode):
        what = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise MjcfError(f"cannot read MJCF file '{path}': it is {what}")


# The values of a model that reach the description (or change what MuJoCo does with it), as MjSpec
# holds them after defaults: by MjSpec's element list, the MJCF element and, per value, the MJCF
# attribute, the spec's field and the least value the description can represent (None: any finite
# value). A value left unset is NaN in some of MjSpec's fields (a body's ipos and fullinertia, a
# geom's mass and fromto): the body's are checked only when it sets its inertial, the geom's in the
# file's text (:func:`_check_unset_markers`).
_NONNEGATIVE = 0.0
_VALUES = {  # element list: (MJCF element, [(attribute, spec field, least value or None)])
    "bodies": ("body", [("pos", "pos", None), ("quat", "quat", None)]),
    "frames": ("frame", [("pos", "pos", None), ("quat", "quat", None)]),
    "joints": ("joint", [("pos", "pos", None), ("axis", "axis", None), ("ref", "ref", None),
                         ("springref", "springref", None), ("stiffness", "stiffness", _NONNEGATIVE),
                         ("damping", "damping", _NONNEGATIVE), ("armature", "armature", _NONNEGATIVE),
                         ("frictionloss", "frictionloss", _NONNEGATIVE), ("range", "range", None)]),
    "sites": ("site", [("pos", "pos", None), ("quat", "quat", None)]),
    "geoms": ("geom", [("pos", "pos", None), ("quat", "quat", None), ("size", "size", None),
                       ("density", "density", _NONNEGATIVE)]),
    "tendons": ("tendon", [("stiffness", "stiffness", _NONNEGATIVE), ("damping", "damping", _NONNEGATIVE),
                           ("armature", "armature", _NONNEGATIVE), ("frictionloss", "frictionloss", _NONNEGATIVE),
                           ("springlength", "springlength", None), ("range", "range", None)]),
    "actuators": ("actuator", [("gear", "gear", None), ("gainprm", "gainprm", None), ("biasprm", "biasprm", None),
                               ("ctrlrange", "ctrlrange", None), ("forcerange", "forcerange", None)]),
    "equalities": ("equality", [("anchor", "data", None), ("solref", "solref", None), ("solimp", "solimp", None)]),
    "keys": ("key", [("qpos", "qpos", None), ("qvel", "qvel", None), ("ctrl", "ctrl", None), ("time", "time", None)]),
}
_INERTIAL = (("inertial pos", "ipos", None), ("inertial quat", "iquat", None), ("inertial mass", "mass", _NONNEGATIVE),
             ("inertial diaginertia", "inertia", _NONNEGATIVE))
# What a negative value would be in the description (the scene format's ranges).
_WHAT = {"density": "a geom's density", "stiffness": "a spring's stiffness", "damping": "a damper's coefficient",
         "armature": "an inertia", "frictionloss": "a friction loss", "inertial mass": "a mass", "inertial diaginertia": "an inertia",
         "gravcomp": "a body's gravity compensation"}
_ALTERNATIVE = {int(mujoco.mjtOrientation.mjORIENTATION_AXISANGLE): "axisangle",
                int(mujoco.mjtOrientation.mjORIENTATION_EULER): "euler",
                int(mujoco.mjtOrientation.mjORIENTATION_XYAXES): "xyaxes",
                int(mujoco.mjtOrientation.mjORIENTATION_ZAXIS): "zaxis"}
_LINEAR = ("stiffness", "damping")  # MJCF takes polynomial terms after the coefficient
# The default class's sub-element for each kind of element that has one.
_DEFAULT_OF = {"joint": "joint", "site": "site", "geom": "geom", "tendon": "tendon", "actuator": "actuator",
               "equality": "equality"}


def _word(value: float) -> str:
    return "nan" if math.isnan(value) else repr(float(value)).removesuffix(".0") if math.isfinite(value) else (
        "inf" if value > 0 else "-inf")


def _check_unset_markers(path: Path) -> None:
    """Refuse a NaN or infinite value in a geom's ``mass`` or ``fromto``: MjSpec holds NaN there for
    "not given" (the mass then comes from the density), so only the file's text tells them apart
    (the file itself; an included file's geoms are not read here)."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return  # MuJoCo read it; nothing more to learn here
    for element in root.iter("geom"):
        for attribute in ("mass", "fromto"):
            text = element.get(attribute)
            if text is None:
                continue
            try:
                values = [float(word) for word in text.split()]
            except ValueError:
                continue  # MuJoCo's parser would have refused it
            if not all(math.isfinite(v) for v in values):
                name = element.get("name")
                label = f"geom '{name}'" if name else "a geom without a name"
                raise MjcfError(f"{path}: {label}: {attribute}=\"{text.strip()}\" is not a finite number: every value "
                                "of the model must be finite")


def _spec_ordinal(spec: mujoco.MjSpec, kind: str, element, index: int) -> str:
    """An unnamed element of the spec (before compiling) as :func:`element_label` names it in the
    compiled model: its tag, its ordinal in file order and what it joins or sits on (``index`` is its
    place in the spec's list of its kind, the world first among bodies)."""
    def body(b) -> str:
        return (b.name or "an unnamed body") if b is not None else "world"

    parent = getattr(element, "parent", None)
    if kind == "body":
        return f"body #{index} (in {body(parent)})"
    if kind == "equality":
        tag = "joint equality" if int(element.type) == _EQ_JOINT else "connect"
        ordinal = sum(1 for e in list(spec.equalities)[:index + 1] if int(e.type) == int(element.type))
        return f"{tag} #{ordinal} ({element.name1}–{element.name2})" if element.name2 else f"{tag} #{ordinal} ({element.name1})"
    if kind == "joint" and parent is not None:
        return f"joint #{index + 1} ({body(parent.parent) if parent.parent is not None else 'world'}–{body(parent)})"
    return f"{kind} #{index + 1} (on {body(parent)})"


def _check_values(path: Path, spec: mujoco.MjSpec) -> None:
    """Refuse a value that is NaN or infinite, or finite and outside the range the description
    can represent (a negative damping, stiffness, armature, mass or inertia): one line naming
    the file, the element, the MJCF attribute and, when the value is its default class's, that
    class. Zero stays "absent" (no spring, no damper)."""
    def refuse(kind: str, element, index: int, attribute: str, field_: str, values, reason: str):
        name = getattr(element, "name", "") or _spec_ordinal(spec, kind, element, index)
        source = ""
        classname = getattr(getattr(element, "classname", None), "name", None)
        if classname and kind in _DEFAULT_OF:
            default = spec.find_default(classname)
            sub = getattr(default, _DEFAULT_OF[kind], None) if default is not None else None
            theirs = getattr(sub, field_, None) if sub is not None else None
            if theirs is not None and np.array_equal(np.atleast_1d(np.asarray(theirs, dtype=float)),
                                                     np.atleast_1d(np.asarray(values, dtype=float)), equal_nan=True):
                source = f" (from default class '{classname}')"
        if attribute in _LINEAR or attribute in ("gear", "gainprm", "biasprm", "size"):  # as written: no trailing zeros
            values = np.trim_zeros(values, "b") if np.any(values != 0.0) else values[:1]
        written = " ".join(_word(v) for v in values)
        label = f"{kind} '{name}'" if getattr(element, "name", "") else name
        raise MjcfError(f"{path}: {label}: {attribute}=\"{written}\"{source} {reason}")

    def check(kind, element, index, attribute, field_, least):
        values = np.atleast_1d(np.asarray(getattr(element, field_), dtype=float)).ravel()
        if attribute == "polycoef":  # a joint equality's data: its five coefficients
            values = values[:5]
        if not np.all(np.isfinite(values)):
            refuse(kind, element, index, attribute, field_, values, "is not a finite number: every value of the "
                   "model must be finite")
        if attribute in _LINEAR and np.any(values[1:] != 0.0):
            refuse(kind, element, index, attribute, field_, values, "cannot be represented: loopcheck's springs and "
                   "dampers are linear (one coefficient, no polynomial terms)")
        if least is not None and np.any(values < least):
            refuse(kind, element, index, attribute, field_, values,
                   f"cannot be represented: {_WHAT.get(attribute, attribute)} must be ≥ {least:g} (0: none)")

    for group, (kind, fields) in _VALUES.items():
        for index, element in enumerate(getattr(spec, group)):
            if kind == "equality" and int(element.type) not in (_CONNECT, _EQ_JOINT):
                continue  # its data is another equality's (refused by kind later)
            for attribute, field_, least in fields:
                if kind == "equality" and int(element.type) == _EQ_JOINT and attribute == "anchor":
                    attribute = "polycoef"
                check(kind, element, index, attribute, field_, least)
    for kind, group in (("body", "bodies"), ("frame", "frames"), ("geom", "geoms")):  # an orientation other than quat, as written
        for index, element in enumerate(getattr(spec, group)):
            attribute = _ALTERNATIVE.get(int(element.alt.type))
            if attribute is not None:
                values = np.asarray(getattr(element.alt, attribute), dtype=float).ravel()
                if not np.all(np.isfinite(values)):
                    refuse(kind, element, index, attribute, attribute, values, "is not a finite number: every value "
                           "of the model must be finite")
    for index, body in enumerate(spec.bodies):  # gravity compensation: finite, ≥ 0 (1: the weight compensated)
        if index:
            check("body", body, index, "gravcomp", "gravcomp", _NONNEGATIVE)
    for index, body in enumerate(spec.bodies):
        if index and body.explicitinertial:
            for attribute, field_, least in _INERTIAL:
                check("body", body, index, attribute, field_, least)
            full = np.asarray(body.fullinertia, dtype=float)
            if not (math.isnan(full[0]) and not np.any(full[1:])):  # NaN then zeros: not given
                check("body", body, index, "inertial fullinertia", "fullinertia", None)
    _check_unset_markers(path)
    option = spec.option
    for attribute, value in (("timestep", [option.timestep]), ("gravity", option.gravity)):
        values = np.asarray(value, dtype=float).ravel()
        if not np.all(np.isfinite(values)):
            raise MjcfError(f"{path}: option: {attribute}=\"{' '.join(_word(v) for v in values)}\" is not a finite "
                            "number: every value of the model must be finite")
    if not option.timestep > 0.0:
        raise MjcfError(f"{path}: option: timestep=\"{_word(option.timestep)}\" cannot be represented: a timestep "
                        "must be > 0 s")


def _key_label(model: mujoco.MjModel, k: int) -> str:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k)
    return f"'{name}'" if name else f"#{k + 1} (unnamed)"


def _state(path: Path, model: mujoco.MjModel, keyframe: str | None, qpos0: bool):
    """(qpos, qvel, ctrl, the keyframe read or None, the line that says a keyframe was chosen or None).

    No keyframe named: qpos0 with ``qpos0``; else the model's only keyframe, said in the line
    returned; several are refused, listed (a load in a keyframe is never silently dropped)."""
    rest = model.qpos0.copy(), np.zeros(model.nv), np.zeros(model.nu), None, None
    if keyframe is not None and qpos0:
        raise MjcfError(f"{path}: --keyframe '{keyframe}' and --qpos0 both given: name a keyframe, or read qpos0")
    if keyframe is None:
        if qpos0 or model.nkey == 0:
            return rest
        if model.nkey > 1:
            listed = ", ".join(_key_label(model, k) for k in range(model.nkey))
            raise MjcfError(f"{path}: the model has {model.nkey} keyframes ({listed}): name the one to read with "
                            "--keyframe, or give --qpos0 to read qpos0 (at rest, no control)")
        k = 0
        label = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, 0) or "#1 (unnamed)"
        said = (f"read at keyframe '{label}', the model's only keyframe (its qpos, qvel and ctrl; --qpos0 reads "
                "qpos0 instead)")
    else:
        k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        if k < 0:
            names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, i) for i in range(model.nkey)]
            listed = ", ".join(f"'{n}'" for n in names if n) or "none"
            raise MjcfError(f"{path}: no keyframe named '{keyframe}' (the model's keyframes: {listed})")
        label, said = keyframe, None
    return model.key_qpos[k].copy(), model.key_qvel[k].copy(), model.key_ctrl[k].copy(), label, said


def _closing_keyframes(reader: _Reader) -> list[str]:
    """The keyframes at which every active connect of the model closes (to CLOSURE_RTOL of the
    model's size at qpos0), by label: named in the refusal of an open qpos0."""
    m = reader.model
    d = mujoco.MjData(m)
    out = []
    for k in range(m.nkey):
        d.qpos[:] = m.key_qpos[k]
        mujoco.mj_kinematics(m, d)
        gaps = []
        for e in range(m.neq):
            if not m.eq_active0[e] or int(m.eq_type[e]) != _CONNECT:
                continue
            if int(m.eq_objtype[e]) == _OBJ_SITE:
                w1, w2 = d.site_xpos[int(m.eq_obj1id[e])], d.site_xpos[int(m.eq_obj2id[e])]
            else:
                b1, b2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
                w1 = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ m.eq_data[e][0:3]
                w2 = d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ m.eq_data[e][3:6]
            gaps.append(float(np.linalg.norm(np.asarray(w1) - np.asarray(w2))))
        if gaps and max(gaps) <= CLOSURE_RTOL * reader.scale:
            out.append(_key_label(m, k))
    return out


@dataclass(frozen=True)
class _Customs:
    """What ``loopcheck export-mjcf`` wrote as ``<custom>`` numerics (:func:`_customs`)."""

    horizon: float | None = None
    control: Control | None = None
    controls: dict = field(default_factory=dict)  # actuator name: Control (loopcheck.ctrl.NAME)
    tolerances: dict = field(default_factory=dict)  # KEY: value
    engine_tolerances: dict = field(default_factory=dict)  # ENGINE: {KEY: value}


def _customs(path: Path, model: mujoco.MjModel) -> _Customs:
    """The model's ``loopcheck.*`` numerics (``loopcheck.horizon``, ``loopcheck.ctrl``,
    ``loopcheck.tolerances.KEY`` and ``loopcheck.tolerances.ENGINE.KEY``); another name under
    ``loopcheck.``, a wrong size or a value that is not finite or out of range is refused, naming
    the numeric. Other numerics are the user's own and act on nothing: not read."""
    keys = [f.name for f in dataclasses.fields(Tolerances)]
    out = _Customs()
    for n in range(model.nnumeric):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_NUMERIC, n) or ""
        if not name.startswith(CUSTOM_PREFIX):
            continue
        adr, size = int(model.numeric_adr[n]), int(model.numeric_size[n])
        data = [float(v) for v in model.numeric_data[adr:adr + size]]
        where = f"{path}: custom numeric '{name}'"
        if not all(math.isfinite(v) for v in data):
            raise MjcfError(f"{where}: data=\"{' '.join(_word(v) for v in data)}\" is not finite: every value of the "
                            "model must be finite")
        if name == CUSTOM_CTRL or name.startswith(CUSTOM_ACTUATOR_CTRL):
            if size < 2 or size % 2:
                raise MjcfError(f"{where}: {size} values: the control table is pairs t0 v0 t1 v1 ... (s, ctrl units)")
            times, values = tuple(data[0::2]), tuple(data[1::2])
            if times[0] < 0.0 or any(b <= a for a, b in zip(times, times[1:])):
                raise MjcfError(f"{where}: the times {', '.join(_word(t) for t in times)} must be ≥ 0 s and "
                                "increase strictly")
            if model.nu == 0:
                raise MjcfError(f"{where}: a control table, and the model has no actuator to apply it to")
            if name == CUSTOM_CTRL:
                out = dataclasses.replace(out, control=Control(times, values))
            else:
                actuator = name[len(CUSTOM_ACTUATOR_CTRL):]
                if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator) < 0:
                    raise MjcfError(f"{where}: the model has no actuator '{actuator}' to apply it to")
                out.controls[actuator] = Control(times, values)
            continue
        if size != 1:
            raise MjcfError(f"{where}: {size} values, not one")
        value = data[0]
        if name == CUSTOM_HORIZON:
            out = dataclasses.replace(out, horizon=value)  # its range is the scene file's, checked with it
            continue
        key = name[len(CUSTOM_TOLERANCES):] if name.startswith(CUSTOM_TOLERANCES) else ""
        engine, _, field_ = key.rpartition(".")
        if field_ not in keys or "." in engine:
            raise MjcfError(f"{where}: not a numeric loopcheck writes ({CUSTOM_HORIZON}, {CUSTOM_CTRL}, "
                            f"{CUSTOM_ACTUATOR_CTRL}ACTUATOR, "
                            f"{CUSTOM_TOLERANCES}KEY or {CUSTOM_TOLERANCES}ENGINE.KEY, KEY one of {', '.join(keys)})")
        if not value > 0.0:
            raise MjcfError(f"{where}: {_word(value)}: a tolerance must be > 0")
        if engine:
            out.engine_tolerances.setdefault(engine, {})[field_] = value
        else:
            out.tolerances[field_] = value
    return out


def import_mjcf(path: str | Path, *, input_joint: str | None = None, keyframe: str | None = None,
                qpos0: bool = False, control: Control | None = None, horizon: float | None = None,
                name: str | None = None, controls: dict[str, Control] | None = None) -> ImportedModel:
    """Read the MJCF file ``path`` as a scene (module docstring).

    Parameters
    ----------
    input_joint : the MuJoCo joint (hinge or slide) whose coordinate is q; default the joint the
        motor drives, else the model's first joint.
        With several degrees of freedom, several joints separated by commas: the first inputs, in
        order (the rest chosen by :func:`_inputs`).
    keyframe : the keyframe to read the configuration, rates and control from; default the
        model's only keyframe (said in ``ImportedModel.said``), qpos0 (at rest, with zero control)
        when it has none; a model with several is refused unless one is named or ``qpos0``.
    qpos0 : read qpos0 (at rest, zero control) even when the model has keyframes.
    control : the motor's control over time, instead of the model's ``loopcheck.ctrl`` table or
        the keyframe's (constant) control.
    horizon : the scene's simulated time, s; default the model's ``loopcheck.horizon``, else 1.
    controls : each actuator's control over time by MuJoCo actuator name (those that become scene
        actuators, :func:`_actuators`), instead of its ``loopcheck.ctrl.NAME`` table or the keyframe's ctrl.

    What ``loopcheck export-mjcf`` writes as ``<custom>`` numerics (the horizon, the tolerances,
    the load's table) is read back under the arguments given (:func:`_customs`).
    name : the scene's name; default the file's stem.

    Raises
    ------
    MjcfError
        One line naming the file and the element that cannot be read, and why.
    """
    path = Path(path)
    model, loading = _load_model(path)
    qpos, qvel, key_ctrl, keyframe, said_key = _state(path, model, keyframe, qpos0)
    customs = _customs(path, model)
    horizon = horizon if horizon is not None else customs.horizon if customs.horizon is not None else 1.0
    given_bare = control  # --ctrl VALUE (the input motor's, or the only actuator's)
    actuation_off = bool(model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)) and model.nu > 0
    if actuation_off and (control is not None or controls):
        raise MjcfError(f"{path}: --ctrl: option flag actuation=\"disable\": the model's actuators do not act")
    control = control if control is not None else customs.control if not actuation_off else None
    with mujoco_warnings() as said:
        reader = _Reader(path, model, qpos, qvel)
    reader.warnings.extend(loading + tuple(said.lines))
    reader.check_options()
    reader.joints()
    named_inputs = _named_inputs(reader, input_joint)
    written_inputs = _custom_inputs(path, model)
    inp, no_motor = _input_joint(reader, named_inputs[0] if named_inputs else None)
    reader.plane(inp)
    reader.check_contacts(qpos)
    with np.errstate(over="ignore", invalid="ignore"):  # a huge position is refused below, by name
        reader.scale = reader.size()
    reader.groups()
    reader.sites()
    tree = reader.tree_joints()
    try:
        cuts = reader.loops()
    except MjcfError as exc:
        closing = _closing_keyframes(reader) if keyframe is None and reader.gaps and \
            reader.gaps[-1] > CLOSURE_RTOL * reader.scale else []
        if not closing:
            raise
        raise MjcfError(f"{exc}; keyframe {closing[0]} closes the loops (--keyframe reads it)") from None
    input_name = reader.joint_of[_object_name(model, mujoco.mjtObj.mjOBJ_JOINT, inp, "joint")]

    # bodies, after every point is known
    joints = tree + cuts
    bodies = [Body(GROUND, reader.group_of[0].points)] if reader.group_of[0].points else []
    for group in reader.moving:
        mass, com, inertia = _mass_properties(reader, group)
        if mass == 0.0 or inertia == 0.0:
            reader.fail(f"body '{group.name}' has no mass or no inertia about the plane's normal")
        gravcomp = _gravcomp(reader, group)
        body = _pivot_body(group, mass, com, inertia, joints, reader.scale, gravcomp)
        where = reader.label(mujoco.mjtObj.mjOBJ_BODY, group.root) + (
            " (with the bodies welded to it)" if len(group.bodies) > 1 else "")
        if body.mass:
            reader.representable(body.mass, "mass", f"{where}: mass")
            reader.representable(body.gravcomp, "gravity compensation", f"{where}: gravcomp")
            reader.representable(body.inertia, "inertia", f"{where}: inertia about the plane's normal")
        else:
            reader.representable(body.inertia, "inertia", f"{where}: inertia about its pivot")
        for axis, value in zip("xy", body.com):
            reader.representable(value, "position", f"{where}: centre of mass, {axis} in its plane frame")
        bodies.append(body)
    for group in [reader.group_of[0], *reader.moving]:
        owner = "the world" if group.root == 0 else reader.label(mujoco.mjtObj.mjOBJ_BODY, group.root)
        for point, xy in group.points.items():
            for axis, value in zip("xy", xy):
                reader.representable(value, "position", f"{owner}: point '{point}' (a site, joint or anchor), {axis} in "
                                                        "its plane frame")
    # the couplings' graph first (their polynomials and references need the coordinates: _couplings)
    placeholders = [JointCoupling(f"coupling{k}", *ends) for k, ends in enumerate(_coupled_joints(reader))]
    # as many provisional inputs as Grübler's count asks (the DOF are counted below, by rank)
    grubler = 3 * len(reader.moving) - 2 * len(joints) - len(placeholders)
    provisional = _provisional_inputs(reader, inp, joints, grubler)
    try:
        linkage = Linkage(bodies, joints, input_name, couplings=placeholders, inputs=provisional)
    except MechanismError as exc:
        reader.fail(f"{exc}" + (f" ({len(reader.moving)} moving bodies, {len(tree)} joints, {len(cuts)} loop "
                                f"closures{f', {len(placeholders)} couplings' if placeholders else ''})"
                                if "degrees of freedom" in str(exc) else ""))
    # x = x_read + T (qpos − qpos_read): the coordinates (bodies' angles, slides' s) are the same for
    # the linkage rebuilt below with another spanning tree
    system = loops.compile_linkage(linkage)
    T, x_read = _joint_coefficients(reader, system, linkage)
    couplings = _couplings(reader, system, T, x_read, {j.name for j in joints})
    read_at = f"keyframe '{keyframe}'" if keyframe is not None else "qpos0"
    inputs, choice = _inputs(reader, bodies, joints, couplings, input_name, provisional, x_read, named_inputs,
                             len(cuts), read_at, actuation_off, written_inputs)
    reader.said_inputs = choice
    if len(inputs) == 1 and no_motor is not None:
        reader.warnings.append(no_motor)
    if inputs[0] != input_name:  # several DOF: the first input chosen (an unnamed joint is found by its scene name)
        input_name = inputs[0]
        inp = next(j for j in range(model.njnt)
                   if reader.joint_of[_object_name(model, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")] == input_name)
    # several DOF: every actuator is a scene actuator (a linkage of several inputs has no input load)
    motor = _input_motor(reader, inp) if not actuation_off and len(inputs) == 1 else None
    if actuation_off:
        reader.warnings.append("option flag actuation=\"disable\": the model's actuators exert no force in MuJoCo, "
                               "left out (no load)")
    motor_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, motor) if motor is not None else None
    if motor_name is not None and motor_name in (controls or {}):  # --ctrl MOTOR=...: the input motor's control
        if given_bare is not None:
            reader.fail(f"--ctrl {motor_name}=...: given twice (a bare --ctrl is the input motor's control too)")
        controls = dict(controls)
        control = controls.pop(motor_name)
    if motor_name is not None and motor_name in customs.controls:  # loopcheck.ctrl.MOTOR: the same, from the file
        named_in_file = customs.controls.pop(motor_name)
        if customs.control is not None:
            reader.fail(f"custom numerics '{CUSTOM_CTRL}' and '{CUSTOM_ACTUATOR_CTRL}{motor_name}' both give the input "
                        "motor's control: keep one")
        control = control if control is not None else named_in_file
    if motor is None and control is not None and model.nu:
        if model.nu != 1:
            reader.fail(f"--ctrl VALUE: the model has {model.nu} actuators: name the one each control is for "
                        "(--ctrl NAME=VALUE)")
        only = _object_name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, 0, "actuator")
        controls = {only: control, **(controls or {})}
        control = None
    load, gear, applied = _load(reader, inp, control, key_ctrl, motor)
    elements, joint_elements = _elements(reader, linkage, system, T, x_read)
    actuators = () if actuation_off else \
        _actuators(reader, linkage, system, x_read, motor, {**customs.controls, **(controls or {})}, key_ctrl)
    inertias = tuple(dict.fromkeys([e.joint for e in joint_elements if e.kind == "inertia"]
                                   + [j for c in couplings for j in (c.joint, c.driver)]))
    try:
        if reader.ranges:
            joints = [dataclasses.replace(j, range=reader.ranges[j.name]) if j.name in reader.ranges else j
                      for j in joints]
        # as the scene file builds it (the tree takes them first), so that its loops are the file's
        linkage = Linkage(bodies, joints, input_name, inertias, couplings, inputs)
        mechanism = Mechanism(linkage, elements, (), joint_elements, (), actuators)
    except MechanismError as exc:
        reader.fail(str(exc))

    system = loops.compile_linkage(linkage)
    guess = x_read
    xdot = T @ reader.qvel  # a body's angular rate about the normal, a slide's ṡ
    several = len(inputs) > 1
    qs = tuple(float(v) for v in system.input_rows @ guess)
    qdots = tuple(float(v) for v in system.input_rows @ xdot)
    q0, qdot0 = qs[0], qdots[0]
    if not several:
        _check_drive(reader, system, linkage, guess, inp, read_at)
    # every loop row, a redundant loop's dependent ones too
    residual = float(np.max(np.abs(loops.all_constraints(system, guess)[1] @ xdot), initial=0.0))
    # and every rate the inputs' alone reproduce (a coupled or other joint's qvel beside them)
    if several:
        with np.errstate(over="ignore", invalid="ignore"):
            finite = all(math.isfinite(v) for v in qdots)
        reproduced = loops.input_rates(system, guess, qdots) if finite else 0.0  # the partition holds the linkage
    else:
        drives = qdot0 != 0.0 and loops.driving_conditioning(system, guess) >= loops.SINGULAR_CONDITIONING
        reproduced = loops.coefficients(system, guess)[0] * qdot0 if drives else 0.0  # else refused (scene file)
    with np.errstate(over="ignore", invalid="ignore"):  # a huge qvel is refused below, by name
        rates_off = float(np.max(np.abs(xdot - reproduced), initial=0.0))
    largest = max((abs(v) for v in qdots), default=0.0)
    if (largest > 0.0 and residual > 1e-6 * max(largest, 1.0) * reader.scale) \
            or rates_off > 1e-6 * max(float(np.max(np.abs(xdot), initial=0.0)), 1.0):
        whose, start = (("the inputs' do", "the inputs' rates") if several else
                        ("the input joint's does", "the input joint's rate"))
        reader.warnings.append(f"the keyframe's qvel does not keep the loops closed, or has rates {whose} not "
                               f"reproduce (rate residual {max(residual, rates_off):.3g}): the scene starts "
                               f"from {start} alone")
    gravity = _gravity(reader)
    for joint_name, q, qdot in zip(inputs, qs, qdots):
        prismatic = isinstance(linkage.joint_map[joint_name], PrismaticJoint)
        whose = f"input '{joint_name}'" if several else "the input joint"
        reader.representable(q, "position" if prismatic else "angle", f"{read_at}: {whose}'s qpos")
        reader.representable(qdot, "speed", f"{read_at}: {whose}'s qvel")
    for axis, value in zip("xy", gravity or ()):
        reader.representable(value, "gravity", f"option gravity, {axis} in the plane")
    for t in range(model.ntext):  # what loopcheck's own export notes it applies outside the model
        text = _object_name(model, mujoco.mjtObj.mjOBJ_TEXT, t, "text")
        kind, _, force = text.partition(" ")
        if kind in ("point_force", "timed_force") and force:
            reader.warnings.append(f"{kind.replace('_', ' ')} '{force}' is applied by loopcheck, not by the model "
                                   "(its custom text says so): not carried into the scene")
    provisional = Scene(name=_clean(name or path.stem)[:100], description=f"imported from {path.name}",
                        mechanism=mechanism, load=load, gravity=gravity, q0=q0, qdot0=qdot0,
                        x0=tuple(float(v) for v in guess), mode=loops.assembly_mode(system, guess),
                        horizon=horizon, engine_tables={}, tolerances=Tolerances(**customs.tolerances),
                        engine_tolerances=customs.engine_tolerances,
                        inputs_q0=qs if several else (), inputs_qdot0=qdots if several else ())
    data = scene_data(provisional)
    try:
        with warnings.catch_warnings():  # said once, among the import's warnings, below
            warnings.simplefilter("ignore", GrublerCountWarning)
            scene = scene_from_dict(data, source=str(path))
    except SceneError as exc:
        reader.fail(str(exc))
    note = redundancy_note(linkage, system, np.asarray(scene.x0))
    if note is not None:  # accepted with one DOF by the rank of its loop equations
        reader.warnings.append(note)
    polish = float(np.max(np.abs(np.asarray(scene.x0) - guess)))
    return ImportedModel(scene=scene, model=model, qpos=qpos, qvel=qvel, joint_of=dict(reader.joint_of),
                         qpos_map=T, x_read=guess, control=applied, gear=gear,
                         keyframe=keyframe, closure_residual=max(reader.gaps, default=0.0), polish=polish,
                         warnings=tuple(reader.warnings),
                         said=((said_key,) if said_key else ()) + reader.said_inputs,
                         connects=_connect_sources(path, model), motor_index=motor if motor is not None else 0,
                         actuator_index=tuple(a for a in range(model.nu) if a != motor and not actuation_off),
                         range_sources=dict(reader.range_sources))


def _check_drive(reader: _Reader, system, linkage: Linkage, x: np.ndarray, inp: int, read_at: str) -> None:
    """Refuse an input joint that cannot drive the linkage at the configuration read and near it (a
    coupling locks it: its driving conditioning stays below the singular threshold a step of 1e-3 along
    a joint that can drive); a dead centre alone is the scene file's to judge (a singular start at rest
    is allowed there). Names a joint that can drive."""
    c = loops.driving_conditioning(system, x)
    if c >= loops.SINGULAR_CONDITIONING:
        return
    mj_names = {scene: mj for mj, scene in reader.joint_of.items()}
    can = [j.name for j in linkage.joints if j.name in mj_names and
           loops.driving_conditioning(system, x, system.joint_row(j.name)) >= loops.SINGULAR_CONDITIONING]
    if not can:
        return
    row = system.joint_row(can[0])
    step = 1e-3 * (1.0 if isinstance(linkage.joint_map[can[0]], RevoluteJoint) else reader.scale)
    near = np.array(x, dtype=float)
    status, _, _ = system.kernel.assemble(float(row @ x) + step, near, row, 1e-12, 50, loops.SINGULAR_CONDITIONING)
    if status != 0 or loops.driving_conditioning(system, near) >= loops.SINGULAR_CONDITIONING:  # 0: closed
        return  # a dead centre (or no assembly there to judge by)
    reader.fail(f"{reader.label(mujoco.mjtObj.mjOBJ_JOINT, inp)} (the input) cannot drive the linkage at {read_at} "
                f"or near it: its driving conditioning {c:.3g} is below {loops.SINGULAR_CONDITIONING:g} (a coupling "
                f"locks it); --input '{mj_names[can[0]]}' names a joint that can")


def _custom_inputs(path: Path, model: mujoco.MjModel) -> tuple[str, ...]:
    """The inputs ``loopcheck export-mjcf`` wrote for a scene of several (the ``<custom>`` text
    ``loopcheck.inputs``, "D,J"), MuJoCo joints' names, empty without it; each must be a joint of the
    model (refused naming the text). :func:`_inputs` takes them before coordinate partitioning."""
    for n in range(model.ntext):
        if mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXT, n) != CUSTOM_INPUTS:
            continue
        adr, size = int(model.text_adr[n]), int(model.text_size[n])
        text = bytes(model.text_data[adr:adr + size]).split(b"\0")[0].decode()
        names = tuple(name.strip() for name in text.split(","))
        for name in names:
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) < 0:
                raise MjcfError(f"{path}: custom text '{CUSTOM_INPUTS}' data=\"{text}\": '{name}' is not a "
                                "joint of the model")
        return names
    return ()


def _named_inputs(reader: _Reader, text: str | None) -> tuple[str, ...]:
    """``--input``'s MuJoCo joints: one name, or several separated by commas (the first inputs of a
    linkage of several DOF, in order); each must be a joint of the model, named once."""
    if text is None:
        return ()
    m = reader.model
    names = tuple(word.strip() for word in text.split(","))
    for name in names:
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name) < 0:
            listed = ", ".join(f"'{_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, i, 'joint')}'" for i in range(m.njnt))
            reader.fail(f"--input '{name}' is not a joint of the model (its joints: {listed})")
    if len(set(names)) != len(names):
        reader.fail(f"--input '{text}' names a joint twice")
    return names


def _input_joint(reader: _Reader, name: str | None) -> tuple[int, str | None]:
    """The first input's MuJoCo joint: ``name``'s, else the first joint a motor drives, else the
    first joint, with the warning that says so (said with one DOF only: with several, the inputs
    are chosen among every actuated joint, :func:`_inputs`)."""
    m = reader.model
    if name is not None:
        return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name), None
    for a in range(m.nu):
        if m.actuator_trntype[a] == _TRN_JOINT:
            return int(m.actuator_trnid[a][0]), None
    return 0, (f"no motor: the input is the first joint, "
               f"'{_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, 0, 'joint')}' (--input names another)")


def _actuated_joints(reader: _Reader) -> list[tuple[str, str]]:
    """(scene joint, what drives it) of every joint an actuator acts on, in the actuators' order: a
    joint transmission's joint, and each joint of a fixed tendon's (in the tendon's order; the
    drivers of a gripper's servo); once each."""
    m = reader.model
    out: dict[str, str] = {}
    for a in range(m.nu):
        label = element_label(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a)
        trn, target = int(m.actuator_trntype[a]), int(m.actuator_trnid[a][0])
        if trn == _TRN_JOINT:
            found = [target]
        elif trn == _TRN_TENDON:
            adr, num = int(m.tendon_adr[target]), int(m.tendon_num[target])
            if any(int(m.wrap_type[k]) != _WRAP_JOINT for k in range(adr, adr + num)):
                continue  # refused with the actuators (_actuators)
            found = [int(m.wrap_objid[k]) for k in range(adr, adr + num) if float(m.wrap_prm[k]) != 0.0]
            label += f" through {element_label(m, mujoco.mjtObj.mjOBJ_TENDON, target)}"
        else:
            continue
        for j in found:
            out.setdefault(reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")], label)
    return list(out.items())


def _provisional_inputs(reader: _Reader, inp: int, joints, grubler: int) -> tuple[str, ...]:
    """As many inputs as Grübler's count asks (at least one), the first input first, then the
    model's other joints: enough for :class:`Linkage` while the DOF are counted by rank (:func:`_inputs`)."""
    m = reader.model
    first = reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, inp, "joint")]
    others = [reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")] for j in range(m.njnt)]
    ordered = list(dict.fromkeys([first, *others]))
    return tuple(ordered[:max(1, grubler)])


# A joint joins the inputs when its row, on the motions the loops allow, keeps this fraction of its
# length once the inputs before it are projected out (below: it moves with them).
INDEPENDENT_RTOL = 1e-6


def _inputs(reader: _Reader, bodies, joints, couplings, input_name: str, provisional: tuple[str, ...],
            x_read: np.ndarray, named: tuple[str, ...], n_cuts: int, read_at: str,
            actuation_off: bool, written: tuple[str, ...] = ()) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(the scene's inputs, the lines that say how they were chosen) for the configuration read.

    The count of DOF is the loop Jacobian's rank deficiency at the configuration read (every
    constraint row, the couplings' too: :func:`loopcheck.kinematics.rank_dof`). One DOF: the first
    input alone, as always. Several: the joints ``--input`` names, then the joints the actuators act
    on (a joint transmission's, a fixed tendon's: :func:`_actuated_joints`), each taken where it does
    not move with those before it, then the joints of ``written`` (the export's ``loopcheck.inputs``,
    :func:`_custom_inputs`) the same way, then coordinate partitioning among the model's other joints (their
    own coordinates): pivoted QR of their rows on the null space of the loop Jacobian, largest
    remainder first, until there are as many inputs as DOF."""
    m = reader.model
    try:
        linkage = Linkage(bodies, joints, input_name, couplings=couplings, inputs=provisional)
    except MechanismError as exc:
        reader.fail(str(exc))
    system = loops.compile_linkage(linkage)
    J = loops.all_constraints(system, x_read)[1]
    with np.errstate(over="ignore", invalid="ignore"):
        finite = bool(np.all(np.isfinite(J)))
    dof = loops.rank_dof(J) if finite else 1  # a value out of range is refused by name later
    if dof <= 1:
        if len(named) > 1:
            reader.fail(f"--input names {len(named)} joints, and the linkage has {max(dof, 0)} degree of freedom at "
                        f"{read_at}: name one")
        return (input_name,), ()
    if n_cuts == 0 and not couplings:
        reader.fail(f"the linkage has {dof} degrees of freedom (the rank of its equations at {read_at}) and no loop: "
                    "no connect equality or joint coupling closes one, and loopcheck checks closed-loop linkages")
    _, _, vt = np.linalg.svd(J)
    null = vt[system.n - dof:].T  # (n, dof): the motions the loops allow at x_read
    mj_joints = [reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")] for j in range(m.njnt)]
    rows = {name: system.joint_row(name) @ null for name in mj_joints}
    chosen: list[str] = []
    basis: list[np.ndarray] = []

    def remainder(name: str) -> np.ndarray:
        r = rows[name].copy()
        for b in basis:
            r -= (r @ b) * b
        return r

    def take(name: str) -> bool:
        r = remainder(name)
        if len(chosen) >= dof or not np.linalg.norm(r) > INDEPENDENT_RTOL * max(np.linalg.norm(rows[name]), 1e-300):
            return False
        chosen.append(name)
        basis.append(r / np.linalg.norm(r))
        return True

    index = {reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")]: j for j in range(m.njnt)}

    def said(scene_name: str) -> str:  # a joint as the file names it ('O1'), an unnamed one by its label
        j = index[scene_name]
        mj = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        return f"'{mj}'" if mj else element_label(m, mujoco.mjtObj.mjOBJ_JOINT, j)

    for name in named:
        scene_name = reader.joint_of[name]
        if not take(scene_name):
            reader.fail(f"--input '{name}' moves with the inputs named before it at {read_at} (or the inputs named "
                        f"exceed the linkage's {dof} degrees of freedom): name independent joints")
    actuated = [] if actuation_off else _actuated_joints(reader)
    taken_actuated, tied = [], []
    for name, label in actuated:
        if name in chosen:
            continue
        (taken_actuated if take(name) else tied).append(f"{said(name)} ({label})")
    from_text = [said(reader.joint_of[name]) for name in written
                 if reader.joint_of[name] not in chosen and take(reader.joint_of[name])]
    partitioned = []
    while len(chosen) < dof:
        rest = [n for n in mj_joints if n not in chosen]
        norms = [float(np.linalg.norm(remainder(n))) for n in rest]
        if not rest or max(norms) <= 0.0:
            reader.fail(f"{dof} degrees of freedom at {read_at}, and the model's joints give only {len(chosen)} "
                        "independent coordinates: loopcheck's inputs are joints' own coordinates")
        best = rest[int(np.argmax(norms))]
        take(best)
        partitioned.append(said(best))
    sigma = np.linalg.svd(np.array([rows[n] for n in chosen]), compute_uv=False)
    lines = [f"{dof} degrees of freedom (the rank of the loop equations at {read_at}); inputs, in order: "
             + ", ".join(said(n) for n in chosen)]
    if named:
        lines.append("  named by --input: " + ", ".join(f"'{n}'" for n in named))
    if taken_actuated:
        lines.append("  driven by an actuator: " + ", ".join(taken_actuated))
    if tied:
        lines.append("  driven too, and moving with the inputs before it (a coupling or a loop ties it): "
                     + ", ".join(tied))
    if from_text:
        lines.append(f"  the inputs export-mjcf wrote (custom text '{CUSTOM_INPUTS}'): " + ", ".join(from_text))
    if partitioned:
        lines.append("  chosen by coordinate partitioning (pivoted QR on the loop Jacobian among the joints' own "
                     "coordinates): " + ", ".join(partitioned))
    lines.append(f"  conditioning of the inputs {sigma[-1] / sigma[0]:.3g} (σmin/σmax of their rows on the motions "
                 "the loops allow); --input J1,J2,... names others")
    return tuple(chosen), tuple(lines)


def _plain_motor(m: mujoco.MjModel, a: int, inp: int) -> bool:
    """Whether actuator a is a motor on the input joint (joint transmission, no dynamics, fixed gain, no bias)."""
    return (m.actuator_trntype[a] == _TRN_JOINT and m.actuator_dyntype[a] == _DYN_NONE
            and m.actuator_gaintype[a] == _GAIN_FIXED and m.actuator_biastype[a] == _BIAS_NONE
            and int(m.actuator_trnid[a][0]) == inp)


def _input_motor(reader: _Reader, inp: int) -> int | None:
    """The actuator that becomes the scene's input load (``[torque]``/``[force]``): the model's only
    actuator when it is a motor on the input joint, or the one named ``input_motor`` (what
    ``loopcheck export-mjcf`` writes for the load) when it is; else None (every actuator becomes a
    scene actuator, :func:`_actuators`)."""
    m = reader.model
    if m.nu == 1 and _plain_motor(m, 0, inp):
        return 0
    a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, INPUT_MOTOR)
    return a if a >= 0 and _plain_motor(m, a, inp) else None


def _profile(control: Control) -> LoadProfile | None:
    """A control over time as a load profile of its own values; None when it is zero throughout a constant."""
    if control.times == (0.0,):
        return ConstantLoad(control.values[0]) if control.values[0] else None
    return PiecewiseConstantLoad(control.times, control.values)


_TRN_TENDON = int(mujoco.mjtTrn.mjTRN_TENDON)
_BIAS_AFFINE = int(mujoco.mjtBias.mjBIAS_AFFINE)


def _actuators(reader: _Reader, linkage: Linkage, system, x_read: np.ndarray, motor: int | None,
               controls: dict, key_ctrl: np.ndarray) -> tuple[Actuator, ...]:
    """Every actuator but the input motor as a scene actuator (:class:`loopcheck.mechanism.Actuator`):
    no activation dynamics, a fixed gain, no or an affine bias, on a joint or a fixed tendon. Its
    transmission's MuJoCo length Σ coef_k qpos_k becomes l = Σ c_j u_j + C over the scene's joint
    coordinates (u_j = u_read + sign·(qpos − qpos_read): c_j = sign·coef_k), and C goes into b0
    (b0 + b1·gear·C). Its control: ``controls`` by name, else the keyframe's ctrl (constant)."""
    m = reader.model
    out = []
    taken: set[str] = set()
    rows = {j.name: system.joint_row(j.name) for j in linkage.joints}
    for a in range(m.nu):
        if a == motor:
            continue
        mj_name = _object_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator")
        label = f"actuator '{mj_name}'"
        if m.actuator_dyntype[a] != _DYN_NONE:
            reader.fail(f"{label} has activation dynamics (dyntype {mujoco.mjtDyn(m.actuator_dyntype[a]).name}): "
                        "not represented (loopcheck's actuators act at once: dyntype none)")
        if m.actuator_gaintype[a] != _GAIN_FIXED:
            reader.fail(f"{label} has gaintype {mujoco.mjtGain(m.actuator_gaintype[a]).name}: only a fixed gain is "
                        "represented")
        if m.actuator_biastype[a] not in (_BIAS_NONE, _BIAS_AFFINE):
            reader.fail(f"{label} has biastype {mujoco.mjtBias(m.actuator_biastype[a]).name}: only none or affine "
                        "is represented")
        trn, target = int(m.actuator_trntype[a]), int(m.actuator_trnid[a][0])
        if trn == _TRN_JOINT:
            wraps = [(target, 1.0)]
        elif trn == _TRN_TENDON:
            adr, num = int(m.tendon_adr[target]), int(m.tendon_num[target])
            if any(int(m.wrap_type[k]) != _WRAP_JOINT for k in range(adr, adr + num)):
                reader.fail(f"{label} acts on spatial {element_label(m, mujoco.mjtObj.mjOBJ_TENDON, target)}: only "
                            "fixed tendons (joint coordinates) are represented as transmissions")
            wraps = [(int(m.wrap_objid[k]), float(m.wrap_prm[k])) for k in range(adr, adr + num)]
        else:
            reader.fail(f"{label} has a {mujoco.mjtTrn(trn).name} transmission: only joint and fixed-tendon "
                        "transmissions are represented")
        terms: dict[str, float] = {}
        offset = 0.0
        for j, coef in wraps:
            joint = reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")]
            sign = reader.joint_sign[j]
            adr = int(m.jnt_qposadr[j])
            terms[joint] = terms.get(joint, 0.0) + coef * sign
            offset += coef * (float(reader.qpos[adr]) - sign * float(rows[joint] @ x_read))
        terms = {j: c for j, c in terms.items() if c != 0.0}
        gear = float(m.actuator_gear[a][0])
        gain = float(m.actuator_gainprm[a][0])
        b0, b1, b2 = (float(v) for v in m.actuator_biasprm[a][0:3]) if m.actuator_biastype[a] == _BIAS_AFFINE \
            else (0.0, 0.0, 0.0)
        name = _unique(_clean(mj_name), taken)
        given = controls.get(mj_name)
        control = _profile(given) if given is not None else _profile(Control.constant(float(key_ctrl[a])))
        clamped = m.actuator_ctrllimited[a] and not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL)
        ranges = [tuple(float(v) for v in rng) if limited else None for limited, rng in
                  ((clamped, m.actuator_ctrlrange[a]),
                   (m.actuator_forcelimited[a], m.actuator_forcerange[a]))]
        only = list(terms.items())
        joint, tendon = (only[0][0], None) if len(only) == 1 and only[0][1] == 1.0 else (None, tuple(only))
        try:
            out.append(Actuator(name, joint, tendon, gain, (b0 + b1 * gear * offset, b1, b2), gear, *ranges, control))
        except MechanismError as exc:  # its message names the scene's actuator; the line names the file's
            reader.fail(f"{label}: {str(exc).removeprefix(f'actuator {name!r}: ')}")
    unknown = sorted(set(controls) - {_object_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator")
                                      for a in range(m.nu) if a != motor})
    if unknown:
        reader.fail(f"--ctrl {unknown[0]}=...: the model has no actuator '{unknown[0]}' other than the input motor")
    return tuple(out)


def _load(reader: _Reader, inp: int, control: Control | None, key_ctrl: np.ndarray, motor: int | None):
    m = reader.model
    if motor is None:
        if control is not None and m.nu == 0:
            reader.fail("--ctrl: the model has no actuator to apply a control to")
        if control is not None:
            reader.fail("--ctrl: the model has no motor on the input joint to apply a bare control to "
                        "(name an actuator: --ctrl NAME=VALUE)")
        return None, 0.0, None
    a = motor
    name = _object_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator")
    gear = float(m.actuator_gear[a][0]) * float(m.actuator_gainprm[a][0])  # force = gain · ctrl, on the joint × gear
    given = control if control is not None else Control.constant(float(key_ctrl[a]))
    values = list(given.values)
    if m.actuator_ctrllimited[a] and not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL):
        low, high = m.actuator_ctrlrange[a]
        clipped = [min(max(v, low), high) for v in values]
        if clipped != values:
            reader.warnings.append(f"actuator '{name}': the control is clamped to its ctrlrange [{low:g}, {high:g}], "
                                   "as MuJoCo clamps it")
            values = clipped
    applied = Control(given.times, tuple(values))
    kind = "force" if m.jnt_type[inp] == _SLIDE else "torque"
    for v in values:
        reader.representable(gear * v, kind,
                             f"actuator '{name}': gear × gain × control (gear × gain {gear:g}, control {v:g})")
    if m.actuator_forcelimited[a]:  # the motor's force gain × control is constant on each piece: its clamp is exact
        low, high = (float(v) for v in m.actuator_forcerange[a])
        forces = [float(m.actuator_gainprm[a][0]) * v for v in values]
        clamped = [min(max(f, low), high) for f in forces]
        if clamped != forces:
            reader.warnings.append(f"actuator '{name}': its force gain × control is clamped to its forcerange "
                                   f"[{low:g}, {high:g}], as MuJoCo clamps it")
            return Control(given.times, tuple(clamped)).load(float(m.actuator_gear[a][0])), gear, applied
    return applied.load(gear), gear, applied


def _configuration(reader: _Reader, system, linkage: Linkage) -> np.ndarray:
    """The scene's coordinates at the configuration read: body angles (rad), slides' s (m)."""
    x = np.zeros(system.n)
    by_name = {g.name: g for g in reader.moving}
    for i, body in enumerate(linkage.moving):
        x[system.coordinate(f"{body}.angle")] = reader.angle(by_name[body])
    for j in linkage.joints:
        if isinstance(j, PrismaticJoint):
            world = {}
            for side, body, point in (("a", j.body_a, j.point_a), ("b", j.body_b, j.point_b)):
                angle = 0.0 if body == GROUND else x[system.coordinate(f"{body}.angle")]
                origin = _origin(reader, body)
                px, py = linkage.body_map[body].points[point]
                c, s = math.cos(angle), math.sin(angle)
                world[side] = origin + np.array([c * px - s * py, s * px + c * py])
            angle_a = 0.0 if j.body_a == GROUND else x[system.coordinate(f"{j.body_a}.angle")]
            u = np.array([math.cos(angle_a + j.direction_a), math.sin(angle_a + j.direction_a)])
            x[system.coordinate(f"{j.name}.s")] = float((world["b"] - world["a"]) @ u)
    return x


def _origin(reader: _Reader, body: str) -> np.ndarray:
    """A description body's frame origin in the plane (m)."""
    group = next((g for g in reader.moving if g.name == body), None)
    if group is None:
        return np.zeros(2)
    p = reader.data.xpos[group.root]
    return np.array([float(p @ reader.e1), float(p @ reader.e2)])


def _one_branch(model: mujoco.MjModel, dofs: np.ndarray) -> bool:
    """Whether the dofs lie on one path from the root (each pair ancestor and descendant)."""
    def ancestors(dof: int) -> set[int]:
        out = set()
        while dof >= 0:
            out.add(dof)
            dof = int(model.dof_parentid[dof])
        return out

    chains = [ancestors(int(d)) for d in dofs]
    return all(int(a) in chains[j] or int(b) in chains[i]
               for i, a in enumerate(dofs) for j, b in enumerate(dofs))


def _gravity(reader: _Reader):
    m = reader.model
    if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        return None
    g = np.array(m.opt.gravity, dtype=float)
    planar = (float(g @ reader.e1), float(g @ reader.e2))
    return planar if any(planar) else None


def _coupled_joints(reader: _Reader) -> list[tuple[str, str]]:
    """(joint, driver) scene names of each joint coupling (joint1, joint2) that :meth:`_Reader.loops`
    kept."""
    m = reader.model
    out = []
    for e in reader.couplings:
        out.append(tuple(reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, int(j), "joint")]
                         for j in (m.eq_obj1id[e], m.eq_obj2id[e])))
    return out


def _couplings(reader: _Reader, system, T: np.ndarray, x_read: np.ndarray, taken: set[str]) -> list[JointCoupling]:
    """Each joint equality (joint1 y, joint2 x: y − y0 = P(x − x0), x0, y0 MuJoCo's qpos0, a joint's
    ``ref``) as a :class:`JointCoupling` on the two joints' own coordinates u = row·x: with u =
    u_read + σ (qpos − qpos_read) (σ = ±1, T's entry), the references are u at qpos0 and
    p(s) = σ_y P(σ_x s), a_k = σ_y σ_x^k P_k. Named after the equality (a name a joint has taken
    gets a suffix)."""
    m = reader.model
    out = []
    names = set(taken)
    for e, (joint, driver) in zip(reader.couplings, _coupled_joints(reader)):
        label = reader.label(mujoco.mjtObj.mjOBJ_EQUALITY, e)
        ends = []
        for j, scene_joint in ((int(m.eq_obj1id[e]), joint), (int(m.eq_obj2id[e]), driver)):
            row = system.joint_row(scene_joint) @ T
            dof, adr = int(m.jnt_dofadr[j]), int(m.jnt_qposadr[j])
            sign = float(row[dof])
            if abs(sign) != 1.0 or np.count_nonzero(row) != 1:
                reader.fail(f"{label}: {reader.label(mujoco.mjtObj.mjOBJ_JOINT, j)}'s own coordinate is not its "
                            "qpos alone in the planar description")
            u_read = float(system.joint_row(scene_joint) @ x_read)
            ends.append((sign, u_read + sign * (float(m.qpos0[adr]) - float(reader.qpos[adr]))))
        (sy, y_ref), (sx, x_ref) = ends
        # closed at the configuration read as the connects are (Loops.loops): MuJoCo's own residual
        # qpos1 − qpos1_0 − P(qpos2 − qpos2_0), in the coupled joint's unit
        j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        a1, a2 = int(m.jnt_qposadr[j1]), int(m.jnt_qposadr[j2])
        s = float(reader.qpos[a2]) - float(m.qpos0[a2])
        gap = abs(float(reader.qpos[a1]) - float(m.qpos0[a1])
                  - sum(float(a) * s ** k for k, a in enumerate(m.eq_data[e][0:5])))
        hinge = m.jnt_type[j1] == _HINGE
        bound = CLOSURE_RTOL * (1.0 if hinge else reader.scale)
        if not gap <= bound:
            unit = "rad" if hinge else "m"
            reader.fail(f"{label} is open by {gap:.3g} {unit} at the configuration read (joint1 off its polynomial "
                        f"of joint2), more than {bound:.3g} {unit}; --assemble closes it by Newton from there "
                        "(moves up to 0.1 rad or 10 mm)")
        coefficients = tuple(sy * sx ** k * float(a) + 0.0 for k, a in enumerate(m.eq_data[e][0:5]))  # no −0
        for value, j, what in ((x_ref, int(m.eq_obj2id[e]), "joint2"), (y_ref, int(m.eq_obj1id[e]), "joint1")):
            reader.representable(value, "angle" if m.jnt_type[j] == _HINGE else "position",
                                 f"{label}: {what}'s reference (its qpos0 in the planar description)")
        name = _unique(_clean(_object_name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e, "coupling")), names)
        try:
            out.append(JointCoupling(name, joint, driver, coefficients, x_ref, y_ref))
        except MechanismError as exc:
            reader.fail(f"{label}: {exc}")
    return out


def _joint_coefficients(reader: _Reader, system, linkage: Linkage) -> tuple[np.ndarray, np.ndarray]:
    """(T, x_read) with x = x_read + T (qpos − qpos_read): every coordinate is affine in qpos,
    since every body turns about the normal; T's columns are MuJoCo's dofs."""
    m = reader.model
    T = np.zeros((system.n, m.nv))
    by_name = {g.name: g for g in reader.moving}
    for body in linkage.moving:
        k = by_name[body].root
        while k != 0:
            for j in range(m.body_jntadr[k], m.body_jntadr[k] + m.body_jntnum[k]):
                if m.jnt_type[j] == _HINGE:
                    T[system.coordinate(f"{body}.angle"), m.jnt_dofadr[j]] = reader.joint_sign[j]
            k = int(m.body_parentid[k])
    for j in range(m.njnt):
        if m.jnt_type[j] == _SLIDE:
            name = reader.joint_of[_object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")]
            T[system.coordinate(f"{name}.s"), m.jnt_dofadr[j]] = 1.0
    return T, _configuration(reader, system, linkage)


def _elements(reader: _Reader, linkage: Linkage, system, T: np.ndarray,
              x_read: np.ndarray) -> tuple[list[LineElement], list[JointElement]]:
    m = reader.model
    disabled = m.opt.disableflags
    springs_on = not disabled & int(mujoco.mjtDisableBit.mjDSBL_SPRING)
    dampers_on = not disabled & int(mujoco.mjtDisableBit.mjDSBL_DAMPER)
    # friction loss and limits are constraints: off with either flag (MuJoCo makes no such rows)
    constraints_off = disabled & int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    friction_on = not (constraints_off or disabled & int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS))
    limits_on = not (constraints_off or disabled & int(mujoco.mjtDisableBit.mjDSBL_LIMIT))
    flag_constraint = 'constraint' if constraints_off else None
    if not friction_on and (np.any(m.dof_frictionloss > 0.0) or np.any(m.tendon_frictionloss > 0.0)):
        reader.warnings.append(f"option flag {flag_constraint or 'frictionloss'}=\"disable\": the joints' and "
                               "tendons' frictionloss do not act in MuJoCo, left out")
    if not limits_on and (np.any(m.jnt_limited) or np.any(m.tendon_limited)):
        reader.warnings.append(f"option flag {flag_constraint or 'limit'}=\"disable\": the joints' and tendons' "
                               "ranges do not act in MuJoCo, left out")
    rows = {j.name: system.joint_row(j.name) for j in linkage.joints}
    taken: set[str] = set()
    lines: list[LineElement] = []
    joint_elements: list[JointElement] = []

    revolute = {j.name: isinstance(j, RevoluteJoint) for j in linkage.joints}
    kinds = {"inertia": ("inertia", "mass"), "damper": ("rotational damping", "damping"),
             "spring": ("rotational stiffness", "stiffness"), "friction": ("torque", "force")}

    def add_range(joint, bounds, where):
        """A range on the joint's own coordinate; two on one joint (its own and a fixed tendon's)
        keep what both allow."""
        for b in bounds:
            reader.representable(b, "angle" if revolute[joint] else "position", where)
        lo, hi = bounds
        if joint in reader.ranges:
            lo, hi = max(lo, reader.ranges[joint][0]), min(hi, reader.ranges[joint][1])
        if not lo < hi:
            reader.fail(f"{where}: the ranges on joint '{joint}' leave it no motion ([{lo:g}, {hi:g}])")
        reader.ranges[joint] = (lo, hi)

    def add_joint_element(kind, base, joint, coefficient, rest=0.0, where="", rest_where=""):
        reader.representable(coefficient, kinds[kind][0 if revolute[joint] else 1], where)
        if kind == "spring":
            reader.representable(rest, "angle" if revolute[joint] else "position", f"{rest_where}: the spring's rest")
        joint_elements.append(JointElement(kind, _unique(_clean(base), taken), joint, coefficient, rest))

    for t in range(m.ntendon):
        name = _object_name(m, mujoco.mjtObj.mjOBJ_TENDON, t, "tendon")
        label = element_label(m, mujoco.mjtObj.mjOBJ_TENDON, t)
        damping = float(m.tendon_damping[t]) if dampers_on else 0.0
        stiffness = float(m.tendon_stiffness[t]) if springs_on else 0.0
        armature = float(m.tendon_armature[t])
        friction = float(m.tendon_frictionloss[t]) if friction_on else 0.0
        limited = bool(m.tendon_limited[t]) and limits_on
        adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
        on_joints = all(int(m.wrap_type[k]) == _WRAP_JOINT for k in range(adr, adr + num))
        if friction > 0.0 and not on_joints:
            reader.fail(f"{label} has frictionloss along a path of sites or geoms: loopcheck's dry friction acts on "
                        "one joint's own coordinate (a joint's frictionloss, or a fixed tendon's on one joint)")
        if limited and not on_joints:
            reader.warnings.append(f"{label} has a range: loopcheck's description has no limits on a tendon's "
                                   "path, so the comparison holds while the motion stays inside it")
        if damping == 0.0 and stiffness == 0.0 and armature == 0.0 and friction == 0.0 and not (limited and on_joints):
            if any(m.actuator_trntype[a] == _TRN_TENDON and int(m.actuator_trnid[a][0]) == t for a in range(m.nu)):
                continue  # an actuator's transmission (_actuators), nothing of its own
            reader.warnings.append(f"{label} has no stiffness, damping or armature: it exerts no force and is "
                                   "left out")
            continue
        low, high = m.tendon_lengthspring[t]
        if stiffness > 0.0 and low != high:
            reader.fail(f"{label} has a dead band (springlength {low:g} {high:g}): not part of loopcheck's "
                        "description")
        adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
        types = [int(m.wrap_type[k]) for k in range(adr, adr + num)]
        if all(w == _WRAP_SITE for w in types) and num == 2:
            ends = [reader.site_point[int(m.wrap_objid[k])] for k in range(adr, adr + num)]
            (ga, pa), (gb, pb) = ends
            if ga is gb:
                reader.fail(f"{label} joins two points of one rigid body ('{ga.name}'): its length never changes")
            if armature > 0.0:
                reader.fail(f"{label} has armature along a line between two points: loopcheck's inertias act on "
                            "one joint (a fixed tendon's or a joint's armature)")
            if damping > 0.0:
                reader.representable(damping, "damping", f"{label}: damping")
                lines.append(LineElement("damper", _unique(_clean(name), taken), ga.name, pa, gb.name, pb, damping))
            if stiffness > 0.0:
                reader.representable(stiffness, "stiffness", f"{label}: stiffness")
                reader.representable(float(low), "position", f"{label}: springlength")
                lines.append(LineElement("spring", _unique(_clean(name), taken), ga.name, pa, gb.name, pb, stiffness,
                                         float(low)))
            continue
        if all(w == _WRAP_JOINT for w in types):
            c = np.zeros(m.nv)
            for k in range(adr, adr + num):
                c[m.jnt_dofadr[int(m.wrap_objid[k])]] += float(m.wrap_prm[k])
            match = None
            for joint, row in rows.items():
                along = row @ T
                for lam in (1.0, -1.0):
                    scale = float(np.max(np.abs(along))) or 1.0
                    if np.max(np.abs(c - lam * along)) <= 1e-12 * scale:
                        match = (joint, lam)
                if match:
                    break
            if match is None:
                reader.fail(f"fixed {label} couples joints in a way that is no joint's own coordinate: "
                            "loopcheck's joint springs and dampers act on one joint")
            joint, lam = match
            u_read = float(rows[joint] @ x_read)
            length_read = float(c @ reader.qpos[[m.jnt_qposadr[j] for j in range(m.njnt)]])
            if armature > 0.0:  # ½ a L̇² = ½ a λ² u̇², λ = ±1
                add_joint_element("inertia", name, joint, armature, where=f"{label}: armature")
                if not _one_branch(m, np.flatnonzero(c)):
                    reader.warnings.append(
                        f"{label}: its armature couples joints of different branches, and MuJoCo keeps only "
                        "the mass-matrix terms of one branch (ancestor pairs): the model as written does not have "
                        "the ½ a L̇² the scene holds")
            if damping > 0.0:
                add_joint_element("damper", name, joint, damping, where=f"{label}: damping")
            if friction > 0.0:  # f on L = λ u + const, λ = ±1: f on u
                add_joint_element("friction", name, joint, friction, where=f"{label}: frictionloss")
            if limited:  # L in [lo, hi]: u = (L − L_read) / λ + u_read
                bounds = sorted((float(b) - length_read) / lam + u_read for b in m.tendon_range[t])
                add_range(joint, bounds, f"{label}: range")
            if stiffness > 0.0:
                # L = λ u + (L_read − λ u_read): ½ k (L − L0)² = ½ k (u − u_rest)² with λ = ±1
                add_joint_element("spring", name, joint, stiffness, (float(low) - length_read + lam * u_read) / lam,
                                  where=f"{label}: stiffness", rest_where=f"{label}: springlength")
            continue
        reader.fail(f"{label} wraps geoms, pulleys or more than two sites: loopcheck's springs and dampers "
                    "act along a straight line between two points or on one joint")

    for j in range(m.njnt):
        mj_name = _object_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
        label = element_label(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        joint = reader.joint_of[mj_name]
        damping = float(m.dof_damping[m.jnt_dofadr[j]]) if dampers_on else 0.0
        stiffness = float(m.jnt_stiffness[j]) if springs_on else 0.0
        armature = float(m.dof_armature[m.jnt_dofadr[j]])
        friction = float(m.dof_frictionloss[m.jnt_dofadr[j]]) if friction_on else 0.0
        if armature > 0.0:
            add_joint_element("inertia", f"{joint}_armature", joint, armature, where=f"{label}: armature")
        if friction > 0.0:
            add_joint_element("friction", f"{joint}_frictionloss", joint, friction, where=f"{label}: frictionloss")
        if m.jnt_limited[j] and limits_on:  # u = u_read + sign (qpos − qpos_read), as MuJoCo resolved limited/autolimits
            adr = int(m.jnt_qposadr[j])
            u_read = float(rows[joint] @ x_read)
            sign = reader.joint_sign[j]
            add_range(joint, sorted(u_read + sign * (float(b) - float(reader.qpos[adr])) for b in m.jnt_range[j]),
                      f"{label}: range")
            offset = u_read - sign * float(reader.qpos[adr])
            unit = "rad" if revolute[joint] else "m"
            made = ("qpos" if sign > 0 else "−qpos") + (f" {'+' if offset >= 0 else '−'} {abs(offset):.6g} {unit}"
                                                          if abs(offset) > 1e-12 else "")
            reader.range_sources[joint] = (f"{label} has range=\"{m.jnt_range[j][0]:g} {m.jnt_range[j][1]:g}\" "
                                           f"in its qpos; the scene's coordinate of joint '{joint}' is {made}")
        if damping > 0.0:
            add_joint_element("damper", f"{joint}_damping", joint, damping, where=f"{label}: damping")
        if stiffness > 0.0:
            adr = int(m.jnt_qposadr[j])
            u_read = float(rows[joint] @ x_read)
            sign = reader.joint_sign[j]
            add_joint_element("spring", f"{joint}_stiffness", joint, stiffness,
                              u_read + sign * (float(m.qpos_spring[adr]) - float(reader.qpos[adr])),
                              where=f"{label}: stiffness", rest_where=f"{label}: springref")
    return lines, joint_elements


__all__ = ["ConnectSource", "Control", "ImportedModel", "MjcfError", "element_label", "first_contact", "import_mjcf"]
