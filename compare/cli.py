"""The ``xval`` command line.

Exit status: 0 success, 1 a check failed or a run failed numerically, 2 bad input.
Bad input gets one line on stderr naming the problem, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from reduced import NumericalFailure, ReducedSettings, SceneError, default_scene_path, load_scene, simulate

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class UsageError(ValueError):
    """Bad command-line input (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit status 2)."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _scene(path: str | None):
    return load_scene(path if path else default_scene_path())


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if value != value or abs(value) == float("inf"):
        raise argparse.ArgumentTypeError(f"must be finite, got {text}")
    return value


def _positive(text: str) -> float:
    value = _finite(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def cmd_reduced(args: argparse.Namespace) -> int:
    scene = _scene(args.scene)
    settings = ReducedSettings(method=args.method, rtol=args.rtol, step=args.step)
    result = simulate(scene, settings)
    print(f"scene            {scene.name}  ({scene.source})")
    print(f"effects          {', '.join(scene.effects) or 'none'}")
    print(f"solver           {result.settings['solver']}  "
          + (f"step = {settings.step:g} s" if settings.method == "rkn4" else f"rtol = {settings.rtol:g}"))
    print(f"peak omega       {result.peak.omega:.10g} rad/s at t = {result.peak.time:.10g} s")
    print(f"energy residual  {result.audit.max_abs_residual:.3e} J "
          f"({result.audit.relative_residual:.3e} of {result.audit.scale:.6g} J)")
    print(f"cost             {result.n_steps} steps, {result.n_evaluations} evaluations, "
          f"{result.wall_s:.3f} s")
    return EXIT_OK


def _mujoco_settings(args: argparse.Namespace, scene):
    """MuJoCo settings: command-line flags over the scene's [mujoco] table over the defaults."""
    from reference_models import MujocoSettings

    kwargs = dict(scene.mujoco)
    for name in ("integrator", "timestep", "solref", "solimp", "iterations", "tolerance", "refsafe", "diagexact"):
        value = getattr(args, name)
        if value is not None:
            kwargs[name] = tuple(value) if isinstance(value, list) else value
    return MujocoSettings(**kwargs)


def cmd_mujoco(args: argparse.Namespace) -> int:
    from reference_models import simulate_mujoco

    scene = _scene(args.scene)
    settings = _mujoco_settings(args, scene)
    result = simulate_mujoco(scene, settings)
    print(f"scene            {scene.name}  ({scene.source})")
    print(f"effects          {', '.join(scene.effects) or 'none'}")
    print(f"settings         {settings.integrator}, timestep {result.settings['timestep']:g} s"
          f"{' (automatic)' if result.settings['timestep_automatic'] else ''}, "
          f"solref {tuple(result.settings['solref'])}, solimp {settings.solimp}, "
          f"refsafe {'on' if settings.refsafe else 'off'}, diagexact {'on' if settings.diagexact else 'off'}, "
          f"iterations {settings.iterations}, tolerance {settings.tolerance:g}, "
          f"MuJoCo {result.settings['mujoco_version']}")
    print(f"peak omega       {result.peak.omega:.10g} rad/s at t = {result.peak.time:.10g} s")
    print(f"loop violation   {result.diagnostics['max_constraint_violation']:.3e} m (largest over the run)")
    print(f"energy residual  {result.audit.max_abs_residual:.3e} J "
          f"({result.audit.relative_residual:.3e} of {result.audit.scale:.6g} J)")
    print(f"cost             {result.n_steps} steps, {result.wall_s:.3f} s")
    for note in result.diagnostics["edge_warnings"]:
        print(f"warning          {note}")
    return EXIT_OK


def cmd_export_mjcf(args: argparse.Namespace) -> int:
    from reference_models import export_mjcf

    scene = _scene(args.scene)
    export_mjcf(scene, args.output, _mujoco_settings(args, scene))
    print(f"wrote {args.output}")
    return EXIT_OK


def _add_mujoco_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("MuJoCo settings")
    g.add_argument("--integrator", choices=("euler", "implicit", "implicitfast", "rk4"), default=None,
                   help="MuJoCo integrator (default: the scene's [mujoco] table, else rk4)")
    g.add_argument("--timestep", type=_positive, default=None,
                   help="MuJoCo timestep in s (default: the scene's [mujoco] table, else 1e-3)")
    g.add_argument("--solref", type=_finite, nargs=2, metavar=("TIMECONST", "DAMPRATIO"), default=None,
                   help="loop constraint solref (default: 2*timestep, 1)")
    g.add_argument("--solimp", type=_finite, nargs=5, metavar=("DMIN", "DMAX", "WIDTH", "MID", "POWER"),
                   default=None, help="loop constraint solimp (default 0.9999 0.9999 0.001 0.5 2)")
    g.add_argument("--iterations", type=_positive_int, default=None, help="constraint solver iterations (default 100)")
    g.add_argument("--tolerance", type=_positive, default=None, help="constraint solver tolerance (default 1e-12)")
    g.add_argument("--no-refsafe", dest="refsafe", action="store_const", const=False, default=None,
                   help="disable refsafe (allows solref time constants below 2*timestep)")
    g.add_argument("--diagexact", action="store_const", const=True, default=None,
                   help="enable MuJoCo's exact constraint-diagonal flag")


def _reduced_reference(args: argparse.Namespace, scene) -> ReducedSettings:
    """The reduced reference: command-line flags over the scene's [reduced] table over the defaults."""
    kwargs = dict(scene.reduced)
    for flag, name in (("reference", "method"), ("reference_rtol", "rtol"), ("reference_step", "step")):
        value = getattr(args, flag)
        if value is not None:
            kwargs[name] = value
    return ReducedSettings(**kwargs)


def _tolerances(scene, args: argparse.Namespace):
    from .run import override_tolerances

    return override_tolerances(scene.tolerances, peak_omega_rtol=args.peak_rtol, q_atol=args.q_atol,
                               omega_atol=args.omega_atol, omega_vs_q_atol=args.omega_vs_q_atol)


def cmd_run(args: argparse.Namespace) -> int:
    from .report import write_outputs
    from .run import compare_engines

    scene = _scene(args.scene)
    comparison = compare_engines(scene, reduced=_reduced_reference(args, scene), mujoco=_mujoco_settings(args, scene),
                                 tolerances=_tolerances(scene, args))
    from .text import comparison_lines

    print("\n".join(comparison_lines(comparison)))
    paths = write_outputs(comparison, args.out)
    print(f"wrote {len(paths)} files to {args.out}/")
    return EXIT_OK


def cmd_check(args: argparse.Namespace) -> int:
    from .run import compare_engines

    scenes = [load_scene(path) for path in args.scenes]  # all bad input is reported before any run
    failed = 0
    for scene in scenes:
        tolerances = _tolerances(scene, args)
        try:
            c = compare_engines(scene, reduced=_reduced_reference(args, scene), mujoco=_mujoco_settings(args, scene),
                                tolerances=tolerances)
        except NumericalFailure as exc:
            failed += 1
            print(f"FAIL  {scene.source}: numerical failure ({exc.reason}): {exc}")
            continue
        d = c.diff
        status = "ok  " if c.gate.passed else "FAIL"
        failed += not c.gate.passed
        print(f"{status}  {scene.source}: peak_omega_rel {d.peak_omega_rel:.2e} (tol {tolerances.peak_omega_rtol:g}), "
              f"q_max_abs {d.q_max_abs:.2e} (tol {tolerances.q_atol:g}), "
              f"omega_max_abs {d.omega_max_abs:.2e} (tol {tolerances.omega_atol:g})")
        for failure in c.gate.failures:
            print(f"      {failure}")
    print(f"{len(scenes) - failed} passed, {failed} failed")
    return EXIT_FAILED if failed else EXIT_OK


def cmd_cost(args: argparse.Namespace) -> int:
    from .cost import (cost_report, ground_truth, ladder, recommend, summary_lines, sweep,
                       write_cost_outputs)

    scene = _scene(args.scene)
    target = args.target if args.target is not None else scene.tolerances.peak_omega_rtol
    repeats = args.repeats if args.repeats is not None else 3
    truth = ground_truth(scene)
    configs = ladder(quick=args.quick)
    measurements = sweep(scene, configs, truth, repeats=repeats, workers=args.workers)
    recommendations = recommend(scene, measurements, truth, target, repeats)
    report = cost_report(scene, truth, measurements, recommendations, repeats)
    for line in summary_lines(report, measurements):
        print(line)
    paths = write_cost_outputs(report, measurements, args.out, target)
    print(f"wrote {', '.join(p.name for p in paths)} to {args.out}/")
    return EXIT_OK


def cmd_stress(args: argparse.Namespace) -> int:
    import json

    from .stress import CATALOGUE, run_catalogue, table_lines

    cases = CATALOGUE if not args.case else [c for c in CATALOGUE if c.name in args.case]
    unknown = set(args.case or ()) - {c.name for c in CATALOGUE}
    if unknown:
        raise UsageError(f"unknown case {sorted(unknown)[0]!r}; cases: {', '.join(c.name for c in CATALOGUE)}")
    results = run_catalogue(cases, progress=lambda r: print(f"  {r.name}: {'pass' if r.passed else 'FAIL'}",
                                                           file=sys.stderr, flush=True))
    for line in table_lines(results):
        print(line)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data = [{"case": r.name, "passed": r.passed, "reduced": r.reduced_status, "mujoco": r.mujoco_status,
             "problems": list(r.problems), "notes": list(r.notes), "figures": r.figures} for r in results]
    tmp = out / ".stress.json.tmp"
    tmp.write_text(json.dumps(data, indent=2, default=float) + "\n", encoding="utf-8")
    tmp.replace(out / "stress.json")
    print(f"wrote {out / 'stress.json'}")
    return EXIT_OK if all(r.passed for r in results) else EXIT_FAILED


def _add_reference_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("reduced reference")
    g.add_argument("--reference", choices=("dop853", "rkn4", "radau"), default=None,
                   help="reduced solver used as the reference (default: the scene's [reduced] table, else dop853)")
    g.add_argument("--reference-rtol", type=_positive, default=None,
                   help="tolerance of an adaptive reference (default 1e-12)")
    g.add_argument("--reference-step", type=_positive, default=None,
                   help="step of an rkn4 reference in s (default 1e-3)")


def _add_tolerance_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("gate tolerances (override the scene's [tolerances] table)")
    g.add_argument("--peak-rtol", type=_positive, default=None, help="relative difference of peak omega")
    g.add_argument("--q-atol", type=_positive, default=None, help="max |dq| in rad")
    g.add_argument("--omega-atol", type=_positive, default=None, help="max |domega| in rad/s")
    g.add_argument("--omega-vs-q-atol", type=_positive, default=None,
                   help="max |domega| at equal crank angle in rad/s (phase-free)")


def _add_comparison_arguments(p: argparse.ArgumentParser) -> None:
    _add_reference_arguments(p)
    _add_mujoco_arguments(p)
    _add_tolerance_arguments(p)


def _add_scene_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", default=None,
                   help="scene TOML file (default: scenes/seed_fourbar.toml, the seed example)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="xval",
        description="Solve a one-DOF mechanism two ways (Eksergian's equation and MuJoCo) and "
                    "say how far apart they are.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("reduced", help="solve the scene's Eksergian equation",
                       description="Solve the scene's Eksergian equation; print the peak angular "
                                   "velocity of the input link, its time and the energy residual.")
    _add_scene_argument(p)
    p.add_argument("--method", choices=("dop853", "rkn4", "radau"), default="dop853",
                   help="adaptive DOP853 (default), fixed-step RKN4, or implicit Radau")
    p.add_argument("--rtol", type=_positive, default=1e-12, help="tolerance of adaptive methods (default 1e-12)")
    p.add_argument("--step", type=_positive, default=1e-3, help="step of RKN4 in s (default 1e-3)")
    p.set_defaults(func=cmd_reduced)

    p = sub.add_parser("mujoco", help="run the scene's MuJoCo model",
                       description="Run the scene's MuJoCo model (open chain closed by an equality "
                                   "constraint); print the peak angular velocity of the crank, its "
                                   "time, the largest loop-constraint violation and the energy residual.")
    _add_scene_argument(p)
    _add_mujoco_arguments(p)
    p.set_defaults(func=cmd_mujoco)

    p = sub.add_parser("export-mjcf", help="write the scene's MuJoCo model as MJCF",
                       description="Write the scene's MuJoCo model as a human-readable MJCF file "
                                   "that MuJoCo loads on its own.")
    _add_scene_argument(p)
    p.add_argument("-o", "--output", required=True, help="MJCF file to write")
    _add_mujoco_arguments(p)
    p.set_defaults(func=cmd_export_mjcf)

    p = sub.add_parser("run", help="run both engines, compare, write report and plots",
                       description="Run the scene through the reduced solver and MuJoCo, print a "
                                   "table of both results and their differences, and write "
                                   "report.json, reduced.csv, mujoco.csv and PNG plots into --out.")
    _add_scene_argument(p)
    p.add_argument("--out", default="xval-out", help="output folder (default ./xval-out)")
    _add_comparison_arguments(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("check", help="CI gate: exit 1 if the engines disagree beyond tolerance",
                       description="Run both engines on each scene and compare the differences "
                                   "against the scene's [tolerances] (flags override). Exit 0 when "
                                   "every scene passes, 1 when any fails, 2 on bad input.")
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene TOML files")
    _add_comparison_arguments(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("cost", help="work-precision study: what accuracy costs in time",
                       description="Sweep both engines over steps, tolerances, MuJoCo integrators and "
                                   "constraint softness; measure errors against the reduced truth "
                                   "(DOP853 rtol 1e-12) and the median wall time of the simulation; "
                                   "write cost.png (work-precision diagram), cost.csv and cost.json; "
                                   "recommend the cheapest configuration of each engine for the target.")
    _add_scene_argument(p)
    p.add_argument("--out", default="xval-out", help="output folder (default ./xval-out)")
    p.add_argument("--quick", action="store_true", help="a small ladder that runs in a few seconds")
    p.add_argument("--target", type=_positive, default=None,
                   help="target relative peak-omega error (default: the scene's peak_omega_rtol)")
    p.add_argument("--repeats", type=_positive_int, default=None, help="timed runs per configuration (default 3)")
    p.add_argument("--workers", type=_positive_int, default=None, help="processes (default: all cores)")
    p.set_defaults(func=cmd_cost)

    p = sub.add_parser("stress", help="run the hard-case catalogue (scenes/hard/)",
                       description="Run every hard case (dead centres, near change point, stiff damper, "
                                   "long conservative run, fast crank, off-grid pulse edge, gravity) "
                                   "through both engines; print a table of each engine's status, "
                                   "differences, constraint violation, energy drift and wall time; "
                                   "write stress.json. Exit 1 if any case does not behave as expected.")
    p.add_argument("--out", default="xval-out", help="output folder (default ./xval-out)")
    p.add_argument("--case", action="append", help="run only this case (repeatable)")
    p.set_defaults(func=cmd_stress)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (SceneError, UsageError, ValueError) as exc:
        print(f"xval: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except NumericalFailure as exc:
        print(f"xval: numerical failure ({exc.reason}): {exc}", file=sys.stderr)
        return EXIT_FAILED
    except BrokenPipeError:  # output piped into e.g. `head`
        sys.stderr.close()
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
