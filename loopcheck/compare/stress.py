"""Hard cases: a catalogue of scenes under ``scenes/hard/`` and what each engine does with them.

Every case runs both engines with the scene's own settings and gate, plus the checks its
kind of difficulty calls for (coordinate switches at dead centres, stability detection for
stiff dampers, energy drift over long runs, the error of an off-grid pulse edge).
A case passes when each engine ends with the status it is expected to have and every check
holds. Nothing is skipped and nothing is marked as expected to fail.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from loopcheck.errors import NumericalFailure
from loopcheck.reduced import ReducedSettings, simulate
from loopcheck.scene import Scene
from loopcheck.scenefile import load_scene
from loopcheck.loads import PulseLoad
from loopcheck.shipped_scenes import scenes_dir
from loopcheck.reference_models import INTEGRATORS, MujocoSettings, simulate_mujoco

from loopcheck.results import EngineResult

from .diff import compare_trajectories
from .run import Comparison, judge
from .settings import mujoco_settings as resolve_mujoco, reduced_settings as resolve_reduced

PROBE_TIMESTEPS = (1e-3, 1e-4, 1e-5)


@dataclass(frozen=True)
class Case:
    """One hard case and what must happen."""

    name: str
    scene_file: str
    must_switch: bool = False  # the reduced solver must change coordinate and stay continuous
    explicit_step: float | None = None  # run RKN4 at this step too ...
    explicit_expect: str = "ok"  # ... and expect this status ("unstable": detected, not returned)
    probe_integrators: bool = False  # report MuJoCo's stability per integrator and timestep
    energy_drift: bool = False  # conservative: report drift per revolution, bound the reduced one
    off_grid_edge: bool = False  # quantify the error of a pulse edge off MuJoCo's step grid

    @property
    def path(self) -> Path:
        return scenes_dir() / self.scene_file


CATALOGUE = (
    Case("dead_centre", "hard/dead_centre.toml", must_switch=True),
    Case("start_dead_centre", "hard/start_dead_centre.toml"),
    Case("near_change_point", "hard/near_change_point.toml"),
    Case("stiff_damper", "hard/stiff_damper.toml", explicit_step=1e-3, explicit_expect="unstable",
         probe_integrators=True),
    Case("long_conservative", "hard/long_conservative.toml", energy_drift=True),
    Case("fast_crank", "hard/fast_crank.toml"),
    Case("off_grid_edge", "hard/off_grid_edge.toml", off_grid_edge=True),
    Case("gravity", "hard/gravity.toml", energy_drift=True),
    # General linkages: a slider-driven slider-crank through its dead centres (the slide cannot
    # drive there: the reduced solver must change coordinate), a six-bar near a toggle.
    Case("slider_dead_centres", "mechanisms/slider_crank_driven_slider.toml", must_switch=True),
    Case("sixbar_near_toggle", "mechanisms/stephenson3_near_toggle.toml"),
)


@dataclass(frozen=True)
class CaseResult:
    """What happened to one case."""

    name: str
    passed: bool
    reduced_status: str  # "ok" or a failure reason
    mujoco_status: str
    problems: tuple[str, ...]  # why the case did not pass (empty when it did)
    figures: dict = field(default_factory=dict)  # peak_omega_rel, q_max_abs, violation, drift, walls
    notes: tuple[str, ...] = ()  # what the case showed, in words
    reduced: EngineResult | None = field(default=None, repr=False)  # the runs, kept for the tests
    mujoco: EngineResult | None = field(default=None, repr=False)
    comparison: Comparison | None = field(default=None, repr=False)  # when both engines finished


def _run(engine_call):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return engine_call(), "ok", ""
    except NumericalFailure as exc:
        return None, exc.reason, str(exc)


def _drift_per_revolution(result) -> float:
    """|E(T) − E(0)| / E(0) per revolution of the input (conservative scenes)."""
    a = result.audit
    energy = a.kinetic + a.potential
    scale = max(a.scale, abs(energy[0]), 1e-300)
    revolutions = max(abs(result.trajectory.q[-1] - result.trajectory.q[0]) / (2 * math.pi), 1.0)
    return float(abs(energy[-1] - energy[0]) / scale / revolutions)


def run_case(case: Case) -> CaseResult:
    """Run one case: both engines, the gate and the case's own checks."""
    scene = load_scene(case.path)
    scene = replace(scene, tolerances=scene.tolerances_for("mujoco"))  # MuJoCo's gate, its automatic step's target
    reduced_settings = resolve_reduced(scene)
    mujoco_settings = resolve_mujoco(scene)
    problems, notes, figures = [], [], {}

    reduced, r_status, r_message = _run(lambda: simulate(scene, reduced_settings))
    mujoco, m_status, m_message = _run(lambda: simulate_mujoco(scene, mujoco_settings))
    if reduced is None:
        problems.append(f"reduced solver failed: {r_message}")
    if mujoco is None:
        problems.append(f"MuJoCo failed: {m_message}")

    comparison = None
    if reduced is not None and mujoco is not None:
        comparison = judge(scene, reduced, mujoco, scene.tolerances)
        diff, modes = comparison.diff, comparison.modes
        problems += [f"gate: {f}" for f in comparison.gate.failures]
        figures.update(peak_omega_rel=diff.peak_omega_rel, peak_omega_abs=diff.peak_omega_abs,
                       t_peak_abs=diff.t_peak_abs, q_max_abs=diff.q_max_abs,
                       omega_max_abs=diff.omega_max_abs, omega_vs_q_max_abs=diff.omega_vs_q_max_abs,
                       span_end=diff.span_end, mode_mismatches=modes.total)
    if reduced is not None:
        figures.update(reduced_wall_s=reduced.wall_s, reduced_energy_residual=reduced.audit.relative_residual,
                       switches=len(reduced.details.switches))
    if mujoco is not None:
        figures.update(mujoco_wall_s=mujoco.wall_s, mujoco_energy_residual=mujoco.audit.relative_residual,
                       constraint_violation=mujoco.constraint_violation.max)

    if case.must_switch and reduced is not None:
        problems += _check_switches(reduced, notes)
    if case.explicit_step is not None:
        problems += _check_explicit(scene, case, notes, figures)
    if case.probe_integrators:
        figures["mujoco_stability"] = _probe_integrators(scene, notes)
    if case.energy_drift:
        for name, result in (("reduced", reduced), ("mujoco", mujoco)):
            if result is not None:
                figures[f"{name}_drift_per_revolution"] = _drift_per_revolution(result)
        if reduced is not None:
            problems += _check_reduced_drift(reduced, reduced_settings, figures, notes)
    if case.off_grid_edge and mujoco is not None and reduced is not None:
        problems += _quantify_off_grid_edge(scene, mujoco_settings, figures, notes)

    return CaseResult(case.name, not problems, r_status, m_status, tuple(problems), figures, tuple(notes),
                      reduced=reduced, mujoco=mujoco, comparison=comparison)


def _check_switches(reduced, notes: list) -> list[str]:
    switches = reduced.details.switches
    joints = reduced.joints
    if not switches:
        return ["the reduced solver never switched coordinate"]
    same_time = np.diff(joints.t) == 0.0
    jump_x = float(np.max(np.abs(np.diff(joints.x, axis=0))[same_time])) if same_time.any() else 0.0
    jump_v = float(np.max(np.abs(np.diff(joints.xdot, axis=0))[same_time])) if same_time.any() else 0.0
    changes = int(np.sum(np.any(joints.mode[1:] != joints.mode[:-1], axis=-1)))
    notes.append(f"{len(switches)} coordinate switches ({', '.join(sorted({s.new for s in switches}))}), "
                 f"{changes} assembly-mode changes tracked; largest jump across a switch: "
                 f"{jump_x:.1e} (rad or m), {jump_v:.1e} (rad or m)/s")
    # Across a switch the state is the same instant seen in two charts: only round-off differs.
    return [] if jump_x < 1e-12 and jump_v < 1e-9 else [f"discontinuity across a switch: {jump_x:.2e} (rad or m), "
                                                        f"{jump_v:.2e} (rad or m)/s"]


def _check_explicit(scene: Scene, case: Case, notes: list, figures: dict) -> list[str]:
    _, status, message = _run(lambda: simulate(scene, ReducedSettings(method="rkn4", step=case.explicit_step)))
    figures["rkn4_status"] = status
    notes.append(f"RKN4 at h = {case.explicit_step:g} s: {status}" + (f" ({message[:110]}...)" if message else ""))
    if status != case.explicit_expect:
        return [f"RKN4 at h = {case.explicit_step:g} s ended '{status}', expected '{case.explicit_expect}'"]
    return []


def _probe_integrators(scene: Scene, notes: list) -> dict:
    table = {}
    for integrator in INTEGRATORS:
        for h in PROBE_TIMESTEPS:
            settings = MujocoSettings(integrator=integrator, timestep=h)
            _, status, _ = _run(lambda settings=settings: simulate_mujoco(scene, settings))
            table[f"{integrator}@{h:g}"] = status
    stable = {i: [h for h in PROBE_TIMESTEPS if table[f"{i}@{h:g}"] == "ok"] for i in INTEGRATORS}
    notes.append("MuJoCo stable at: " + "; ".join(
        f"{i} {', '.join(f'{h:g}' for h in hs) or 'none'}" for i, hs in stable.items()) + " s")
    return table


def _check_reduced_drift(reduced, settings: ReducedSettings, figures: dict, notes: list) -> list[str]:
    """Bound: an adaptive method keeps each step's local error below rtol (relative to the
    state), so energy can drift by at most about rtol per step; per revolution the bound is
    rtol × (steps per revolution). For RKN4 the same reasoning with its own error is not a
    bound, so only adaptive references are held to it."""
    drift = figures["reduced_drift_per_revolution"]
    revolutions = max(abs(reduced.trajectory.q[-1] - reduced.trajectory.q[0]) / (2 * math.pi), 1.0)
    bound = settings.rtol * reduced.n_steps / revolutions
    figures["reduced_drift_bound"] = bound
    span = f"{revolutions:.0f} revolutions" if revolutions > 1.0 else "swinging, under one revolution"
    notes.append(f"{span}; energy drift per revolution (or over the run): reduced {drift:.1e} "
                 f"(bound {bound:.1e}), MuJoCo {figures.get('mujoco_drift_per_revolution', math.nan):.1e}")
    if settings.method != "rkn4" and not drift <= bound:
        return [f"reduced energy drift {drift:.2e} per revolution exceeds its bound {bound:.2e}"]
    return []


def _quantify_off_grid_edge(scene: Scene, settings: MujocoSettings, figures: dict, notes: list) -> list[str]:
    """MuJoCo's error with the edge off the grid against the same scene with the edge moved
    onto the grid (each against its own reduced reference)."""
    torque = scene.load
    if not isinstance(torque, PulseLoad):
        return ["off-grid case needs a pulse torque"]
    h = settings.timestep
    on_grid = replace(scene, load=replace(torque, duration=round(torque.duration / h) * h))

    def error(s: Scene):
        reference = simulate(s, resolve_reduced(s))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            other = simulate_mujoco(s, settings)
        return compare_trajectories(reference.trajectory, other.trajectory, horizon=s.horizon), caught

    off, caught = error(scene)
    on, _ = error(on_grid)
    warned = any("not a multiple of the timestep" in str(w.message) for w in caught)
    figures.update(off_grid_peak_rel=off.peak_omega_rel, on_grid_peak_rel=on.peak_omega_rel,
                   off_grid_q_max=off.q_max_abs, on_grid_q_max=on.q_max_abs)
    notes.append(f"edge {torque.start + torque.duration:g} s off the {h:g} s grid: peak error "
                 f"{off.peak_omega_rel:.1e} (on grid {on.peak_omega_rel:.1e}), max |dq| {off.q_max_abs:.1e} {scene.input_unit} "
                 f"(on grid {on.q_max_abs:.1e}); warned: {'yes' if warned else 'NO'}")
    problems = [] if warned else ["no warning for the off-grid pulse edge"]
    if not off.q_max_abs > on.q_max_abs:
        problems.append("the off-grid edge shows no extra error: the quantification is not measuring it")
    return problems


def run_catalogue(cases=CATALOGUE, progress=None) -> list[CaseResult]:
    results = []
    for case in cases:
        start = time.perf_counter()
        result = run_case(case)
        results.append(replace(result, figures={**result.figures, "case_wall_s": time.perf_counter() - start}))
        if progress:
            progress(result)
    return results


def table_lines(results: list[CaseResult]) -> list[str]:
    def f(x, fmt=".1e"):
        return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)

    header = (f"{'case':18s} {'reduced':>9s} {'mujoco':>9s} {'peak rel':>8s} {'max|dq|':>8s} "
              f"{'loop (m)':>8s} {'drift/rev':>17s} {'wall (s)':>11s}  verdict")
    lines = [header]
    for r in results:
        g = r.figures
        drift = (f"{f(g.get('reduced_drift_per_revolution'))}/{f(g.get('mujoco_drift_per_revolution'))}"
                 if "reduced_drift_per_revolution" in g else "-")
        walls = f"{f(g.get('reduced_wall_s'), '.2f')}/{f(g.get('mujoco_wall_s'), '.2f')}"
        lines.append(f"{r.name:18s} {r.reduced_status:>9s} {r.mujoco_status:>9s} {f(g.get('peak_omega_rel')):>8s} "
                     f"{f(g.get('q_max_abs')):>8s} {f(g.get('constraint_violation')):>8s} {drift:>17s} "
                     f"{walls:>11s}  {'PASS' if r.passed else 'FAIL'}")
        for note in r.notes:
            lines.append(f"{'':18s}   {note}")
        for problem in r.problems:
            lines.append(f"{'':18s}   problem: {problem}")
    lines.append(f"{sum(r.passed for r in results)} passed, {sum(not r.passed for r in results)} failed")
    return lines


STRESS_FILES = ("stress.json",)


def write_stress(results: list[CaseResult], out_dir, committed=None) -> list:
    """stress.json (one entry per case: status, problems, notes, figures) into ``out_dir``,
    through :func:`loopcheck.compare.output.write_folder`."""
    from .output import json_text, write_folder

    data = [{"case": r.name, "passed": r.passed, "reduced": r.reduced_status, "mujoco": r.mujoco_status,
             "problems": list(r.problems), "notes": list(r.notes), "figures": r.figures} for r in results]
    return write_folder(out_dir, {"stress.json": lambda p: p.write_text(json_text(data), encoding="utf-8")},
                        one_run=True, committed=committed)
