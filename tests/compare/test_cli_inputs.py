"""What the command line takes and refuses around its inputs: an output that is an input (by
name, through a symbolic or a hard link) is refused; the model flags with scene files; --horizon
over a scene's horizon; a missing extra of `run --engines` before any work; a signal during
start-up and a killed file writer end in one line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import loopcheck.compare.engines
import loopcheck.compare.report
import loopcheck.compare.run
from loopcheck.compare.cli import main

from helpers import SEED_SCENE, plots_left_out, short_seed_file, spawn  # noqa: F401 - fixtures


def one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """The seed's MuJoCo model, exported once for the module."""
    path = tmp_path_factory.mktemp("model") / "seed.xml"
    assert main(["export-mjcf", str(SEED_SCENE), "-o", str(path)]) == 0
    return path


def _linked(tmp_path: Path, source: Path, how: str) -> tuple[Path, Path]:
    """(the input given on the command line, the output named) for ``how`` the output is the input."""
    data = tmp_path / ("in" + source.suffix)
    data.write_bytes(source.read_bytes())
    if how == "same name":
        return data, data
    other = tmp_path / ("other" + source.suffix)
    if how == "hard link":
        os.link(data, other)
        return data, other
    os.symlink(data.name, other)  # the input given through a symbolic link, the output the file itself
    return other, data


@pytest.mark.parametrize("how", ["same name", "hard link", "symbolic link"])
@pytest.mark.parametrize("command", ["import-mjcf", "export-mjcf", "draw", "run", "run-folder"])
def test_an_output_that_is_an_input_is_refused_and_nothing_is_written(command, how, tmp_path, model, capsys):
    """Issue: `import-mjcf m.xml -o m.xml` replaced the user's model with the scene (exit 0)."""
    source = model if command == "import-mjcf" else SEED_SCENE
    given, out = _linked(tmp_path, source, how)
    before = out.read_bytes()
    name = {"import-mjcf": "import-mjcf", "export-mjcf": "export-mjcf", "draw": "draw"}.get(command, "run")
    target = out
    if command == "run-folder":  # an output file of the folder that is the input
        folder = tmp_path / "folder"
        folder.mkdir()
        os.link(out, folder / "report.json")
        target = folder
    assert main([name, str(given), "-o", str(target)]) == 2
    line = one_error_line(capsys)
    assert "is an input of this command" in line and "never writes over" in line, line
    assert capsys.readouterr().out == ""
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.rglob("*") if p.name.startswith(".loopcheck")) == []


def test_an_output_beside_its_input_is_written(tmp_path, model, capsys):
    """The check compares files, not folders or names: another file of the same folder is fine."""
    scene = tmp_path / "s.xml"
    assert main(["import-mjcf", str(model), "-o", str(tmp_path / "s.toml")]) == 0
    assert main(["export-mjcf", str(tmp_path / "s.toml"), "-o", str(scene)]) == 0
    assert scene.read_text().lstrip().startswith("<")


@pytest.mark.parametrize("argv", [["run", "{scene}", "--keyframe", "home"], ["run", "{scene}", "--input", "O1"],
                                  ["run", "{scene}", "--ctrl", "1"],
                                  ["run", "{scene}", "--engines", "reduced,mujoco", "--ctrl", "1"],
                                  ["check", "{scene}", "--keyframe", "nosuch", "--input", "nosuch"]])
def test_model_flags_with_scene_files_alone_are_refused(argv, tmp_path, monkeypatch, capsys):
    """Issue: `check seed_fourbar --keyframe nosuch --input nosuch` passed (exit 0): they were ignored."""
    monkeypatch.setattr(loopcheck.compare.run, "compare_engines", lambda *a, **k: pytest.fail("work started"))
    argv = [a.format(scene=SEED_SCENE) for a in argv] + (["-o", str(tmp_path / "out")] if argv[0] == "run" else [])
    assert main(argv) == 2
    line = one_error_line(capsys)
    assert "MuJoCo model (.xml)" in line and "--" in line, line
    assert not (tmp_path / "out").exists()


def test_in_a_mixed_list_the_model_flags_are_the_models(model, capsys):
    """`check scene model.xml --keyframe K`: the keyframe is the model's (here, one it lacks)."""
    assert main(["check", str(SEED_SCENE), str(model), "--keyframe", "nosuch"]) == 2
    line = one_error_line(capsys)
    assert "nosuch" in line and "keyframe" in line and "MuJoCo model (.xml)" not in line, line


def test_horizon_overrides_a_scene_s_and_says_so(tmp_path, capsys):
    """Issue: `run seed_fourbar --horizon 0.5` ran 2 s. The compared span, report.json and the
    CSVs end at the flag's horizon, and the first line says where it came from."""
    scene = short_seed_file(tmp_path, "0.3")
    out = tmp_path / "out"
    with plots_left_out():
        assert main(["run", str(scene), "--horizon", "0.1", "-o", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == f"horizon 0.1 s from --horizon, over {scene}'s simulation.horizon = 0.3 s"
    report = json.loads((out / "report.json").read_text())
    assert report["scene"]["horizon"] == 0.1 and report["diff"]["span_end"] == pytest.approx(0.1, abs=1e-12)
    times = [float(line.split(",")[0]) for line in (out / "reduced.csv").read_text().splitlines()[1:]]
    assert times[-1] == pytest.approx(0.1, abs=1e-12)
    assert main(["check", str(scene), "--horizon", "5000"]) == 2  # the scene file's range applies to it
    assert "with --horizon 5000" in one_error_line(capsys)


@pytest.mark.parametrize("horizon", [None, '"long"'])
def test_horizon_over_a_scene_file_that_is_wrong_as_written_is_refused(tmp_path, capsys, horizon):
    """The scene file is checked as written before --horizon replaces its horizon: a missing or
    unreadable simulation.horizon is its one-line refusal, exit 2 (it was a TypeError traceback,
    formatting the value it replaced)."""
    text = short_seed_file(tmp_path, "0.3").read_text()
    head, rest = text.split("horizon = 0.3", 1)
    scene = tmp_path / "wrong.toml"
    scene.write_text(head + ("" if horizon is None else f"horizon = {horizon}") + rest)
    assert main(["run", str(scene), "--horizon", "0.1", "-o", str(tmp_path / "out")]) == 2
    assert "simulation.horizon" in one_error_line(capsys)
    assert not (tmp_path / "out").exists()


def test_run_engines_with_a_missing_extra_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """Issue: `run --engines reduced,mujoco,pin` ran the reduced solver and MuJoCo first; `check
    --engines` already refused at once."""
    import importlib.util

    missing = next((n for n, module in (("pin", "pinocchio"), ("mjx", "jax"), ("mjwarp", "warp"))
                    if importlib.util.find_spec(module) is None), None)
    if missing is None:
        pytest.skip("every extra is installed")
    monkeypatch.setattr(loopcheck.compare.engines, "check_engines", lambda *a, **k: pytest.fail("work started"))
    monkeypatch.setattr(loopcheck.compare.run, "compare_engines", lambda *a, **k: pytest.fail("work started"))
    out = tmp_path / "out"
    assert main(["run", str(SEED_SCENE), "--engines", f"reduced,mujoco,{missing}", "-o", str(out)]) == 2
    line = one_error_line(capsys)
    assert "pip install" in line, line
    assert capsys.readouterr().out == "" and not out.exists()


def _caught(pid: int) -> int:
    """The signals a process catches (SigCgt of /proc/PID/status), as a bit mask."""
    with open(f"/proc/{pid}/status") as status:
        return next(int(line.split()[1], 16) for line in status if line.startswith("SigCgt:"))


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
def test_ctrl_c_during_start_up_is_one_line_and_exit_130(tmp_path, spawn):
    """Issue: a Ctrl-C in the first ~0.3 s (the command's modules loading) printed a traceback.
    The signal is sent once the command catches SIGTERM (its start-up handlers, Python's own
    catch SIGINT only) while numpy is not loaded yet: inside the start-up, deterministically."""
    proc = spawn([sys.executable, "-m", "loopcheck.compare.cli", "run", str(SEED_SCENE), "-o", str(tmp_path / "o")],
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while not _caught(proc.pid) & (1 << (signal.SIGTERM - 1)):
        assert proc.poll() is None and time.monotonic() < deadline
    with open(f"/proc/{proc.pid}/maps") as maps:
        loaded = maps.read()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert "_multiarray_umath" not in loaded, "the command caught SIGTERM only once numpy had loaded"
    assert (proc.returncode, err, out) == (130, "loopcheck: interrupted\n", "")
    assert not (tmp_path / "o").exists()


def test_a_killed_file_writer_is_one_line_and_exit_1(tmp_path, monkeypatch, capsys):
    """Issue: a plot writer killed (SIGKILL: the out-of-memory killer) printed a traceback. The
    writer run in the forked child kills itself; the folder stays as it was."""
    if "jax" in sys.modules or (os.cpu_count() or 1) < 2:
        pytest.skip("the writers run in this process here (no fork)")
    parent = os.getpid()

    def plot(c, path):
        if os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
        path.write_bytes(b"png")

    monkeypatch.setattr(loopcheck.compare.report, "PLOTS", {f"{k}.png": plot for k in range(4)})
    scene = short_seed_file(tmp_path, "0.05")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out)]) == 1
    line = one_error_line(capsys)
    assert line.startswith("loopcheck: error: a file writer (process ") and "SIGKILL" in line, line
    assert line.endswith("nothing was written")
    assert not out.exists()


@pytest.mark.parametrize("argv, status", [(["scenes"], 0), (["run", "nosuch.toml"], 2)])
def test_the_command_ends_without_the_interpreter_s_finalization(argv, status, tmp_path):
    """The command's process leaves by os._exit once its output is flushed: no thread (a signal
    being sent again, a library's) can run into the interpreter's finalization, where a signal
    test once ended in "Fatal Python error: PyThreadState_Get ... finalizing" (exit -6, 1 run in
    14). Seen from outside: an atexit function (a sitecustomize registers one) never runs, and
    the output is all there. (Planted: returning from main instead, "finalized" is printed.)"""
    (tmp_path / "sitecustomize.py").write_text(
        "import atexit, sys\natexit.register(lambda: sys.stderr.write('finalized\\n'))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[2]), str(tmp_path)])}
    done = subprocess.run([sys.executable, "-m", "loopcheck.compare.cli", *argv], capture_output=True, text=True,
                          env=env, cwd=tmp_path, timeout=120)
    assert done.returncode == status and "finalized" not in done.stderr, done.stderr
    assert (done.stdout.count("\n") > 10) if status == 0 else done.stderr.startswith("loopcheck: error:")
    probe = subprocess.run([sys.executable, "-c", "print(1)"], capture_output=True, text=True, env=env, timeout=60)
    assert probe.stderr == "finalized\n"  # the control: the hook works in this interpreter


def test_python_s_resource_warnings_are_not_the_user_s(monkeypatch, capsys):
    """A signal that cuts an import short leaves the .pyc it was reading unclosed: Python's
    ResourceWarning was printed as a second line, `loopcheck: warning: unclosed file <...pyc>`, before
    `loopcheck: terminated` (1 signal test in 25). Here a command drops an open file."""
    import gc

    from loopcheck.compare import cli

    def leaky(args):
        open(SEED_SCENE, "rb")  # noqa: SIM115 - dropped open on purpose
        gc.collect()
        return 0

    monkeypatch.setattr(cli, "cmd_scenes", leaky)
    assert main(["scenes"]) == 0
    assert capsys.readouterr().err == ""


def test_a_scene_the_reference_cannot_run_is_refused_before_any_output(capsys):
    """`check a b` where the reference refuses b (joint friction under scipy's Radau): one line
    naming b's file, exit 2, and nothing of a's check printed first (planted: the refusal raised
    only when b runs printed a's result lines and named no file)."""
    root = Path(__file__).resolve().parents[2] / "scenes"
    friction = root / "mechanisms" / "friction_fourbar.toml"
    assert main(["check", str(root / "seed_fourbar.toml"), str(friction), "--reference-method", "radau"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.count("\n") == 1 and err.startswith(f"loopcheck: error: {friction}: the reduced engine's method radau")


@pytest.mark.parametrize("command", ["check", "run"])
def test_a_name_the_mujoco_model_reserves_is_refused_naming_the_scene_file(command, tmp_path, capsys):
    """An actuator named 'input_motor' beside a [torque] load (the name of the load's motor in the
    MuJoCo model): one line naming the scene file, exit 2, nothing on stdout (planted: the builder's
    ValueError printed without the file)."""
    text = (Path(__file__).resolve().parents[2] / "scenes" / "mechanisms" / "friction_fourbar.toml").read_text()
    text = text.replace("[torque]", '[[actuators]]\nname = "input_motor"\njoint = "O3"\n\n[torque]', 1)
    scene = tmp_path / "clash.toml"
    scene.write_text(text)
    assert main([command, str(scene), "-o", str(tmp_path / "out")] if command == "run" else [command, str(scene)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert err.startswith(f"loopcheck: error: {scene}: actuator name 'input_motor' is the input load's motor")
