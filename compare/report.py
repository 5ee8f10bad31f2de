"""``report.json``, trajectory CSVs and plots of a comparison, written all-or-nothing.

Everything is first written into a fresh temporary folder beside the output folder and
then moved into place, ``report.json`` last; a failure part-way leaves no partial report.
The schema is documented in the README ("report.json").
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from reduced import EngineResult

from .run import Comparison

SCHEMA_VERSION = 1


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
        "scene": {"name": s.name, "source": s.source, "description": s.description,
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
    """Write report.json, reduced.csv, mujoco.csv and the PNG plots into ``out_dir``."""
    from .plots import PLOTS

    out = Path(out_dir)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".xval-", dir=out))
    try:
        _write_csv(c.reduced, staging / "reduced.csv")
        _write_csv(c.mujoco, staging / "mujoco.csv")
        for name, plot in PLOTS.items():
            plot(c, staging / name)
        (staging / "report.json").write_text(json.dumps(report_dict(c), indent=2) + "\n", encoding="utf-8")
        names = ["reduced.csv", "mujoco.csv", *PLOTS, "report.json"]
        for name in names:
            os.replace(staging / name, out / name)
        return [out / n for n in names]
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        if created:
            shutil.rmtree(out, ignore_errors=True)
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
