"""How a compiled model's qpos/qvel map onto the scene's general coordinates, and the rest of
what a run takes from the scene alone (:class:`Layout`, made once for all the runs of a scene's
model, whatever their timestep)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from loopcheck import kinematics as loops
from loopcheck.mechanism import PrismaticJoint
from loopcheck.scene import Scene

from .build import coordinate_map, initial_qpos_qvel


@dataclass(frozen=True)
class InputJoint:
    """One input joint in the model: its name, its dof (qvel index), whether it is a hinge (else a
    slide), its child and parent bodies (the tree edge's), and row (nq,): its coordinate's rate
    from qvel, q̇ = row·qvel."""

    name: str
    dof: int
    hinge: bool
    body: str
    parent: str
    row: np.ndarray


@dataclass(frozen=True)
class Layout:
    """How MuJoCo's qpos/qvel map to the scene's coordinates (:func:`build.coordinate_map`),
    and the rest of what a run takes from the scene alone (made once for all the runs of a
    scene's model, whatever their timestep).

    x0 (n,), T (n, nq): x = x0 + T qpos; drive (n,): q = drive·x; input_dof: the input
    joint's dof; input_hinge: whether it is a hinge (else a slide); qpos0, qvel0: the initial
    state (:func:`build.initial_qpos_qvel`); size: the mechanism's size (m,
    :func:`_mechanism_size`); inputs: every input joint (:class:`InputJoint`, in the scene's
    inputs order; the first is the one of input_dof, input_hinge, input_body, input_parent).
    """

    system: loops.LoopSystem
    x0: np.ndarray
    T: np.ndarray
    input_dof: int
    input_hinge: bool
    input_body: str
    input_parent: str
    qpos0: np.ndarray
    qvel0: np.ndarray
    size: float
    inputs: tuple[InputJoint, ...] = ()

    @staticmethod
    def of(scene: Scene, model: mujoco.MjModel) -> "Layout":
        linkage = scene.mechanism.linkage
        system = loops.compile_linkage(linkage)
        x0, T = coordinate_map(scene)
        inputs = []
        for name, row in zip(linkage.inputs, system.input_rows):
            joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            edge = next(e for e in linkage.tree if e.joint == name)
            inputs.append(InputJoint(name, int(model.jnt_dofadr[joint]),
                                     not isinstance(linkage.joint_map[name], PrismaticJoint), edge.body, edge.parent,
                                     row @ T))
        first = inputs[0]
        return Layout(system, x0, T, first.dof, first.hinge, first.body, first.parent,
                      *initial_qpos_qvel(scene), _mechanism_size(scene), tuple(inputs))

    def x(self, qpos: np.ndarray) -> np.ndarray:
        return self.x0 + np.atleast_2d(qpos) @ self.T.T

    def xdot(self, qvel: np.ndarray) -> np.ndarray:
        return np.atleast_2d(qvel) @ self.T.T

    @property
    def input_row(self) -> np.ndarray:
        """(nq,) the input coordinate's rate from qvel: q̇ = input_row·qvel."""
        return self.system.drive @ self.T


def _mechanism_size(scene: Scene) -> float:
    """The largest distance between two named points at x0 (m): the mechanism's size."""
    system = loops.compile_linkage(scene.mechanism.linkage)
    p = loops.positions(system.points, np.asarray(scene.x0, dtype=float))
    return float(np.max(np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)))
