"""The command line, called in-process (``main([...])`` with captured output): destinations
refused before any work, exit statuses, signals, warnings, flags. One subprocess smoke test
checks the installed entry point.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import stat
import subprocess
import sys
from pathlib import Path

import pytest

import loopcheck.compare.cost
import loopcheck.compare.draw
import loopcheck.compare.report
import loopcheck.compare.run
import loopcheck.compare.stress
import loopcheck.compare.sweep
import loopcheck.reference_models
from loopcheck.compare import cli
from loopcheck.compare.cli import main
from loopcheck.compare.output import check_folder
from loopcheck.compare.cost import worker_count
from loopcheck.scenefile import scene_from_dict
from loopcheck.reduced.settings import ReducedSettings
from loopcheck.reference_models.settings import MujocoSettings
from loopcheck.settings import given_flags

from helpers import ROOT, SEED_SCENE, interruptible, seed_dict, short_seed_file, spawn  # noqa: F401 - fixtures



def one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    assert captured.out == ""  # nothing was computed or printed before the refusal
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]


@pytest.fixture
def no_work(monkeypatch):
    """Any computation fails the test: destinations must be refused before it starts."""
    def computed(*args, **kwargs):
        raise AssertionError("work started before the destination was checked")
    for module, name in ((loopcheck.compare.run, "compare_engines"), (loopcheck.compare.cost, "ground_truth"),
                         (loopcheck.compare.stress, "run_catalogue"), (loopcheck.reference_models, "build_model"),
                         (loopcheck.compare.sweep, "run_sweep"), (loopcheck.compare.draw, "draw_scene")):
        monkeypatch.setattr(module, name, computed)


def place(tmp_path: Path, kind: str) -> str:
    """A destination of the given kind under ``tmp_path``."""
    (tmp_path / "file").write_text("keep")
    (tmp_path / "folder").mkdir()
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    return {"existing file": str(tmp_path / "file"), "below a file": str(tmp_path / "file" / "out"),
            "missing folder": str(tmp_path / "nope" / "out"), "unwritable": str(locked / "out"),
            "long name": str(tmp_path / ("x" * 300)), "empty": "", "folder": str(tmp_path / "folder"),
            "dot-dot": str(tmp_path / "folder" / ".."), "device": str(tmp_path / "null"),
            "symlink": str(tmp_path / "link"), "in /proc": "/proc/loopcheck-out", "in /sys": "/sys/loopcheck-out",
            "/sys folder": "/sys/kernel"}[kind]


# (command, destination kind, words the message must contain)
BAD_DESTINATIONS = [
    *[(command, kind, words) for command in ("run", "cost", "stress") for kind, words in (
        ("existing file", "is a file"), ("below a file", "is not a folder"),
        ("missing folder", "does not exist"), ("unwritable", "cannot write"),
        ("long name", "too long"), ("empty", "--out is empty"))],
    ("export-mjcf", "folder", "is a folder"), ("export-mjcf", "dot-dot", "is a folder"),
    ("export-mjcf", "missing folder", "does not exist"), ("export-mjcf", "empty", "-o is empty"),
    ("export-mjcf", "device", "device node"), ("export-mjcf", "symlink", "symbolic link"),
    ("export-mjcf", "long name", "too long"),
    # Issue 24: os.access says yes to root there; refused only after the work until the probe.
    *[(command, kind, "cannot write") for command in ("run", "cost", "stress", "sweep", "draw", "export-mjcf")
      for kind in ("in /proc", "in /sys", "/sys folder")],
]


@pytest.mark.parametrize("command,kind,words", BAD_DESTINATIONS)
def test_bad_destination_is_refused_before_any_work(command, kind, words, tmp_path, capsys, no_work):
    dest = place(tmp_path, kind)
    if kind == "unwritable" and os.access(tmp_path / "locked", os.W_OK):  # root may write in it
        if os.access("/proc/1", os.W_OK):
            pytest.skip("no unwritable folder available to this user")
        dest = "/proc/1/out"
    if kind == "symlink":
        os.symlink(tmp_path / "file", dest)
    if kind == "device":  # our own null device: a planted bug must not replace the real one
        if os.geteuid() != 0:
            pytest.skip("creating a device node needs root")
        os.mknod(dest, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    before = sorted(p.name for p in tmp_path.rglob("*"))
    flag = ["-o", dest] if command == "export-mjcf" else ["--out", dest]
    if command in ("draw", "export-mjcf") and kind.startswith(("in ", "/sys")):
        flag[1] += "/l.png" if kind == "/sys folder" else ".png"
    extra = ["--vary", "dampers.0.coefficient=50,60"] if command == "sweep" else []
    assert main([command, *flag, *extra]) == 2
    assert words in one_error_line(capsys)
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing created, nothing removed
    assert (tmp_path / "file").read_text() == "keep"


@pytest.mark.parametrize("argv,words", [
    (["mujoco", "--iterations", "2147483648"], "--iterations: must be between 1 and 10000"),
    (["cost", "--workers", "100000"], "--workers: must be between 1 and 1024"),
    (["cost", "--repeats", "0"], "--repeats: must be between 1 and 1000"),
    (["check", str(SEED_SCENE), "--peak-rtol", "nan"], "must be finite"),
    (["mujoco", "--timestep", "-1"], "must be positive"),
    (["stress", "--case", "no_such_case"], "unknown case"),
    (["frobnicate"], "invalid choice"),
])
def test_bad_flag_value_exits_2_with_one_line(argv, words, capsys, no_work):
    assert main(argv) == 2
    assert words in one_error_line(capsys)


def test_only_the_flags_given_override_the_scene():
    data = seed_dict()
    data["mujoco"] = {"integrator": "euler", "timestep": 5e-4}
    scene = scene_from_dict(data)
    parser = cli.build_parser()
    plain = parser.parse_args(["run"])
    assert given_flags(plain, MujocoSettings) == {}
    assert given_flags(plain, ReducedSettings, prefix=cli.REFERENCE_PREFIX) == {}
    settings = cli._mujoco_settings(parser.parse_args(["run", "--integrator", "rk4"]), scene)
    assert (settings.integrator, settings.timestep) == ("rk4", 5e-4)  # flag over table, table kept
    reduced = parser.parse_args(["reduced"])
    assert (reduced.method, reduced.rtol, reduced.step) == (None, None, None)
    data["reduced"] = {"method": "radau"}
    scene = scene_from_dict(data)
    settings = cli._settings("reduced", parser.parse_args(["reduced", "--rtol", "1e-9"]), scene)
    assert (settings.method, settings.rtol) == ("radau", 1e-9)


def test_workers_are_capped_at_the_cores():
    cores = os.cpu_count() or 1
    assert worker_count(1024, 100) == cores
    assert worker_count(None, 1) == 1
    assert worker_count(1, 100) == 1


def test_warnings_are_one_line_each(capsys):
    """An off-grid pulse edge (1.00037 s on a 1 ms grid) is warned about on stderr, once, in one line."""
    scene = str(ROOT / "scenes" / "hard" / "off_grid_edge.toml")
    assert main(["mujoco", scene, "--timestep", "0.001"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err and all(line.startswith("loopcheck: warning: ") for line in err), err
    assert any("not a multiple of the timestep" in line for line in err)
    assert len(err) == len(set(err))


@pytest.mark.parametrize("signum,status,line", [(signal.SIGINT, 130, "loopcheck: interrupted"),
                                                (signal.SIGTERM, 143, "loopcheck: terminated")])
def test_a_signal_stops_cleanly_and_leaves_nothing(signum, status, line, tmp_path, capsys, monkeypatch,
                                                  interruptible):
    def signalled(*args, **kwargs):
        os.kill(os.getpid(), signum)
        raise AssertionError("the signal did not stop the run")
    monkeypatch.setattr(loopcheck.compare.run, "compare_engines", signalled)
    previous = signal.getsignal(signal.SIGTERM)
    assert main(["run", str(SEED_SCENE), "--out", str(tmp_path / "out")]) == status
    assert capsys.readouterr().err == line + "\n"
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) == previous  # handlers restored after main()


def test_failed_gate_exits_1_and_still_writes_the_report(tmp_path, capsys):
    """Also: a scene name that is mathtext to matplotlib, and longer than a title shows (the
    scene's limit is 100 characters, titles cut at NAME_CHARS = 60), is plotted as text."""
    data = seed_dict()
    data["name"] = r"a $x^$ and $\undefined$ " + "x" * 70  # both are errors as mathtext
    scene = tmp_path / "dollar.toml"
    scene.write_text(SEED_SCENE.read_text().replace('name = "seed_fourbar"', f"name = {json.dumps(data['name'])}"))
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--peak-rtol", "1e-12", "--timestep", "1e-3"]) == 1
    captured = capsys.readouterr()
    assert "gate: FAILED" in captured.out and "Traceback" not in captured.err
    report = json.loads((out / "report.json").read_text())
    assert report["gate"]["passed"] is False and report["scene"]["name"] == data["name"]
    assert not Path(report["scene"]["source"]).is_absolute()
    assert all((out / name).stat().st_size > 0 for name in loopcheck.compare.report.REPORT_FILES)


def test_long_names_are_cut_in_titles():
    from loopcheck.compare.plots import NAME_CHARS, short_name

    assert short_name("x" * 10**6) == "x" * (NAME_CHARS - 1) + "…"
    assert short_name("a\nb  c") == "a b c" and short_name("seed_fourbar") == "seed_fourbar"


def test_entry_point_smoke(tmp_path):
    """The one subprocess: ``python -m loopcheck.compare.cli`` runs, exits 2 with one line on a bad -o."""
    proc = subprocess.run([sys.executable, "-m", "loopcheck.compare.cli", "export-mjcf", "-o", ""], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr == "loopcheck: error: -o is empty: give a file name\n"
    assert list(tmp_path.iterdir()) == []


def test_a_scene_table_the_engine_refuses_names_the_file_and_table(tmp_path, capsys):
    """[mujoco] solimp out of MuJoCo's range in a scene: one line naming the file and the table,
    exit 2, nothing written; the same values as a flag name the field."""
    scene = tmp_path / "bad_solimp.toml"
    scene.write_text(SEED_SCENE.read_text().replace(
        "[simulation]", "[mujoco]\nsolimp = [2.0, 2.0, 2.0, 2.0, 2.0]\n\n[simulation]"))
    assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"loopcheck: error: {scene}: [mujoco] solimp") and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- help states the real defaults

def _options():
    """(command, action) for every option of every command."""
    parser = cli.build_parser()
    [commands] = [a for a in parser._actions if a.dest == "command"]
    for name, sub in commands.choices.items():
        for action in sub._actions:
            if action.option_strings and action.help:
                yield name, action


def _resolved_defaults() -> dict[str, list[str]]:
    """Flag -> the defaults the settings resolve to when neither the flag nor the scene gives
    one, as the help should print them; taken from the settings objects, not the CLI."""
    from loopcheck.sweep_spec import spec_from_args
    from loopcheck.reduced import ReducedSettings

    mj = loopcheck.reference_models.MujocoSettings()
    rtols = [f"{ReducedSettings(method=m).rtol:g} (" for m in ("dop853", "rkn4", "radau", "scipy-dop853")]
    step = [f"{ReducedSettings(method='rkn4').step:g}"]
    method = [ReducedSettings().method]
    assert mj.timestep is None  # chosen from the scene: the help must say so, with no number
    return {"--integrator": [mj.integrator], "--timestep": ["chosen from the scene"],
            "--solimp": [", ".join(f"{v:g}" for v in mj.solimp)], "--iterations": [f"else {mj.iterations}"],
            "--tolerance": [f"{mj.tolerance:g}"], "--reference-method": method, "--method": method,
            "--reference-rtol": rtols, "--rtol": rtols, "--reference-step": step, "--step": step,
            "--seed": [f"default {spec_from_args(['a.b=1,2']).seed}"]}


def test_every_help_default_is_the_resolved_default():
    import re

    from loopcheck.pin import PinSettings

    pin = PinSettings()  # `loopcheck pin`'s flags share names with the reduced engine's, not their defaults
    resolved_by_command = {"pin": {"--method": [f"else {pin.method}"], "--rtol": [f"else {pin.rtol:g}"]},
                           **{port: {**_resolved_defaults(), "--timestep": ["the grid step"]} for port in ("mjx", "mjwarp")}}
    for command, action in _options():
        resolved = resolved_by_command.get(command) or _resolved_defaults()
        flag = max(action.option_strings, key=len)
        text = " ".join(action.help.split())
        if flag in resolved:
            for expected in resolved[flag]:
                assert expected in text, f"loopcheck {command} {flag}: help {text!r} lacks the default {expected!r}"
            if flag == "--timestep":
                assert not re.search(r"\d", text), f"loopcheck {command} {flag}: {text!r} states a number"
        elif action.default not in (None, False, True) and "default" in text:
            shown = str(action.default)
            assert shown in text, f"loopcheck {command} {flag}: help {text!r} lacks its default {shown!r}"


# ---------------------------------------------------------------- a signal at any moment of a run

def _run_folder(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_at_any_moment_of_loopcheck_run_ends_it_cleanly(signum, tmp_path, spawn):
    """Issue 24: SIGTERM or Ctrl-C while `loopcheck run` forked its plot writers hung it (a zombie
    writer, a second SIGTERM ignored, the staging folder left) or was swallowed (exit 0, the
    results replaced). The signal goes to the whole process group, as a terminal's Ctrl-C does,
    at delays spread from start-up to past the run's end (the run's length measured first, on
    this machine). Every time: exit 130/143 (or killed by the signal itself before loopcheck's
    handlers are set: -2/-15 here, 130/143 in a shell), at most one line on stderr, no process of
    the group left, no staging folder, and the folder as it was unless the run said it wrote."""
    import time

    from loopcheck.compare.output import STAGING_PREFIX

    scene = short_seed_file(tmp_path)
    old = tmp_path / "old"
    length = math.inf
    for _ in range(3):  # the shortest of three (warm caches), as on a loaded machine the runs below may be
        start = time.monotonic()  # faster than one slowed calibration run: signals then all came after the end
        first = subprocess.run([sys.executable, "-m", "loopcheck.compare.cli", "run", str(scene), "--out", str(old)],
                               capture_output=True, text=True, timeout=300)
        length = min(length, time.monotonic() - start)
        assert first.returncode == 0, first.stderr
    before = _run_folder(old)
    statuses = {signal.SIGINT: (130, -signal.SIGINT), signal.SIGTERM: (143, -signal.SIGTERM)}[signum]
    outcomes = []
    for fraction in (0.03, 0.3, 0.6, 0.8, 0.9, 0.97, 1.1):
        out = tmp_path / f"out-{fraction}"
        shutil.copytree(old, out)
        proc = spawn([sys.executable, "-m", "loopcheck.compare.cli", "run", str(scene), "--out", str(out)],
                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        time.sleep(fraction * length)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signum)
        printed, err = proc.communicate(timeout=60)  # a hang fails here
        left = subprocess.run(["ps", "-o", "pid=,args=", "-g", str(proc.pid)], capture_output=True, text=True).stdout
        wrote = "wrote " in printed
        outcomes.append((fraction, proc.returncode, wrote))
        assert left == "", f"at {fraction:.2f} of the run: processes left: {left}"
        assert not [p for p in out.iterdir() if p.name.startswith(STAGING_PREFIX)], f"staging left at {fraction}"
        if proc.returncode == 0:  # only when the run had ended before the signal was sent
            assert wrote and fraction >= 0.6, (fraction, err)
        else:
            assert proc.returncode in statuses, (fraction, proc.returncode, err)
            assert err.count("\n") <= 1 or proc.returncode < 0, (fraction, err)
        now = _run_folder(out)
        if wrote:
            assert set(now) == set(before) and now["report.json"] != before["report.json"], fraction
        else:
            assert now == before, f"at {fraction:.2f} of the run the folder changed"
    assert sum(not wrote for _, _, wrote in outcomes) >= 3, outcomes  # most signals came during the run


def test_the_default_output_folder_is_loopcheck_out_and_the_scene(tmp_path, monkeypatch, capsys):
    """Without -o, a command writes into loopcheck-out/<scene file's stem>[-cost|-sweep] (stress, which
    has no scene: loopcheck-out/stress); loopcheck-out is created with the outputs, never on bad input."""
    from loopcheck.compare.output import write_folder

    monkeypatch.chdir(tmp_path)
    (tmp_path / "press.toml").write_text(SEED_SCENE.read_text(encoding="utf-8"), encoding="utf-8")
    parser = cli.build_parser()
    for argv, expected in ((["run"], "loopcheck-out/seed_fourbar"), (["run", "press.toml"], "loopcheck-out/press"),
                           (["run", "watt2_sixbar"], "loopcheck-out/watt2_sixbar"),
                           (["cost", "press.toml"], "loopcheck-out/press-cost"), (["stress"], "loopcheck-out/stress"),
                           (["sweep", "press.toml"], "loopcheck-out/press-sweep"), (["run", "-o", "mine"], "mine")):
        args = parser.parse_args(argv)
        assert cli._out_folder(args, getattr(args, "scene", None)) == expected, argv
    (tmp_path / "bad.toml").write_text('name = "x"\n', encoding="utf-8")
    assert main(["run", "bad.toml"]) == 2 and "missing key 'linkage'" in one_error_line(capsys)
    assert not (tmp_path / "loopcheck-out").exists()  # bad input leaves nothing behind
    with pytest.raises(cli.OutputError, match="does not exist"):
        check_folder("elsewhere/press")  # only the default root may be missing
    [path] = write_folder("loopcheck-out/press", {"a.txt": lambda p: p.write_text("a")})
    assert path == Path("loopcheck-out/press/a.txt") and path.read_text() == "a"
