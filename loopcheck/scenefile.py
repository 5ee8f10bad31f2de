"""Reading scenes: TOML text into a validated :class:`~loopcheck.scene.Scene`.

A malformed scene raises :class:`~loopcheck.scene.SceneError` with one message that names the
offending key and the reason; nothing else in the package raises on bad input. Every number
lies in the range of its kind (:data:`~loopcheck.scene.LIMITS`, one table for both engines); the
linkage is checked as a graph (:class:`~loopcheck.mechanism.Linkage`) and assembled at q0 by
Newton's method from the scene's guess (:func:`~loopcheck.kinematics.assemble`). How far the scene
moves is not judged here: a bound on the motion cannot be tight (on a swinging crank one was 500
times the truth), so the engines' work budgets stop a run that turns out too long, naming the
setting to change.

Two forms of ``[linkage]``: ``type = "planar"``, the general description (bodies with named
points, revolute and prismatic joints, an input joint), and ``type = "four_bar"``, the seed's
shorthand (c1…c4 and a branch), expanded here into the general description with the bodies
crank, coupler, rocker; points O1, A, B, O3, G (a centre of mass) and ``damper<k>`` /
``spring<k>`` (the ends of the k-th damper or spring); joints O1, A, B, O3, input O1.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from . import kinematics as loops
from .loads import ConstantLoad, PiecewiseConstantLoad, PulseLoad, LoadProfile
from .mechanism import (GROUND, POLY_TERMS, Actuator, Body, GrublerCountWarning, JointCoupling, JointElement, LineElement,
                        Linkage, Mechanism,
                        MechanismError, PointForce, PrismaticJoint, RevoluteJoint, TimedForce)
from .registry import ENGINES, REFERENCE, judged_engines
from .settings import options, read_table
from .sweep_spec import SweepSpecError, spec_from_table
from .scene import (LIMITS, MAX_BODIES, MAX_DESCRIPTION_CHARS, MAX_ELEMENTS, MAX_JOINTS, MAX_NAME_CHARS, FourBarGeometry,
                    Scene, SceneError, Tolerances)
from .toml_reader import (Table, array_of_tables, check_range, count, name_key, number, parse_toml, point,
                          read_text, table_pair, text_value)

FOUR_BAR_BODIES = ("crank", "coupler", "rocker")
FOUR_BAR_PIVOTS = {"crank": "O1", "rocker": "O3"}  # the links that turn about a fixed pivot
COM = "G"  # the four-bar expansion's name for a centre of mass given in the scene
LINKAGE_TYPES = ("planar", "four_bar")
JOINT_TYPES = ("revolute", "prismatic")
# The Newton assembly of the four-bar shorthand must land on the closed form's configuration:
# both are exact to round-off (~1e-15 rad), so anything above this is another assembly.
SAME_ASSEMBLY_RAD = 1e-9


def _parse_profile(t: Table, kind: str) -> LoadProfile:
    """A load over time on the input joint: constant, pulse or table; values of ``kind``
    (torque in N·m on a revolute input, force in N on a prismatic one)."""
    profile_type = t.string("type")
    if profile_type == "constant":
        profile = ConstantLoad(t.number("value", kind=kind))
    elif profile_type == "pulse":
        profile = PulseLoad(amplitude=t.number("value", kind=kind),
                              start=t.number("start", 0.0, nonnegative=True, kind="time"),
                              duration=t.number("duration", nonnegative=True, kind="time"))
    elif profile_type == "table":
        ts, vs = table_pair(t, "times", "values", "time", kind)
        if any(b <= a for a, b in zip(ts, ts[1:])):
            raise SceneError(f"'{t.key('times')}' must be strictly increasing")
        profile = PiecewiseConstantLoad(times=ts, values=vs)
    else:
        raise SceneError(f"'{t.key('type')}' must be \"constant\", \"pulse\" or \"table\", got \"{profile_type}\"")
    t.close()
    return profile


def _point_ref(t: Table, name: str) -> tuple[str, str]:
    """A ``"body.point"`` reference."""
    value = t.string(name)
    parts = value.split(".")
    if len(parts) != 2 or not all(parts):
        raise SceneError(f"'{t.key(name)}' must name a point as \"body.point\", got \"{value}\"")
    return parts[0], parts[1]


# -- the general description ----------------------------------------------------------

def _parse_planar_body(t: Table, name: str) -> Body:
    """``[bodies.<name>]``: points, and mass, com, inertia (or pivot_inertia about a point), and
    gravcomp (default 0; with mass, com and inertia only: a body given by its pivot inertia has
    no weight that moves)."""
    pts = t.raw("points", {} if name == GROUND else ...)
    if not isinstance(pts, dict):
        raise SceneError(f"'{t.key('points')}' must be a table of named points {{ A = [x, y], ... }}")
    points = {}
    for point_name, value in pts.items():
        key = f"{t.key('points')}.{point_name}"
        points[name_key(point_name, key)] = point(value, key)
    if name == GROUND:
        t.close()
        if not points:
            raise SceneError(f"'{t.key('points')}' is empty: give the ground's fixed points")
        return Body(GROUND, points)
    if not points:
        raise SceneError(f"'{t.key('points')}' is empty: a body needs the points its joints use")
    if t.has("pivot_inertia"):
        for other in ("mass", "com", "inertia"):
            if t.has(other):
                raise SceneError(f"'{t.key(other)}' conflicts with '{t.key('pivot_inertia')}': give mass, com "
                                 "and inertia, or pivot_inertia and pivot")
        inertia = t.number("pivot_inertia", positive=True, kind="inertia")
        pivot = t.string("pivot")
        if pivot not in points:
            raise SceneError(f"'{t.key('pivot')}' = \"{pivot}\" is not one of the body's points")
        t.close()
        return Body(name, points, mass=0.0, com=points[pivot], inertia=inertia)
    mass = t.number("mass", positive=True, kind="mass")
    com = t.point("com")
    inertia = t.number("inertia", positive=True, kind="inertia")
    gravcomp = t.number("gravcomp", 0.0, nonnegative=True, kind="gravity compensation")
    t.close()
    return Body(name, points, mass=mass, com=com, inertia=inertia, gravcomp=gravcomp)


def _parse_joint(t: Table):
    name = name_key(t.string("name"), t.key("name"))
    kind = t.choice("type", JOINT_TYPES)
    body_a, point_a = _point_ref(t, "a")
    body_b, point_b = _point_ref(t, "b")
    span = t.point("range", None, kind="angle" if kind == "revolute" else "position")  # [lo, hi] of u
    if span is not None and not span[0] < span[1]:
        raise SceneError(f"'{t.key('range')}' = [{span[0]:g}, {span[1]:g}]: the lower bound must be below the upper")
    if kind == "revolute":
        joint = _mechanism_value(t.path, lambda: RevoluteJoint(name, body_a, point_a, body_b, point_b, span))
    else:
        direction = t.number("direction", kind="angle")
        joint = _mechanism_value(t.path, lambda: PrismaticJoint(name, body_a, point_a, direction, body_b, point_b,
                                                                span))
    t.close()
    return joint


def _line_law(t: Table, kind: str) -> tuple[float, float]:
    """(coefficient, rest length) of a damper (b, 0) or a spring (k, D0); closes the table."""
    if kind == "damper":
        coefficient, rest = t.number("coefficient", positive=True, kind="damping"), 0.0
    else:
        coefficient = t.number("stiffness", positive=True, kind="stiffness")
        rest = t.number("rest_length", nonnegative=True, kind="position")
    t.close()
    return coefficient, rest


def _parse_line_elements(top: Table) -> list[LineElement]:
    out = []
    for kind, table in (("damper", "dampers"), ("spring", "springs")):
        for k, t in enumerate(array_of_tables(top, table)):
            body_a, point_a = _point_ref(t, "a")
            body_b, point_b = _point_ref(t, "b")
            name = name_key(t.string("name", f"{kind}{k}"), t.key("name"))
            coefficient, rest = _line_law(t, kind)
            out.append(_mechanism_value(t.path, lambda: LineElement(kind, name, body_a, point_a, body_b,
                                                                     point_b, coefficient, rest)))
    return out


def _parse_joint_elements(top: Table, linkage: Linkage) -> list[JointElement]:
    """``[[joint_dampers]]`` (joint, coefficient), ``[[joint_springs]]`` (joint, stiffness,
    rest_angle on a revolute joint or rest_displacement on a prismatic one),
    ``[[joint_inertias]]`` (joint, inertia: MuJoCo's armature) and ``[[joint_frictions]]`` (joint,
    friction: MuJoCo's frictionloss): elements on the joint's own coordinate, in N·m·s/rad,
    N·m/rad, kg·m² and N·m on a revolute joint, N·s/m, N/m, kg and N on a prismatic one."""
    out = []
    joints = linkage.joint_map

    def on_joint(t) -> tuple[str, bool]:
        """The element's joint (one of the linkage's, else SceneError naming the key) and whether it
        is revolute."""
        joint = t.string("joint")
        if joint not in joints:
            raise SceneError(f"'{t.key('joint')}' = \"{joint}\" is not one of the joints: {', '.join(joints)}")
        return joint, not isinstance(joints[joint], PrismaticJoint)

    # one number each: (kind, table, key, its kind on a revolute joint, on a prismatic one)
    for kind, table, key, on_revolute, on_prismatic in (("inertia", "joint_inertias", "inertia", "inertia", "mass"),
                                                         ("friction", "joint_frictions", "friction", "torque", "force")):
        for k, t in enumerate(array_of_tables(top, table)):
            joint, revolute = on_joint(t)
            name = name_key(t.string("name", f"{table[:-1]}{k}"), t.key("name"))
            value = t.number(key, positive=True, kind=on_revolute if revolute else on_prismatic)
            t.close()
            out.append(_mechanism_value(t.path, lambda: JointElement(kind, name, joint, value)))
    for kind, table in (("damper", "joint_dampers"), ("spring", "joint_springs")):
        for k, t in enumerate(array_of_tables(top, table)):
            joint, revolute = on_joint(t)
            name = name_key(t.string("name", f"joint_{kind}{k}"), t.key("name"))
            rest = 0.0
            if kind == "damper":
                coefficient = t.number("coefficient", positive=True,
                                       kind="rotational damping" if revolute else "damping")
            else:
                coefficient = t.number("stiffness", positive=True,
                                       kind="rotational stiffness" if revolute else "stiffness")
                rest_key, other = (("rest_angle", "rest_displacement") if revolute
                                   else ("rest_displacement", "rest_angle"))
                if t.has(other):
                    raise SceneError(f"'{t.key(other)}' does not fit the {'revolute' if revolute else 'prismatic'} "
                                     f"joint '{joint}': give '{rest_key}' ({'rad' if revolute else 'm'})")
                rest = t.number(rest_key, kind="angle" if revolute else "position")
            t.close()
            out.append(_mechanism_value(t.path, lambda: JointElement(kind, name, joint, coefficient, rest)))
    return out


def _parse_point_forces(top: Table, input_kind: str) -> list[PointForce]:
    out = []
    for k, t in enumerate(array_of_tables(top, "point_forces")):
        body, point = _point_ref(t, "point")
        name = name_key(t.string("name", f"force{k}"), t.key("name"))
        direction = t.number("direction", kind="angle")
        coordinate, values = table_pair(t, "q", "values", input_kind, "force")
        if len(coordinate) < 2:
            raise SceneError(f"'{t.key('q')}' needs two or more entries")
        if any(b <= a for a, b in zip(coordinate, coordinate[1:])):
            raise SceneError(f"'{t.key('q')}' must be strictly increasing")
        period = t.number("period", None, positive=True)
        t.close()
        out.append(_mechanism_value(t.path, lambda: PointForce(name, body, point, direction, coordinate,
                                                               values, period)))
    return out


def _parse_timed_forces(top: Table) -> list[TimedForce]:
    """``[[timed_forces]]``: point, direction (rad, ground frame), optional name, and the load
    over time as the input's ``[torque]`` gives it (type constant, pulse or table; values in N)."""
    out = []
    for k, t in enumerate(array_of_tables(top, "timed_forces")):
        body, point = _point_ref(t, "point")
        name = name_key(t.string("name", f"timed_force{k}"), t.key("name"))
        direction = t.number("direction", kind="angle")
        profile = _parse_profile(t, "force")  # closes the table
        out.append(_mechanism_value(t.path, lambda: TimedForce(name, body, point, direction, profile)))
    return out


def _parse_couplings(top: Table, joints) -> list[JointCoupling]:
    """``[[couplings]]``: name, joint (y, the coupled joint), driver (x), polycoef (1 to 5 numbers
    a0 … a4) and reference = [x_ref, y_ref] (default [0, 0]), each in its joint's own coordinate
    (rad on a revolute, m on a prismatic): y − y_ref = a0 + a1 (x − x_ref) + … + a4 (x − x_ref)⁴,
    MuJoCo's equality/joint with x_ref, y_ref its qpos0."""
    out = []
    by_name = {j.name: j for j in joints}
    for k, t in enumerate(array_of_tables(top, "couplings")):
        name = name_key(t.string("name", f"coupling{k}"), t.key("name"))
        ends = []
        for role in ("joint", "driver"):
            joint = t.string(role)
            if joint not in by_name:
                raise SceneError(f"'{t.key(role)}' = \"{joint}\" is not one of the joints: {', '.join(by_name)}")
            ends.append(joint)
        raw = t.raw("polycoef")
        if not isinstance(raw, list) or not 1 <= len(raw) <= POLY_TERMS:
            raise SceneError(f"'{t.key('polycoef')}' must be an array of 1 to {POLY_TERMS} numbers [a0, a1, …, a4]")
        coefficients = [number(v, f"{t.key('polycoef')}[{i}]") for i, v in enumerate(raw)]
        reference = t.raw("reference", [0.0, 0.0])
        if not isinstance(reference, list) or len(reference) != 2:
            raise SceneError(f"'{t.key('reference')}' must be an array of two numbers [x_ref, y_ref] "
                             "(the driver's and the joint's reference values)")
        refs = [number(v, f"{t.key('reference')}[{i}]",
                       kind="position" if isinstance(by_name[j], PrismaticJoint) else "angle")
                for i, (v, j) in enumerate(zip(reference, ends[::-1]))]
        t.close()
        out.append(_mechanism_value(t.path, lambda: JointCoupling(name, ends[0], ends[1], tuple(coefficients),
                                                                  refs[0], refs[1])))
    return out


ACTUATOR = "actuator value"  # the range of an actuator's numbers (loopcheck.scene.LIMITS)


def _pair_or_none(t: Table, name: str) -> tuple[float, float] | None:
    """An optional [lo, hi] range, lo < hi."""
    if not t.has(name):
        return None
    value = t.raw(name)
    if not isinstance(value, list) or len(value) != 2:
        raise SceneError(f"'{t.key(name)}' must be an array of two numbers [lo, hi]")
    lo, hi = (number(v, f"{t.key(name)}[{i}]", kind=ACTUATOR) for i, v in enumerate(value))
    if not lo < hi:
        raise SceneError(f"'{t.key(name)}' must have lo < hi, got [{lo:g}, {hi:g}]")
    return lo, hi


def _parse_actuators(top: Table, linkage: Linkage) -> list[Actuator]:
    """``[[actuators]]``: name, its transmission (``joint = "J"`` or ``tendon = { J1 = c1, … }``,
    a fixed tendon l = Σ c_j u_j), gain, bias = [b0, b1, b2], gear, optional ctrlrange and
    forcerange [lo, hi], and its control over time (``[actuators.control]``, the forms of the
    input's ``[torque]``: constant, pulse or table; zero without one):
    :class:`loopcheck.mechanism.Actuator`."""
    out = []
    joints = linkage.joint_map
    for k, t in enumerate(array_of_tables(top, "actuators")):
        name = name_key(t.string("name", f"actuator{k}"), t.key("name"))
        if name in {a.name for a in out}:
            raise SceneError(f"'{t.key('name')}' = \"{name}\": duplicate actuator name")
        if t.has("joint") == t.has("tendon"):
            raise SceneError(f"'{t.path}' needs its transmission: 'joint' or 'tendon' (one of the two)")
        joint, tendon = None, None
        if t.has("joint"):
            joint = t.string("joint")
            if joint not in joints:
                raise SceneError(f"'{t.key('joint')}' = \"{joint}\" is not one of the joints: {', '.join(joints)}")
        else:
            tt = t.table("tendon")
            if not tt.data:
                raise SceneError(f"'{tt.path}' must name one joint or more with its coefficient")
            terms = []
            for j in tt.data:
                if j not in joints:
                    raise SceneError(f"'{tt.key(j)}': \"{j}\" is not one of the joints: {', '.join(joints)}")
                c = tt.number(j, kind=ACTUATOR)
                if c == 0.0:
                    raise SceneError(f"'{tt.key(j)}' must be nonzero")
                terms.append((j, c))
            tendon = tuple(terms)
        gain = t.number("gain", 1.0, kind=ACTUATOR)
        bias = t.raw("bias", [0.0, 0.0, 0.0])
        if not isinstance(bias, list) or len(bias) != 3:
            raise SceneError(f"'{t.key('bias')}' must be an array of three numbers [b0, b1, b2]")
        bias = tuple(number(v, f"{t.key('bias')}[{i}]", kind=ACTUATOR) for i, v in enumerate(bias))
        gear = t.number("gear", 1.0, kind=ACTUATOR)
        if gear == 0.0:
            raise SceneError(f"'{t.key('gear')}' must be nonzero")
        ctrlrange, forcerange = _pair_or_none(t, "ctrlrange"), _pair_or_none(t, "forcerange")
        control = _parse_profile(t.table("control"), ACTUATOR) if t.has("control") else None
        t.close()
        out.append(_mechanism_value(t.path, lambda: Actuator(name, joint, tendon, gain, bias, gear, ctrlrange,
                                                             forcerange, control)))
    return out


def _with_inertias_in_tree(linkage: Linkage, joint_elements: list[JointElement]) -> Linkage:
    """The linkage with its joint inertias' and couplings' joints taken into the spanning tree first
    (MuJoCo holds an inertia and an equality/joint only on a tree joint:
    :func:`loopcheck.mujoco_model.build.build_spec`)."""
    first = tuple(dict.fromkeys([e.joint for e in joint_elements if e.kind == "inertia"]
                                + [j for c in linkage.couplings for j in (c.joint, c.driver)]))
    if not first:
        return linkage
    return _mechanism_value("joints", lambda: Linkage(linkage.bodies, linkage.joints, linkage.input_joint, first,
                                                             linkage.couplings, linkage.inputs))


def _mechanism_value(key: str, build):
    """Build a mechanism value; its MechanismError becomes a SceneError naming ``key``."""
    try:
        return build()
    except MechanismError as exc:
        raise SceneError(f"'{key}': {exc}") from None


def _parse_inputs(link: Table) -> tuple[str, ...]:
    """``linkage.input = "J"`` (one degree of freedom) or ``linkage.inputs = ["J1", "J2", …]``
    (several, in order: the initial values and the reports follow it), one of the two."""
    if link.has("input") == link.has("inputs"):
        raise SceneError("'linkage' needs 'input' (one joint) or 'inputs' (several), one of the two")
    if link.has("input"):
        return (link.string("input"),)
    names = link.raw("inputs")
    if not isinstance(names, list) or len(names) < 2 or not all(isinstance(v, str) for v in names):
        raise SceneError(f"'{link.key('inputs')}' must be an array of two joint names or more "
                         f"(one input is written input = \"J\")")
    if len(set(names)) != len(names):
        raise SceneError(f"'{link.key('inputs')}' names a joint twice")
    return tuple(names)


def _initial_values(init: Table, name: str, default, kinds: tuple[str, ...]) -> tuple[float, ...]:
    """``initial.q`` / ``initial.qdot``: a number for one input, an array in the inputs' order for several."""
    if len(kinds) == 1:
        return (init.number(name, default, kind=kinds[0]),)
    value = init.raw(name, [default] * len(kinds) if default is not ... else ...)
    if not isinstance(value, list) or len(value) != len(kinds):
        raise SceneError(f"'{init.key(name)}' must be an array of {len(kinds)} numbers, one per input (linkage.inputs)")
    return tuple(number(v, f"{init.key(name)}[{i}]", kind=kind) for i, (v, kind) in enumerate(zip(value, kinds)))


def _parse_planar(top: Table, link: Table) -> tuple[Mechanism, FourBarGeometry | None]:
    inputs = _parse_inputs(link)
    input_joint = inputs[0]
    link.close()
    bodies_t = top.table("bodies")
    names = list(bodies_t.data)
    count([n for n in names if n != GROUND], "bodies", MAX_BODIES, "moving bodies")
    bodies = [_parse_planar_body(bodies_t.table(name_key(n, bodies_t.key(n))), n) for n in names]
    bodies_t.close()
    joints_t = array_of_tables(top, "joints", MAX_JOINTS)
    if not joints_t:
        raise SceneError("missing key 'joints': a planar linkage needs [[joints]]")
    joints = [_parse_joint(t) for t in joints_t]
    joint_names = [j.name for j in joints]
    for name in inputs:
        if name not in joint_names:
            key = "linkage.input" if len(inputs) == 1 else "linkage.inputs"
            raise SceneError(f"'{key}' = \"{name}\" is not one of the joints: {', '.join(joint_names)}")
    couplings = _parse_couplings(top, joints)
    linkage = _mechanism_value("couplings" if couplings else "joints",
                               lambda: Linkage(bodies, joints, input_joint, couplings=couplings, inputs=inputs))
    input_kind = "position" if isinstance(linkage.joint_map[input_joint], PrismaticJoint) else "angle"
    elements = _parse_line_elements(top)
    forces = _parse_point_forces(top, input_kind)
    if forces and len(inputs) > 1:
        raise SceneError("'point_forces' are tabulated over the input coordinate q, and a linkage with several inputs "
                         "has no one q: give the force over time ([[timed_forces]]) or as an actuator")
    joint_elements = _parse_joint_elements(top, linkage)
    linkage = _with_inertias_in_tree(linkage, joint_elements)
    timed = _parse_timed_forces(top)
    actuators = _parse_actuators(top, linkage)
    count(elements + forces + joint_elements + timed + actuators,
           "dampers, springs, joint_dampers, joint_springs, joint_inertias, joint_frictions, point_forces, timed_forces and actuators",
           MAX_ELEMENTS, "entries together")
    return _mechanism_value("bodies", lambda: Mechanism(linkage, elements, forces, joint_elements, timed,
                                                        actuators)), None


# -- the four-bar shorthand ------------------------------------------------------------

def _parse_four_bar_geometry(t: Table) -> FourBarGeometry:
    lengths = [t.number(f"c{i}", positive=True, kind="length") for i in (1, 2, 3, 4)]
    branch = t.raw("branch")
    if isinstance(branch, bool) or branch not in (1, -1):
        raise SceneError(f"'{t.key('branch')}' must be 1 or -1 (the sign of ± in the φ1 formula)")
    t.close()
    return FourBarGeometry(*lengths, branch=int(branch))


def _parse_four_bar_body(t: Table, name: str, needs_mass: bool) -> tuple[float, tuple | None, float]:
    """(mass, com, inertia about the com) of a four-bar link; mass 0 and com None for a link
    given by its inertia about its fixed pivot alone."""
    grounded = name in FOUR_BAR_PIVOTS
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
            check_range(centroidal, t.key("pivot_inertia"), LIMITS["inertia"], " − mass·|com|²")
    if needs_mass and (mass is None or com is None):
        missing = " and ".join(f"'{t.key(k)}'" for k, v in (("mass", mass), ("com", com)) if v is None)
        raise SceneError(f"missing {'keys' if ' and ' in missing else 'key'} {missing}:"
                         " gravity needs the mass and centre of mass of every moving link")
    if mass is None:
        return 0.0, None, pivot
    return mass, com, centroidal


def _parse_four_bar(top: Table, link: Table, needs_mass: bool) -> tuple[Mechanism, FourBarGeometry]:
    """The shorthand, expanded into the general description (module docstring)."""
    g = _parse_four_bar_geometry(link)
    points = {GROUND: {"O1": (0.0, 0.0), "O3": (g.c4, 0.0)},
              "crank": {"O1": (0.0, 0.0), "A": (g.c1, 0.0)},
              "coupler": {"A": (0.0, 0.0), "B": (g.c2, 0.0)},
              "rocker": {"O3": (0.0, 0.0), "B": (g.c3, 0.0)}}
    bodies_t = top.table("bodies")
    mass_properties = {}
    for name in FOUR_BAR_BODIES:
        mass, com, inertia = _parse_four_bar_body(bodies_t.table(name), name, needs_mass)
        if com is None:  # its inertia about the fixed pivot, at the pivot
            com = points[name][FOUR_BAR_PIVOTS[name]]
        else:
            points[name][COM] = com
        mass_properties[name] = (mass, com, inertia)
    bodies_t.close()
    elements = []
    for kind, table in (("damper", "dampers"), ("spring", "springs")):
        for k, t in enumerate(array_of_tables(top, table)):
            body = t.string("body")
            if body not in FOUR_BAR_BODIES:
                raise SceneError(f"'{t.key('body')}' must be one of {', '.join(FOUR_BAR_BODIES)}, got \"{body}\"")
            name = f"{kind}{k}"
            points[GROUND][name] = t.point("ground_point")
            points[body][name] = t.point("body_point")
            coefficient, rest = _line_law(t, kind)
            elements.append(LineElement(kind, name, GROUND, name, body, name, coefficient, rest))
    bodies = [Body(GROUND, points[GROUND])] + [
        Body(name, points[name], *mass_properties[name]) for name in FOUR_BAR_BODIES]
    joints = [RevoluteJoint("O1", GROUND, "O1", "crank", "O1"),
              RevoluteJoint("A", "crank", "A", "coupler", "A"),
              RevoluteJoint("B", "coupler", "B", "rocker", "B"),
              RevoluteJoint("O3", GROUND, "O3", "rocker", "O3")]
    linkage = Linkage(bodies, joints, "O1")
    joint_elements = _parse_joint_elements(top, linkage)
    linkage = _with_inertias_in_tree(linkage, joint_elements)
    actuators = _parse_actuators(top, linkage)
    return _mechanism_value("bodies", lambda: Mechanism(linkage, elements, (), joint_elements, (), actuators)), g


# -- the scene -------------------------------------------------------------------------

def scene_from_dict(data: Mapping[str, Any], source: str = "<memory>") -> Scene:
    """Build and validate a :class:`Scene` from parsed TOML data."""
    top = Table(dict(data), "")
    stem = "".join(c if c.isprintable() else "?" for c in Path(source).stem[:MAX_NAME_CHARS])
    name = text_value(top, "name", stem if source != "<memory>" else "scene", MAX_NAME_CHARS)
    description = text_value(top, "description", "", MAX_DESCRIPTION_CHARS)
    gravity = top.point("gravity", None, kind="gravity")

    link = top.table("linkage")
    kind = link.string("type", "four_bar")
    if kind not in LINKAGE_TYPES:
        raise SceneError(f"'linkage.type' must be \"planar\" or \"four_bar\", got \"{kind}\"")
    link.used.add("type")
    if kind == "four_bar":
        mechanism, four_bar = _parse_four_bar(top, link, needs_mass=gravity is not None)
    else:
        mechanism, four_bar = _parse_planar(top, link)
    linkage = mechanism.linkage
    prismatic_input = isinstance(linkage.joint_map[linkage.input_joint], PrismaticJoint)

    load_key, other_key = ("force", "torque") if prismatic_input else ("torque", "force")
    several = len(linkage.inputs) > 1
    for key in ("torque", "force") if several else ():
        if top.has(key):
            raise SceneError(f"'{key}': a linkage with several inputs takes each input's load as an actuator on its "
                             f"joint ([[actuators]] with joint = \"{linkage.input_joint}\" and its [actuators.control])")
    if top.has(other_key):
        raise SceneError(f"'{other_key}' does not fit the {'prismatic' if prismatic_input else 'revolute'} "
                         f"input joint '{linkage.input_joint}': give [{load_key}] "
                         f"({'N' if prismatic_input else 'N·m'})")
    load = _parse_profile(top.table(load_key), load_key) if top.has(load_key) else None
    top.used.add(load_key)

    init = top.table("initial")
    kinds = tuple("position" if isinstance(linkage.joint_map[j], PrismaticJoint) else "angle" for j in linkage.inputs)
    q0s = _initial_values(init, "q", ..., kinds)
    qdot0s = _initial_values(init, "qdot", 0.0, ("speed",) * len(kinds))
    q0, qdot0 = q0s[0], qdot0s[0]
    guess_t = init.table("guess") if init.has("guess") else None
    mode = init.raw("mode", None)
    init.used.add("guess")

    sim = top.table("simulation")
    horizon = sim.number("horizon", positive=True, kind="horizon")
    sim.close()

    tolerances, engine_tolerances = _parse_tolerances(top)
    engine_tables = {name: read_table(engine.settings, top.raw(name), name)
                     for name, engine in ENGINES.items() if top.has(name)}
    if top.has("sweep"):
        _check_sweep(top.raw("sweep"), source)
    top.used.add("sweep")
    top.close()
    _check_steps(engine_tables, horizon)

    system = loops.compile_linkage(linkage)
    if four_bar is not None:
        if guess_t is not None or mode is not None:
            raise SceneError("'initial.guess' and 'initial.mode' are for a planar linkage: the four-bar "
                             "shorthand assembles on 'linkage.branch'")
        init.close()
        x0, found_mode = _assemble_four_bar(system, four_bar, q0)
    else:
        guess = _parse_guess(guess_t, system, linkage) if guess_t is not None else np.zeros(system.n)
        init.close()
        x0 = _assemble(system, q0s, guess, mode, linkage)
        found_mode = loops.assembly_mode(system, x0)
        note = redundancy_note(linkage, system, x0)
        if note is not None:
            warnings.warn(f"{source or f'scene {name!r}'}: {note}", GrublerCountWarning, stacklevel=2)
    if not several:  # several inputs: assemble_inputs refused a singular set of them
        _check_start(system, x0, q0, qdot0)
    _check_ranges(system, mechanism.linkage, x0)

    scene = Scene(name=name, description=description, mechanism=mechanism, load=load, gravity=gravity,
                  q0=q0, qdot0=qdot0, x0=tuple(float(v) for v in x0),
                  mode=found_mode, horizon=horizon, tolerances=tolerances,
                  engine_tables=engine_tables, source=source, four_bar=four_bar, engine_tolerances=engine_tolerances,
                  inputs_q0=q0s if several else (), inputs_qdot0=qdot0s if several else ())
    return scene


def _parse_tolerances(top: Table) -> tuple[Tolerances, dict[str, dict[str, float]]]:
    """``[tolerances]`` and its engine tables ``[tolerances.ENGINE]``, one per registered engine
    but the reduced reference: each key positive; an engine's table holds the keys it gives."""
    if not top.has("tolerances"):
        return Tolerances(), {}
    tol = top.table("tolerances")
    fields = dataclasses.fields(Tolerances)
    tolerances = Tolerances(**{f.name: tol.number(f.name, f.default, positive=True) for f in fields})
    judged = judged_engines()
    engine_tolerances = {}
    for name in [key for key in tol.data if key not in tol.used]:
        if name not in (REFERENCE, *judged) and not isinstance(tol.data[name], dict):
            continue  # an unknown key: tol.close() names it
        if name == REFERENCE:
            raise SceneError(f"'{tol.key(name)}': the reduced engine is the reference the others are judged against; "
                             f"it has no tolerances (engine tables: {', '.join(judged)})")
        if name not in judged:
            raise SceneError(f"'{tol.key(name)}' names no engine; [tolerances.ENGINE] is one of {', '.join(judged)}")
        table = tol.table(name)
        engine_tolerances[name] = {f.name: table.number(f.name, positive=True) for f in fields if table.has(f.name)}
        table.close()
    tol.close()
    return tolerances, engine_tolerances


def _parse_guess(t: Table, system, linkage: Linkage) -> np.ndarray:
    """``initial.guess``: body angles (rad) by body name, slider displacements (m) by joint
    name; a coordinate not given starts at 0."""
    guess = np.zeros(system.n)
    for key in list(t.data):
        coordinate = f"{key}.angle" if key in linkage.moving else f"{key}.s"
        if coordinate not in system.coordinate_names:
            raise SceneError(f"'{t.key(key)}': the guess names a moving body (its angle, rad) or a prismatic "
                             f"joint (its displacement, m); \"{key}\" is neither")
        guess[system.coordinate(coordinate)] = t.number(key, kind="angle" if key in linkage.moving else "position")
    t.close()
    return guess


def _assemble(system, q0s: tuple[float, ...], guess: np.ndarray, mode, linkage: Linkage) -> np.ndarray:
    """Newton from the guess; the degrees of freedom by the loop Jacobian's rank (one per input, or
    refused naming Grübler's count and the rank's) and the asked mode are checked."""
    q0 = f"{q0s[0]:g}" if len(q0s) == 1 else "[" + ", ".join(f"{v:g}" for v in q0s) + "]"
    try:
        x0 = loops.assemble(system, q0s[0], guess) if len(q0s) == 1 else loops.assemble_inputs(system, q0s, guess)
    except loops.AssemblyError as exc:
        raise SceneError(f"'initial.q' = {q0}: {exc}" + (
            f"; the linkage has {linkage.grubler_dof} degrees of freedom by Grübler's count: a structure, unless "
            "its loop equations are redundant" if linkage.grubler_dof < 1 else "")) from None
    rank = loops.jacobian_rank(system, x0)
    if rank != system.n - len(q0s):
        dof = system.n - rank
        raise SceneError(f"'initial.q' = {q0}: the loop equations have rank {rank} ({system.m} rows over "
                         f"{system.n} coordinates) at the assembled configuration: {dof} degrees of freedom by "
                         f"rank ({linkage.grubler_dof} by Grübler's count), not {len(q0s)}"
                         + (": the linkage is locked" if dof == 0 else " (redundant or parallel joints)"))
    found = loops.assembly_mode(system, x0)
    if mode is not None:
        if (not isinstance(mode, list) or len(mode) != len(found)
                or any(isinstance(v, bool) or v not in (1, -1) for v in mode)):
            raise SceneError(f"'initial.mode' must be an array of {len(found)} signs (1 or -1), one per loop")
        if tuple(mode) != found:
            raise SceneError(f"'initial.guess' assembles in mode {list(found)}, not the 'initial.mode' "
                             f"{list(mode)} asked for: start the guess nearer that assembly")
    return x0


def redundancy_note(linkage: Linkage, system, x0: np.ndarray) -> str | None:
    """The warning (one line, without the scene's name) of a linkage accepted with one degree of
    freedom by the rank of its loop equations at x0 whose Grübler count differs; None where it
    does not (:class:`~loopcheck.mechanism.GrublerCountWarning`: the scene reader and the MJCF import
    say it in these words)."""
    dof = linkage.dof
    if linkage.grubler_dof == dof:
        return None
    rank = loops.jacobian_rank(system, x0)
    return (f"Grübler's count gives {linkage.grubler_dof} degrees of freedom, the rank of the loop equations at "
            f"the start gives {dof} ({system.m - rank} of its {system.m} loop equations are redundant): a redundantly "
            f"closed loop, run with {'one degree' if dof == 1 else f'{dof} degrees'} of freedom on its independent equations")


ASSEMBLY_CACHE = 64
"""How many four-bar assemblies :func:`_assemble_four_bar` keeps (a sweep's variants that change
no length nor q0 share one)."""
_ASSEMBLIES: dict[tuple, tuple[np.ndarray, tuple[int, ...]]] = {}


def _assembly_key(system, g: FourBarGeometry, q0: float) -> tuple:
    """Everything :func:`_assemble_four_bar`'s answer depends on: the lengths, branch and q0 (their
    bits: −0.0 is not 0.0), and the loop system Newton runs on (its coordinates, loop table,
    linear and coupling rows, drive and selected rows, as bytes)."""
    t = system.loops
    arrays = (t.offset, t.row, t.coef, t.mag, t.angle, t.phase, system.linear, system.drive, system.coupling_rows)
    return (tuple(float(v).hex() for v in (g.c1, g.c2, g.c3, g.c4, q0)), g.branch, system.coordinate_names,
            system.rows, tuple((a.dtype.str, a.shape, a.tobytes()) for a in arrays))


def _assemble_four_bar(system, g: FourBarGeometry, q0: float) -> tuple[np.ndarray, tuple[int, ...]]:
    """Newton from the closed form's assembly on the scene's branch, checked to stay there, and its
    assembly mode (:func:`loopcheck.kinematics.assembly_mode`).

    The closed form, not Newton from a rough guess on the branch: that changes x0's last bits,
    which moved the shipped runs by up to 1.7e-6, and cannot reach a limit position, a double
    root (docs/architecture.md, "The four-bar closed form").

    Kept for the next scene of the same key (:func:`_assembly_key`; at most
    :data:`ASSEMBLY_CACHE`, the oldest dropped): the same deterministic answer, a copy of x0."""
    key = _assembly_key(system, g, q0)
    found = _ASSEMBLIES.get(key)
    if found is None:
        x0 = _assemble_four_bar_now(system, g, q0)
        found = x0, loops.assembly_mode(system, x0)
        while len(_ASSEMBLIES) >= ASSEMBLY_CACHE:
            _ASSEMBLIES.pop(next(iter(_ASSEMBLIES), None), None)
        _ASSEMBLIES[key] = found
    x0, mode = found
    return x0.copy(), mode


def _assemble_four_bar_now(system, g: FourBarGeometry, q0: float) -> np.ndarray:
    """:func:`_assemble_four_bar` without its cache."""
    from .four_bar import AssemblyError as ClosedFormError, FourBar

    try:
        q, phi1, phi2 = FourBar(g).assemble(q0)
    except ClosedFormError as exc:
        raise SceneError(f"'initial.q' = {q0}: {exc}") from None
    guess = np.array([q, phi1, phi2 + math.pi])  # the rocker's frame points O3 → B
    try:
        x0 = loops.assemble(system, q0, guess)
    except loops.AssemblyError as exc:
        raise SceneError(f"'initial.q' = {q0}: {exc}") from None
    gap = float(np.max(np.abs(np.angle(np.exp(1j * (x0 - guess))))))
    if not gap <= SAME_ASSEMBLY_RAD:
        raise SceneError(f"'initial.q' = {q0}: the general description assembles {gap:.3g} rad away from the "
                         f"four-bar closed form on branch {g.branch}")
    return x0


# The assembled x0 is known to Newton's tolerance (m or rad): a joint found outside its range by no
# more than that starts on its bound (Menagerie's Robotiq 2F-85 at qpos0: its driver at its lower
# bound 0 came out at -3.2e-32 rad and was refused).
RANGE_START_TOL = 1e-12


def _check_ranges(system, linkage: Linkage, x0: np.ndarray) -> None:
    """Every joint with a range starts inside it (lo ≤ u0 ≤ hi, to the assembly's RANGE_START_TOL)."""
    for joint in linkage.joints:
        if joint.range is None:
            continue
        u0 = float(system.joint_row(joint.name) @ x0)
        lo, hi = joint.range
        if not lo - RANGE_START_TOL <= u0 <= hi + RANGE_START_TOL:
            unit = "m" if isinstance(joint, PrismaticJoint) else "rad"
            raise SceneError(f"joint '{joint.name}' starts at {u0:.9g} {unit}, outside its range [{lo:g}, {hi:g}] {unit}")


def _check_start(system, x0: np.ndarray, q0: float, qdot0: float) -> None:
    if qdot0 == 0.0:
        return
    if loops.driving_conditioning(system, x0) < loops.SINGULAR_CONDITIONING:
        raise SceneError(f"'initial.qdot' = {qdot0}: the input joint is at a dead centre at q = {q0}, "
                         "where its speed must be zero")


def _check_steps(engine_tables: dict[str, dict[str, Any]], horizon: float) -> None:
    """A time step in an engine's table (an option ``within_horizon``) is at most the horizon."""
    for name, table in engine_tables.items():
        for o in options(ENGINES[name].settings):
            step = table.get(o.name)
            if o.within_horizon and step is not None and step > horizon:
                raise SceneError(f"'{name}.{o.name}' = {step:.12g} s is longer than 'simulation.horizon' = {horizon:.12g} s")


def _check_sweep(table: Any, source: str) -> None:
    """The optional [sweep] table (a family of variants of this scene, ``loopcheck sweep``): read by
    :func:`loopcheck.sweep_spec.spec_from_table`, its errors as SceneErrors. The scene itself
    does not use it; whether its keys fit the scene is checked when the sweep runs."""
    try:
        spec_from_table(table, source="")
    except SweepSpecError as exc:
        raise SceneError(str(exc)) from None


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
    data = parse_toml(read_text(path), path)
    try:
        return scene_from_dict(data, source=str(path))
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None


