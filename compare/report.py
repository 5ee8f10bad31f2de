"""``report.json``, trajectory CSVs and plots of a comparison, written all-or-nothing.

The files are written through :func:`compare.output.write_folder`: staged in a fresh
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
(``q_rad`` or ``q_m``).

``xval run --animate`` adds ``mechanism.gif`` (:data:`ANIMATION_FILE`) to the set.
"""

from __future__ import annotations

import math
import warnings
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from reduced.result import EngineResult

from .output import json_text, portable_source, write_folder
from .plots import PLOTS
if TYPE_CHECKING:
    from .run import Comparison

SCHEMA_VERSION = 2
REPORT_FILES = ("reduced.csv", "mujoco.csv", *PLOTS, "report.json")  # in the order they are committed
ANIMATION_FILE = "mechanism.gif"


def report_files(animate: bool = False) -> tuple[str, ...]:
    """The names ``write_outputs`` writes, with the animation when asked for."""
    return REPORT_FILES[:-1] + ((ANIMATION_FILE,) if animate else ()) + REPORT_FILES[-1:]


def resolve_animation(animate: bool) -> bool:
    """Whether ``xval run --animate`` writes mechanism.gif: asked for, and matplotlib's
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


def engine_summary(result: EngineResult) -> dict:
    """The per-engine part of the report."""
    summary = {
        "peak_omega": result.peak.omega,
        "t_peak": result.peak.time,
        "wall_s": result.wall_s,
        "n_steps": result.n_steps,
        "n_evaluations": result.n_evaluations,
        "settings": result.settings,
        "energy_residual": result.audit.max_abs_residual,
        "energy_residual_rel": result.audit.relative_residual,
        "effects": result.diagnostics.get("effects", []),
    }
    if "max_constraint_violation" in result.diagnostics:
        summary["max_constraint_violation"] = result.diagnostics["max_constraint_violation"]
        summary["warnings"] = result.diagnostics.get("edge_warnings", [])
    return summary


def report_dict(c: "Comparison") -> dict:
    """The comparison as plain JSON-serialisable data."""
    s = c.scene
    return {
        "schema_version": SCHEMA_VERSION,
        "scene": {"name": s.name, "source": portable_source(s.source), "description": s.description,
                  "effects": list(s.effects), "input_joint": s.mechanism.linkage.input_joint,
                  "input_unit": s.input_unit, "q0": s.q0, "qdot0": s.qdot0, "mode": list(s.mode),
                  "horizon": s.horizon},
        "reduced": engine_summary(c.reduced),
        "mujoco": engine_summary(c.mujoco),
        "diff": {**{k: _finite(v) for k, v in c.diff.figures().items()},
                 "mode_mismatches": list(c.modes.mismatches),
                 "mode_mismatch_first_times": list(c.modes.first_times),
                 "mode_mismatches_total": c.modes.total},
        "gate": {"passed": c.gate.passed, "failures": list(c.gate.failures),
                 "tolerances": {"peak_omega_rtol": c.gate.tolerances.peak_omega_rtol,
                                "q_atol": c.gate.tolerances.q_atol,
                                "omega_atol": c.gate.tolerances.omega_atol,
                                "omega_vs_q_atol": c.gate.tolerances.omega_vs_q_atol}},
    }


def _write_csv(result: EngineResult, path: Path, unit: str = "rad") -> None:
    """The input coordinate's trajectory: t (s), q, q̇, q̈ in ``unit`` ("rad" or "m")."""
    tr = result.trajectory
    np.savetxt(path, np.column_stack([tr.t, tr.q, tr.qdot, tr.qddot]), delimiter=",",
               header=f"t_s,q_{unit},qdot_{unit}_per_s,qddot_{unit}_per_s2", comments="", fmt="%.17g")


def write_outputs(c: "Comparison", out_dir: str | Path, *, animate: bool = False) -> list[Path]:
    """Write report.json, reduced.csv, mujoco.csv and the PNG plots (with the mechanism
    strip) into ``out_dir``, as a set; with ``animate``, also mechanism.gif (the caller
    checks :func:`compare.draw.gif_writer_available` first).

    Raises
    ------
    OutputError
        If ``out_dir`` cannot receive them (nothing is then written).
    """
    unit = c.scene.input_unit
    files = {"reduced.csv": lambda p: _write_csv(c.reduced, p, unit),
             "mujoco.csv": lambda p: _write_csv(c.mujoco, p, unit)}
    files.update({name: (lambda p, plot=plot: plot(c, p)) for name, plot in PLOTS.items()})
    if animate:
        from .draw import animate_run

        files[ANIMATION_FILE] = lambda p: animate_run(c.scene, c.reduced.diagnostics["joints"],
                                                      c.mujoco.diagnostics["joints"], p)
    files["report.json"] = lambda p: p.write_text(json_text(report_dict(c)), encoding="utf-8")
    return write_folder(out_dir, files, workers=min(2, os.cpu_count() or 1), one_run=True)
