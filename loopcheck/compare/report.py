"""``report.json``, trajectory CSVs and plots of a comparison, written all-or-nothing.

The files are written through :func:`loopcheck.compare.output.write_folder`: staged in a fresh
hidden folder and replaced as a set, so a failure or an interrupt part-way leaves the
output folder as it was. ``report.json`` is strict JSON (non-finite numbers are null) and
names the scene file relative to the working directory, never by an absolute path.
The schema is documented in the README ("report.json"). Schema 2 (the general linkage):
``scene.input_unit`` ("rad" or "m") is the unit of q, q0 and every q figure (their rates
in it per s); ``scene.mode`` is the assembly mode at q0 (one sign per loop); the
``diff`` keys ``mode_mismatches`` and ``mode_mismatch_first_times`` are lists, one entry
per loop (samples where MuJoCo's mode of that loop differs from the reduced reference's,
and the first such time in s or null), with ``mode_mismatches_total`` their sum; they
replace schema 1's single ``branch_mismatches``. The CSV headers name the unit
(``q_rad`` or ``q_m``). Schema 3 (one peak event): each engine's ``peak_omega``/``t_peak``
is the compared peak (the reduced run's largest |q̇| and MuJoCo's extremum of the same sign
nearest in time, :mod:`loopcheck.compare.diff`), signed, with ``peak_still_rising`` (the peak is the
end of the horizon, |q̇| still rising); the ``diff`` peaks ``peak_omega_reference`` and
``peak_omega_other`` are signed too (schema 2: magnitudes). Each CSV also carries the coordinate and rate of every joint (a scene of
at most :data:`JOINTS_BY_DEFAULT` joints; else the input's and those ``loopcheck run --joints``
names), and ``report.json``'s ``joints`` list summarizes them (:func:`joint_report`; from schema 7, every joint). Schema 5
(several engines, ``loopcheck run --engines``): ``engines``, one verdict per engine judged against the
reduced reference (:func:`engines_report`), and ``outlier``, the engine farthest from the others
or null; ``other_engine`` names the engine the rest of the report compares with the reference,
whose summary is under its own name (``mujoco``, or ``pin`` when MuJoCo is not in the list) and
whose CSV is ``<engine>.csv``. Schema 6 (the comparison by role: :class:`loopcheck.compare.run.Comparison`'s
``reference`` and ``other``): ``reference_engine`` names the engine whose summary is the reference's
(``reduced``), beside ``other_engine``. Schema 7 (several degrees of freedom): ``scene`` gains
``inputs``, ``input_units``, ``initial_q`` and ``initial_qdot`` (every input in order; ``input_joint``,
``input_unit``, ``q0`` and ``qdot0`` stay the first's), and ``inputs`` holds one entry per input (the one
input's too): its ``name``, ``unit``, the compared peak of the ``reference`` and the ``other`` engine, and the ``diff``
figures (the top-level ``diff`` and the engines' peaks stay the first input's); ``joints`` lists every
joint of the scene (no cap: the CSVs' columns alone follow :func:`joint_columns`).

``loopcheck run --animate`` adds ``mechanism.gif`` (:data:`ANIMATION_FILE`) to the set, ``loopcheck run
--engines`` ``engines.png`` (:data:`ENGINES_PLOT`).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
import os
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from loopcheck import kinematics as loops
from loopcheck.mechanism import PrismaticJoint
from loopcheck.results import EngineResult
from loopcheck.registry import DEFAULT_ENGINES, REFERENCE, engine_of_run
from loopcheck.settings import settings_dict
from loopcheck.scene import Scene
from loopcheck.trajectory import Peak

from .output import json_text, portable_source, write_folder
from .plots import (plot_constraint_violation, plot_differences, plot_energy, plot_engines, plot_omega_vs_q,
                    plot_trajectories)
if TYPE_CHECKING:
    from loopcheck.trajectory import JointTrajectory

    from .engines import EnginesCheck
    from .run import Comparison

SCHEMA_VERSION = 7


def plot_mechanism_strip(c, path) -> None:
    """:func:`loopcheck.compare.draw.plot_mechanism_strip` (imported when a run draws it: every command
    imports this module, ~24 ms more with the drawing's)."""
    from .draw import plot_mechanism_strip as plot

    plot(c, path)


# The figures a run writes, by file (each function takes the Comparison and the path).
PLOTS = {
    "trajectories.png": plot_trajectories,
    "differences.png": plot_differences,
    "omega_vs_q.png": plot_omega_vs_q,
    "constraint_violation.png": plot_constraint_violation,
    "energy.png": plot_energy,
    "mechanism.png": plot_mechanism_strip,
}
REPORT_FILES = (f"{REFERENCE}.csv", f"{DEFAULT_ENGINES[1]}.csv", *PLOTS, "report.json")  # in the order they are committed
ANIMATION_FILE = "mechanism.gif"
ENGINES_PLOT = "engines.png"  # loopcheck run --engines: every engine's |Δq̇| against the reference


def output_name(engine: str) -> str:
    """The name under which the report files hold the run named ``engine`` (its CSV ``<name>.csv``,
    its summary in report.json): the name of the engine whose run it is (a user's own model run as
    written is MuJoCo's: :attr:`loopcheck.registry.Engine.runs`)."""
    owner = engine_of_run(engine)
    return owner.name if owner is not None else engine


def report_files(animate: bool = False, *, other: str = DEFAULT_ENGINES[1], engines: bool = False) -> tuple[str, ...]:
    """The names ``write_outputs`` writes: the CSV of the engine ``other`` compared with the
    reference (``<other>.csv``), the animation and the engines' plot when asked for."""
    files = tuple(f"{other}.csv" if name == REPORT_FILES[1] else name for name in REPORT_FILES[:-1])
    return (files + ((ANIMATION_FILE,) if animate else ()) + ((ENGINES_PLOT,) if engines else ())
            + REPORT_FILES[-1:])


def resolve_animation(animate: bool) -> bool:
    """Whether ``loopcheck run --animate`` writes mechanism.gif: asked for, and matplotlib's
    PillowWriter available (pillow is a dependency of matplotlib, so normally it is); when
    it is not, a warning says so and the run goes on without the GIF."""
    if not animate:
        return False
    from .draw import gif_writer_available

    if gif_writer_available():
        return True
    warnings.warn(f"--animate: matplotlib's PillowWriter is not available (pillow is not installed); "
                  f"{ANIMATION_FILE} is not written")
    return False


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def engine_summary(result: EngineResult, peak: Peak | None = None) -> dict:
    """The per-engine part of the report. ``peak`` is the event reported (default the run's
    own, ``result.peak``); a comparison passes its compared peak, the same event in both
    engines (``Difference.peak_reference``/``peak_other``)."""
    peak = result.peak if peak is None else peak
    summary = {
        "peak_omega": peak.omega,
        "t_peak": peak.time,
        "peak_still_rising": peak.still_rising,
        "wall_s": result.wall_s,
        "n_steps": result.n_steps,
        "n_evaluations": result.n_evaluations,
        "settings": settings_dict(result.settings),
        "details": result.details.as_dict(),
        "energy_residual": result.audit.max_abs_residual,
        "energy_residual_rel": result.audit.relative_residual,
        "effects": list(result.effects),
    }
    if result.constraint_violation is not None:
        summary["max_constraint_violation"] = result.constraint_violation.max
    return summary


def engines_report(c: "Comparison", check: "EnginesCheck | None" = None) -> list[dict]:
    """report.json's ``engines``: each engine judged against the reduced reference (``check``'s
    verdicts; without one, the engine of ``c`` alone): ``engine``, ``passed``, its compared peak
    ``peak_omega`` (signed) and ``peak_omega_rel``, ``q_max_abs``, ``omega_max_abs`` (null when it
    did not run), the ``tolerances`` it was judged by, the gate's ``failures``, ``failure`` (why
    it did not run, else null), ``failed_at`` (s: the time of a failure found part-way through a
    run, a loop gap or the energy balance beyond its bound, else null) and ``known_defects`` (the
    engine's known defects that bear on the run, a failed one's too: :attr:`EngineResult.caveats`)."""
    def entry(engine: str, comparison, tolerances, failure: str | None, defects=None, failed_at=None) -> dict:
        d = comparison.diff if comparison is not None else None
        return {"engine": engine, "passed": comparison is not None and comparison.gate.passed,
                "peak_omega": d.peak_omega_other if d else None,
                **{key: _finite(getattr(d, key)) if d else None for key in ("peak_omega_rel", "q_max_abs", "omega_max_abs")},
                "tolerances": dataclasses.asdict(tolerances),
                "failures": list(comparison.gate.failures) if comparison is not None else [], "failure": failure,
                "failed_at": failed_at,
                "known_defects": list(comparison.other.caveats if defects is None else defects)}

    if check is None:
        return [entry(output_name(c.other.engine), c, c.gate.tolerances, None)]
    return [entry(v.engine, v.comparison, v.tolerances, v.failure, v.known_defects, v.failed_at)
            for v in check.verdicts]


def inputs_report(c: "Comparison") -> list[dict]:
    """report.json's ``inputs``: per input of the scene, in order, its ``name``, ``unit``, the compared
    peak (``peak_omega`` signed, ``t_peak``, ``peak_still_rising``) of the ``reference`` and of the
    ``other`` engine (``reference_engine`` and ``other_engine`` name them), and its ``diff`` figures
    (:meth:`loopcheck.compare.diff.Difference.figures`)."""
    out = []
    for name, unit, d in zip(c.scene.inputs, c.scene.input_units(), c.diffs):
        peaks = {role: {"peak_omega": p.omega, "t_peak": p.time, "peak_still_rising": p.still_rising}
                 for role, p in (("reference", d.peak_reference), ("other", d.peak_other))}
        out.append({"name": name, "unit": unit, **peaks, "diff": {k: _finite(v) for k, v in d.figures().items()}})
    return out


def report_dict(c: "Comparison", joints: Sequence[str] | None = None, engines: "EnginesCheck | None" = None,
                extraction: dict | None = None) -> dict:
    """The comparison as plain JSON-serialisable data; ``joints`` the joints of its ``joints``
    list (:func:`joint_report`; default every joint of the scene; none for ``()``); ``engines`` the
    check of several engines ``c`` is one of (``loopcheck run --engines``: :func:`engines_report`)."""
    s = c.scene
    names = tuple(j.name for j in s.mechanism.linkage.joints) if joints is None else tuple(joints)
    return {
        "schema_version": SCHEMA_VERSION,
        "scene": {"name": s.name, "source": portable_source(s.source), "description": s.description,
                  "effects": list(s.effects), "input_joint": s.mechanism.linkage.input_joint,
                  "input_unit": s.input_unit, "q0": s.q0, "qdot0": s.qdot0, "inputs": list(s.inputs),
                  "input_units": list(s.input_units()), "initial_q": list(s.initial_q()),
                  "initial_qdot": list(s.initial_qdot()), "mode": list(s.mode), "horizon": s.horizon},
        "reference_engine": output_name(c.reference.engine),
        "other_engine": output_name(c.other.engine),
        output_name(c.reference.engine): engine_summary(c.reference, c.diff.peak_reference),
        output_name(c.other.engine): engine_summary(c.other, c.diff.peak_other),
        "diff": {**{k: _finite(v) for k, v in c.diff.figures().items()},
                 "mode_mismatches": list(c.modes.mismatches),
                 "mode_mismatch_first_times": list(c.modes.first_times),
                 "mode_mismatches_total": c.modes.total},
        "gate": {"passed": c.gate.passed, "failures": list(c.gate.failures),
                 "tolerances": {"peak_omega_rtol": c.gate.tolerances.peak_omega_rtol,
                                "q_atol": c.gate.tolerances.q_atol,
                                "omega_atol": c.gate.tolerances.omega_atol,
                                "omega_vs_q_atol": c.gate.tolerances.omega_vs_q_atol}},
        "inputs": inputs_report(c),
        "joints": joint_report(c, names) if names else [],
        "engines": engines_report(c, engines),
        "outlier": engines.outlier if engines is not None else None,
        **({"extraction": extraction} if extraction is not None else {}),
    }


# A scene of at most this many joints gets every joint's columns in the CSVs by default; a larger
# one the inputs' alone, unless ``loopcheck run --joints`` names others (report.json lists every joint).
JOINTS_BY_DEFAULT = 12


def joint_columns(scene: Scene, names: Sequence[str] | None = None) -> tuple[str, ...]:
    """The joints whose own coordinate and rate the CSVs carry, in the description's order:
    ``names`` and the input joints when names are given, else every joint of a scene of at most
    :data:`JOINTS_BY_DEFAULT` joints, else the input joints alone (``report.json`` lists every joint).

    Raises
    ------
    ValueError
        If a name is not one of the scene's joints (``--joints`` names it).
    """
    linkage = scene.mechanism.linkage
    every = [j.name for j in linkage.joints]
    if names is None:
        return tuple(every) if len(every) <= JOINTS_BY_DEFAULT else tuple(n for n in every if n in linkage.inputs)
    for name in names:
        if name not in every:
            raise ValueError(f"--joints: {name!r} is not a joint of the scene; its joints are {', '.join(every)}")
    chosen = {*linkage.inputs, *names}
    return tuple(name for name in every if name in chosen)


def joint_unit(scene: Scene, name: str) -> str:
    """"m" for a prismatic joint's displacement, "rad" for a revolute joint's relative angle."""
    return "m" if isinstance(scene.mechanism.linkage.joint_map[name], PrismaticJoint) else "rad"


def _joint_rows(scene: Scene, names: Sequence[str]) -> np.ndarray:
    """(len(names), n): each named joint's row u = row·x (:attr:`loopcheck.kinematics.LoopSystem.joint_rows`)."""
    system = loops.compile_linkage(scene.mechanism.linkage)
    return np.array([system.joint_row(name) for name in names]).reshape(len(names), system.n)


def joint_values(scene: Scene, joints: "JointTrajectory", t: np.ndarray,
                 names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Each named joint's own coordinate u and rate u̇ at the samples ``t`` of the engine's input
    trajectory, shapes (len(t), len(names)): u = row·x and u̇ = row·ẋ from the engine's body
    poses and rates (:attr:`loopcheck.kinematics.LoopSystem.joint_rows`: θ_b − θ_a of a revolute joint,
    cut or not; s of a prismatic one). A time the trajectory repeats (a load edge) takes the
    joints' first sample there: positions and rates are continuous."""
    rows = _joint_rows(scene, names)
    index = np.minimum(np.searchsorted(joints.t, t, side="left"), len(joints.t) - 1)
    if not np.array_equal(joints.t[index], t):
        raise ValueError("the engine's joint samples are not at its trajectory's times")
    return joints.x[index] @ rows.T, joints.xdot[index] @ rows.T


def joint_report(c: "Comparison", names: Sequence[str]) -> list[dict]:
    """Per named joint: its type, unit, whether it is cut, each engine's range of u and largest
    |u̇| (by engine name), and the largest differences MuJoCo (or the other engine) − reduced of u
    and u̇ on its samples (the
    reference's body poses interpolated there: :meth:`loopcheck.reduced.charts.JointTrajectory.interpolate`)."""
    linkage = c.scene.mechanism.linkage
    out = []
    ref_t, mj_t = c.reference.trajectory.t, c.other.trajectory.t
    ru, rv = joint_values(c.scene, c.reference.joints, ref_t, names)
    mu, mv = joint_values(c.scene, c.other.joints, mj_t, names)
    inside = (mj_t >= ref_t[0]) & (mj_t <= ref_t[-1])
    x_ref, xdot_ref = c.reference.joints.interpolate(mj_t[inside])
    rows = _joint_rows(c.scene, names)
    u_ref, v_ref = x_ref @ rows.T, xdot_ref @ rows.T
    du, dv = np.abs(mu[inside] - u_ref), np.abs(mv[inside] - v_ref)
    for k, name in enumerate(names):
        engines = {}
        for engine, u, v in ((output_name(c.reference.engine), ru, rv), (output_name(c.other.engine), mu, mv)):
            engines[engine] = {"min": float(np.min(u[:, k])), "max": float(np.max(u[:, k])),
                               "final": float(u[-1, k]), "rate_max_abs": float(np.max(np.abs(v[:, k])))}
        out.append({"name": name, "type": "prismatic" if joint_unit(c.scene, name) == "m" else "revolute",
                    "unit": joint_unit(c.scene, name), "cut": name in linkage.cut_joints, **engines,
                    "diff_max_abs": _finite(float(np.max(du[:, k]))) if len(du) else None,
                    "rate_diff_max_abs": _finite(float(np.max(dv[:, k]))) if len(dv) else None})
    return out


def _write_csv(result: EngineResult, path: Path, unit: str = "rad", scene: Scene | None = None,
               joints: Sequence[str] = ()) -> None:
    """The input coordinate's trajectory: t (s), q, q̇, q̈ in ``unit`` ("rad" or "m"); then, for
    each of ``joints``, its own coordinate and rate (``<joint>_rad``, ``<joint>_rate_rad_per_s``,
    or ``_m``, ``_rate_m_per_s`` for a prismatic joint: :func:`joint_values`)."""
    tr = result.trajectory
    columns = [tr.t, tr.q, tr.qdot, tr.qddot]
    header = f"t_s,q_{unit},qdot_{unit}_per_s,qddot_{unit}_per_s2"
    if joints:
        u, v = joint_values(scene, result.joints, tr.t, joints)
        for k, name in enumerate(joints):
            ju = joint_unit(scene, name)
            columns += [u[:, k], v[:, k]]
            header += f",{name}_{ju},{name}_rate_{ju}_per_s"
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=header, comments="", fmt="%.17g")


def write_outputs(c: "Comparison", out_dir: str | Path, *, animate: bool = False,
                  joints: Sequence[str] | None = None, engines: "EnginesCheck | None" = None,
                  committed=None, extraction: dict | None = None) -> list[Path]:
    """Write report.json, reduced.csv, mujoco.csv (``<engine>.csv`` of the engine ``c`` compares
    with the reference) and the PNG plots (with the mechanism strip) into ``out_dir``, as a set;
    with ``animate``, also mechanism.gif (the caller checks
    :func:`loopcheck.compare.draw.gif_writer_available` first); with ``engines`` (the check of several
    engines ``c`` is one of), engines.png and each engine's verdict in report.json. The CSVs carry
    the coordinates of the joints :func:`joint_columns` picks from ``joints``, report.json those of every joint.
    ``committed``: as :func:`loopcheck.compare.output.write_folder`'s (the command's "wrote" line).
    ``extraction``: report.json's ``extraction`` (``--loop``: what was welded and dropped), when given.

    Raises
    ------
    OutputError
        If ``out_dir`` cannot receive them (nothing is then written).
    """
    unit = c.scene.input_unit
    names = joint_columns(c.scene, joints)
    files = {"reduced.csv": lambda p: _write_csv(c.reference, p, unit, c.scene, names),
             f"{output_name(c.other.engine)}.csv": lambda p: _write_csv(c.other, p, unit, c.scene, names)}
    files.update({name: (lambda p, plot=plot: plot(c, p)) for name, plot in PLOTS.items()})
    if animate:
        from .draw import animate_run
        from .text import engine_label

        files[ANIMATION_FILE] = lambda p: animate_run(c.scene, c.reference.joints, c.other.joints, p,
                                                      other_label=engine_label(c.other.engine))
    if engines is not None:
        files[ENGINES_PLOT] = lambda p: plot_engines(engines, p)
    files["report.json"] = lambda p: p.write_text(json_text(report_dict(c, None, engines, extraction)), encoding="utf-8")
    return write_folder(out_dir, files, workers=min(2, os.cpu_count() or 1), one_run=True, committed=committed)
