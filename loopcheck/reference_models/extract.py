"""One closed loop out of a larger MuJoCo model, as a standalone model (``--loop NAME``, docs/import.md).

:func:`extract_loop` reads a model at one configuration (the keyframe's ``qpos`` or ``qpos0``, as
:func:`loopcheck.reference_models.mjcf_import.import_mjcf` reads it) and edits its ``MjSpec``:

- the loop: the connects and joint couplings named, with every closure joined to them through a shared
  moving body or a coupled joint (:func:`_components`: the mechanism is kept whole), and the
  bodies on the tree path between each one's two ends (the path's top body, where the two branches
  meet, is the loop's ground); those bodies keep their joints;
- mass: the descendants of the loop's moving bodies stay, their joints welded at the configuration
  read, as part of the body they hang from;
- ground: every other body, its joints (free and ball joints too) welded at the configuration read;
  each welded body's pose is rebased to its pose there;
- what acts outside the kept set is dropped and listed (actuators, tendons, equalities, contact
  pairs, sensors); a spatial tendon with a site on a moving body is kept (its other sites are then
  ground); a joint coupling joins the loop of each joint it couples (:func:`_components`), so none
  reaches a welded joint; a connect or weld between the loop and a welded body is refused (a lock);
  a collidable geom on ground stays (a foot and the floor: a contact fails the check).
- the plane: the loop's hinge axes must be parallel within :data:`PLANAR_TOL` rad; above
  :data:`AXIS_TOL`, they are projected on their mean normal, with a warning quoting the largest angle.

With ``assemble`` (``--assemble``), loops left open in the configuration read are closed first by
Newton, the input joint held (:func:`_assemble`; :func:`import_assembled` does it for a whole model).

The result (:class:`Extraction`) holds the standalone MJCF, with one keyframe (the state read; none
when qpos0 was read), written by editing the file's own XML as the spec was edited
(:func:`_exact_xml`: MuJoCo's writer rounds numbers to 6 digits) and checked once read back (every
body where it sat); :func:`import_loop` writes it to a file, loads that file back, and imports it (the
check runs exactly the model ``--write-submodel`` writes).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from .mjcf_import import (AXIS_TOL, ImportedModel, MjcfError, _in_plane_x, _load_model, _state, element_label,
                          import_mjcf)
from loopcheck.mujoco_model.warning_handler import compile_spec, mujoco_warnings

# Hinge axes parallel within this angle (rad) are a planar loop (the decision): projected.
PLANAR_TOL = 1e-6
# A rebased body must sit where it sat, within this fraction of the model's size.
REBASE_RTOL = 1e-9
CHECK_SCOPE = "the loop's accuracy under the model's own settings, with the rest of the robot held still"

_OBJ = mujoco.mjtObj
_FREE, _BALL, _HINGE, _SLIDE = (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL),
                                int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_CONNECT, _WELD, _EQ_JOINT = int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD), int(mujoco.mjtEq.mjEQ_JOINT)


@dataclass(frozen=True)
class Extraction:
    """A loop cut out of a model: the standalone MJCF and what became of each element.

    source : the model the loop was cut from. loops : the closures kept (as messages name them).
    key : the extracted model's keyframe (the state read); None when qpos0 was read (the extracted
    model's own qpos0 is then that state). xml : the extracted MJCF.
    moving : the loop's moving bodies; mass : (body, the moving body it is welded to) for each
    descendant kept as mass; ground : the bodies that became ground.
    welded : each welded joint and its value(s) at the configuration read.
    dropped : each element dropped, and why. kept_across : elements kept across the boundary, and how.
    normal, x_axis : the loop's plane in the world (its normal; ground's 2-D x axis).
    largest_angle : the largest angle between two of the loop's hinge axes (rad), before projection.
    warnings : lines for stderr. said : lines for stdout (the model's only keyframe, read without --keyframe).
    """

    source: Path
    loops: tuple[str, ...]
    key: str | None
    xml: str
    moving: tuple[str, ...]
    mass: tuple[tuple[str, str], ...]
    ground: tuple[str, ...]
    welded: tuple[str, ...]
    dropped: tuple[str, ...]
    kept_across: tuple[str, ...]
    normal: tuple[float, float, float]
    x_axis: tuple[float, float, float]
    largest_angle: float
    warnings: tuple[str, ...]
    said: tuple[str, ...] = ()
    assembly: Assembly | None = None

    def __post_init__(self):
        if not self.loops or not self.moving:
            raise ValueError("an extraction keeps at least one loop and one moving body")
        for v in (*self.normal, *self.x_axis, self.largest_angle):
            if not math.isfinite(v):
                raise ValueError("an extraction's plane must be finite")

    def lines(self) -> tuple[str, ...]:
        """What ``check`` and ``run`` print about the extraction (one line each)."""
        vec = lambda v: "(" + ", ".join(f"{x:.6g}" for x in v) + ")"  # noqa: E731
        return (f"loop: {', '.join(self.loops)} out of {self.source.name}: {CHECK_SCOPE}",
                f"plane: normal {vec(self.normal)}, x axis {vec(self.x_axis)} in the world; hinge axes parallel "
                f"within {self.largest_angle:.3g} rad",
                f"moving bodies: {', '.join(self.moving)}",
                "welded as mass: " + (", ".join(f"{b} to {p}" for b, p in self.mass) or "none"),
                "ground: " + (", ".join(self.ground) or "none"),
                "welded at the configuration read: " + ("; ".join(self.welded) or "none"),
                "dropped: " + ("; ".join(self.dropped) or "none"),
                *(["kept across the boundary: " + "; ".join(self.kept_across)] if self.kept_across else []),
                *([self.assembly.line()] if self.assembly else []))

    def as_dict(self) -> dict:
        """report.json's ``extraction``."""
        return {"source": str(self.source), "loops": list(self.loops), "check": CHECK_SCOPE, "keyframe": self.key,
                "moving_bodies": list(self.moving), "mass": [{"body": b, "welded_to": p} for b, p in self.mass],
                "ground": list(self.ground), "welded": list(self.welded), "dropped": list(self.dropped),
                "kept_across": list(self.kept_across),
                "plane": {"normal": list(self.normal), "x_axis": list(self.x_axis),
                          "largest_axis_angle": self.largest_angle},
                "assembly": self.assembly.as_dict() if self.assembly else None}


def _body(m: mujoco.MjModel, b: int) -> str:
    return "world" if b == 0 else (mujoco.mj_id2name(m, _OBJ.mjOBJ_BODY, b) or element_label(m, _OBJ.mjOBJ_BODY, b))


def _ancestors(m: mujoco.MjModel, b: int) -> list[int]:
    out = [b]
    while b != 0:
        b = int(m.body_parentid[b])
        out.append(b)
    return out


def _path(m: mujoco.MjModel, b1: int, b2: int) -> tuple[set[int], int]:
    """The bodies on the tree path between ``b1`` and ``b2`` without their common ancestor, and that ancestor."""
    a1, a2 = _ancestors(m, b1), _ancestors(m, b2)
    top = next(b for b in a1 if b in set(a2))
    return set(a1[:a1.index(top)]) | set(a2[:a2.index(top)]), top


@dataclass
class _Closure:
    index: int
    label: str
    name: str | None
    bodies: set  # the path's bodies (moving)
    top: int
    kind: int = _CONNECT
    ends: tuple = ()  # a coupling's two joints' bodies


def _closures(m: mujoco.MjModel) -> list[_Closure]:
    """The active connects and joint couplings (with a joint2): what closes a loop."""
    out = []
    for e in range(m.neq):
        kind = int(m.eq_type[e])
        if not m.eq_active0[e] or kind not in (_CONNECT, _EQ_JOINT):
            continue
        if kind == _EQ_JOINT:
            if int(m.eq_obj2id[e]) < 0:
                continue
            ends = [int(m.jnt_bodyid[int(m.eq_obj1id[e])]), int(m.jnt_bodyid[int(m.eq_obj2id[e])])]
        elif int(m.eq_objtype[e]) == int(_OBJ.mjOBJ_SITE):
            ends = [int(m.site_bodyid[int(m.eq_obj1id[e])]), int(m.site_bodyid[int(m.eq_obj2id[e])])]
        else:
            ends = [int(m.eq_obj1id[e]), int(m.eq_obj2id[e])]
        bodies, top = _path(m, *ends)
        if kind == _EQ_JOINT:  # a coupling's joints move their own bodies even on one branch
            bodies |= {b for b in ends if b != 0}
        out.append(_Closure(e, element_label(m, _OBJ.mjOBJ_EQUALITY, e),
                            mujoco.mj_id2name(m, _OBJ.mjOBJ_EQUALITY, e) or None, bodies, top, kind, tuple(ends)))
    return out


def _components(closures: list[_Closure]) -> list[list[_Closure]]:
    """The loops: closures (connects and joint couplings alike) grouped when their moving bodies
    overlap, transitively (one mechanism). A coupling's moving bodies hold its two joints, so a
    coupling joins every loop one of its joints moves (the coupled fingers of a hand, a geared
    flywheel), and a coupled joint is never welded."""
    groups: list[list[_Closure]] = []
    for c in closures:
        joined = [g for g in groups if any(c.bodies & o.bodies for o in g)]
        merged = [c] + [o for g in joined for o in g]
        groups = [g for g in groups if not any(g is j for j in joined)] + [sorted(merged, key=lambda o: o.index)]
    return sorted(groups, key=lambda g: g[0].index)


def _loop_text(group: list[_Closure]) -> str:
    return " + ".join(c.label for c in group)


def _select(path: Path, m: mujoco.MjModel, names: list[str]) -> list[list[_Closure]]:
    loops = _components(_closures(m))
    listed = "; ".join(_loop_text(g) for g in loops) or "none"
    chosen: list[list[_Closure]] = []
    for name in names:
        said = name.replace("-", "–")  # an unnamed connect's ends typed with a hyphen
        by_closure = [g for g in loops for c in g
                      if name == c.name or said in (c.label.replace("-", "–"),
                                                    c.label.replace("-", "–").split(" ", 1)[-1])]
        if not by_closure:
            b = mujoco.mj_name2id(m, _OBJ.mjOBJ_BODY, name)
            by_closure = [g for g in loops if b >= 0 and any(b in c.bodies or b == c.top for c in g)]
            if len(by_closure) > 1:
                raise MjcfError(f"{path}: --loop {name}: body '{name}' belongs to {len(by_closure)} loops ("
                                + "; ".join(_loop_text(g) for g in by_closure) + "): name the loop's connect")
        if not by_closure:
            raise MjcfError(f"{path}: --loop {name}: no connect, joint coupling or loop body of that name closes a "
                            f"loop (the model's loops: {listed})")
        for g in by_closure:
            if g not in chosen:
                chosen.append(g)
    return chosen


def _qpos_text(m: mujoco.MjModel, j: int, qpos: np.ndarray) -> str:
    a, kind = int(m.jnt_qposadr[j]), int(m.jnt_type[j])
    n = {_FREE: 7, _BALL: 4}.get(kind, 1)
    values = " ".join(f"{v:.6g}" for v in qpos[a:a + n])
    unit = {_HINGE: " rad", _SLIDE: " m"}.get(kind, " (pos, quat)" if kind == _FREE else " (quat)")
    return f"{element_label(m, _OBJ.mjOBJ_JOINT, j)} at {values}{unit}"


# --assemble: Newton may move a joint by at most this much (the decision), qpos units.
MAX_TURN = 0.1  # rad
MAX_SLIDE = 0.01  # m
NEWTON_ITERATIONS = 50


@dataclass(frozen=True)
class Assembly:
    """The loops closed by Newton from the configuration read (``--assemble``).

    input : the joint held at its value read (as messages name it) and that value (qpos units).
    moves : (joint, how far Newton moved it in qpos units, "rad" or "m") for each joint it moved.
    open_before, open_after : the loops' largest residual (m, or the coupling's units) before and after.
    """

    input: str
    input_value: float
    moves: tuple[tuple[str, float, str], ...]
    open_before: float
    open_after: float

    def __post_init__(self):
        if not all(math.isfinite(v) for v in (self.input_value, self.open_before, self.open_after,
                                               *(m for _, m, _ in self.moves))):
            raise ValueError("an assembly's figures must be finite")

    def line(self) -> str:
        moved = ", ".join(f"{name} by {move:+.3g} {unit}" for name, move, unit in self.moves) or "nothing"
        return (f"assembled (--assemble): loops open by {self.open_before:.3g} at the configuration read, closed to "
                f"{self.open_after:.3g} by Newton with {self.input} held at {self.input_value:.6g}; it moved {moved}")

    def as_dict(self) -> dict:
        return {"input": self.input, "input_qpos": self.input_value, "open_before": self.open_before,
                "open_after": self.open_after,
                "moves": [{"joint": n, "move": v, "unit": u} for n, v, u in self.moves]}


def _assemble(path: Path, m: mujoco.MjModel, qpos: np.ndarray, eqs: set[int], joints: list[int],
              input_joint: int) -> tuple[np.ndarray, Assembly]:
    """Close the equalities ``eqs`` by (least-squares) Newton on the hinges and slides ``joints``
    but ``input_joint`` (held at its value read), from ``qpos``; refuse a move above MAX_TURN or
    MAX_SLIDE, or no convergence."""
    mc = copy.deepcopy(m)
    mc.opt.jacobian = int(mujoco.mjtJacobian.mjJAC_DENSE)
    d = mujoco.MjData(mc)
    q = qpos.copy()
    free = [j for j in joints if j != input_joint and int(m.jnt_type[j]) in (_HINGE, _SLIDE)]
    dofs = [int(m.jnt_dofadr[j]) for j in free]
    adrs = [int(m.jnt_qposadr[j]) for j in free]

    def residual():
        d.qpos[:] = q
        with mujoco_warnings():
            mujoco.mj_fwdPosition(mc, d)
        rows = [i for i in range(d.nefc) if int(d.efc_type[i]) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
                and int(d.efc_id[i]) in eqs]
        return d.efc_pos[rows].copy(), d.efc_J.reshape(d.nefc, mc.nv)[rows][:, dofs] if rows else np.zeros((0, len(dofs)))

    def gap() -> float:  # the largest closure's gap: a connect's distance, a coupling's residual
        ids = [int(d.efc_id[i]) for i in range(d.nefc) if int(d.efc_type[i]) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
               and int(d.efc_id[i]) in eqs]
        return max((float(np.linalg.norm(r[[k for k, x in enumerate(ids) if x == e]])) for e in set(ids)), default=0.0)

    r, J = residual()
    before = gap()
    scale = max(float(np.ptp(d.xpos, axis=0).max()), 1e-9)
    for _ in range(NEWTON_ITERATIONS):  # to round-off: until a step no longer shrinks the gap
        if not r.size or not dofs or float(np.abs(r).max()) <= 1e-15 * scale:
            break
        trial = q.copy()
        q[adrs] += np.linalg.lstsq(J, -r, rcond=None)[0]
        r_new, J_new = residual()
        if float(np.abs(r_new).max()) >= float(np.abs(r).max()):
            q = trial
            r, J = residual()
            break
        r, J = r_new, J_new
    after = gap()
    if after > 1e-10 * scale:
        raise MjcfError(f"{path}: --assemble: Newton did not close the loops from the configuration read (still open "
                        f"by {after:.3g} after {NEWTON_ITERATIONS} iterations)")
    moves = []
    for j, a in zip(free, adrs):
        move = float(q[a] - qpos[a])
        unit, limit = ("rad", MAX_TURN) if int(m.jnt_type[j]) == _HINGE else ("m", MAX_SLIDE)
        if abs(move) > limit:
            raise MjcfError(f"{path}: --assemble: closing the loops moves {element_label(m, _OBJ.mjOBJ_JOINT, j)} by "
                            f"{move:.3g} {unit}, more than {limit:g} {unit}: the configuration read is too far from "
                            "closed; author a keyframe that closes them")
        if abs(move) > 1e-12:  # a move of round-off is no move
            moves.append((element_label(m, _OBJ.mjOBJ_JOINT, j), move, unit))
    return q, Assembly(element_label(m, _OBJ.mjOBJ_JOINT, input_joint), float(qpos[int(m.jnt_qposadr[input_joint])]),
                       tuple(moves), before, after)


def _input_of(path: Path, m: mujoco.MjModel, joints: list[int], name: str | None) -> int:
    """The joint --assemble holds: ``--input``'s, else the first joint an actuator drives, else the first hinge."""
    if name is not None:
        j = mujoco.mj_name2id(m, _OBJ.mjOBJ_JOINT, name)
        if j not in joints:
            raise MjcfError(f"{path}: --input {name}: no joint of that name is among the loop's joints")
        return j
    for a in range(m.nu):
        if int(m.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT) and int(m.actuator_trnid[a, 0]) in joints:
            return int(m.actuator_trnid[a, 0])
    return min(joints)


def _rate_text(m: mujoco.MjModel, j: int, qvel: np.ndarray) -> str:
    """A welded joint's rate in the state read, when not zero: held still, it is dropped (said so)."""
    a = int(m.jnt_dofadr[j])
    rates = qvel[a:a + {_FREE: 6, _BALL: 3}.get(int(m.jnt_type[j]), 1)]
    return f" (its rate {' '.join(f'{v:.3g}' for v in rates)} dropped: held still)" if np.any(rates != 0.0) else ""


def extract_loop(path: str | Path, loops: list[str], *, keyframe: str | None = None,
                 qpos0: bool = False, assemble: bool = False, input_joint: str | None = None) -> Extraction:
    """The loop(s) named, cut out of the model at ``path`` as a standalone model (module docstring).

    Raises
    ------
    MjcfError
        One line naming the file and the reason: a name that closes no loop, a body in several
        loops, a spatial loop, a connect or weld that locks the loop to the held robot.
    """
    path = Path(path)
    model, loading = _load_model(path)
    qpos, qvel, ctrl, key_label, said_key = _state(path, model, keyframe, qpos0)
    with mujoco_warnings() as said:
        spec = mujoco.MjSpec.from_file(str(path))
        m = compile_spec(spec)
    warnings = list(dict.fromkeys([*loading, *said.lines]))
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    chosen = _select(path, m, loops)
    closures = [c for g in chosen for c in g]
    kept_eq = {c.index for c in closures}
    moving = set().union(*(c.bodies for c in closures))
    # mass: the moving bodies' descendants; the world's own body is never moving
    mass: dict[int, int] = {}
    for b in range(1, m.nbody):
        if b in moving:
            continue
        for a in _ancestors(m, b)[1:]:
            if a in moving:
                mass[b] = a
                break
    mover = moving | set(mass)
    kept_joints = {j for j in range(m.njnt) if int(m.jnt_bodyid[j]) in moving}
    for j in sorted(kept_joints):
        if int(m.jnt_type[j]) in (_FREE, _BALL):
            raise MjcfError(f"{path}: --loop {', '.join(loops)}: the loop is spatial: its "
                            f"{element_label(m, _OBJ.mjOBJ_JOINT, j)} is a "
                            f"{'free' if int(m.jnt_type[j]) == _FREE else 'ball'} "
                            "joint")
    label = lambda kind, i: element_label(m, kind, i)  # noqa: E731
    assembly = None
    if assemble:
        joints = sorted(kept_joints)
        qpos, assembly = _assemble(path, m, qpos, {c.index for c in closures}, joints,
                                   _input_of(path, m, joints, input_joint))
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)

    # the plane: the loop's hinge axes, parallel within PLANAR_TOL
    hinges = sorted(j for j in kept_joints if int(m.jnt_type[j]) == _HINGE)
    if not hinges:
        raise MjcfError(f"{path}: --loop {', '.join(loops)}: the loop has no hinge")
    axes = [d.xaxis[j] / np.linalg.norm(d.xaxis[j]) for j in hinges]
    first = axes[0]
    signed = [a if a @ first >= 0 else -a for a in axes]
    largest, pair = 0.0, (hinges[0], hinges[0])
    for i, a in enumerate(signed):
        for k, b in enumerate(signed[:i]):
            angle = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
            if angle > largest:
                largest, pair = angle, (hinges[k], hinges[i])
    if largest > PLANAR_TOL:
        raise MjcfError(f"{path}: --loop {', '.join(loops)}: the loop is spatial: {label(_OBJ.mjOBJ_JOINT, pair[1])}'s "
                        f"axis is at {largest:.3g} rad to {label(_OBJ.mjOBJ_JOINT, pair[0])}'s (a planar loop's hinge "
                        f"axes are parallel within {PLANAR_TOL:g} rad)")
    normal = np.sum(signed, axis=0)
    normal /= np.linalg.norm(normal)
    for j in sorted(kept_joints):
        if int(m.jnt_type[j]) == _SLIDE:
            axis = d.xaxis[j] / np.linalg.norm(d.xaxis[j])
            off = abs(math.asin(min(1.0, abs(float(axis @ normal)))))
            if off > PLANAR_TOL:
                raise MjcfError(f"{path}: --loop {', '.join(loops)}: the loop is spatial: {label(_OBJ.mjOBJ_JOINT, j)}'s "
                                f"slide axis leaves the plane by {off:.3g} rad (more than {PLANAR_TOL:g} rad)")
            largest = max(largest, off)
    project = largest > AXIS_TOL
    if project:
        warnings.append(f"the loop's axes are parallel within {largest:.3g} rad (at most {PLANAR_TOL:g}): projected on "
                        f"the loop's plane")

    # elements across the boundary
    dropped: list[str] = []
    across: list[str] = []
    drop_eq, drop_act, drop_ten, drop_pair = [], [], [], []
    for e in range(m.neq):
        if e in kept_eq:
            continue
        kind = int(m.eq_type[e])
        what = label(_OBJ.mjOBJ_EQUALITY, e)
        if kind in (_EQ_JOINT,):
            js = [int(m.eq_obj1id[e])] + ([int(m.eq_obj2id[e])] if int(m.eq_obj2id[e]) >= 0 else [])
            inside = [j for j in js if j in kept_joints]
            if inside and len(inside) == len(js):  # within the loop: it acts there
                continue
            # an active coupling of two joints closes a loop (_closures) and joins the loop of either
            # joint (_components): one that reaches a welded joint here is inactive at the start
        elif kind in (_CONNECT, _WELD):
            if int(m.eq_objtype[e]) == int(_OBJ.mjOBJ_SITE):
                bs = [int(m.site_bodyid[int(m.eq_obj1id[e])]), int(m.site_bodyid[int(m.eq_obj2id[e])])]
            else:
                bs = [int(m.eq_obj1id[e]), int(m.eq_obj2id[e])]
            if any(b in mover for b in bs) and m.eq_active0[e]:
                raise MjcfError(f"{path}: --loop {', '.join(loops)}: {what} joins the loop's "
                                f"{_body(m, next(b for b in bs if b in mover))} to the held rest of the robot: it locks "
                                "the loop (name it with --loop when it closes the same loop)")
        drop_eq.append(e)
        dropped.append(f"{what} (acts outside the loop)")
    for t in range(m.ntendon):
        adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
        types = [int(m.wrap_type[adr + i]) for i in range(num)]
        objs = [int(m.wrap_objid[adr + i]) for i in range(num)]
        what = label(_OBJ.mjOBJ_TENDON, t)
        if types and all(k == int(mujoco.mjtWrap.mjWRAP_JOINT) for k in types):
            inside = [j for j in objs if j in kept_joints]
            if inside and len(inside) < len(objs):
                raise MjcfError(f"{path}: --loop {', '.join(loops)}: {what} runs along the loop's "
                                f"{label(_OBJ.mjOBJ_JOINT, inside[0])} and welded "
                                f"{label(_OBJ.mjOBJ_JOINT, next(j for j in objs if j not in kept_joints))}: "
                                "a fixed tendon across the boundary cannot be kept")
            if not inside:
                drop_ten.append(t)
                dropped.append(f"{what} (along welded joints)")
            continue
        sites = [o for k, o in zip(types, objs) if k == int(mujoco.mjtWrap.mjWRAP_SITE)]
        on = [int(m.site_bodyid[s]) in mover for s in sites]
        if any(on) and not all(on):
            across.append(f"{what} (its sites off the loop are ground)")
        elif not any(on):
            drop_ten.append(t)
            dropped.append(f"{what} (between welded bodies)")
    for a in range(m.nu):
        trn, target = int(m.actuator_trntype[a]), int(m.actuator_trnid[a, 0])
        if trn in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            keep = target in kept_joints
            why = f"on welded {label(_OBJ.mjOBJ_JOINT, target)}"
        elif trn == int(mujoco.mjtTrn.mjTRN_TENDON):
            keep = target not in drop_ten
            why = f"on dropped {label(_OBJ.mjOBJ_TENDON, target)}"
        elif trn == int(mujoco.mjtTrn.mjTRN_BODY):
            keep, why = target in mover, f"on welded body {_body(m, target)}"
        else:  # site and slider-crank transmissions: on the site's body
            keep, why = int(m.site_bodyid[target]) in mover, "on a welded body's site"
        if not keep:
            drop_act.append(a)
            dropped.append(f"{label(_OBJ.mjOBJ_ACTUATOR, a)} ({why})")
    for p in range(m.npair):
        bodies = [int(m.geom_bodyid[int(m.pair_geom1[p])]), int(m.geom_bodyid[int(m.pair_geom2[p])])]
        if not any(b in mover for b in bodies):
            drop_pair.append(p)
            dropped.append(f"{label(_OBJ.mjOBJ_PAIR, p)} (between ground geoms)")
    # geoms on ground that can touch the loop's stay: a contact in a run fails the check
    collidable = [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) not in mover and int(m.geom_bodyid[g]) != 0
                  and (m.geom_contype[g] or m.geom_conaffinity[g])]
    if collidable:
        across.append(f"{len(collidable)} collidable geoms on ground (a contact with the loop fails the check)")

    # -- edit the spec -----------------------------------------------------------
    bind = lambda element: int(m.bind(element).id)  # noqa: E731
    spec_body = {bind(b): b for b in spec.bodies}
    spec_joint = {bind(j): j for j in spec.joints}
    welded = [_qpos_text(m, j, qpos) + _rate_text(m, j, qvel) for j in range(m.njnt) if j not in kept_joints]
    key_qpos = np.concatenate([qpos[int(m.jnt_qposadr[j]):int(m.jnt_qposadr[j]) + 1] for j in sorted(kept_joints)])
    key_qvel = np.array([qvel[int(m.jnt_dofadr[j])] for j in sorted(kept_joints)])
    key_ctrl = np.array([ctrl[a] for a in range(m.nu) if a not in drop_act])
    for body in spec.bodies:
        b = bind(body)
        if b == 0 or b in moving or m.body_jntnum[b] == 0:  # a body without joints sits as written
            continue
        parent = int(m.body_parentid[b])
        R_p = d.xmat[parent].reshape(3, 3)
        body.pos = R_p.T @ (d.xpos[b] - d.xpos[parent])
        q_inv, q = np.zeros(4), np.zeros(4)
        mujoco.mju_negQuat(q_inv, d.xquat[parent])
        mujoco.mju_mulQuat(q, q_inv, d.xquat[b])
        body.quat = q / np.linalg.norm(q)
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
    if project:
        for joint in spec.joints:
            j = bind(joint)
            if j not in kept_joints:
                continue
            R = d.xmat[int(m.jnt_bodyid[j])].reshape(3, 3)
            axis = d.xaxis[j] / np.linalg.norm(d.xaxis[j])
            if int(m.jnt_type[j]) == _HINGE:
                world = normal if axis @ normal >= 0 else -normal
            else:
                world = axis - (axis @ normal) * normal
                world /= np.linalg.norm(world)
            joint.axis = R.T @ world
    doomed = ([x for x in spec.joints if bind(x) not in kept_joints]
              + [x for x in spec.actuators if bind(x) in drop_act]
              + [x for x in spec.tendons if bind(x) in drop_ten]
              + [x for x in spec.equalities if bind(x) in drop_eq]
              + [x for x in spec.pairs if bind(x) in drop_pair])
    sensors = list(spec.sensors)
    if sensors:
        dropped.append(f"{len(sensors)} sensors (they measure, and act on nothing)")
    for key in list(spec.keys):
        spec.delete(key)
    for element in [*doomed, *sensors]:
        spec.delete(element)
    # the state read: a keyframe (named as the one read, or 'assembled'); none for qpos0, which the
    # extracted model's own qpos0 then is
    key = key_label.strip("'") if key_label is not None else "assembled" if assemble else None
    if key is not None:
        spec.add_key(name=key, qpos=key_qpos.tolist(), qvel=key_qvel.tolist(), ctrl=key_ctrl.tolist())
    with mujoco_warnings() as said:
        try:
            sub = compile_spec(spec)
        except ValueError as exc:
            raise MjcfError(f"{path}: --loop {', '.join(loops)}: the extracted model does not compile: "
                            f"{' '.join(str(exc).split())}") from None
        _check_rebased(path, m, d, sub, key_qpos)
        xml = _exact_xml(path, m, drops=dict(joint=set(range(m.njnt)) - kept_joints, actuator=set(drop_act),
                                             tendon=set(drop_ten), equality=set(drop_eq), pair=set(drop_pair)),
                         spec_body=spec_body, spec_joint=spec_joint, project=project,
                         key=(key, key_qpos, key_qvel, key_ctrl))
        try:  # the text written, read back: what the check will load
            written = compile_spec(mujoco.MjSpec.from_string(xml))
        except ValueError as exc:
            raise MjcfError(f"{path}: --loop {', '.join(loops)}: the extracted model does not load: "
                            f"{' '.join(str(exc).split())}") from None
    if (written.njnt, written.nu, written.ntendon, written.neq, written.npair) != (
            len(kept_joints), m.nu - len(drop_act), m.ntendon - len(drop_ten), m.neq - len(drop_eq),
            m.npair - len(drop_pair)):
        raise MjcfError(f"{path}: --loop {', '.join(loops)}: the extracted model written does not hold the elements "
                        "kept: the extraction cannot be trusted")
    _check_rebased(path, m, d, written, key_qpos)
    e1 = _in_plane_x(normal)
    return Extraction(
        source=path, loops=tuple(c.label for c in closures), key=key, xml=xml,
        moving=tuple(_body(m, b) for b in sorted(moving)),
        mass=tuple((_body(m, b), _body(m, mass[b])) for b in sorted(mass)),
        ground=tuple(_body(m, b) for b in range(1, m.nbody) if b not in mover),
        welded=tuple(welded), dropped=tuple(dropped), kept_across=tuple(across),
        normal=tuple(float(x) for x in normal), x_axis=tuple(float(x) for x in e1),
        largest_angle=float(largest), warnings=tuple(dict.fromkeys([*warnings, *said.lines])),
        said=(said_key,) if said_key else (), assembly=assembly)


_UNSUPPORTED = ("replicate", "attach", "model")
_ORIENTATIONS = ("quat", "euler", "axisangle", "xyaxes", "zaxis")


def _words(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _flatten_includes(root: ET.Element, folder: Path, path: Path, depth: int = 0) -> None:
    """Replace each ``<include file="..."/>`` by the children of the file's root, as MuJoCo does
    (a file named relative to the main model's folder)."""
    if depth > 20:
        raise MjcfError(f"{path}: --loop: <include> nested more than 20 deep")
    for parent in list(root.iter()):
        for k, child in reversed(list(enumerate(parent))):
            if child.tag != "include":
                continue
            try:
                included = ET.parse(folder / child.get("file", "")).getroot()
            except (ET.ParseError, OSError) as exc:
                raise MjcfError(f"{path}: --loop: cannot read <include file=\"{child.get('file')}\">: {exc}") from None
            _flatten_includes(included, folder, path, depth + 1)
            parent.remove(child)
            for i, grandchild in enumerate(list(included)):
                parent.insert(k + i, grandchild)


def _exact_xml(path: Path, m: mujoco.MjModel, *, drops: dict, spec_body: dict, spec_joint: dict, key,
               rebase: bool = True, project: bool = False) -> str:
    """The extracted model written by editing the file's own XML as the spec was edited (MuJoCo's
    writer rounds numbers to 6 digits, which would move the loop by 1e-6): its ``<include>``s
    flattened, welded joints and dropped elements removed, welded bodies' poses (the spec's, in full
    precision), projected axes, one keyframe. Refused (MjcfError) when the file has what this cannot
    follow (``<replicate>``, ``<attach>``, a welded body inside a ``<frame>``) or does not match the
    model element for element."""
    def refuse(why: str):
        raise MjcfError(f"{path}: --loop/--assemble: the extracted model cannot be written exactly: {why}")

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        refuse(f"the file does not parse as XML ({exc})")
    _flatten_includes(root, path.parent, path)
    unsupported = sorted({e.tag for e in root.iter() if e.tag in _UNSUPPORTED})
    if unsupported:
        refuse(f"it uses {', '.join(f'<{t}>' for t in unsupported)}, which the extraction does not follow")
    parents = {child: parent for parent in root.iter() for child in parent}
    bodies = [b for w in root.findall("worldbody") for b in w.iter("body")]
    joints = [j for b in bodies for j in b if j.tag in ("joint", "freejoint")]
    listed = {kind: [e for block in root.findall(section) for e in block if isinstance(e.tag, str)
                     and (kind != "pair" or e.tag == "pair")]
              for kind, section in (("actuator", "actuator"), ("tendon", "tendon"), ("equality", "equality"),
                                    ("pair", "contact"))}
    counts = {"body": (len(bodies), m.nbody - 1), "joint": (len(joints), m.njnt),
              "actuator": (len(listed["actuator"]), m.nu),
              "tendon": (len(listed["tendon"]), m.ntendon), "equality": (len(listed["equality"]), m.neq),
              "pair": (len(listed["pair"]), m.npair)}
    if any(a != b for a, b in counts.values()) or root.find("worldbody/joint") is not None:
        refuse("its elements do not match the compiled model's one for one ("
               + ", ".join(f"{k}: {a} in the file, {b} compiled" for k, (a, b) in counts.items() if a != b) + ")")
    by_id = spec_body
    for b, element in enumerate(bodies if rebase else (), start=1):
        sb = by_id[b]
        own = range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
        if not m.body_jntnum[b] or all(j not in drops["joint"] for j in own):  # as written
            continue
        if parents[element].tag == "frame":
            refuse(f"{_body(m, b)}, welded, sits inside a <frame>")  # a moving body of the loop: as written
        for attr in _ORIENTATIONS:
            element.attrib.pop(attr, None)
        element.set("pos", _words(sb.pos))
        element.set("quat", _words(sb.quat))
    by_joint = spec_joint
    for j, element in enumerate(joints):
        if j in drops["joint"]:
            parents[element].remove(element)
        elif project and j in by_joint and element.tag == "joint":
            element.set("axis", _words(by_joint[j].axis))
    for kind in ("actuator", "tendon", "equality", "pair"):
        for i, element in enumerate(listed[kind]):
            if i in drops[kind]:
                parents[element].remove(element)
    for section in ("sensor", "keyframe") if rebase else ("keyframe",):
        for block in root.findall(section):
            root.remove(block)
    name, qpos, qvel, ctrl = key
    if name is None:  # read at qpos0: the model's own qpos0
        ET.indent(root)
        return ET.tostring(root, encoding="unicode") + "\n"
    frame = ET.SubElement(root, "keyframe")
    entry = ET.SubElement(frame, "key", name=name, qpos=_words(qpos))
    if len(qvel):
        entry.set("qvel", _words(qvel))
    if len(ctrl):
        entry.set("ctrl", _words(ctrl))
    if m.nmesh or m.nhfield or m.ntex:  # the written file may sit elsewhere: assets by absolute path
        compiler = root.find("compiler")
        if compiler is None:
            compiler = ET.Element("compiler")
            root.insert(0, compiler)
        for attr in ("meshdir", "texturedir"):
            compiler.set(attr, str((path.parent / compiler.get(attr, compiler.get("assetdir", "."))).resolve()))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _check_rebased(path: Path, m: mujoco.MjModel, d: mujoco.MjData, sub: mujoco.MjModel, key_qpos: np.ndarray) -> None:
    """Every body of the extracted model sits where it sat in the model at the configuration read."""
    ds = mujoco.MjData(sub)
    ds.qpos[:] = key_qpos
    mujoco.mj_kinematics(sub, ds)
    scale = max(float(np.ptp(d.xpos, axis=0).max()), 1e-9)
    gap = float(np.abs(ds.xpos - d.xpos).max())
    turn = float(np.abs(ds.xmat - d.xmat).max())
    if sub.nbody != m.nbody or gap > REBASE_RTOL * scale or turn > REBASE_RTOL:
        raise MjcfError(f"{path}: the extracted model's bodies do not sit where the model's sat at the configuration "
                        f"read (off by {gap:.3g} m, {turn:.3g} in orientation): the extraction cannot be trusted")


def import_loop(path: str | Path, loops: list[str], *, write_to: str | Path | None = None,
                keyframe: str | None = None, qpos0: bool = False, assemble: bool = False,
                **kwargs) -> tuple[ImportedModel, Extraction]:
    """Extract the loop (:func:`extract_loop`), write it to a file, load that file back from disk and
    import it (:func:`import_mjcf`, ``kwargs`` its own); the same text to ``write_to`` once imported."""
    path = Path(path)
    ext = extract_loop(path, loops, keyframe=keyframe, qpos0=qpos0, assemble=assemble,
                       input_joint=kwargs.get("input_joint"))
    with tempfile.TemporaryDirectory(prefix="loopcheck-loop-") as tmp:
        target = Path(tmp) / f"{path.stem}.loop.xml"
        target.write_text(ext.xml)
        try:
            imported = import_mjcf(target, keyframe=ext.key, qpos0=ext.key is None, name=kwargs.pop("name", None) or path.stem, **kwargs)
        except MjcfError as exc:
            text = str(exc).replace(str(target), f"{path} (--loop {', '.join(loops)})")
            for name in (kwargs.get("controls") or {}):
                if any(d.startswith(f"actuator '{name}' ") for d in ext.dropped):
                    text += f" (--loop dropped actuator '{name}': it acts outside the loop)"
            given = kwargs.get("input_joint")
            if given is not None and any(w.startswith(f"joint '{given}' ") for w in ext.welded):
                text += f" (--loop welded joint '{given}': the input is one of the loop's joints)"
            raise MjcfError(text) from None
    if write_to is not None:  # the file the check ran, once it is read (no partial output)
        Path(write_to).write_text(ext.xml)
    imported = dataclasses.replace(imported, scene=_named_after(imported.scene, path, " ".join(f"--loop {n}" for n in loops)),
                                   extraction=ext, said=ext.said + imported.said,
                                   warnings=tuple(dict.fromkeys([*ext.warnings, *imported.warnings])))
    return imported, ext


def _named_after(scene, path: Path, flags: str):
    """The scene read from a temporary file, named after the user's model and the flags that made it
    (``leg.xml --loop foot_loop``): the temporary file is gone once read."""
    return dataclasses.replace(scene, source=f"{path} {flags}", description=f"imported from {path.name} ({flags})")


def import_assembled(path: str | Path, *, keyframe: str | None = None, qpos0: bool = False,
                     **kwargs) -> ImportedModel:
    """``--assemble`` without ``--loop``: the whole model's loops closed by Newton from the
    configuration read (:func:`_assemble`; every hinge and slide but the input moves), the model
    written again with that state as its one keyframe, loaded back from disk and imported
    (:func:`import_mjcf`, ``kwargs`` its own)."""
    path = Path(path)
    model, _ = _load_model(path)
    qpos, qvel, ctrl, key_label, said_key = _state(path, model, keyframe, qpos0)
    eqs = {c.index for c in _closures(model)}
    joints = [j for j in range(model.njnt) if int(model.jnt_type[j]) in (_HINGE, _SLIDE)]
    if not joints:
        raise MjcfError(f"{path}: --assemble: the model has no hinge or slide to move")
    qpos, assembly = _assemble(path, model, qpos, eqs, joints, _input_of(path, model, joints, kwargs.get("input_joint")))
    key = key_label.strip("'") if key_label is not None else "assembled"
    xml = _exact_xml(path, model, drops=dict(joint=set(), actuator=set(), tendon=set(), equality=set(), pair=set()),
                     spec_body={}, spec_joint={}, key=(key, qpos, qvel, ctrl), rebase=False)
    warnings: list[str] = []
    with tempfile.TemporaryDirectory(prefix="loopcheck-assembled-") as tmp:
        target = Path(tmp) / f"{path.stem}.assembled.xml"
        target.write_text(xml)
        try:
            imported = import_mjcf(target, keyframe=key, name=kwargs.pop("name", None) or path.stem, **kwargs)
        except MjcfError as exc:
            raise MjcfError(str(exc).replace(str(target), f"{path} (--assemble)")) from None
    return dataclasses.replace(imported, scene=_named_after(imported.scene, path, "--assemble"),
                               said=((said_key,) if said_key else ()) + (assembly.line(),) + imported.said,
                               warnings=tuple(dict.fromkeys([*warnings, *imported.warnings])))


__all__ = ["Assembly", "import_assembled", "CHECK_SCOPE", "Extraction", "PLANAR_TOL", "extract_loop", "import_loop"]
