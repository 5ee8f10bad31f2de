"""The coordinates of an engine that integrates the linkage's spanning tree (MuJoCo, Pinocchio).

Such an engine has one coordinate q_k per tree joint (:attr:`loopcheck.mechanism.Linkage.tree`): a
revolute joint's relative angle θ_child − θ_parent counted from the assembled pose, a prismatic
joint's displacement. Every body turns about the plane's normal, so the scene's general
coordinates x (:class:`loopcheck.kinematics.LoopSystem`: body angles in rad, slider displacements in
m) are affine in q: x = x0 + T q, ẋ = T q̇, and q = P (x − x0), with P T = I (:func:`coordinate_map`).
The engines order their joints depth-first over the body tree (:func:`depth_first`), the order
MuJoCo's compiler gives qpos and Pinocchio's algorithms need.
"""

from __future__ import annotations

import numpy as np

from . import kinematics as loops
from .mechanism import GROUND, Linkage, PrismaticJoint, TreeEdge


def depth_first(tree: tuple[TreeEdge, ...]) -> tuple[TreeEdge, ...]:
    """The tree's edges depth-first from ground, children in the order they were added."""
    children: dict[str, list[TreeEdge]] = {}
    for e in tree:
        children.setdefault(e.parent, []).append(e)
    order: list[TreeEdge] = []

    def visit(body: str) -> None:
        for e in children.get(body, ()):
            order.append(e)
            visit(e.body)
    visit(GROUND)
    return tuple(order)


def joint_order(linkage: Linkage) -> tuple[str, ...]:
    """The tree joints' names, depth-first (:func:`depth_first`)."""
    return tuple(e.joint for e in depth_first(linkage.tree))


def coordinate_map(linkage: Linkage, joint_names: tuple[str, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(T, P) for the tree joints ``joint_names`` (default :func:`joint_order`): x = x0 + T q and
    q = P (x − x0), shapes (n, nq) and (nq, n). T: a body's angle takes every revolute joint on
    its tree path, a slider's s its own joint; P: a revolute joint's θ_child − θ_parent, a
    prismatic joint's s."""
    system = loops.compile_linkage(linkage)
    names = joint_order(linkage) if joint_names is None else tuple(joint_names)
    column = {name: k for k, name in enumerate(names)}
    joints = linkage.joint_map
    up = {e.body: e for e in linkage.tree}
    T = np.zeros((system.n, len(names)))
    P = np.zeros((len(names), system.n))
    for i, body in enumerate(linkage.moving):
        b = body
        while b != GROUND:
            e = up[b]
            if not isinstance(joints[e.joint], PrismaticJoint):
                T[i, column[e.joint]] = 1.0
            b = e.parent
    for e in linkage.tree:
        k = column[e.joint]
        if isinstance(joints[e.joint], PrismaticJoint):
            T[system.coordinate(f"{e.joint}.s"), k] = 1.0
            P[k, system.coordinate(f"{e.joint}.s")] = 1.0
        else:
            P[k, linkage.moving.index(e.body)] += 1.0
            if e.parent != GROUND:
                P[k, linkage.moving.index(e.parent)] -= 1.0
    return T, P


def initial_rates(linkage: Linkage, x0: np.ndarray, qdot0: float) -> np.ndarray:
    """ẋ0 consistent with the loops at (x0, q̇0), shape (n,): K of the best-conditioned
    coordinate x_i (:func:`loopcheck.kinematics.conditioning`), scaled so that drive·ẋ = q̇0 (a start
    at a dead centre of the input, where q̇0 must be 0, is fine too)."""
    system = loops.compile_linkage(linkage)
    x0 = np.asarray(x0, dtype=float)
    if qdot0 == 0.0:
        return np.zeros(system.n)
    best = int(np.argmax(loops.conditioning(system, x0)))
    K, _ = loops.coefficients(system.driven_by(best), x0)
    return K * (qdot0 / float(system.drive @ K))


__all__ = ["coordinate_map", "depth_first", "initial_rates", "joint_order"]
