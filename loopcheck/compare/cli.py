"""The ``loopcheck`` command line.

Exit status: 0 success; 1 a gate or check failed or a run failed numerically; 2 bad input
(including an output path that cannot be written, checked before any work); 130 interrupted
(Ctrl-C); 143 terminated (SIGTERM); one signal ends the command (a second one while it cleans up is
not raised again). Errors are one line on stderr, never a traceback; an
interrupted or failed run leaves its output folder as it was (:mod:`loopcheck.compare.output`).
Warnings raised while settings are resolved or engines run (a setting the method ignores, a
load edge off MuJoCo's step grid) are printed as one line each, ``loopcheck: warning: ...``.

Engine flags default to None: only the flags given override the scene's [reduced] and
[mujoco] tables, which override each engine's own defaults.
"""

from __future__ import annotations

import os
import signal
import sys
from functools import partial


def _ended_at_start_up(signum: int, frame) -> None:
    """SIGINT or SIGTERM before :func:`main` handles signals (while the command's modules load, a
    quarter of a second): one line and the signal's exit status, no traceback. Nothing has been
    written yet, nor any process started."""
    os.write(2, b"loopcheck: interrupted\n" if signum == signal.SIGINT else b"loopcheck: terminated\n")
    os._exit(128 + signum)


# Started as the command (`loopcheck`, `python -m loopcheck.compare.cli`), not imported by a program
# (nor by a spawned worker, whose main module is __mp_main__): signals end it in one line from here
# on (main() raises them as exceptions while it runs).
_MAIN = sys.modules.get("__main__")
_AS_COMMAND = __name__ == "__main__" or (getattr(_MAIN, "__name__", "") == "__main__" and os.path.basename(
    getattr(_MAIN, "__file__", None) or "") == "loopcheck")
if _AS_COMMAND:
    for _signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(_signum) is not signal.SIG_IGN:  # nohup's or a background job's choice stays
            signal.signal(_signum, _ended_at_start_up)

import argparse  # noqa: E402 - after the start-up handlers: a signal while these load is one line
import contextlib  # noqa: E402
import logging  # noqa: E402
import warnings
from dataclasses import replace
from pathlib import Path

# Only what parsing and error reporting need is imported here; each command imports its
# engine (the reduced solver, MuJoCo, matplotlib) when it runs.
from loopcheck.errors import NumericalFailure

try:
    from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE, model_reader, model_readers
except ValueError as _exc:  # an engine an installed distribution declares wrongly (loopcheck.registry)
    if not _AS_COMMAND:
        raise
    print(f"loopcheck: {_exc}", file=sys.stderr)
    sys.exit(2)
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene
from loopcheck.settings import add_flags, given_flags, parse_number, parse_whole
from loopcheck.shipped_scenes import catalogue, default_scene_path, resolve_scene
from loopcheck.sweep_spec import ENGINE_CHOICES

from .output import (DEFAULT_ROOT, EXIT_INTERRUPTED, EXIT_TERMINATED, MANIFEST_FILE, OutputError, Terminated,
                     WriterDied, check_file, check_folder, refuse_same_outputs, signals_as_exceptions, write_file)
from .report import JOINTS_BY_DEFAULT

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
MAX_REPEATS = 1000
MAX_WORKERS = 1024  # the cost study uses at most one process per core; more than this is a typo
OTHER = next(name for name in DEFAULT_ENGINES if name != REFERENCE)  # the default comparison's other engine (MuJoCo)
REFERENCE_PREFIX = "reference-"  # the comparisons' flags of the reduced reference: --reference-method, ...


class UsageError(ValueError):
    """Bad command-line input (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit status 2)."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _scene_path(path: str | None) -> Path:
    """The scene file a command's scene argument names (the seed's without one)."""
    return resolve_scene(path) if path else default_scene_path()


def _scene(path: str | None):
    return load_scene(_scene_path(path))


MODEL_FLAGS = ("input", "keyframe", "qpos0", "ctrl", "loop", "write_submodel", "assemble")  # read a MuJoCo model; a scene file has none of these


def _refuse_model_flags(args: argparse.Namespace, what: str) -> None:
    """--input, --keyframe and --ctrl read a MuJoCo model (.xml): given with ``what`` (scene files
    alone), they would be ignored, so they are refused (exit 2)."""
    given = [f"--{name.replace('_', '-')}" for name in MODEL_FLAGS if getattr(args, name, None) is not None]
    if given:
        raise UsageError(f"{', '.join(given)}: read{'s' if len(given) == 1 else ''} a MuJoCo model (.xml), and "
                         f"{what}; a scene file sets its input, state and load itself")


def _run_scene(args: argparse.Namespace, path: str | None):
    """The scene file of ``run`` or ``check``, with ``--horizon``, when given, over its
    simulation.horizon: the file is checked as written first, then every check of the scene file
    applies to the new value; the override is said on stdout."""
    scene = _scene(path)
    if args.horizon is None:
        return scene
    from loopcheck.scenefile import scene_from_dict
    from loopcheck.toml_reader import parse_toml, read_text

    file = _scene_path(path)
    data = parse_toml(read_text(file), file)
    data = {**data, "simulation": {**data["simulation"], "horizon": args.horizon}}
    try:
        overridden = scene_from_dict(data, source=str(file))
    except SceneError as exc:
        raise SceneError(f"{file}: with --horizon {args.horizon:g}: {exc}") from None
    print(f"horizon {overridden.horizon:g} s from --horizon, over {file}'s simulation.horizon = {scene.horizon:g} s")
    return overridden


def _named(exc: ValueError, source: str) -> ValueError:
    """``exc`` as a refusal naming the scene file ``source``, unless it already does."""
    if isinstance(exc, UsageError) or str(exc).startswith(source):
        return exc
    return UsageError(f"{source}: {exc}")


def _positive(text: str) -> float:
    """An argparse type: a positive number (the engines' flags read theirs the same way)."""
    return parse_number(text, positive=True)


def _int_in(low: int, high: int):
    """An argparse type: a whole number in [low, high]."""
    def parse(text: str) -> int:
        return parse_whole(text, low, high)

    parse.__name__ = "whole number"
    return parse


def _settings(engine: str, args: argparse.Namespace, scene, prefix: str = ""):
    """An engine's settings: the flags given (``--PREFIXNAME``) over the scene's table over the
    defaults."""
    from .settings import engine_settings

    return engine_settings(engine, scene, **given_flags(args, ENGINES[engine].settings, prefix=prefix))


def cmd_scenes(args: argparse.Namespace) -> int:
    """The shipped scenes, a line each: the name a command takes, and where the file lies."""
    preferred: dict = {}
    for name, path in catalogue().items():  # a bare file name, where it is unique, over the full name
        if path not in preferred or "/" in preferred[path]:
            preferred[path] = name
    width = max(len(name) for name in preferred.values())
    for path, name in sorted(preferred.items()):
        print(f"{name:{width}s}  {path}")
    return EXIT_OK


def cmd_engine(args: argparse.Namespace) -> int:
    """``loopcheck NAME``: the registered engine ``NAME`` alone on the scene (a missing optional
    extra: one line, exit 2)."""
    from .text import result_lines

    engine = ENGINES[args.command]
    scene = _scene(args.scene)
    settings = _settings(engine.name, args, scene)
    engine.load()
    # an automatic step is chosen for the engine's gate ([tolerances.NAME] over [tolerances])
    result = engine.simulate(replace(scene, tolerances=scene.tolerances_for(engine.name)), settings)
    print("\n".join(result_lines(scene, result)))
    return EXIT_OK  # off-grid load edges: an OffGridEdgeWarning, printed by main()


def _model_engine():
    """The engine that reads model files (``import-mjcf``, ``export-mjcf``; MuJoCo's MJCF)."""
    readers = model_readers()
    if not readers:
        raise UsageError("no registered engine reads model files")
    return readers[0]


def cmd_export_mjcf(args: argparse.Namespace) -> int:
    engine = _model_engine()
    check_file(args.out, flag="-o", inputs=[_scene_path(args.scene)])  # before any work
    scene = _scene(args.scene)
    xml = engine.models.model_text(scene, _settings(engine.name, args, scene))
    path = write_file(args.out, xml, flag="-o")
    print(f"wrote {path}")
    return EXIT_OK


def _control(text: str):
    """An argparse type: an actuator's control, ``[NAME=]VALUE`` or ``[NAME=]t:value,t:value,...``."""
    try:
        return _model_engine().models.Control.parse_named(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def cmd_import_mjcf(args: argparse.Namespace) -> int:
    from loopcheck.scene_writer import scene_toml

    check_file(args.out, flag="-o", inputs=[args.model])  # before any work
    if args.write_submodel is not None:
        refuse_same_outputs([("-o", args.out), ("--write-submodel", args.write_submodel)])
    imported = _import(args, args.model)
    for line in imported.warnings:
        print(f"loopcheck: warning: {line}", file=sys.stderr)
    for line in imported.said:  # the model's only keyframe, read without --keyframe
        print(f"{args.model}: {line}")
    scene = imported.scene
    where = f"keyframe '{imported.keyframe}'" if imported.keyframe else "qpos0"
    header = (f"Imported by `loopcheck import-mjcf` from {Path(args.model).name}, read at {where}.\n"
              f"Loops closed there to {imported.closure_residual:.3g} m; Newton moved the configuration by "
              f"{imported.polish:.3g} (rad or m).\n"
              + "".join(f"Warning: {line}\n" for line in imported.warnings))
    path = write_file(args.out, scene_toml(scene, header), flag="-o")
    print(f"{len(scene.mechanism.linkage.moving)} moving bodies, {len(scene.mechanism.linkage.joints)} joints "
          f"({len(scene.mechanism.linkage.cut_joints)} closing loops"
          + "".join(f", coupling '{c.name}'" for c in scene.mechanism.linkage.couplings)
          + (f"), inputs {', '.join(repr(i) for i in scene.inputs)}; the first, " if scene.dof > 1 else "), input ")
          + f"'{scene.mechanism.linkage.input_joint}': "
          f"{_reader(args.model).models.input_coordinate(imported).text()}; loops closed to {imported.closure_residual:.3g} m at {where}; "
          f"horizon {scene.horizon:g} s")
    if imported.extraction:
        print(_extraction_lines(imported))
    print(f"wrote {path}")
    return EXIT_OK


def cmd_draw(args: argparse.Namespace) -> int:
    from .draw import drawing_format, write_drawing

    target = check_file(args.out, flag="--out", inputs=[_scene_path(args.scene)])  # before any work
    drawing_format(args.out)  # .png, .pdf or .svg, before any work too
    scene = _scene(args.scene)
    path = write_drawing(scene, target)
    print(f"wrote {path}")
    return EXIT_OK


def _mujoco_settings(args: argparse.Namespace, scene):
    """The default comparison's other engine's settings (MuJoCo's): its flags given over the scene's table."""
    return _settings(OTHER, args, scene)


def _add_mujoco_arguments(p: argparse.ArgumentParser) -> None:
    add_flags(p, ENGINES[OTHER].settings, title=f"{ENGINES[OTHER].label} settings", table=OTHER)


def _reduced_reference(args: argparse.Namespace, scene):
    """The reduced reference: command-line flags over the scene's [reduced] table over the defaults."""
    return _settings(REFERENCE, args, scene, prefix=REFERENCE_PREFIX)


def _tolerances(scene, args: argparse.Namespace, engine: str = OTHER):
    """The tolerances ``engine`` is judged by: the flags given over the scene's for it."""
    from .settings import gate_tolerances

    return gate_tolerances(scene, engine, peak_omega_rtol=args.peak_rtol, q_atol=args.q_atol,
                           omega_atol=args.omega_atol, omega_vs_q_atol=args.omega_vs_q_atol)


def cmd_run(args: argparse.Namespace) -> int:
    from .report import joint_columns, report_files, resolve_animation, write_outputs
    from .text import comparison_lines

    animate = resolve_animation(args.animate)  # warns and skips when no GIF writer exists
    if args.engines is not None:
        if args.scene is not None and _is_mjcf(args.scene):
            raise UsageError("--engines runs scenes: a MuJoCo model (.xml) is run as written against the reduced "
                             "solution alone")
        _refuse_model_flags(args, "--engines runs scene files")
        return _run_engines(args, animate)
    if args.scene is None or not _is_mjcf(args.scene):
        _refuse_model_flags(args, f"'{args.scene or default_scene_path().name}' is a scene file")
    check_folder(args.out, (*report_files(animate), MANIFEST_FILE),  # before any work (and before MuJoCo is loaded)
                 inputs=[_run_input(args.scene)])
    from .run import compare_engines

    if args.scene is not None and _is_mjcf(args.scene):  # the user's model as written (docs/import.md)
        from .model_check import check_model, reader_of

        imported = _import(args, args.scene)
        _print_notes(args.scene, imported)
        scene = imported.scene
        joints = joint_columns(scene, args.joints)
        check = check_model(imported, tolerances=_tolerances(scene, args), reduced=_reduced_reference(args, scene))
        if check.as_written.comparison is None:
            raise check.as_written.failure
        comparison = check.as_written.comparison
        print("\n".join(comparison_lines(comparison)))
        print("\n".join(line.strip() for line in reader_of(imported).models.diagnosis_lines(check)))
        if imported.extraction:
            print(_extraction_lines(imported))
        extraction = imported.extraction.as_dict() if imported.extraction else None
    else:
        scene = _run_scene(args, args.scene)
        joints = joint_columns(scene, args.joints)  # an unknown name is refused before any work
        try:
            comparison = compare_engines(scene, reduced=_reduced_reference(args, scene),
                                         mujoco=_mujoco_settings(args, scene), tolerances=_tolerances(scene, args))
        except ValueError as exc:  # what an engine refuses of the scene (a name its model reserves): the file named
            raise _named(exc, scene.source) from None
        print("\n".join(comparison_lines(comparison)))
        extraction = None
    write_outputs(comparison, args.out, animate=animate, joints=joints, extraction=extraction,
                  committed=lambda paths: print(f"wrote {len(paths)} files to {args.out}/", flush=True))
    return EXIT_OK if comparison.gate.passed else EXIT_FAILED


def _run_engines(args: argparse.Namespace, animate: bool) -> int:
    """``loopcheck run --engines``: every engine of the list against the reduced reference (as ``loopcheck check
    --engines``), the report folder of the reference against MuJoCo (else the list's first other
    engine) as ``loopcheck run`` writes it, with every engine's verdict in report.json and engines.png."""
    from .engines import compared_engine, engines_lines
    from .report import joint_columns, report_files, write_outputs
    from .text import comparison_lines, engine_label

    other = compared_engine(args.engines)
    check_folder(args.out, (*report_files(animate, other=other, engines=True), MANIFEST_FILE),  # before any work
                 inputs=[_scene_path(args.scene)])
    _load_extras(args.engines)
    scene = _run_scene(args, args.scene)
    joints = joint_columns(scene, args.joints)  # an unknown name is refused before any work
    check = _engines_check(args, scene)
    compared = next(v for v in check.verdicts if v.engine == other)
    if compared.comparison is not None:
        print("\n".join(comparison_lines(compared.comparison)))
    print("\n".join(engines_lines(check)))
    if compared.comparison is None:
        print(f"{engine_label(other)} did not run: no report written to {args.out}/")
        return EXIT_FAILED
    write_outputs(compared.comparison, args.out, animate=animate, joints=joints, engines=check,
                  committed=lambda paths: print(f"wrote {len(paths)} files to {args.out}/", flush=True))
    return EXIT_OK if check.passed else EXIT_FAILED


def _run_input(path: str | None) -> Path:
    """The file ``loopcheck run``'s argument names: a MuJoCo model as given, else the scene file."""
    return Path(path) if path is not None and _is_mjcf(path) else _scene_path(path)


def _is_mjcf(path: str) -> bool:
    """A model file an engine reads (MuJoCo's MJCF, checked as written, ``loopcheck check model.xml``)
    rather than a scene (:func:`loopcheck.registry.model_reader`)."""
    return model_reader(path) is not None


def _reader(path: str):
    """The engine that reads the model file ``path`` (``import-mjcf`` reads MJCF: MuJoCo's)."""
    return model_reader(path) or _model_engine()


def _import(args: argparse.Namespace, path: str):
    models = _reader(path).models
    horizon = {} if args.horizon is None else {"horizon": args.horizon}  # else import_mjcf's default, 1 s
    try:
        bare, named = models.Control.by_name(args.ctrl)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if getattr(args, "loop", None):  # one loop out of a larger model (docs/import.md)
        if args.write_submodel is not None:
            check_file(args.write_submodel, flag="--write-submodel", inputs=[path])  # before any work
        return models.import_loop(path, args.loop, write_to=args.write_submodel, keyframe=args.keyframe,
                           qpos0=bool(args.qpos0), assemble=bool(args.assemble), input_joint=args.input,
                           control=bare, controls=named, **horizon)[0]
    if getattr(args, "write_submodel", None) is not None:
        raise UsageError("--write-submodel writes the loop that --loop NAME cuts out of the model: give --loop")
    if getattr(args, "assemble", None):  # the whole model's loops (docs/import.md)
        return models.import_assembled(path, input_joint=args.input, keyframe=args.keyframe, qpos0=bool(args.qpos0),
                                control=bare, controls=named, **horizon)
    return models.import_model(path, input_joint=args.input, keyframe=args.keyframe, qpos0=bool(args.qpos0),
                       control=bare, controls=named, **horizon)


def _print_notes(path: str, imported) -> None:
    """What reading the model ``path`` said: its warnings (stderr) and its notes (the keyframe read,
    ...), each line naming the file."""
    for line in imported.warnings:
        print(f"loopcheck: warning: {path}: {line}", file=sys.stderr)
    for line in imported.said:
        print(f"{path}: {line}")


def _extraction_lines(imported, indent: str = "") -> str:
    """What ``--loop`` cut out of the model (:meth:`Extraction.lines`), for stdout."""
    return "\n".join(f"{indent}{line}" for line in imported.extraction.lines()) if imported.extraction else ""


def cmd_check(args: argparse.Namespace) -> int:
    from .run import compare_engines
    from .text import check_lines

    if not any(_is_mjcf(path) for path in args.scenes):  # with a model listed, they are the models'
        _refuse_model_flags(args, "no MuJoCo model is listed")
    if getattr(args, "write_submodel", None) is not None and len(args.scenes) > 1:
        raise UsageError("--write-submodel writes one model's loop: list one model")
    models = {path: _import(args, path) for path in args.scenes if _is_mjcf(path)}
    scenes = [_run_scene(args, path) for path in args.scenes if not _is_mjcf(path)]  # all bad input first
    if args.engines is not None:  # a model: the engine that read it runs it as written, the others its scene as imported
        return _check_engines(args, scenes, models)
    for path, scene in [*((p, m.scene) for p, m in models.items()), *((s.source, s) for s in scenes)]:
        try:  # the reference's refusals, before anything is printed
            ENGINES[REFERENCE].check_work(scene, _reduced_reference(args, scene))
        except ValueError as exc:
            raise UsageError(f"{path}: {exc}") from None
    failed = 0
    for path, imported in models.items():
        from .model_check import check_model, reader_of

        own = reader_of(imported).models  # the reading engine's check and its lines

        said = partial(_print_notes, path, imported)  # after the check: a refusal in it prints its line alone

        try:
            check = check_model(imported, tolerances=_tolerances(imported.scene, args),
                                reduced=_reduced_reference(args, imported.scene))
        except NumericalFailure as exc:  # the reduced reference's (the model's own runs record theirs)
            failed += 1
            said()
            print("\n".join(own.reference_failure_lines(imported, exc, path)))
            continue
        said()
        failed += not check.passed
        print("\n".join(own.check_lines(check, path)))
        if imported.extraction:
            print(_extraction_lines(imported, "      "))
    for scene in scenes:
        tolerances = _tolerances(scene, args)
        try:
            c = compare_engines(scene, reduced=_reduced_reference(args, scene), mujoco=_mujoco_settings(args, scene),
                                tolerances=tolerances)
        except ValueError as exc:  # what an engine refuses of the scene (a name its model reserves): the file named
            raise _named(exc, scene.source) from None
        except NumericalFailure as exc:
            failed += 1
            print(f"FAIL  {scene.source}: numerical failure ({exc.reason}): {exc}")
            continue
        failed += not c.gate.passed
        print("\n".join(check_lines(c)))
    total = len(scenes) + len(models)
    print(f"{total - failed} passed, {failed} failed")
    return EXIT_FAILED if failed else EXIT_OK


def _engines(text: str) -> tuple[str, ...]:
    """An argparse type: ``--engines``' list of engine names."""
    from .engines import parse_engines

    try:
        return parse_engines(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _engines_check(args: argparse.Namespace, scene, as_written=None, refuse=None):
    """``--engines``: each engine of the list run on ``scene`` and judged against the reduced
    reference at its own tolerances (the flags given over the scene's for it); ``as_written`` and
    ``refuse`` as :func:`loopcheck.compare.engines.check_engines` takes them (a user's model)."""
    from .engines import check_engines
    from .settings import engine_settings

    # the flags are the reference's and MuJoCo's (another engine's flags of the same name, --method,
    # --rtol, are not read as its): the others run with their scene table over their defaults
    settings = {name: (_reduced_reference(args, scene) if name == REFERENCE else
                       _mujoco_settings(args, scene) if name == OTHER else engine_settings(name, scene))
                for name in args.engines}
    tolerances = {name: _tolerances(scene, args, name) for name in args.engines if name != REFERENCE}
    return check_engines(scene, args.engines, settings, tolerances, as_written, refuse)


def _load_extras(engines) -> None:
    """Load each engine of an ``--engines`` list: a missing extra is said in one line (exit 2)
    before any work."""
    for name in engines:
        ENGINES[name].load()


def _check_engines(args: argparse.Namespace, scenes: list, models: dict | None = None) -> int:
    """``loopcheck check --engines``: each engine against the reduced reference, the outlier named.
    A user's model (``models``: path → imported) runs as written in the engine that read it (listed
    or not among the others, by its role) and as its imported scene in the others."""
    from .engines import engines_lines
    from .model_check import reader_of

    _load_extras(args.engines)
    failed = 0
    for path, imported in (models or {}).items():
        _print_notes(path, imported)
        reader = reader_of(imported)
        vacuous = partial(reader.models.refuse_vacuous_model, imported,
                          tolerances=_tolerances(imported.scene, args, reader.name))
        as_written = (reader.name, f"{path} as written (the others: its scene as imported)",
                      partial(reader.models.run_model, imported))
        check = _engines_check(args, imported.scene, as_written, vacuous)
        failed += not check.passed
        print("\n".join(engines_lines(check)))
    for scene in scenes:
        check = _engines_check(args, scene)
        failed += not check.passed
        print("\n".join(engines_lines(check)))
    print(f"{len(scenes) + len(models or {}) - failed} passed, {failed} failed")
    return EXIT_FAILED if failed else EXIT_OK


def _add_model_arguments(p: argparse.ArgumentParser) -> None:
    """How a MuJoCo model (MJCF) is read as a scene: ``import-mjcf``'s flags."""
    g = p.add_argument_group("reading a MuJoCo model (MJCF, a file ending in .xml; docs/import.md)")
    g.add_argument("--input", default=None, metavar="JOINT",
                   help="the MuJoCo joint whose coordinate is q (default: the joint the motor drives, else the "
                        "first joint); with several degrees of freedom, the first inputs in order, comma separated "
                        "(the rest: the joints actuators act on, then coordinate partitioning)")
    g.add_argument("--keyframe", default=None, metavar="NAME",
                   help="read the configuration, rates and control of this keyframe (default: the model's only "
                        "keyframe, said in the output; qpos0 without keyframes; several are refused unless one is "
                        "named or --qpos0 is given)")
    g.add_argument("--qpos0", action="store_true", default=None,
                   help="read qpos0 (at rest, no control) even when the model has keyframes")
    g.add_argument("--ctrl", type=_control, action="append", default=None, metavar="[NAME=]CTRL",
                   help="an actuator's control over time, in its ctrl units: a number, or a table "
                        "t:value,t:value,... (s; each value held from its time on, zero before the first); "
                        "NAME=CTRL for actuator NAME, repeated once per actuator; a bare CTRL is the only "
                        "actuator's (or the input motor's); default the model's loopcheck.ctrl (loopcheck.ctrl.NAME) "
                        "numeric, else the keyframe's ctrl")
    g.add_argument("--loop", action="append", default=None, metavar="NAME",
                   help="check one loop of a larger model: the connect or joint coupling that closes it (repeated "
                        "when several do; an unnamed one as messages name it, e.g. 'connect #2 (a–b)'), or a body of "
                        "it; the rest of the robot is welded at the configuration read, what acts outside is dropped")
    g.add_argument("--write-submodel", default=None, metavar="FILE",
                   help="with --loop: write the extracted model (MJCF, loadable on its own) there; the check runs it")
    g.add_argument("--assemble", action="store_true", default=None,
                   help="close loops left open in the configuration read by Newton from there, the input joint held "
                        "(a move above 0.1 rad or 10 mm is refused; the moves are printed in qpos units); with --loop, "
                        "the loop's, else the whole model's")
    g.add_argument("--horizon", type=_positive, default=None,
                   help="the simulated time (s): a model's (default its loopcheck.horizon numeric, else 1); given "
                        "with a scene file, it replaces the scene's simulation.horizon (said in the output). --input, "
                        "--keyframe, --qpos0 and --ctrl read models only: with scene files alone they are refused")


def cmd_cost(args: argparse.Namespace) -> int:
    from .cost import COST_FILES, study, summary_lines, write_cost_outputs

    from loopcheck.registry import DEFAULT_ENGINES

    check_folder(args.out, (*COST_FILES, MANIFEST_FILE), inputs=[_scene_path(args.scene)])  # before any work
    engines = args.engines or DEFAULT_ENGINES
    _load_extras(engines)  # a missing extra: one line, before any work
    scene = _scene(args.scene)
    report, measurements, target = study(scene, quick=args.quick, target=args.target, repeats=args.repeats,
                                         workers=args.workers, engines=engines)
    print("\n".join(summary_lines(report, measurements)))
    write_cost_outputs(report, measurements, args.out, target,
                       committed=lambda paths: print(f"wrote {', '.join(p.name for p in paths)} to {args.out}/", flush=True))
    return EXIT_FAILED if any(m.status == "failed" for m in measurements) else EXIT_OK  # a worker died twice


def cmd_stress(args: argparse.Namespace) -> int:
    from .stress import CATALOGUE, STRESS_FILES, run_catalogue, table_lines, write_stress

    cases = CATALOGUE if not args.case else [c for c in CATALOGUE if c.name in args.case]
    unknown = set(args.case or ()) - {c.name for c in CATALOGUE}
    if unknown:
        raise UsageError(f"unknown case {sorted(unknown)[0]!r}; cases: {', '.join(c.name for c in CATALOGUE)}")
    check_folder(args.out, (*STRESS_FILES, MANIFEST_FILE))  # before any work
    from loopcheck.registry import DEFAULT_ENGINES

    engines = args.engines or DEFAULT_ENGINES
    _load_extras(engines)  # a missing extra: one line, before any work
    results = run_catalogue(cases, progress=lambda r: print(f"  {r.name}: {'pass' if r.passed else 'FAIL'}",
                                                           file=sys.stderr, flush=True), engines=engines)
    for line in table_lines(results):
        print(line)
    write_stress(results, args.out, committed=lambda paths: print(f"wrote {paths[0]}", flush=True))
    return EXIT_OK if all(r.passed for r in results) else EXIT_FAILED


def cmd_sweep(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from .sweep import run_sweep, sweep_files
    from .sweep_summary import summary_lines
    from loopcheck.sweep_spec import spec_from_args

    from .sweep_scene import check, load_sweep

    if args.scheduler is not None:
        from .sweep_dask import require_dask

        if args.workers is not None:
            raise UsageError("--workers and --scheduler: the Dask cluster's workers run the sweep; give one of them")
        require_dask()  # before any work: one line naming the extra to install
    path = str(resolve_scene(args.scene)) if args.scene else str(default_scene_path())
    data, table_spec = load_sweep(path)
    if args.vary:
        spec = spec_from_args(args.vary, args.samples, args.seed)
    elif table_spec is None:
        raise UsageError(f"{path}: nothing to sweep: give --vary KEY=SPEC or a [sweep] table in the scene file")
    elif args.samples is not None or args.seed is not None:
        raise UsageError("--samples and --seed go with --vary (the scene's [sweep] table has its own)")
    else:
        spec = table_spec
    if args.engines is not None:  # the flag overrides the table's engines only when given
        spec = replace(spec, engines=args.engines)
    check(data, spec, path)  # before any work: every key, the nominal scene and each key's extremes, the engines
    _load_extras(spec.engines)
    from .sweep import batch_sizes

    batched = batch_sizes(spec.engines, args.batch_size)
    if args.batch_size not in (None, 1) and not batched:
        warnings.warn(f"--batch-size {args.batch_size}: no engine of {','.join(spec.engines)} runs in batches "
                      "(none declares a batch size); the variants run one by one")
    if args.scheduler is not None:
        if batched:
            raise UsageError(f"--scheduler runs engines variant by variant; {', '.join(batched)} run in batches in "
                             "this process: give --batch-size 1 with --scheduler")
    if args.sensitivity_engines:  # before any work: each engine installed and declaring its peak accuracy
        from .sensitivity import check_engines_declare

        _load_extras(args.sensitivity_engines)
        check_engines_declare(data, spec, path, args.sensitivity_engines)
    check_folder(args.out, (*sweep_files(spec, args.keep_trajectories), MANIFEST_FILE), inputs=[path])
    if args.resume and args.keep_trajectories:
        raise UsageError("--resume and --keep-trajectories: the journal keeps the rows, not the trajectories")
    from .sweep_journal import check_journal

    check_journal(args.out, data, spec, resume=args.resume, restart=args.restart)  # before any work
    client = None
    if args.scheduler is not None:
        from .sweep_dask import connect

        client = connect(args.scheduler)  # before any work: an unreachable scheduler is one line, exit 2
    try:
        found = None
        if args.sensitivity or args.sensitivity_engines:
            from .sensitivity import sensitivities, sensitivity_lines

            items = sensitivities(data, spec, path, **({"engines": args.sensitivity_engines}
                                                       if args.sensitivity_engines else {}))
            scene = _scene(path)
            print("\n".join(sensitivity_lines(items, unit=f"{scene.input_unit}/s",
                                               units={n: f"{u}/s" for n, u in zip(scene.inputs, scene.input_units())})))
            found = [s.as_dict() for s in items]
        def said(summary, paths) -> None:  # with the files in place, before a held signal comes
            print("\n".join(summary_lines(summary)))
            print(f"wrote {', '.join(p.name for p in paths)} to {args.out}/", flush=True)

        summary, _ = run_sweep(data, spec, path, args.out, workers=args.workers,
                               keep_trajectories=args.keep_trajectories, sensitivity=found, client=client,
                               resume=args.resume, restart=args.restart, batch_size=args.batch_size,
                               committed=said)
    finally:
        if client is not None:
            client.close()
    unmeasured = found is not None and any("failure" in item for item in found)  # an engine's sensitivity failed
    return EXIT_FAILED if summary.failed_any or unmeasured else EXIT_OK


def _add_reference_arguments(p: argparse.ArgumentParser) -> None:
    add_flags(p, ENGINES[REFERENCE].settings, title=f"{ENGINES[REFERENCE].label} reference", prefix=REFERENCE_PREFIX,
              table=REFERENCE)


def _add_tolerance_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("gate tolerances (given, each overrides the scene's [tolerances] and "
                             "[tolerances.ENGINE] value for every engine judged)")
    g.add_argument("--peak-rtol", type=_positive, default=None, help="relative difference of the peak input speed")
    g.add_argument("--q-atol", type=_positive, default=None, help="max |dq| in rad (m for a prismatic input)")
    g.add_argument("--omega-atol", type=_positive, default=None, help="max |dqdot| in rad/s (m/s for a prismatic input)")
    g.add_argument("--omega-vs-q-atol", type=_positive, default=None,
                   help="max |dqdot| at equal input position, rad/s or m/s (phase-free)")


def _add_engines_argument(p: argparse.ArgumentParser, what: str) -> None:
    """``--engines LIST`` of ``run`` and ``check``: ``what`` they do with it."""
    p.add_argument("--engines", type=_engines, default=None, metavar="LIST",
                   help=f"engines to {what} (any of {', '.join(ENGINES)}; default reduced,mujoco); with three or "
                        "more, the one farthest from the others is named when they disagree. Each is judged by the "
                        "scene's [tolerances.ENGINE] over its [tolerances]; engines beside reduced and mujoco run "
                        "with their scene table's settings")


def _add_comparison_arguments(p: argparse.ArgumentParser) -> None:
    _add_reference_arguments(p)
    _add_mujoco_arguments(p)
    _add_tolerance_arguments(p)


def _add_out_folder(p: argparse.ArgumentParser, default: str) -> None:
    """-o/--out of a command that writes a folder of files; ``default`` is the folder's name in
    ``loopcheck-out/`` when none is given, with ``{scene}`` the scene's name (:func:`_out_folder`)."""
    shown = f"{DEFAULT_ROOT}/{default.format(scene='SCENE')}"
    p.add_argument("-o", "--out", default=None,
                   help=f"output folder, created if absent in an existing folder (default {shown}, SCENE the "
                        "scene's file name without .toml: a folder holds one run)")
    p.set_defaults(out_default=default)


def _out_folder(args: argparse.Namespace, scene: str | None = None) -> str:
    """The output folder: ``--out`` if given, else ``loopcheck-out/`` and the command's default name
    for the scene argument ``scene`` (a file's or catalogue name's stem; the seed without one)."""
    if args.out is not None:
        return args.out
    stem = Path(str(resolve_scene(scene) if scene else default_scene_path())).stem
    return str(DEFAULT_ROOT / args.out_default.format(scene=stem))


def _add_scene_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", default=None,
                   help="scene TOML file, or the name of a shipped scene when no such file exists (`loopcheck scenes` "
                        "lists them; default: seed_fourbar, the seed example)")


def _version() -> str:
    import loopcheck

    return loopcheck.__version__


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="loopcheck",
        description="Solve a one-DOF mechanism two ways (Eksergian's equation and MuJoCo) and "
                    "say how far apart they are.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    talk = parser.add_mutually_exclusive_group()
    talk.add_argument("-q", "--quiet", action="store_true",
                      help="no progress lines on stderr (warnings and errors still), e.g. `loopcheck -q check ...`")
    talk.add_argument("-v", "--verbose", action="store_true",
                      help="more progress lines: each engine run's method, steps and time")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("scenes", help="list the shipped scenes, by the names every command accepts",
                       description="List the shipped scenes (the seed, the mechanism catalogue, the hard cases): "
                                   "the name any command takes in place of a scene file, and the file.")
    p.set_defaults(func=cmd_scenes)

    for engine in ENGINES.values():  # each registered engine alone: `loopcheck NAME`
        p = sub.add_parser(engine.name, help=f"one engine alone: {engine.description}",
                           description=f"Run the scene through this engine alone: {engine.description}. Print "
                                       "its settings as run, the peak speed of the input joint and its time, the "
                                       "loop gap where the engine records one, the energy residual and the cost. "
                                       "An engine of an optional extra that is not installed says how to install "
                                       "it (docs/engines.md).")
        _add_scene_argument(p)
        add_flags(p, engine.settings, title=f"{engine.label} settings", table=engine.name)
        p.set_defaults(func=cmd_engine)

    p = sub.add_parser("export-mjcf", help="write the scene's MuJoCo model as MJCF",
                       description="Write the scene's MuJoCo model as a human-readable MJCF file "
                                   "that MuJoCo loads on its own.")
    _add_scene_argument(p)
    p.add_argument("-o", "--out", required=True, help="MJCF file to write")
    _add_mujoco_arguments(p)
    p.set_defaults(func=cmd_export_mjcf)

    p = sub.add_parser("import-mjcf", help="read a MuJoCo model (MJCF) as a scene file",
                       description="Read the planar one-DOF linkage of a MuJoCo model (hinges, slides, connect "
                                   "equalities, tendons, joint springs and dampers, one motor, gravity) at a "
                                   "keyframe or qpos0 and write it as a scene file (docs/import.md). What the "
                                   "description cannot hold is refused with one line naming the element.")
    p.add_argument("model", help="MJCF file")
    p.add_argument("-o", "--out", required=True, help="scene TOML file to write")
    _add_model_arguments(p)
    p.set_defaults(func=cmd_import_mjcf)

    p = sub.add_parser("draw", help="draw the scene's linkage at q0 (PNG, PDF or SVG)",
                       description="Draw the scene's linkage assembled at q0 in its assembly mode: "
                                   "bodies, revolute and prismatic joints, ground pivots, dampers, "
                                   "springs, point forces and centres of mass, labelled, lengths in m. "
                                   "Check a scene's geometry before running it.")
    _add_scene_argument(p)
    p.add_argument("-o", "--out", default="linkage.png",
                   help="file to write, in the format its suffix names: .png, .pdf or .svg (default ./linkage.png)")
    p.set_defaults(func=cmd_draw)

    p = sub.add_parser("run", help="run both engines, compare, write report and plots",
                       description="Run the scene through the reduced solver and MuJoCo, print a "
                                   "table of both results and their differences, and write "
                                   "report.json, reduced.csv, mujoco.csv and PNG plots (with a strip of "
                                   "the mechanism at the peak speed and at the largest disagreement, "
                                   "both engines overlaid) into --out.")
    _add_scene_argument(p)
    _add_out_folder(p, "{scene}")
    p.add_argument("--animate", action="store_true",
                   help="also write mechanism.gif, both engines' mechanism over the run (needs pillow)")
    p.add_argument("--joints", nargs="+", metavar="NAME", default=None,
                   help="the joints whose coordinate and rate the CSVs carry, with the inputs' "
                        f"(default: every joint of a scene of at most {JOINTS_BY_DEFAULT} joints, else the inputs' "
                        "alone; report.json lists every joint)")
    _add_comparison_arguments(p)
    _add_engines_argument(p, "judge against the reduced reference, comma-separated, e.g. reduced,mujoco,pin: each "
                             "one's verdict is printed and written to report.json, their |dqdot| to engines.png, and "
                             "the files of a plain run describe the reference against MuJoCo (else the list's first "
                             "other engine)")
    _add_model_arguments(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("check", help="CI gate: exit 1 if the engines disagree beyond tolerance",
                       description="Run both engines on each scene and compare the differences "
                                   "against the scene's [tolerances] (flags override). A MuJoCo model "
                                   "(model.xml) is run as written against the exact solution of its "
                                   "linkage; the check says which of its settings causes the difference "
                                   "and the cheapest options that meet the tolerances. Exit 0 when "
                                   "every scene passes, 1 when any fails, 2 on bad input.")
    p.add_argument("scenes", nargs="+", metavar="SCENE",
                   help="scene TOML files (or names of shipped scenes, as `loopcheck scenes` lists them), or MuJoCo "
                        "models (.xml)")
    _add_comparison_arguments(p)
    _add_engines_argument(p, "judge against the reduced reference, comma-separated, e.g. reduced,mujoco,pin")
    _add_model_arguments(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("cost", help="work-precision study: what accuracy costs in time",
                       description="Sweep each engine over its accuracy ladder (steps, tolerances, integrators, "
                                   "constraint softness: what the engine declares); measure errors against the "
                                   "reference's truth (DOP853 rtol 1e-12) and the median wall time of the simulation; "
                                   "write cost.png (work-precision diagram, every engine on it), cost.csv and "
                                   "cost.json; recommend the cheapest configuration of each engine for the target, "
                                   "and its cost against the reference's.")
    _add_scene_argument(p)
    _add_out_folder(p, "{scene}-cost")
    p.add_argument("--quick", action="store_true", help="a small ladder that runs in a few seconds")
    p.add_argument("--target", type=_positive, default=None,
                   help="target relative peak-omega error (default: the scene's peak_omega_rtol)")
    p.add_argument("--repeats", type=_int_in(1, MAX_REPEATS), default=None,
                   help="timed runs per configuration (default 3)")
    p.add_argument("--workers", type=_int_in(1, MAX_WORKERS), default=None,
                   help="processes, at most one per core (default: all cores)")
    from loopcheck import registry as _registry  # (a name of its own: build_parser's other names stay global)

    p.add_argument("--engines", type=_engines, default=None, metavar="LIST",
                   help=f"engines to sweep, comma-separated, the reference {_registry.REFERENCE} among them (any "
                        f"of {', '.join(ENGINES)}; default {','.join(_registry.DEFAULT_ENGINES)})")
    p.set_defaults(func=cmd_cost)

    p = sub.add_parser("stress", help="run the hard-case catalogue (scenes/hard/)",
                       description="Run every hard case (dead centres, near change point, stiff damper, "
                                   "long conservative run, fast crank, off-grid pulse edge, gravity) "
                                   "through the engines (--engines); print a table of each engine's status, "
                                   "differences, constraint violation, energy drift and wall time; "
                                   "write stress.json. Exit 1 if any case does not behave as expected.")
    _add_out_folder(p, "stress")
    p.add_argument("--case", action="append", help="run only this case (repeatable)")
    from loopcheck.registry import DEFAULT_ENGINES, REFERENCE

    p.add_argument("--engines", type=_engines, default=None, metavar="LIST",
                   help=f"the engines each case runs, comma-separated (any of {', '.join(ENGINES)}; default "
                        f"{','.join(DEFAULT_ENGINES)}), the reference {REFERENCE} among them, each judged by its own "
                        "tolerances as check --engines judges it, with its declared probes where a case asks for "
                        "them; an engine's failure or refusal is its verdict in the case")
    p.set_defaults(func=cmd_stress)

    p = sub.add_parser("sweep", help="a family of scene variants through both engines, gated",
                       description="Run variants of the scene (numbers of the scene file varied over a grid "
                                   "or a Monte Carlo sample) through both engines and the gate, as loopcheck run "
                                   "does (the scene's own settings and tolerances), in parallel; write "
                                   "sweep.csv and sweep.json (one row per variant: its status, the varied values, "
                                   "report.json's diff and gate figures, both engines' peaks and times), plots, "
                                   "and print a summary. With --engines reduced, only the reduced solver runs "
                                   "(its own error and energy checks, no MuJoCo, no gate). Variants that cannot be "
                                   "assembled (invalid) or whose engines fail numerically (failed) are counted "
                                   "rows. Exit 1 if any variant fails the gate or numerically or none is valid, 2 on bad input "
                                   "(checked before any run).")
    _add_scene_argument(p)
    p.add_argument("--vary", action="append", metavar="KEY=SPEC",
                   help="a dotted key of the scene file (bodies.coupler.mass, dampers.0.coefficient, "
                        "linkage.c2, mujoco.timestep, tolerances.peak_omega_rtol...) and its values: lo:hi:n, "
                        "a list a,b,c, normal(mu, sigma) or uniform(lo, hi); repeat for a full grid or a joint "
                        "sample. Without --vary: the scene file's [sweep] table; when both are given, "
                        "--vary wins and the table is ignored")
    p.add_argument("--engines", default=None, metavar="LIST",
                   help=f"what runs on each variant: {ENGINE_CHOICES[0]} (the design card's pair, compared and "
                        f"gated), {ENGINE_CHOICES[1]} (the reference alone with the settings the comparison gives "
                        f"it; sweep.csv has no diff or gate columns, no gate map or worst-differences plot), or a "
                        f"comma-separated list of engines (any of {', '.join(ENGINES)}; the reference among them), "
                        "each judged against the reference at its own tolerances. Default: the [sweep] table's "
                        "engines when the table is used, else both")
    p.add_argument("--batch-size", type=_int_in(1, 1_000_000), default=None, metavar="N",
                   help="variants of one structure that each engine declaring a batch size (BATCH_SIZE) runs "
                        "at once, in this process; default each engine's own; 1 runs them variant by variant on "
                        "the process pool")
    p.add_argument("--samples", type=_int_in(1, 1_000_000), default=None,
                   help="number of Monte Carlo variants (distributions only)")
    p.add_argument("--seed", type=_int_in(0, 2**63 - 1), default=None,
                   help="seed of the Monte Carlo sample (default 0)")
    _add_out_folder(p, "{scene}-sweep")
    p.add_argument("--workers", type=_int_in(1, MAX_WORKERS), default=None,
                   help="processes, at most one per core (default: all cores); not with --scheduler")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run the variants on the Dask cluster of this scheduler (tcp://host:8786) instead of "
                        "local processes: the same chunks of variants are its tasks and the rows are the same, "
                        "in the same order. Needs the distributed extra (pip install -e '.[distributed]' in loopcheck's checkout); "
                        "refused with --workers (the cluster's workers run the sweep); an address not "
                        "reached within 10 s is an error (exit 2)")
    p.add_argument("--keep-trajectories", action="store_true",
                   help="also write trajectories.csv, every variant's input trajectory from both engines "
                        "(for small sweeps)")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted sweep: the rows it finished, kept in the journal beside --out "
                        "(OUT.sweep-journal.csv, removed when a sweep completes), are not run again; the scene "
                        "file, keys, values and engines must be the same; its rows are checked and the first that "
                        "does not check runs again, with those after it. Not with --keep-trajectories")
    p.add_argument("--restart", action="store_true",
                   help="discard the journal of an interrupted sweep into --out and run every variant (without "
                        "--resume or --restart, a sweep whose journal is there is refused)")
    p.add_argument("--sensitivity", action="store_true",
                   help="also print d(peak |omega|)/d(key) at the nominal scene for each varied key, by central "
                        "differences of the reduced solver at two steps with an error estimate (in sweep.json too)")
    p.add_argument("--sensitivity-engines", type=_engines, default=None, metavar="LIST",
                   help="--sensitivity with each engine of the list (comma-separated, the reference among them): "
                        "each engine's own d(peak)/d(key), with the steps it chose at the nominal scene frozen, "
                        "printed beside the reference's (an engine that declares no peak accuracy is refused)")
    p.set_defaults(func=cmd_sweep)

    return parser


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"loopcheck: warning: {_one_line(message)}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _progress_shown(level: int = logging.INFO):
    """The engines' progress lines (the ``loopcheck`` loggers: MuJoCo's timestep search at INFO, each
    engine run's cost at DEBUG) on stderr as ``loopcheck: ...`` while a command runs, from ``level`` up
    (``--quiet``: warnings only; ``--verbose``: DEBUG)."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("loopcheck: %(message)s"))
    logger = logging.getLogger("loopcheck")
    logger.addHandler(handler)
    previous, logger.level = logger.level, level
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous)


def main(argv: list[str] | None = None) -> int:
    """Run one ``loopcheck`` command; return its exit status (see the module docstring).

    Started as the command (``loopcheck``, ``python -m loopcheck.compare.cli``: no ``argv``), the
    process ends here once its output is flushed (:func:`_end`), without the interpreter's
    finalization: nothing of the command is left to run then, and a thread still running (a
    signal being sent again, a library's) cannot crash the exit ("Fatal Python error:
    PyThreadState_Get ... finalizing", seen once in 14 runs of the signal test)."""
    status = _command(argv)
    if _AS_COMMAND and argv is None:
        _end(status)
    return status


def _end(status: int) -> None:
    """Flush stdout and stderr and leave the process with ``status`` at once (``os._exit``)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (`loopcheck ... | head`), a closed stream
            pass
    os._exit(status)


def _command(argv: list[str] | None) -> int:
    received: list[int] = []
    try:
        with signals_as_exceptions() as received, warnings.catch_warnings():
            warnings.simplefilter("default")  # each distinct warning once
            # but not Python's own ResourceWarning (a file a module import had open when a signal
            # cut it short, "unclosed file <...pyc>"): a developer's diagnostic, not the user's
            warnings.simplefilter("ignore", ResourceWarning)
            warnings.showwarning = _show_warning
            argv = sys.argv[1:] if argv is None else argv
            if not argv:  # `loopcheck` alone: what it can do
                build_parser().print_help()
                return EXIT_OK
            try:
                args = build_parser().parse_args(argv)
            except SystemExit as exc:  # --help, or a usage error already printed
                return exc.code if isinstance(exc.code, int) else EXIT_OK
            level = logging.WARNING if args.quiet else logging.DEBUG if args.verbose else logging.INFO
            if hasattr(args, "out_default"):
                args.out = _out_folder(args, getattr(args, "scene", None))
            with _progress_shown(level):
                return args.func(args)
    except BaseException as exc:  # noqa: BLE001 - each kind has its status; others go on
        return _failure(exc, received)


def _failure(exc: BaseException, received: list[int]) -> int:
    """Print the one line of what ended the command and return its exit status; raise what is
    not an expected failure (a bug: its traceback). A signal received decides, whatever became
    of its exception (a module interrupted while loading raises ImportError)."""
    import signal

    if isinstance(exc, KeyboardInterrupt) or (received and received[0] == signal.SIGINT):
        print("loopcheck: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    if isinstance(exc, Terminated) or received:
        print("loopcheck: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    if isinstance(exc, WriterDied):  # the outputs are as they were
        print(f"loopcheck: error: {_one_line(exc)}; nothing was written", file=sys.stderr)
        return EXIT_FAILED
    if isinstance(exc, NumericalFailure):
        print(f"loopcheck: numerical failure ({exc.reason}): {_one_line(exc)}", file=sys.stderr)
        for caveat in getattr(exc.partial, "caveats", ()):  # the failed run's known defects (loopcheck mjx)
            print(f"loopcheck: known defect: {caveat}", file=sys.stderr)
        return EXIT_FAILED
    if isinstance(exc, (SceneError, UsageError, OutputError, ValueError, ImportError)):
        # ImportError: an engine's library missing or of the wrong version, said in one line
        print(f"loopcheck: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if isinstance(exc, BrokenPipeError):  # output piped into e.g. `head`
        sys.stderr.close()
        return EXIT_OK
    if isinstance(exc, OSError):  # e.g. the disk filled up while writing: the outputs are as they were
        where = f"'{exc.filename}': " if exc.filename else ""
        print(f"loopcheck: error: {where}{exc.strerror or _one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    raise exc


if __name__ == "__main__":
    sys.exit(main())
