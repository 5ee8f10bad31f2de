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


def _scene(path: str | None):
    return load_scene(path if path else default_scene_path())


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0.0 or value != value or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
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


def _mujoco_settings(args: argparse.Namespace):
    from reference_models import MujocoSettings

    kwargs = {"integrator": args.integrator, "timestep": args.timestep}
    if args.solref is not None:
        kwargs["solref"] = tuple(args.solref)
    if args.solimp is not None:
        kwargs["solimp"] = tuple(args.solimp)
    return MujocoSettings(**kwargs)


def cmd_mujoco(args: argparse.Namespace) -> int:
    from reference_models import simulate_mujoco

    scene = _scene(args.scene)
    settings = _mujoco_settings(args)
    result = simulate_mujoco(scene, settings)
    print(f"scene            {scene.name}  ({scene.source})")
    print(f"effects          {', '.join(scene.effects) or 'none'}")
    print(f"settings         {settings.integrator}, timestep {settings.timestep:g} s, "
          f"solref {tuple(settings.effective_solref)}, solimp {settings.solimp}, MuJoCo {result.settings['mujoco_version']}")
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
    export_mjcf(scene, args.output, _mujoco_settings(args))
    print(f"wrote {args.output}")
    return EXIT_OK


def _add_mujoco_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("MuJoCo settings")
    g.add_argument("--integrator", choices=("euler", "implicit", "implicitfast", "rk4"), default="rk4",
                   help="MuJoCo integrator (default rk4)")
    g.add_argument("--timestep", type=_positive, default=1e-3, help="MuJoCo timestep in s (default 1e-3)")
    g.add_argument("--solref", type=float, nargs=2, metavar=("TIMECONST", "DAMPRATIO"), default=None,
                   help="loop constraint solref (default: 2*timestep, 1)")
    g.add_argument("--solimp", type=float, nargs=5, metavar=("DMIN", "DMAX", "WIDTH", "MID", "POWER"),
                   default=None, help="loop constraint solimp (default 0.9999 0.9999 0.001 0.5 2)")


def _add_scene_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", default=None,
                   help="scene TOML file (default: scenes/seed_fourbar.toml, the seed example)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="xval",
        description="Solve a one-DOF mechanism two ways (Eksergian's equation and MuJoCo) and "
                    "say how far apart they are.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

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


if __name__ == "__main__":
    sys.exit(main())
