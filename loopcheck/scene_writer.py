"""Writing scenes: a :class:`~loopcheck.scene.Scene` as the TOML text that :mod:`loopcheck.scenefile` reads
back into the same scene.

The text is always the general description (``[linkage] type = "planar"``): a ``four_bar``
shorthand scene is written expanded. Every number is written as the shortest text that reads
back to the same double (``repr``), so points, masses and loads survive the trip exactly; the
initial guess is the scene's assembled configuration ``x0``, from which the reader's Newton
assembly starts (and stays, to round-off), with its assembly mode. A ``[sweep]`` table is not
part of a scene and is not written. Used by ``loopcheck import-mjcf`` to write what it read.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

from . import kinematics as loops
from .loads import ConstantLoad, LoadProfile, PiecewiseConstantLoad, PulseLoad
from .mechanism import GROUND, Body, Mechanism, PrismaticJoint
from .scene import Scene, Tolerances


def _point(body: str, point: str) -> str:
    return f"{body}.{point}"


def _pivot(body: Body, mechanism: Mechanism) -> str:
    """The point of a body given by its inertia about a fixed pivot (mass 0): the point of its
    revolute joint to ground at its ``com`` (:class:`~loopcheck.mechanism.Mechanism` checked it exists)."""
    for j in mechanism.linkage.joints:
        if isinstance(j, PrismaticJoint) or GROUND not in (j.body_a, j.body_b) or body.name not in (j.body_a, j.body_b):
            continue
        own = j.point_b if j.body_b == body.name else j.point_a
        if body.points[own] == body.com:
            return own
    raise ValueError(f"body {body.name!r} has no mass and no pivot at its com")  # Mechanism refuses this


def _body(body: Body, mechanism: Mechanism) -> dict[str, Any]:
    table: dict[str, Any] = {"points": {name: list(xy) for name, xy in body.points.items()}}
    if body.name == GROUND:
        return table
    if body.mass == 0.0:
        table.update(pivot_inertia=body.inertia, pivot=_pivot(body, mechanism))
    else:
        table.update(mass=body.mass, com=list(body.com), inertia=body.inertia)
        if body.gravcomp:
            table["gravcomp"] = body.gravcomp
    return table


def profile_data(profile: LoadProfile) -> dict[str, Any]:
    """A load over time as the scene file writes it (``[torque]``, ``[force]``, a timed force)."""
    if isinstance(profile, ConstantLoad):
        return {"type": "constant", "value": profile.amplitude}
    if isinstance(profile, PulseLoad):
        return {"type": "pulse", "value": profile.amplitude, "start": profile.start, "duration": profile.duration}
    if isinstance(profile, PiecewiseConstantLoad):
        return {"type": "table", "times": list(profile.times), "values": list(profile.values)}
    raise TypeError(f"no scene-file form for a {type(profile).__name__}")


def _actuator(a) -> dict[str, Any]:
    """An actuator as ``[[actuators]]`` writes it (:func:`loopcheck.scenefile._parse_actuators`)."""
    row: dict[str, Any] = {"name": a.name}
    if a.joint is not None:
        row["joint"] = a.joint
    else:
        row["tendon"] = {j: c for j, c in a.tendon}
    row.update({"gain": a.gain, "bias": list(a.bias), "gear": a.gear})
    for key in ("ctrlrange", "forcerange"):
        if getattr(a, key) is not None:
            row[key] = list(getattr(a, key))
    if a.control is not None:
        row["control"] = profile_data(a.control)
    return row


def scene_data(scene: Scene) -> dict[str, Any]:
    """The scene as TOML data (tables, arrays, numbers, strings) in the scene file's layout."""
    mech = scene.mechanism
    linkage = mech.linkage
    data: dict[str, Any] = {"name": scene.name}
    if scene.description:
        data["description"] = scene.description
    if scene.gravity is not None:
        data["gravity"] = list(scene.gravity)
    data["linkage"] = ({"type": "planar", "inputs": list(linkage.inputs)} if len(linkage.inputs) > 1
                       else {"type": "planar", "input": linkage.input_joint})
    data["bodies"] = {b.name: _body(b, mech) for b in linkage.bodies}
    joints = []
    for j in linkage.joints:
        row: dict[str, Any] = {"name": j.name, "type": "prismatic" if isinstance(j, PrismaticJoint) else "revolute",
                               "a": _point(j.body_a, j.point_a), "b": _point(j.body_b, j.point_b)}
        if isinstance(j, PrismaticJoint):
            row["direction"] = j.direction_a
        if j.range is not None:
            row["range"] = list(j.range)
        joints.append(row)
    data["joints"] = joints
    for kind, table in (("damper", "dampers"), ("spring", "springs")):
        rows = []
        for e in mech.elements:
            if e.kind == kind:
                row = {"name": e.name, "a": _point(e.body_a, e.point_a), "b": _point(e.body_b, e.point_b)}
                row.update({"coefficient": e.coefficient} if kind == "damper"
                           else {"stiffness": e.coefficient, "rest_length": e.rest_length})
                rows.append(row)
        if rows:
            data[table] = rows
    joint_kinds = linkage.joint_map
    if linkage.couplings:
        data["couplings"] = [{"name": c.name, "joint": c.joint, "driver": c.driver,
                              "polycoef": list(c.coefficients), "reference": [c.x_ref, c.y_ref]}
                             for c in linkage.couplings]
    if mech.joint_inertias:
        data["joint_inertias"] = [{"name": e.name, "joint": e.joint, "inertia": e.coefficient}
                                  for e in mech.joint_inertias]
    if mech.joint_frictions:
        data["joint_frictions"] = [{"name": e.name, "joint": e.joint, "friction": e.coefficient}
                                   for e in mech.joint_frictions]
    for kind, table in (("damper", "joint_dampers"), ("spring", "joint_springs")):
        rows = []
        for e in mech.joint_elements:
            if e.kind == kind:
                row = {"name": e.name, "joint": e.joint}
                if kind == "damper":
                    row["coefficient"] = e.coefficient
                else:
                    rest = "rest_displacement" if isinstance(joint_kinds[e.joint], PrismaticJoint) else "rest_angle"
                    row.update({"stiffness": e.coefficient, rest: e.rest})
                rows.append(row)
        if rows:
            data[table] = rows
    if mech.point_forces:
        data["point_forces"] = [
            {"name": p.name, "point": _point(p.body, p.point), "direction": p.direction, "q": list(p.coordinate),
             "values": list(p.values), **({"period": p.period} if p.period is not None else {})}
            for p in mech.point_forces]
    if mech.timed_forces:
        data["timed_forces"] = [{"name": p.name, "point": _point(p.body, p.point), "direction": p.direction,
                                 **profile_data(p.profile)} for p in mech.timed_forces]
    if mech.actuators:
        data["actuators"] = [_actuator(a) for a in mech.actuators]
    if scene.load is not None:
        data[scene.load_name] = profile_data(scene.load)
    system = loops.compile_linkage(linkage)
    guess = {}
    for name, value in zip(system.coordinate_names, scene.x0):
        guess[name.rpartition(".")[0]] = value  # "<body>.angle" or "<joint>.s"
    data["initial"] = ({"q": list(scene.initial_q()), "qdot": list(scene.initial_qdot()), "guess": guess}
                       if scene.dof > 1 else {"q": scene.q0, "qdot": scene.qdot0, "guess": guess})
    if all(sign in (1, -1) for sign in scene.mode):  # a sign 0 (a dyad at a limit) is not a mode one can ask for
        data["initial"]["mode"] = list(scene.mode)
    data["simulation"] = {"horizon": scene.horizon}
    data["tolerances"] = {f.name: getattr(scene.tolerances, f.name) for f in dataclasses.fields(Tolerances)
                          if getattr(scene.tolerances, f.name) is not None}
    for engine, given in scene.engine_tolerances.items():  # [tolerances.ENGINE], written inline in [tolerances]
        data["tolerances"][engine] = dict(given)
    for engine, table in scene.engine_tables.items():
        if table:
            data[engine] = dict(table)
    return data


# -- TOML text ---------------------------------------------------------------------------

def _key(name: str) -> str:
    """A bare key where TOML allows one (ASCII letters, digits, '_', '-'), else a quoted one."""
    if name and all(c.isascii() and (c.isalnum() or c in "_-") for c in name):
        return name
    return json.dumps(name)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"a scene holds finite numbers only, got {value}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # JSON's escapes are TOML basic-string escapes
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"no TOML form for a {type(value).__name__}")


def _is_table(value: Any) -> bool:
    return isinstance(value, dict)


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def toml_text(data: dict[str, Any], header: str = "") -> str:
    """TOML text of ``data``: top-level values first, then each table (``[initial]``; a table of
    tables as one table each, ``[bodies.crank]``) and array of tables (``[[joints]]``); tables
    inside those are written inline.
    ``header``: comment lines put first (each prefixed with ``# ``)."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]

    def block(path: str, table: dict[str, Any], array: bool = False) -> None:
        lines.append("")
        lines.append(f"[[{path}]]" if array else f"[{path}]")
        lines.extend(f"{_key(k)} = {_value(v)}" for k, v in table.items())

    for k, v in data.items():
        if not (_is_table(v) or _is_table_array(v)):
            lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in data.items():
        if _is_table(v):
            if v and all(_is_table(w) for w in v.values()):  # [bodies.<name>]
                for name, sub in v.items():
                    block(f"{_key(k)}.{_key(name)}", sub)
            else:
                block(_key(k), v)
        elif _is_table_array(v):
            for row in v:
                block(_key(k), row, array=True)
    return "\n".join(lines).lstrip("\n") + "\n"


def scene_toml(scene: Scene, header: str = "") -> str:
    """The scene file of ``scene`` (:func:`scene_data` as TOML text), with ``header`` as comments."""
    return toml_text(scene_data(scene), header)
