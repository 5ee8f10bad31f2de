"""``report.json``, trajectory CSVs and plots of a comparison, written all-or-nothing.

The files are written through :func:`compare.output.write_folder`: staged in a fresh
hidden folder and replaced as a set, so a failure or an interrupt part-way leaves the
output folder as it was. ``report.json`` is strict JSON (non-finite numbers are null) and
names the scene file relative to the working directory, never by an absolute path.
The schema is documented in the README ("report.json").
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from reduced import EngineResult

from .output import json_text, portable_source, write_folder
from .plots import PLOTS
from .run import Comparison

SCHEMA_VERSION = 1
REPORT_FILES = ("reduced.csv", "mujoco.csv", *PLOTS, "report.json")  # in the order they are committed


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


def report_dict(c: Comparison) -> dict:
    """The comparison as plain JSON-serialisable data."""
    s = c.scene
    return {
        "schema_version": SCHEMA_VERSION,
        "scene": {"name": s.name, "source": portable_source(s.source), "description": s.description,
                  "effects": list(s.effects), "q0": s.q0, "qdot0": s.qdot0, "horizon": s.horizon},
        "reduced": engine_summary(c.reduced),
        "mujoco": engine_summary(c.mujoco),
        "diff": {**{k: _finite(v) for k, v in c.diff.figures().items()},
                 "branch_mismatches": c.branches.mismatches, "branch_mismatch_first_time": c.branches.first_time},
        "gate": {"passed": c.gate.passed, "failures": list(c.gate.failures),
                 "tolerances": {"peak_omega_rtol": c.gate.tolerances.peak_omega_rtol,
                                "q_atol": c.gate.tolerances.q_atol,
                                "omega_atol": c.gate.tolerances.omega_atol,
                                "omega_vs_q_atol": c.gate.tolerances.omega_vs_q_atol}},
    }


def _write_csv(result: EngineResult, path: Path) -> None:
    tr = result.trajectory
    np.savetxt(path, np.column_stack([tr.t, tr.q, tr.qdot, tr.qddot]), delimiter=",",
               header="t_s,q_rad,qdot_rad_per_s,qddot_rad_per_s2", comments="", fmt="%.17g")


def write_outputs(c: Comparison, out_dir: str | Path) -> list[Path]:
    """Write report.json, reduced.csv, mujoco.csv and the PNG plots into ``out_dir``, as a set.

    Raises
    ------
    OutputError
        If ``out_dir`` cannot receive them (nothing is then written).
    """
    files = {"reduced.csv": lambda p: _write_csv(c.reduced, p),
             "mujoco.csv": lambda p: _write_csv(c.mujoco, p)}
    files.update({name: (lambda p, plot=plot: plot(c, p)) for name, plot in PLOTS.items()})
    files["report.json"] = lambda p: p.write_text(json_text(report_dict(c)), encoding="utf-8")
    return write_folder(out_dir, files)
