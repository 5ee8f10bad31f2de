"""Build a ``pinocchio.Model`` of a scene's planar linkage, with one closure constraint per cut joint.

Tree. The linkage's spanning tree (:attr:`loopcheck.mechanism.Linkage.tree`, parents first) becomes
Pinocchio's joint tree, one joint per tree edge, added depth-first (:func:`depth_first`: Pinocchio's
algorithms need a joint's subtree right after it), so Pinocchio's q and v hold one entry per
tree joint in that order: a revolute tree joint is an ``RZ`` joint whose frame sits at the
joint's point, a prismatic one a ``PrismaticUnaligned`` joint along the joint's line. Each body's
joint frame is its description frame moved to its own joint point (no rotation): a named point
p of the body is at p − o in the joint frame, o the body's joint point (0 for ground, the
universe). The model is placed at the scene's assembled pose ``scene.x0``, so q = 0 is the
assembly and x = x0 + T q (:attr:`PinModel.T`): a body's angle is its x0 angle plus the RZ
angles on its tree path, a slider's s is s0 plus its joint's q.

Loops. Each cut joint (always revolute) is a ``RigidConstraintModel`` of type ``CONTACT_3D``
between its two points (the joint's two bodies; ground is the universe, joint 0), with the
settings' Baumgarte gains. Its z row is 0 = 0 (everything moves in the plane): Pinocchio's
proximal solver (``ProximalSettings``' μ > 0) handles the rank-deficient rows.

Mass properties. A body with mass: ``Inertia(m, com − o, diag(I, I, I))`` (I about the centre of
mass; the out-of-plane moments never enter: every joint turns about z or slides in the plane).
A body of mass 0 given by its inertia about a fixed pivot: mass 0 with that inertia (about any
point: a zero mass has no parallel-axis term). A joint inertia (½ I u̇² on a joint's own
coordinate u) on a tree joint is Pinocchio's ``armature`` of that joint's one dof (u is that
joint's q: I·row·rowᵀ is I on the diagonal); on a cut joint u is a sum of several q's and its
cross terms do not fit a diagonal armature: refused with one line.

Couplings. A joint coupling (MuJoCo's equality/joint, y − y_ref = p(x − x_ref) on two joints' own
coordinates) has no Pinocchio constraint model (its constraint models hold frames: contacts,
anchors, joint limits and friction; its mimic joint is linear and takes the coupled joint's dof
away): each is a :class:`CouplingRow`, one holonomic row beside the loops, which
:mod:`loopcheck.pin.run` adds to ``constraintDynamics``' solution. A joint's own coordinate is
linear in Pinocchio's q (u = u0 + c·q: a revolute's relative angle is a difference of the
bodies' angles x0 + T q, a slider's s is its q), a cut joint's too, so a coupling on a joint
that closes a loop needs no frames.

Everything else (dampers, springs, loads, point and timed forces) is applied as generalized
forces by :mod:`loopcheck.pin.run` from the point Jacobians of :meth:`PinModel.point_jacobians`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

try:
    import pinocchio as pin
except ModuleNotFoundError as exc:  # the optional extra
    raise ModuleNotFoundError("the pin engine needs Pinocchio: pip install -e '.[pin]' in loopcheck's checkout (the PyPI package pin)",
                              name="pinocchio") from exc

from loopcheck import kinematics as loops
from loopcheck.tree_coordinates import coordinate_map, depth_first
from loopcheck.mechanism import GROUND, JointCoupling, PrismaticJoint, RevoluteJoint
from loopcheck.scene import Scene

from .settings import Settings


@dataclass(frozen=True)
class CouplingRow:
    """A joint coupling y − y_ref = p(x − x_ref) (:class:`loopcheck.mechanism.JointCoupling`) over
    Pinocchio's q: each joint's own coordinate u = u0 + c·q (linear in q, a cut joint's too: a
    revolute's relative angle is a difference of the bodies' angles, each x0 + T q), so

        φ = u_y − y_ref − p(u_x − x_ref),   its Jacobian row (c_y − p'(s) c_x),
        φ̈ = (c_y − p'(s) c_x)·a − p''(s) (c_x·v)²   (s = u_x − x_ref).

    coupling : the scene's coupling; y_coef, y0 : the coupled joint's c and u0; x_coef, x0 : the
    driver's; length : m per unit of φ when the residual is read as a gap (the mechanism's size
    for a revolute coupled joint, rad; 1 for a prismatic one, m).
    """

    coupling: JointCoupling
    y_coef: np.ndarray
    y0: float
    x_coef: np.ndarray
    x0: float
    length: float

    def state(self, q: np.ndarray, v: np.ndarray) -> tuple[float, np.ndarray, float, float]:
        """(φ, the row (nq,), φ̇, γ = p''(s) (c_x·v)²) at (q, v): φ̈ = row·a − γ."""
        c = self.coupling
        p, dp, ddp = c.polynomial(self.x0 + float(self.x_coef @ q))
        phi = self.y0 + float(self.y_coef @ q) - c.y_ref - p
        row = self.y_coef - dp * self.x_coef
        rate = float(self.x_coef @ v)
        return phi, row, float(row @ v), ddp * rate * rate


@dataclass(frozen=True)
class PinModel:
    """A scene's Pinocchio model and what a run reads from it.

    model, data : Pinocchio's model and a data of it.
    constraints, constraint_datas : one CONTACT_3D ``RigidConstraintModel`` per cut joint
        (Pinocchio's std vectors), and their datas.
    system : the scene's loop kinematics (:func:`loopcheck.kinematics.compile_linkage`).
    joint_names : the tree joints in Pinocchio's q order (:func:`depth_first`).
    x0 (n,), T (n, nq) : x = x0 + T q, ẋ = T v (general coordinates of :class:`LoopSystem`).
    P (nq, n) : q = P (x − x0), v = P ẋ (a revolute joint's relative angle, a slider's s); P T = I.
    frames : frame id of each (body, point) the run needs, by (body, point).
    input_row (nq,) : the input coordinate's rate from v: q̇_in = input_row · v (the first input's).
    input_rows (k, nq) : every input's rate from v, in the scene's inputs order (the first is
        ``input_row``): q̇ = input_rows · v.
    joint_coef : for each joint of a joint element, (coef (nq,), u0): its own coordinate
        u = u0 + coef · q (relative angle rad, or displacement m).
    size : the mechanism's size (m), the largest distance between two named points at x0.
    couplings : one :class:`CouplingRow` per joint coupling of the linkage, in its order.
    compensation, compensation_data : where a body has ``gravcomp`` under gravity, a copy of the
        model whose bodies weigh gravcomp × their mass at the same centre of mass (no rotational
        inertia: only its gravity is read), and a data of it; else None. Pinocchio's gravity is one
        for the model: the compensating force is that copy's generalized gravity, added to τ, and its
        potential is taken off the model's (MuJoCo's passive gravcomp force, g·gravcomp·m at the
        centre of mass against gravity).
    """

    model: object
    data: object
    constraints: object
    constraint_datas: object
    system: loops.LoopSystem
    joint_names: tuple[str, ...]
    x0: np.ndarray
    T: np.ndarray
    P: np.ndarray
    frames: dict
    input_row: np.ndarray
    joint_coef: dict
    size: float
    compensation: object = None
    compensation_data: object = None
    input_rows: np.ndarray | None = None
    couplings: tuple[CouplingRow, ...] = ()

    def point_jacobians(self, frames: list[int]) -> list[np.ndarray]:
        """The (2, nv) in-plane translational Jacobians of the frames, in the world's axes, at
        the configuration of the last :func:`pinocchio.computeJointJacobians` (and frame update)."""
        return [pin.getFrameJacobian(self.model, self.data, f, pin.LOCAL_WORLD_ALIGNED)[:2] for f in frames]

    def x(self, q: np.ndarray) -> np.ndarray:
        """General coordinates from Pinocchio's q (rows of samples allowed)."""
        return self.x0 + np.atleast_2d(q) @ self.T.T

    def xdot(self, v: np.ndarray) -> np.ndarray:
        return np.atleast_2d(v) @ self.T.T


def _se3(angle: float, xy) -> "pin.SE3":
    c, s = math.cos(angle), math.sin(angle)
    return pin.SE3(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([xy[0], xy[1], 0.0]))


def build(scene: Scene, settings: Settings) -> PinModel:
    """The scene's :class:`PinModel` (the module's docstring says how).

    Raises
    ------
    ValueError
        A joint inertia on a cut joint, or a joint friction (one line naming it).
    """
    mech = scene.mechanism
    linkage = mech.linkage
    bodies, joints = linkage.body_map, linkage.joint_map
    system = loops.compile_linkage(linkage)
    x0 = np.asarray(scene.x0, dtype=float)
    angle = {GROUND: 0.0, **{b: float(x0[i]) for i, b in enumerate(linkage.moving)}}
    if mech.joint_frictions:
        raise ValueError(f"joint friction {mech.joint_frictions[0].name!r}: the Pinocchio engine has no dry "
                         "(Coulomb) friction with stick and slip; leave the pin engine out")
    for e in mech.joint_inertias:
        if e.joint in linkage.cut_joints:
            raise ValueError(f"joint inertia {e.name!r} is on joint {e.joint!r}, which closes a loop in the "
                             "Pinocchio model: its ½ I u̇² couples several joints' rates and Pinocchio's armature "
                             "is diagonal; move the inertia to a joint of the tree or leave the pin engine out")

    compensated = {}  # Pinocchio joint id: (gravcomp × mass kg, centre of mass in the joint frame m)
    model = pin.Model()
    model.name = scene.name
    model.gravity = pin.Motion(np.array([*(scene.gravity or (0.0, 0.0)), 0.0]), np.zeros(3))
    joint_id = {GROUND: 0}
    origin = {GROUND: (0.0, 0.0)}  # each body's joint-frame origin in its own frame (its joint point)
    names = []
    for edge in depth_first(linkage.tree):
        jt = joints[edge.joint]
        child_is_b = jt.body_b == edge.body
        own = jt.point_b if child_is_b else jt.point_a
        other = jt.point_a if child_is_b else jt.point_b
        px, py = bodies[edge.parent].points[other]
        ox, oy = origin[edge.parent]
        cx, cy = bodies[edge.body].points[own]
        if isinstance(jt, PrismaticJoint):
            s0 = float(x0[system.coordinate(f"{jt.name}.s")])
            sign = 1.0 if child_is_b else -1.0
            ex, ey = math.cos(jt.direction_a), math.sin(jt.direction_a)
            placement = _se3(0.0, (px + sign * s0 * ex - ox, py + sign * s0 * ey - oy))
            joint_model = pin.JointModelPrismaticUnaligned(np.array([sign * ex, sign * ey, 0.0]))
        else:
            placement = _se3(angle[edge.body] - angle[edge.parent], (px - ox, py - oy))
            joint_model = pin.JointModelRZ()
        jid = model.addJoint(joint_id[edge.parent], joint_model, placement, jt.name)
        body = bodies[edge.body]
        inertia = np.diag([body.inertia] * 3)
        lever = np.array([body.com[0] - cx, body.com[1] - cy, 0.0])
        model.appendBodyToJoint(jid, pin.Inertia(body.mass, lever, inertia), pin.SE3.Identity())
        if body.gravcomp and scene.gravity is not None:
            compensated[jid] = (body.gravcomp * body.mass, lever)
        joint_id[edge.body], origin[edge.body] = jid, (cx, cy)
        names.append(jt.name)
    names = tuple(names)
    if tuple(model.names[1:]) != names or model.nq != len(names) or model.nv != len(names):
        raise ValueError(f"Pinocchio's joints {tuple(model.names[1:])} are not the tree joints {names} in order")

    frames = {}

    def frame(body: str, point: str) -> int:
        if (body, point) not in frames:
            px, py = bodies[body].points[point]
            ox, oy = origin[body]
            frames[(body, point)] = model.addFrame(pin.Frame(f"{body}.{point}", joint_id[body],
                                                             _se3(0.0, (px - ox, py - oy)), pin.FrameType.OP_FRAME))
        return frames[(body, point)]

    for e in mech.elements:
        frame(e.body_a, e.point_a), frame(e.body_b, e.point_b)
    for f in mech.point_forces + mech.timed_forces:
        frame(f.body, f.point)
    constraint_models = pin.StdVec_RigidConstraintModel()
    for name in linkage.cut_joints:
        jt = joints[name]
        frame(jt.body_a, jt.point_a), frame(jt.body_b, jt.point_b)
        ends = [(jt.body_a, jt.point_a), (jt.body_b, jt.point_b)]
        if joint_id[jt.body_a] == 0:  # the universe goes second (Pinocchio's convention for a contact with it)
            ends.reverse()
        placements = []
        for body, point in ends:
            px, py = bodies[body].points[point]
            ox, oy = origin[body]
            placements += [joint_id[body], _se3(0.0, (px - ox, py - oy))]
        cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, *placements, pin.ReferenceFrame.LOCAL)
        cm.name = name
        cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(settings.baumgarte_kp,
                                                                            settings.kd))
        constraint_models.append(cm)

    T, P = coordinate_map(linkage, tuple(names))
    column = {n: k for k, n in enumerate(names)}
    for e in mech.joint_inertias:
        model.armature[column[e.joint]] += e.coefficient
    joint_coef = {}
    for joint in dict.fromkeys([e.joint for e in mech.joint_elements]
                               + [j for a in mech.actuators for j, _ in a.terms]  # actuators' joints too
                               + [j for c in linkage.couplings for j in (c.joint, c.driver)]):  # couplings' too
        row = system.joint_row(joint)
        joint_coef[joint] = (row @ T, float(row @ x0))
    data = model.createData()
    constraint_datas = pin.StdVec_RigidConstraintData()
    for cm in constraint_models:
        constraint_datas.append(cm.createData())
    pin.initConstraintDynamics(model, data, constraint_models, constraint_datas)
    p = loops.positions(system.points, x0)
    size = float(np.max(np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)))
    compensation = None
    if compensated:
        compensation = pin.Model(model)
        for jid in range(1, compensation.njoints):
            mass, lever = compensated.get(jid, (0.0, np.zeros(3)))
            compensation.inertias[jid] = pin.Inertia(mass, lever, np.zeros((3, 3)))
    couplings = tuple(CouplingRow(c, *joint_coef[c.joint], *joint_coef[c.driver],
                                  size if isinstance(joints[c.joint], RevoluteJoint) else 1.0)
                      for c in linkage.couplings)
    return PinModel(model, data, constraint_models, constraint_datas, system, names, x0, T, P, frames,
                    system.drive @ T, joint_coef, size, compensation,
                    None if compensation is None else compensation.createData(), system.input_rows @ T, couplings)
