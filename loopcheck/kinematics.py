"""Loop kinematics of a general planar one-DOF linkage, on plain arrays.

Coordinates x (shape (n,)): the absolute angle (rad) of each moving body's frame, in the
order of :attr:`Linkage.moving`, then the displacement s (m) of each prismatic joint, in
the order the joints are declared.

Every point, and every loop-closure vector, is a row of a :class:`TermTable`,

    r(x) = offset + Σ_t m_t e(θ_t),   m_t = coef_t · (x[mag_t] if mag_t ≥ 0 else 1),
                                       θ_t = (x[angle_t] if angle_t ≥ 0 else 0) + phase_t,

built from the spanning tree (the path from ground to the body): a revolute tree joint adds
the rotating vector of the child's point, a prismatic one adds s e(θ + direction), a term
whose magnitude is a coordinate. The constraints Φ(x) = 0 are (m = n − 1 rows, or more for a
redundantly closed loop, whose kernel then runs on an orthonormal basis of Φ_x's rows: m > n − 1,
:attr:`LoopSystem.redundant`):

- two rows per cut joint: its two points, reached along the tree, coincide. Cut joints are
  always revolute: :class:`~loopcheck.mechanism.Linkage` takes prismatic joints into the tree
  first and refuses a loop of prismatic joints only, so a prismatic joint is never cut;
- one linear row per prismatic joint: θ_b − θ_a = 0, the slider keeps its angle;
- one row per joint coupling (:class:`~loopcheck.mechanism.JointCoupling`): u_y − y_ref =
  p(u_x − x_ref) on the two joints' own coordinates u = row·x, whose γ is −p''(s) (r_x·K)².

The input joint adds the driving row c·x = q: c picks s for a prismatic input and
θ_b − θ_a for a revolute one (θ of ground is 0), so a revolute between two moving bodies is
driven by its relative angle without a coordinate of its own. With A = [Φ_x; c]:

    A K = (0, …, 0, 1),      A L = (−γ, 0),   γ = Σ_t 2 ṁ_t θ̇_t e⊥(θ_t) − m_t θ̇_t² e(θ_t),

the part of d²Φ/dq² that does not contain L (ṁ = coef K[mag], θ̇ = K[angle]); the linear
rows contribute nothing to γ. No finite differences anywhere.

The arithmetic is compiled, once for both engines (:mod:`loopcheck.kernels.loops`, whose source run
as plain Python under ``LOOPCHECK_PURE_PYTHON=1`` is the slow reference): this module builds the
tables from a description (:func:`compile_linkage`), packs them into the kernel's arrays
(:func:`pack`) and gives Python callers its results as arrays; numpy here is plumbing, and the
singular values of :func:`jacobian_rank`.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass, replace

import numpy as np

from .errors import NumericalFailure
from .kernels import loops as _loops
from .mechanism import GROUND, Linkage, PrismaticJoint

# The one singular-position threshold (docs/physics.md, "Singular positions"): below this
# conditioning (:func:`driving_conditioning`, a Hadamard ratio between 0 and 1) a coordinate
# cannot drive the linkage: a dead-centre or change point. Every verdict of "singular" in the
# project compares the same measure with this value: the numpy kinematics here, the scene
# file's checks, the reduced engine's start and its compiled core (the engine passes the value
# in when it builds a chart, :meth:`loopcheck.reduced.dynamics.MechanismModel.new_chart`), and the
# assembly mode of a dyad (:func:`assembly_modes`). At c = 1e-9, K and L computed from Φ_x have
# lost about log10(1/c) = 9 of their 16 digits (A's condition number grows as 1/c): below it
# they are not worth integrating.
SINGULAR_CONDITIONING = 1e-9
# Jacobian rank (:func:`jacobian_rank`, how many degrees of freedom a configuration has) is
# another question, answered by Φ_x's singular values: those above RANK_RTOL × the largest.
RANK_RTOL = 1e-9


class AssemblyError(ValueError):
    """The linkage cannot be assembled at the requested input from the given guess."""


@dataclass(frozen=True)
class Kinematics:
    """All joint coordinates and their velocity and acceleration coefficients at one
    configuration: x (n,) rad or m, K = dx/dx_i, L = d²x/dx_i² for the coordinate x_i they
    are taken with respect to."""

    x: np.ndarray
    K: np.ndarray
    L: np.ndarray


@dataclass(frozen=True)
class TermTable:
    """Rows of phasor sums in the plane; plain arrays only (see the module docstring).

    offset : (rows, 2) float, m
    row, coef, mag, angle, phase : (terms,) — the row each term adds to, its coefficient
        (m, or dimensionless when mag ≥ 0), the coordinate scaling it (−1: none), the
        coordinate of its angle (−1: the ground's, 0) and its phase (rad).
    """

    offset: np.ndarray
    row: np.ndarray
    coef: np.ndarray
    mag: np.ndarray
    angle: np.ndarray
    phase: np.ndarray

    @property
    def rows(self) -> int:
        return self.offset.shape[0]

    def kernel(self, n: int) -> _loops.Loops:
        """The compiled kinematics of this table alone (its table :data:`_loops.LOOPS`) for
        coordinates of length n: positions and rates (:func:`positions`, :func:`rates`)."""
        return _cached_kernel(self, n, lambda: pack(n, n, (self,)))


def _cached_kernel(owner, key, build) -> _loops.Loops:
    """One :class:`_loops.Loops` per (owner, key) and thread, built by ``build`` once: a kernel
    holds scratch that a call writes, so threads do not share one. Kept in the owner's
    ``__dict__`` (frozen values: derived once, as a cached property is)."""
    cache = owner.__dict__.setdefault("_kernels", {})
    k = (key, threading.get_ident())
    if k not in cache:
        cache[k] = _loops.Loops(*build())
    return cache[k]


def kernel_table(table: TermTable, rows: list[int] | None = None):
    """A :class:`TermTable` (or its rows ``rows``, in that order) as the kernel's arrays: offset
    (rows, 2), w (terms, 2) = coef · e(phase), row, mag, angle (terms,).

    A row listed twice in ``rows`` (two elements on one body point) is copied twice, each copy
    with its own terms: every listed row k of the result is table row ``rows[k]`` whole."""
    offset, row, coef, mag, angle, phase = (table.offset, table.row, table.coef, table.mag, table.angle,
                                            table.phase)
    if rows is not None:
        terms = [np.flatnonzero(row == r) for r in rows]
        take = np.concatenate(terms) if terms else np.zeros(0, dtype=np.int64)
        offset = offset[np.asarray(rows, dtype=np.int64)].reshape(-1, 2)
        row = np.repeat(np.arange(len(rows), dtype=np.int64), [len(t) for t in terms])
        coef, mag, angle, phase = coef[take], mag[take], angle[take], phase[take]
    w = np.column_stack([coef * np.cos(phase), coef * np.sin(phase)]).reshape(-1, 2)
    return np.asarray(offset, dtype=float).reshape(-1, 2), w, row, mag, angle


class Packer:
    """Appends arrays to the flat F (float64) and I (int64) of a compiled kernel, whose first
    ``header`` entries of I are its header (:mod:`loopcheck.kernels.loops` documents the layout)."""

    def __init__(self, header: int):
        self.F: list[np.ndarray] = []
        self.I: list[np.ndarray] = [np.zeros(header, dtype=np.int64)]
        self.nf, self.ni = 0, header
        self.header = self.I[0]

    def float(self, values) -> int:
        a = np.ascontiguousarray(values, dtype=float).ravel()
        self.F.append(a)
        self.nf += a.size
        return self.nf - a.size

    def int(self, values) -> int:
        a = np.ascontiguousarray(values, dtype=np.int64).ravel()
        self.I.append(a)
        self.ni += a.size
        return self.ni - a.size

    def kinematics(self, n: int, n_angles: int, tables, linear: np.ndarray,
                   couplings: np.ndarray | None = None) -> None:
        """The kinematics' header and arrays: n coordinates (the first n_angles of them angles),
        the term tables (:func:`kernel_table`'s arrays; the first is the loops'), the linear
        constraint rows (k, n) and the couplings' rows (c, 2n + 7: :attr:`LoopSystem.couplings`),
        packed as the kernel's polynomial rows, the linear ones first."""
        if len(tables) > _loops.N_TABLES:
            raise ValueError(f"at most {_loops.N_TABLES} term tables, not {len(tables)}")
        h = self.header
        rows = polynomial_rows(n, linear, couplings)
        h[_loops.N], h[_loops.N_ANGLES], h[_loops.N_LINEAR] = n, n_angles, len(rows)
        h[_loops.MAX_ROWS] = max(len(t[0]) for t in tables)
        h[_loops.LINEAR] = self.float(rows)
        for k, (offset, w, row, mag, angle) in enumerate(tables):
            tb = _loops.TABLES + _loops.TABLE_ENTRIES * k
            h[tb], h[tb + 1] = len(offset), len(row)
            h[tb + 2], h[tb + 3] = self.float(offset), self.float(w)
            h[tb + 4], h[tb + 5], h[tb + 6] = self.int(row), self.int(mag), self.int(angle)

    def copy(self) -> "Packer":
        """A packer holding what this one holds (the arrays packed so far shared, read-only; the
        header copied), to append to apart."""
        other = Packer.__new__(Packer)
        other.F, other.I = list(self.F), [self.I[0].copy(), *self.I[1:]]
        other.nf, other.ni, other.header = self.nf, self.ni, other.I[0]
        return other

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.concatenate(self.F) if self.F else np.zeros(1), np.concatenate(self.I)


def polynomial_rows(n: int, linear: np.ndarray, couplings: np.ndarray | None = None) -> np.ndarray:
    """The kernel's polynomial rows (rows, 2n + 7: r_y, r_x, x_ref, y_ref, a0 … a4;
    :mod:`loopcheck.kernels.loops`) of linear rows (k, n), which have r_x = 0 and p = 0, then of
    the couplings' rows (c, 2n + 7) as they are."""
    linear = np.asarray(linear, dtype=float).reshape(-1, n)
    rows = np.zeros((len(linear), 2 * n + _loops.ROW_EXTRA))
    rows[:, :n] = linear
    if couplings is None:
        return rows
    return np.vstack([rows, np.asarray(couplings, dtype=float).reshape(-1, 2 * n + _loops.ROW_EXTRA)])


def pack(n: int, n_angles: int, tables: tuple[TermTable, ...], linear: np.ndarray | None = None,
         couplings: np.ndarray | None = None):
    """The compiled kinematics' arrays (F, I) of term tables (the first the loops') over n
    coordinates, the first n_angles of them angles, the linear rows (k, n) and the couplings'
    rows (c, 2n + 7)."""
    P = Packer(_loops.KIN_HEADER)
    P.kinematics(n, n_angles, [kernel_table(t) for t in tables],
                 np.zeros((0, n)) if linear is None else linear, couplings)
    return P.arrays()


@dataclass(frozen=True)
class LoopSystem:
    """The compiled kinematics of a :class:`~loopcheck.mechanism.Linkage` (plain arrays).

    coordinate_names : (n,) names, ``"<body>.angle"`` or ``"<joint>.s"``
    loops : TermTable of the loop-closure vectors (2 constraint rows each)
    linear : (k, n) — the linear constraints linear·x = 0
    drive : (n,) — the input coordinate q = drive·x
    points : TermTable with one row per named point, named by ``point_names`` (body, point)
    input_unit : "rad" or "m"
    centres : TermTable with one row per moving body: its centre of mass (m)
    mode_pairs : (loops, 2) int — for each loop the two coordinates that close it at its
        cut joint (:func:`assembly_mode`)
    joint_names, joint_rows : the joints in the description's order and (joints, n) the row
        of each one's own coordinate u = row·x: a revolute joint's relative angle θ_b − θ_a
        (rad; also of a cut joint), a prismatic joint's displacement s (m)
    couplings : (c, 2n + 7) — one row per joint coupling (:class:`~loopcheck.mechanism.JointCoupling`),
        the constraint r_y·x − y_ref = p(r_x·x − x_ref): r_y (n) the coupled joint's row, r_x (n)
        the driver's, x_ref, y_ref, a0 … a4 (:mod:`loopcheck.kernels.loops`'s polynomial rows)
    rows : the n − 1 independent constraint rows the kernel runs on (:func:`independent_rows` at
        an assembled configuration, :meth:`with_independent_rows`), or None: all of them (a
        linkage without redundant loops has exactly n − 1)
    """

    coordinate_names: tuple[str, ...]
    loops: TermTable
    linear: np.ndarray
    drive: np.ndarray
    points: TermTable
    point_names: tuple[tuple[str, str], ...]
    input_unit: str
    centres: TermTable
    mode_pairs: np.ndarray
    joint_names: tuple[str, ...]
    joint_rows: np.ndarray
    rows: tuple[int, ...] | None = None
    couplings: np.ndarray | None = None
    inputs: tuple[str, ...] = ()

    @property
    def input_rows(self) -> np.ndarray:
        """(k, n) the rows of the k inputs' own coordinates, q = input_rows·x, in the linkage's
        inputs order (:attr:`loopcheck.mechanism.Linkage.inputs`); the first is :attr:`drive`."""
        if not self.inputs:
            return self.drive[None, :]
        return np.array([self.joint_row(name) for name in self.inputs], dtype=float).reshape(-1, self.n)

    @property
    def dof(self) -> int:
        """The degrees of freedom the linkage is driven with: one per input."""
        return max(len(self.inputs), 1)

    @property
    def coupling_rows(self) -> np.ndarray:
        """:attr:`couplings`, (0, 2n + 7) when there are none."""
        if self.couplings is None:
            return np.zeros((0, 2 * self.n + _loops.ROW_EXTRA))
        return self.couplings

    @property
    def kernel(self) -> _loops.Loops:
        """The compiled kinematics of the loops (:mod:`loopcheck.kernels.loops`; table LOOPS), on
        the constraint rows :attr:`rows`."""
        n_angles = sum(name.endswith(".angle") for name in self.coordinate_names)
        select = None if self.rows is None else np.asarray(self.rows, dtype=np.int64)
        return _cached_kernel(self, None,
                              lambda: (*pack(self.n, n_angles, (self.loops,), self.linear, self.couplings), select))

    def with_independent_rows(self, x: np.ndarray, rtol: float = RANK_RTOL) -> "LoopSystem":
        """The same linkage whose kernel runs on the independent constraint rows at the assembled
        configuration x (:func:`independent_rows` of every row's Jacobian, chosen once here).
        Raises :class:`AssemblyError` where they are not n − dof (not :attr:`dof` degrees of freedom)."""
        J = all_constraints(self, x)[1]
        rows = independent_rows(J, rtol)
        if len(rows) != self.n - self.dof:
            raise AssemblyError(f"the loop equations have rank {len(rows)} of {J.shape[0]} rows over "
                                f"{self.n} coordinates: {self.n - len(rows)} degrees of freedom, not {self.dof}")
        return replace(self, rows=rows)

    @property
    def m(self) -> int:
        """Every constraint row: two per loop, one per linear row (n − 1 without a redundant loop)."""
        return 2 * self.loops.rows + len(self.linear)

    @property
    def redundant(self) -> bool:
        """More constraint rows than n − 1: a redundantly closed loop (Grübler's count below 1).
        Without :attr:`rows` its kernel runs on an orthonormal basis of Φ_x's rows, taken at every
        evaluation (:class:`loopcheck.kernels.loops.Loops`)."""
        return self.m > self.n - 1

    def joint_row(self, name: str) -> np.ndarray:
        """(n,) the row of joint ``name``'s own coordinate (:attr:`joint_rows`)."""
        return self.joint_rows[self.joint_names.index(name)]

    @property
    def n(self) -> int:
        return len(self.coordinate_names)

    def point_index(self, body: str, point: str) -> int:
        """Row of (body, point) in :attr:`points`."""
        try:
            return self.point_names.index((body, point))
        except ValueError:
            raise KeyError(f"no point {point!r} on body {body!r}") from None

    def coordinate(self, name: str) -> int:
        """Index of the coordinate called ``name``."""
        return self.coordinate_names.index(name)

    def driven_by(self, index: int) -> "LoopSystem":
        """The same linkage with coordinate x[index] as the input (coordinate partitioning):
        :func:`assemble` then holds x[index] = q and :func:`coefficients` gives dx/dx[index]."""
        drive = np.zeros(self.n)
        drive[index] = 1.0
        unit = "rad" if self.coordinate_names[index].endswith(".angle") else "m"
        return replace(self, drive=drive, input_unit=unit)


# -- evaluation, compiled (loopcheck.kernels.loops) ------------------------------------------------

def positions(t: TermTable, x: np.ndarray) -> np.ndarray:
    """r(x) of every row, shape (rows, 2) (m)."""
    return t.kernel(len(x)).positions(_loops.LOOPS, x)


def rates(t: TermTable, x: np.ndarray, K: np.ndarray, L: np.ndarray | None = None):
    """K_r = dr/dq and L_r = d²r/dq² of every row, each shape (rows, 2).

    With L = None, L_r is γ: the part of d²r/dq² without L (m/rad², or m/m² for a
    displacement input).
    """
    out = t.kernel(len(x)).rates(_loops.LOOPS, x, K, L)
    return out[:, 0:2], out[:, 2:4]


def constraint_residual(system: LoopSystem, x: np.ndarray) -> np.ndarray:
    """Φ(x): the loop vectors (m) then the linear rows (rad) and the couplings (rad or m), shape (n − 1,)."""
    return system.kernel.constraints(x)[0]


def all_constraints(system: LoopSystem, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Φ(x) (m,) and Φ_x (m, n) of every constraint row, the dependent rows of a redundant loop
    too (m ≥ n − 1): loop vectors (m) then linear rows (rad), then the couplings (rad or m)."""
    return system.kernel.all_constraints(x)


def constraint_jacobian(system: LoopSystem, x: np.ndarray) -> np.ndarray:
    """Φ_x, shape (n − 1, n): the rows the kernel runs on (every row; the selected ones,
    :attr:`LoopSystem.rows`; or a redundant loop's orthonormal basis of them, :attr:`LoopSystem.redundant`)."""
    return system.kernel.constraints(x)[1]


# -- the singular-position measure ---------------------------------------------------------

def hadamard_ratio(M: np.ndarray) -> np.ndarray | float:
    """det M / Π ‖M[:, l]‖ of a square matrix M (or of each of a stack, shape (..., k, k)).

    Its magnitude is between 0 (singular) and 1 (orthogonal columns) by Hadamard's inequality,
    0 when a column is zero; its sign is det M's (a dyad's assembly mode). Unchanged by scaling
    a column (a coordinate's unit), by rotating the plane and by scaling a linkage's lengths
    (each column of a revolute linkage's Φ_x scales with them).
    """
    norms = np.prod(np.sqrt(np.einsum("...ij,...ij->...j", M, M)), axis=-1)
    det = np.linalg.det(M)
    ratio = np.divide(det, norms, out=np.zeros_like(det), where=norms > 0)
    return float(ratio) if np.ndim(ratio) == 0 else ratio


def dependent_jacobian(J: np.ndarray, row: np.ndarray) -> np.ndarray:
    """The loop Jacobian in the dependent coordinates when p = row·x drives the linkage,
    shape (n − 1, n − 1): the definition of :func:`driving_conditioning`'s measure, |hadamard_ratio|
    of this matrix (the compiled kernel evaluates it from its LU factors).

    J is Φ_x (n − 1, n). With i the coordinate of row's largest |entry| (the first of equals),
    x_i = (p − Σ_{l≠i} row_l x_l) / row_i: the dependent coordinates are the others, and
    column l of Φ in them is J[:, l] − (row_l / row_i) J[:, i]. For row = e_i that is Φ_x
    without column i (Φ_dep); for a relative angle θ_b − θ_a, column a becomes J[:, a] + J[:, b].
    """
    row = np.asarray(row, dtype=float)
    i = int(np.argmax(np.abs(row)))
    others = np.arange(len(row)) != i
    return J[:, others] - np.outer(J[:, i], row[others] / row[i])


def driving_conditioning(system: LoopSystem, x: np.ndarray, row: np.ndarray | None = None) -> float:
    """The conditioning of p = row·x (the input q = drive·x by default) at x: the Hadamard
    ratio of its :func:`dependent_jacobian`, between 0 (p cannot drive the linkage here) and 1.

    The one singular-position measure (module constant SINGULAR_CONDITIONING): for coordinate j,
    |det Φ_dep| / Π ‖columns of Φ_dep‖ = |K_j| |det A| / Π_{l≠j} ‖Φ_x[:, l]‖ (Cramer's rule,
    K w.r.t. any driving coordinate), evaluated as |det A| / (|row_i| Π_{l≠i} ‖column l of the
    dependent Jacobian‖) with A = [Φ_x; row] (:mod:`loopcheck.kernels.loops`, which the reduced
    engine's charts evaluate at every step); for the seed four-bar driven by its crank,
    |sin(φ2 − φ1)|.
    """
    return system.kernel.driving_conditioning(x, system.drive if row is None else row)


# -- position, velocity and acceleration -----------------------------------------------

def assemble(system: LoopSystem, q: float, guess: np.ndarray, *, tol: float = 1e-12,
             max_iter: int = 50) -> np.ndarray:
    """All coordinates x with the loops closed and the input coordinate equal to q.

    Newton's method on (Φ(x), drive·x − q) = 0 from ``guess`` (shape (n,)); the assembly
    found is the one the guess leads to. Converged when every residual is ≤ ``tol`` (m or
    rad), followed by one more step to reach round-off (compiled: :mod:`loopcheck.kernels.loops`).

    Raises
    ------
    AssemblyError
        Non-finite input, a singular Jacobian on the way (dead-centre or change point), or
        no convergence in ``max_iter`` iterations (the loops cannot close at this q, or the
        guess is too far from an assembly).
    """
    x = np.array(guess, dtype=float)
    if x.shape != (system.n,):
        raise AssemblyError(f"the guess has shape {x.shape}, expected ({system.n},) "
                            f"for coordinates {', '.join(system.coordinate_names)}")
    if not (math.isfinite(q) and np.all(np.isfinite(x))):
        raise AssemblyError(f"q = {q} and the guess must be finite")
    status, iteration, largest = system.kernel.assemble(float(q), x, system.drive, tol, max_iter,
                                                        SINGULAR_CONDITIONING)
    if status == _loops.NON_FINITE:
        raise AssemblyError(f"Newton's method diverged at q = {q:.15g} {system.input_unit} "
                            f"(non-finite residual at iteration {iteration}): start from "
                            f"another guess")
    if status == _loops.SINGULAR_JACOBIAN:
        raise AssemblyError(f"the loop Jacobian is singular at q = {q:.15g} {system.input_unit} "
                            f"during assembly (a dead-centre or change point): start from "
                            f"another guess")
    if status == _loops.NOT_CLOSED:
        raise AssemblyError(f"the loops do not close at q = {q:.15g} {system.input_unit}: largest "
                            f"residual {largest:.3g} after {max_iter} Newton iterations "
                            f"(the lengths cannot meet there, or the guess is too far from an assembly)")
    if system.redundant:  # Newton ran on a basis of the rows: every row, the dependent ones too, must close
        largest = float(np.max(np.abs(system.kernel.all_constraints(x)[0])))
        if not largest <= tol:
            raise AssemblyError(f"the loops do not close at q = {q:.15g} {system.input_unit}: the loop equations "
                                f"beyond the independent ones are left at {largest:.3g} where those closed (no "
                                "configuration at this q closes every loop: a structure, or redundant links whose "
                                "lengths do not fit)")
    return x


def assemble_inputs(system: LoopSystem, q, guess: np.ndarray, *, tol: float = 1e-12,
                    max_iter: int = 50) -> np.ndarray:
    """All coordinates x with the loops closed and every input at its value: q (k,) in the
    inputs' order (:attr:`LoopSystem.input_rows`), for a linkage of k ≥ 1 degrees of freedom.

    Newton's method on (Φ(x), R x − q) = 0 from ``guess``, every constraint row (a redundant
    loop's too: the step is the least-squares one, exact for consistent rows), converged when
    every residual is ≤ ``tol`` (m or rad), then one more step to reach round-off. Set-up only
    (a scene's start): plain NumPy, not the compiled kernel the one-input :func:`assemble` runs.

    Raises
    ------
    AssemblyError
        Non-finite values, a Jacobian [Φ_x; R] of rank below n on the way (the inputs cannot
        hold the linkage there: a singular configuration of these inputs), or no convergence in
        ``max_iter`` iterations."""
    R = system.input_rows
    q = np.array(q, dtype=float).reshape(-1)
    x = np.array(guess, dtype=float)
    if q.shape != (R.shape[0],):
        raise AssemblyError(f"{len(q)} input values for {R.shape[0]} inputs")
    if x.shape != (system.n,):
        raise AssemblyError(f"the guess has shape {x.shape}, expected ({system.n},) "
                            f"for coordinates {', '.join(system.coordinate_names)}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(x))):
        raise AssemblyError(f"q = {q.tolist()} and the guess must be finite")
    where = ", ".join(f"{v:.15g}" for v in q)
    polished = False
    for _ in range(max_iter + 1):
        phi, J = system.kernel.all_constraints(x)
        residual = np.concatenate([phi, R @ x - q])
        if not np.all(np.isfinite(residual)):
            raise AssemblyError(f"Newton's method diverged at q = ({where}): start from another guess")
        A = np.vstack([J, R])
        step, _, rank, _ = np.linalg.lstsq(A, -residual, rcond=None)
        if rank < system.n:
            raise AssemblyError(f"the inputs cannot hold the linkage at q = ({where}) during assembly (the "
                                f"Jacobian [Φ_x; R] has rank {rank} of {system.n}: a singular configuration of "
                                "these inputs): start from another guess")
        if polished:
            return x
        converged = bool(np.max(np.abs(residual)) <= tol)
        x = x + step
        polished = converged
    largest = float(np.max(np.abs(residual)))
    raise AssemblyError(f"the loops do not close at q = ({where}): largest residual {largest:.3g} after {max_iter} "
                        "Newton iterations (the lengths cannot meet there, or the guess is too far from an assembly)")


def input_rates(system: LoopSystem, x: np.ndarray, qdot) -> np.ndarray:
    """ẋ (n,) at an assembled x with every input at its rate: qdot (k,) in the inputs' order
    (:attr:`LoopSystem.input_rows`), ẋ = K q̇ with K from [Φ_x; R] K = [0; I].

    Every constraint row (a redundant loop's too: the least-squares solve, exact for consistent
    rows). Set-up only (an engine's initial state): plain NumPy.

    Raises
    ------
    AssemblyError
        Non-finite values, a count of rates other than the inputs', or [Φ_x; R] of rank below n
        (the inputs cannot hold the linkage at x: a singular configuration of these inputs)."""
    R = system.input_rows
    qdot = np.array(qdot, dtype=float).reshape(-1)
    x = np.asarray(x, dtype=float)
    if qdot.shape != (R.shape[0],):
        raise AssemblyError(f"{len(qdot)} input rates for {R.shape[0]} inputs")
    if not (np.all(np.isfinite(qdot)) and np.all(np.isfinite(x))):
        raise AssemblyError(f"the input rates {qdot.tolist()} and the configuration must be finite")
    if not np.any(qdot):
        return np.zeros(system.n)
    J = all_constraints(system, x)[1]
    A = np.vstack([J, R])
    xdot, _, rank, _ = np.linalg.lstsq(A, np.concatenate([np.zeros(J.shape[0]), qdot]), rcond=None)
    if rank < system.n:
        raise AssemblyError(f"the inputs cannot hold the linkage at their rates {qdot.tolist()} (the Jacobian "
                            f"[Φ_x; R] has rank {rank} of {system.n}: a singular configuration of these inputs)")
    return xdot


def coefficients(system: LoopSystem, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K = dx/dq and L = d²x/dq² at an assembled x, each shape (n,).

    Raises NumericalFailure(SINGULAR) where q cannot drive the linkage.
    """
    c, K, L = system.kernel.coefficients(x, system.drive)
    if c < SINGULAR_CONDITIONING:
        raise NumericalFailure("singular", f"dead-centre position: the input coordinate cannot "
                                           f"drive the linkage at q = {system.drive @ x:.15g} "
                                           f"{system.input_unit}")
    return K, L


def point_kinematics(system: LoopSystem, x: np.ndarray, K: np.ndarray, L: np.ndarray):
    """r, K_r = dr/dq and L_r = d²r/dq² of every named point, each shape (points, 2)."""
    kr, lr = rates(system.points, x, K, L)
    return positions(system.points, x), kr, lr


def assembly_modes(system: LoopSystem, x: np.ndarray) -> np.ndarray:
    """The assembly mode of each configuration: one sign (±1, 0 when degenerate) per loop.

    For loop k, closed at its cut joint by the coordinates u, v of :attr:`LoopSystem.mode_pairs`
    (the joint coordinates nearest the cut on either side: a body's angle or a slider's
    displacement), the sign of −det [∂Φ_k/∂x_u, ∂Φ_k/∂x_v]. For two links a, b meeting at
    the cut pin P that turn about their tree joints A and B, that is the sign of the cross
    product (P − A) × (P − B), the dyad's "elbow up or down" (+1 for the seed four-bar's
    branch +1). It
    changes only where that dyad is singular (a limit position), where it is 0. x has shape (n,) or
    (samples, n); the result (loops,) or (samples, loops), int.
    """
    X = np.atleast_2d(np.asarray(x, dtype=float))
    if system.redundant:  # every row (loop k's are 2k, 2k + 1), not the n − 1 selected ones
        J = np.array([system.kernel.all_constraints(row)[1] for row in X]).reshape(len(X), system.m, system.n)
    else:
        J = system.kernel.jacobians(np.ascontiguousarray(X))  # (samples, n − 1, n)
    out = np.zeros((X.shape[0], len(system.mode_pairs)), dtype=int)
    for k, (u, v) in enumerate(system.mode_pairs):
        block = J[:, 2 * k:2 * k + 2][:, :, [u, v]]  # (samples, 2, 2): rows x, y of loop k; columns u, v
        # At the dyad's limit position (its block's conditioning, |sin| of the angle between
        # the columns, below SINGULAR_CONDITIONING) the sign is round-off: the mode is 0 there.
        out[:, k] = _mode_signs(block)
    return out[0] if np.ndim(x) == 1 else out


MODE_MARGIN = 1e-12
"""How far the closed-form ratio of :func:`_mode_signs` must be from 0 and from
SINGULAR_CONDITIONING to decide a mode alone: both it and :func:`hadamard_ratio`'s LU are within a
few ulps (~1e-15) of the exact ratio, which is in [−1, 1] (|ad| + |bc| ≤ the columns' norms'
product, Cauchy–Schwarz)."""


def _mode_signs(block: np.ndarray) -> np.ndarray:
    """−sign(:func:`hadamard_ratio`) of each 2 × 2 block (samples, 2, 2), 0 where its magnitude is
    below SINGULAR_CONDITIONING, exactly as from :func:`hadamard_ratio` itself: decided by the
    closed form ad − bc over the columns' norms where that is over :data:`MODE_MARGIN` away from
    the threshold, else (a limit position, a zero column, a value not finite) by
    :func:`hadamard_ratio`'s LU (np.linalg.det), which the closed form saves on the other samples."""
    a, b, c, d = block[:, 0, 0], block[:, 0, 1], block[:, 1, 0], block[:, 1, 1]
    norms = np.sqrt(a * a + c * c) * np.sqrt(b * b + d * d)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = (a * d - b * c) / norms
    size = np.abs(ratio)
    clear = np.isfinite(ratio) & (norms > 0) & (np.abs(size - SINGULAR_CONDITIONING) > MODE_MARGIN)
    out = np.where(size < SINGULAR_CONDITIONING, 0, -np.sign(ratio))
    unclear = np.flatnonzero(~clear)
    if len(unclear):
        exact = np.atleast_1d(hadamard_ratio(block[unclear]))
        out[unclear] = np.where(np.abs(exact) < SINGULAR_CONDITIONING, 0, -np.sign(exact))
    return out.astype(int)


def assembly_mode(system: LoopSystem, x: np.ndarray) -> tuple[int, ...]:
    """:func:`assembly_modes` of one configuration, as a tuple."""
    return tuple(int(v) for v in assembly_modes(system, np.asarray(x, dtype=float)))


def unwrap_angles(angles: np.ndarray) -> np.ndarray:
    """Angles sampled along a run (samples, columns) made continuous (no 2π jumps): exactly
    ``np.unwrap(angles, axis=0)``, which a run whose samples never jump by π or more (every run
    sampled finely enough) gets without its corrections: their sum is +0.0 there, so the result is
    the angles + 0.0 (−0.0 becomes +0.0, as in np.unwrap)."""
    steps = np.diff(angles, axis=0)
    if not np.all(np.abs(steps) < math.pi):  # a jump to correct (or a value not finite)
        return np.unwrap(angles, axis=0)
    out = np.array(angles, dtype=float)
    out[1:] += 0.0
    return out


def jacobian_rank(system: LoopSystem, x: np.ndarray, rtol: float = RANK_RTOL) -> int:
    """Rank of Φ_x at x (singular values above ``rtol`` × the largest); n − 1 for one DOF.

    How many degrees of freedom the configuration has, not whether a given coordinate can drive
    it (that is :func:`driving_conditioning`): an SVD, run once per scene at assembly. Every row,
    a redundant loop's dependent ones too: n − rank is the configuration's DOF (:func:`rank_dof`)."""
    sv = np.linalg.svd(all_constraints(system, x)[1], compute_uv=False)
    return int(np.sum(sv > rtol * sv[0])) if sv.size else 0  # a single body on one joint: no constraint


def independent_rows(J: np.ndarray, rtol: float = RANK_RTOL) -> tuple[int, ...]:
    """The rows of a constraint Jacobian J (m, n) that are independent, in ascending order:
    a rank-revealing factorization, QR with column pivoting of Jᵀ (scipy's ``qr(pivoting=True)``),
    keeps pivot k while |R_kk| > ``rtol`` × |R_00| (RANK_RTOL: the same relative tolerance as
    :func:`jacobian_rank`).

    A redundantly closed loop (a parallelogram with an extra link, two coaxial arms pinned at
    their tips) has more loop rows than its rank: its degrees of freedom are n − len(rows), not
    Grübler's count. The rows not selected are combinations of the selected ones at this x;
    for a consistently redundant linkage they stay satisfied along its motion, so Newton's
    assembly, K and L may use the selected rows only. The selection is made once, at the
    assembled configuration: it holds where those rows keep their rank (the conditioning of
    the driving coordinate measures that along a run)."""
    from scipy.linalg import qr

    J = np.asarray(J, dtype=float)
    if J.ndim != 2:
        raise ValueError(f"J must be a matrix (rows, coordinates), got shape {J.shape}")
    if not np.all(np.isfinite(J)):
        raise ValueError("J has non-finite entries")
    if J.shape[0] == 0 or not np.any(J):
        return ()
    _, R, piv = qr(J.T, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > rtol * diag[0]))
    return tuple(sorted(int(k) for k in piv[:rank]))


def rank_dof(J: np.ndarray, rtol: float = RANK_RTOL) -> int:
    """Degrees of freedom of a configuration whose constraint Jacobian is J (m, n): n minus the
    number of :func:`independent_rows` (not Grübler's count, which counts redundant rows)."""
    return int(np.asarray(J).shape[1]) - len(independent_rows(J, rtol))


def conditioning(system: LoopSystem, x: np.ndarray) -> np.ndarray:
    """:func:`driving_conditioning` of each coordinate x_j as the independent one,
    |det Φ_dep| / Π ‖columns of Φ_dep‖, shape (n,): between 0 (that coordinate cannot drive
    the linkage here) and 1 (the other columns orthogonal)."""
    return system.kernel.conditioning(x)


# -- building the tables from a description --------------------------------------------

class _Sum:
    """A phasor sum under construction: offset and terms (coef, mag, angle, phase)."""

    def __init__(self, offset=(0.0, 0.0), terms=()):
        self.offset = (float(offset[0]), float(offset[1]))
        self.terms = list(terms)

    def add(self, coef: float, mag: int, angle: int, phase: float) -> "_Sum":
        if angle < 0 and mag < 0:  # a constant vector
            return _Sum((self.offset[0] + coef * math.cos(phase),
                         self.offset[1] + coef * math.sin(phase)), self.terms)
        return _Sum(self.offset, self.terms + [(coef, mag, angle, phase)])

    def rotated(self, vector, angle: int) -> "_Sum":
        """Plus R(θ) vector, θ = x[angle] (or 0 for ground)."""
        u, v = vector
        if u == 0.0 and v == 0.0:
            return self
        return self.add(math.hypot(u, v), -1, angle, math.atan2(v, u))

    def minus(self, other: "_Sum") -> "_Sum":
        return _Sum((self.offset[0] - other.offset[0], self.offset[1] - other.offset[1]),
                    self.terms + [(-c, m, a, p) for c, m, a, p in other.terms])


def _table(sums: list[_Sum]) -> TermTable:
    terms = [(k,) + t for k, s in enumerate(sums) for t in s.terms]
    cols = list(zip(*terms)) if terms else [(), (), (), (), ()]
    return TermTable(offset=np.array([s.offset for s in sums], dtype=float).reshape(-1, 2),
                     row=np.array(cols[0], dtype=np.intp), coef=np.array(cols[1], dtype=float),
                     mag=np.array(cols[2], dtype=np.intp), angle=np.array(cols[3], dtype=np.intp),
                     phase=np.array(cols[4], dtype=float))


_SYSTEMS: dict[int, tuple[weakref.ref, "LoopSystem"]] = {}
"""compile_linkage's results, by the id of the linkage object, while it lives (a weak reference
checked on each look-up, the entry dropped when the linkage goes)."""


_BY_GEOMETRY: dict[tuple, "LoopSystem"] = {}
"""compile_linkage's latest results by :func:`_geometry`, at most :data:`GEOMETRIES` of them."""
GEOMETRIES = 8
_GEOMETRY_LOCK = threading.Lock()


def _geometry(linkage: Linkage) -> tuple | None:
    """What :func:`_compile_linkage` reads of a linkage, as a key: the bodies' names, points and
    centres of mass in order (not their mass, inertia or gravcomp), the joints, the inputs,
    the tree's preferences and the couplings; None where a coordinate is −0.0 (equal to 0.0 as a
    key, but not bit for bit: the two are compiled apart)."""
    bodies = tuple((b.name, tuple(b.points.items()), b.com) for b in linkage.bodies)
    numbers = [v for _, points, com in bodies for v in (*(c for _, xy in points for c in xy), *com)]
    numbers += [j.direction_a for j in linkage.joints if isinstance(j, PrismaticJoint)]
    numbers += [v for c in linkage.couplings for v in (*c.coefficients, c.x_ref, c.y_ref)]
    if any(v == 0.0 and math.copysign(1.0, v) < 0.0 for v in numbers):
        return None
    return bodies, linkage.joints, linkage.inputs, linkage.tree_first, linkage.couplings


def compile_linkage(linkage: Linkage) -> LoopSystem:
    """The term tables, linear rows and driving row of a checked linkage.

    Compiled once per :class:`~loopcheck.mechanism.Linkage` object (frozen: a scene file's
    assembly and the reduced engine's model share it; the system's kernels are per thread,
    :func:`_cached_kernel`), and once per geometry among the latest :data:`GEOMETRIES` (a sweep's
    variants that change masses, loads or settings share one system, its kernels and what
    :mod:`loopcheck.reduced.dynamics` derives from it): another linkage of the same
    :func:`_geometry` gets the same system, the same arrays to the bit."""
    entry = _SYSTEMS.get(id(linkage))
    if entry is not None and entry[0]() is linkage:
        return entry[1]
    geometry = _geometry(linkage)
    system = _BY_GEOMETRY.get(geometry) if geometry is not None else None
    if system is None:
        system = _compile_linkage(linkage)
        if geometry is not None:
            with _GEOMETRY_LOCK:  # threads (a Dask worker's) share the cache
                while len(_BY_GEOMETRY) >= GEOMETRIES:
                    del _BY_GEOMETRY[next(iter(_BY_GEOMETRY))]
                _BY_GEOMETRY[geometry] = system
    key = id(linkage)
    _SYSTEMS[key] = (weakref.ref(linkage, lambda _, key=key: _SYSTEMS.pop(key, None)), system)
    return system


def _compile_linkage(linkage: Linkage) -> LoopSystem:
    bodies = linkage.body_map
    joints = linkage.joint_map
    prismatic = [j.name for j in linkage.joints if isinstance(j, PrismaticJoint)]
    angle = {b: i for i, b in enumerate(linkage.moving)}
    angle[GROUND] = -1
    disp = {name: len(linkage.moving) + k for k, name in enumerate(prismatic)}
    n = len(linkage.moving) + len(prismatic)
    names = tuple(f"{b}.angle" for b in linkage.moving) + tuple(f"{j}.s" for j in prismatic)

    # r_B(p) = base[B] + R(θ_B)(p − anchor[B])
    base = {GROUND: _Sum()}
    anchor = {GROUND: (0.0, 0.0)}

    def point(body: str, name: str) -> _Sum:
        px, py = bodies[body].points[name]
        ax, ay = anchor[body]
        return base[body].rotated((px - ax, py - ay), angle[body])

    def relative_angle(body_a: str, body_b: str) -> np.ndarray:
        """The row r with r·x = θ_b − θ_a (θ of ground is 0)."""
        row = np.zeros(n)
        if angle[body_b] >= 0:
            row[angle[body_b]] += 1.0
        if angle[body_a] >= 0:
            row[angle[body_a]] -= 1.0
        return row

    linear_rows = []  # θ_b − θ_a = 0 for each prismatic joint: the slider keeps its angle

    for edge in linkage.tree:
        jt = joints[edge.joint]
        child_is_b = jt.body_b == edge.body
        own, other = ("b", "a") if child_is_b else ("a", "b")
        if isinstance(jt, PrismaticJoint):
            linear_rows.append(relative_angle(jt.body_a, jt.body_b))
            # point_b = point_a + s e(θ_a + direction); θ_a is the child's or the parent's.
            sign = 1.0 if child_is_b else -1.0
            base[edge.body] = point(edge.parent, getattr(jt, f"point_{other}")).add(
                sign, disp[jt.name], angle[jt.body_a], jt.direction_a)
        else:
            base[edge.body] = point(edge.parent, getattr(jt, f"point_{other}"))
        anchor[edge.body] = bodies[edge.body].points[getattr(jt, f"point_{own}")]

    up = {e.body: e for e in linkage.tree}

    def coordinates_below(body: str) -> list[int]:
        """The coordinates of the tree joints from ``body`` down to ground, nearest first."""
        out = []
        while body != GROUND:
            e = up[body]
            jt = joints[e.joint]
            out.append(disp[jt.name] if isinstance(jt, PrismaticJoint) else angle[e.body])
            body = e.parent
        return out

    # An input's own coordinate never names a mode: q is given, so the mode is the sign of a
    # pair of dependent coordinates, which changes only where q cannot drive the loop.
    driven = set()
    for name in linkage.inputs:
        inp = joints[name]
        driven |= {disp[inp.name]} if isinstance(inp, PrismaticJoint) else {
            angle[b] for b in (inp.body_a, inp.body_b) if angle[b] >= 0 and GROUND in (inp.body_a, inp.body_b)}
    loops, mode_pairs = [], []
    for name in linkage.cut_joints:
        jt = joints[name]
        assert not isinstance(jt, PrismaticJoint), "Linkage never cuts a prismatic joint"
        loops.append(point(jt.body_a, jt.point_a).minus(point(jt.body_b, jt.point_b)))
        full_a, full_b = coordinates_below(jt.body_a), coordinates_below(jt.body_b)
        side_a = [c for c in full_a if c not in driven]
        side_b = [c for c in full_b if c not in driven]
        if side_a and side_b:
            pair = (side_a[0], side_b[0])
        else:  # the cut joint is on ground or on the input body: the two nearest on the other side
            side = (side_a or side_b) + [c for c in full_a + full_b if c not in side_a + side_b]
            pair = (side[0], side[1])
        mode_pairs.append(pair)

    def centre(body: str) -> _Sum:
        cx, cy = bodies[body].com
        ax, ay = anchor[body]
        return base[body].rotated((cx - ax, cy - ay), angle[body])

    inp = joints[linkage.input_joint]
    if isinstance(inp, PrismaticJoint):
        drive = np.zeros(n)
        drive[disp[inp.name]] = 1.0
        unit = "m"
    else:  # a revolute's coordinate is its relative angle, also between two moving bodies
        drive = relative_angle(inp.body_a, inp.body_b)
        unit = "rad"

    def joint_row(jt) -> np.ndarray:
        if isinstance(jt, PrismaticJoint):
            row = np.zeros(n)
            row[disp[jt.name]] = 1.0
            return row
        return relative_angle(jt.body_a, jt.body_b)

    rows = {j.name: joint_row(j) for j in linkage.joints}
    couplings = []
    for c in linkage.couplings:  # y − y_ref = p(x − x_ref) on the joints' own coordinates
        couplings.append(np.concatenate([rows[c.joint], rows[c.driver], [c.x_ref, c.y_ref], c.coefficients]))
    point_names = tuple((b.name, p) for b in linkage.bodies for p in b.points)
    return LoopSystem(couplings=np.array(couplings, dtype=float).reshape(-1, 2 * n + _loops.ROW_EXTRA)
                      if couplings else None,joint_names=tuple(j.name for j in linkage.joints),
                      joint_rows=np.array([joint_row(j) for j in linkage.joints], dtype=float).reshape(-1, n),
                      coordinate_names=names, loops=_table(loops),
                      linear=np.array(linear_rows, dtype=float).reshape(-1, n),
                      drive=drive,
                      points=_table([point(b, p) for b, p in point_names]),
                      point_names=point_names, input_unit=unit,
                      centres=_table([centre(b) for b in linkage.moving]),
                      mode_pairs=np.array(mode_pairs, dtype=np.intp).reshape(-1, 2),
                      inputs=linkage.inputs if len(linkage.inputs) > 1 else ())
