"""Assembly modes per loop in the comparison, and the mechanism strip and animation of
``loopcheck run``, on JointTrajectory objects built here from the loop kinematics.

The engines are not run: the runs are the Watt II six-bar (two loops) assembled by Newton's
method (loopcheck.kinematics.assemble) along a prescribed input motion q(t), with ẋ = K q̇. The
"MuJoCo" run is the same motion shifted by a small known Δq(t), or with its second loop
put in the other assembly mode part-way; the oracles are those constructions.
"""

from __future__ import annotations

import dataclasses
import math
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from loopcheck.compare.diff import ModeCheck, compare_modes, compare_trajectories, gate
from loopcheck.compare.draw import animate_run, configuration_at, draw_strip, gif_writer_available
from loopcheck.compare.draw import strip_moments
from loopcheck.compare.text import gate_lines
from loopcheck.kinematics import assemble, assembly_modes, coefficients, compile_linkage
from loopcheck.trajectory import JointTrajectory
from loopcheck.scene import Tolerances
from loopcheck.trajectory import Trajectory

from test_draw import watt_ii_scene

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def joint_trajectory(names, t, x, xdot, mode):
    return JointTrajectory(tuple(names), t, x, xdot, np.zeros(len(t), dtype=int), mode)


def input_motion(t, shift=0.0):
    """q(t) = 0.2 + 1.5t + 0.3t² + shift·sin(πt) (rad) and its first two derivatives."""
    q = 0.2 + 1.5 * t + 0.3 * t * t + shift * np.sin(math.pi * t)
    qd = 1.5 + 0.6 * t + shift * math.pi * np.cos(math.pi * t)
    qdd = 0.6 + 0.0 * t - shift * math.pi ** 2 * np.sin(math.pi * t)
    return q, qd, qdd


def watt_run(scene, t, shift=0.0, second_mode=1):
    """(JointTrajectory, Trajectory) of the Watt II along input_motion, second loop in
    ``second_mode``."""
    system = compile_linkage(scene.mechanism.linkage)
    q, qd, qdd = input_motion(t, shift)
    x = np.array([q[0], 0.7, 1.3, 0.3, -1.4 * second_mode])
    X, V = [], []
    for qq, vv in zip(q, qd):
        x = assemble(system, float(qq), x)
        K, _ = coefficients(system, x)
        X.append(x)
        V.append(K * vv)
    X, V = np.array(X), np.array(V)
    return (joint_trajectory(system.coordinate_names, t, X, V, assembly_modes(system, X)),
            Trajectory(t, q, qd, qdd))


@pytest.fixture(scope="module")
def scene():
    return watt_ii_scene((1, 1))


@pytest.fixture(scope="module")
def runs(scene):
    t = np.linspace(0.0, 1.0, 501)
    return watt_run(scene, t), watt_run(scene, t, shift=0.02)


# -- modes --------------------------------------------------------------------------------

def test_a_loop_in_its_other_mode_is_counted_on_that_loop(scene):
    t = np.linspace(0.0, 1.0, 101)
    (right, _), (other, _) = watt_run(scene, t), watt_run(scene, t, second_mode=-1)
    assert np.all(right.mode == [1, 1]) and np.all(other.mode == [1, -1])
    wrong = dataclasses.replace(right, x=np.vstack([right.x[:60], other.x[60:]]),
                                mode=np.vstack([right.mode[:60], other.mode[60:]]))
    assert compare_modes(right, right) == ModeCheck((0, 0), (None, None))
    check = compare_modes(right, wrong)
    assert check.mismatches == (0, 41) and check.first_times[0] is None
    assert check.first_times[1] == pytest.approx(0.6) and check.total == 41
    assert check.lines() == ["loop 2: 41 sample(s) from t = 0.6 s"]


def test_a_change_of_the_reference_s_mode_is_not_judged_near_it(scene):
    """A loop's mode changes legitimately at a limit position: a compared run that changes
    one sample later is not a mismatch; one that never changes is, after the window."""
    t = np.linspace(0.0, 1.0, 101)
    right, _ = watt_run(scene, t)
    ref_mode = right.mode.copy()
    ref_mode[50:, 0] = -1
    late = ref_mode.copy()
    late[50, 0] = 1
    ref = dataclasses.replace(right, mode=ref_mode)
    assert compare_modes(ref, dataclasses.replace(right, mode=late)).total == 0
    never = compare_modes(ref, right)  # window 2 × 0.01 s: samples 48..52 are not judged
    assert never.mismatches == (48, 0) and never.first_times[0] == pytest.approx(0.53)


def test_degenerate_samples_and_loop_counts(scene):
    t = np.linspace(0.0, 1.0, 11)
    right, _ = watt_run(scene, t)
    zero = right.mode.copy()
    zero[5, 1] = 0  # the dyad singular there: not judged
    assert compare_modes(right, dataclasses.replace(right, mode=zero)).total == 0
    with pytest.raises(ValueError, match="2 loop"):
        compare_modes(right, dataclasses.replace(right, mode=right.mode[:, :1]))


def test_the_gate_names_the_loop_and_the_unit(runs):
    (ref_j, ref), (oth_j, oth) = runs
    diff = compare_trajectories(ref, oth, horizon=1.0)
    modes = ModeCheck((0, 3), (None, 0.25))
    verdict = gate(diff, Tolerances(q_atol=1e-3), modes, unit="m")
    assert not verdict.passed
    text = "\n".join(verdict.failures)
    assert "assembly mode differs (loop 2: 3 sample(s) from t = 0.25 s)" in text
    assert f"q_max_abs = {diff.q_max_abs:.3e} m > tolerance 1.000e-03 m" in text
    assert "m/s" in gate_lines(verdict, "m")[0] and "rad" not in gate_lines(verdict, "m")[0]


# -- configurations along a run --------------------------------------------------------

def test_configuration_between_samples_is_the_assembled_one(scene, runs):
    """Cubic Hermite on 2 ms samples: measured worst 5.4e-12 rad against Newton's assembly
    over all midpoints (linear interpolation: 2e-6); bound 3e-11 (about 6x)."""
    (joints, _), _ = runs
    system = compile_linkage(scene.mechanism.linkage)
    mids = 0.5 * (joints.t[:-1] + joints.t[1:])
    q, _, _ = input_motion(mids)
    worst = 0.0
    for k in range(len(mids)):
        want = assemble(system, float(q[k]), joints.x[k])
        worst = max(worst, float(np.max(np.abs(configuration_at(joints, mids[k]) - want))))
    assert worst < 3e-11, worst
    assert np.array_equal(configuration_at(joints, 5.0), joints.x[-1])  # clamped to the run


def test_strip_moments_are_the_peak_and_the_largest_difference(runs, scene):
    (_, ref), (_, oth) = runs
    diff = compare_trajectories(ref, oth, horizon=1.0)
    c = type("C", (), {"diff": diff, "other_diffs": ()})()  # one input
    (l1, t1), (l2, t2) = strip_moments(c)
    # q̇ = 1.5 + 0.6 t rises to the end of the run: the peak is the horizon's end, and says so.
    assert (l1, l2) == ("peak speed (at the end of the horizon, still rising)", "largest |Δq|")
    assert t1 == pytest.approx(diff.t_peak_reference) and t1 == 1.0
    # Δq = 0.02 sin(πt): largest at t = 0.5 s, on the 2 ms grid.
    assert t2 == pytest.approx(0.5, abs=1e-12)


def test_strip_overlays_both_engines_at_the_moments(tmp_path, monkeypatch, scene, runs):
    """Panel k draws the reduced run solid and MuJoCo's dashed, each at its own
    configuration at that moment; the title gives both q in the input's unit."""
    import loopcheck.compare.plots

    (ref_j, _), (oth_j, _) = runs
    figures = []
    real_save = loopcheck.compare.plots._save

    def keep(fig, path):
        figures.append([(ax.get_title(), [(l.get_linestyle(), l.get_xydata().copy()) for l in ax.lines])
                        for ax in fig.axes])
        real_save(fig, path)

    monkeypatch.setattr(loopcheck.compare.plots, "_save", keep)
    out = tmp_path / "mechanism.png"
    draw_strip(scene, ref_j, oth_j, [("peak speed", 0.3), ("largest |Δq|", 0.5)], out)
    assert out.read_bytes()[:8] == PNG_SIGNATURE
    assert struct.unpack(">II", out.read_bytes()[16:24]) == (990, 462)  # 9 × 4.2 in at 110 dpi
    system = compile_linkage(scene.mechanism.linkage)
    from loopcheck.kinematics import positions

    (panels,) = figures
    for (title, lines), t in zip(panels, (0.3, 0.5)):
        q_ref, q_oth = input_motion(np.array([t]))[0][0], input_motion(np.array([t]), 0.02)[0][0]
        assert f"t = {t:g} s" in title and f"q reduced {q_ref:.6g} rad, MuJoCo {q_oth:.6g} rad" in title
        for style, joints, q in (("-", ref_j, q_ref), ("--", oth_j, q_oth)):
            crank = next(xy for ls, xy in lines if ls == style and len(xy) == 2)  # first body: crank
            r = positions(system.points, configuration_at(joints, t))
            want = np.array([r[system.point_index("crank", "O1")], r[system.point_index("crank", "A")]])
            assert np.allclose(np.sort(crank, axis=0), np.sort(want, axis=0), atol=1e-14)
            assert abs(math.atan2(*(want[1] - want[0])[::-1]) - q) < 1e-9  # the crank at q(t)


def test_a_run_of_another_linkage_is_refused(tmp_path, scene, runs):
    (ref_j, _), _ = runs
    renamed = dataclasses.replace(ref_j, names=("a",) + ref_j.names[1:])
    with pytest.raises(ValueError, match="not the scene's"):
        draw_strip(scene, ref_j, renamed, [("t", 0.1)], tmp_path / "x.png")


def test_animation_is_a_gif_with_one_frame_per_step(tmp_path, scene, runs):
    assert gif_writer_available()  # pillow is a dependency of matplotlib
    from PIL import Image

    (ref_j, _), (oth_j, _) = runs
    out = tmp_path / "mechanism.gif"
    animate_run(scene, ref_j, oth_j, out, frames=6)
    assert out.read_bytes()[:6] == b"GIF89a"
    with Image.open(out) as image:
        assert image.n_frames == 6


def test_without_a_gif_writer_the_animation_is_skipped_with_a_warning(monkeypatch):
    import loopcheck.compare.draw
    from loopcheck.compare.report import ANIMATION_FILE, REPORT_FILES, report_files, resolve_animation

    assert resolve_animation(False) is False
    assert resolve_animation(True) is True
    assert report_files(True) == REPORT_FILES[:-1] + (ANIMATION_FILE, "report.json")
    assert "mechanism.png" in REPORT_FILES
    monkeypatch.setattr(loopcheck.compare.draw, "gif_writer_available", lambda: False)
    with pytest.warns(UserWarning, match="--animate: matplotlib's PillowWriter is not available"):
        assert resolve_animation(True) is False


# -- the report of a comparison, without the engines ------------------------------------

def engine_result(engine, joints, trajectory, violation=0.0):
    from loopcheck.results import EngineResult
    from loopcheck.trajectory import Peak

    t = trajectory.t
    k = int(np.argmax(np.abs(trajectory.qdot)))
    kinetic = 0.5 * trajectory.qdot ** 2
    audit = EnergyAudit(t, kinetic, np.zeros_like(t), kinetic - kinetic[0], np.zeros_like(t))
    from loopcheck.reduced.settings import ReducedSettings
    from loopcheck.reference_models.settings import MujocoSettings
    from loopcheck.results import ConstraintViolation

    from loopcheck.reduced.engine import ReducedDetails
    from loopcheck.reference_models.run import MujocoDetails

    if engine == "mujoco":
        settings, violations = MujocoSettings(timestep=1e-3), ConstraintViolation(t, np.full(len(t), violation))
        details = MujocoDetails(trajectory.q, trajectory.qdot, np.zeros_like(t), {}, (), "test")
    else:
        settings, violations = ReducedSettings(), None
        details = ReducedDetails("DOP853", (), None, 1e-8, 1.0)
    return EngineResult(engine, trajectory, joints, Peak(float(t[k]), float(trajectory.qdot[k])), audit, 0.1,
                        len(t), 4 * len(t), settings, ("torque",), violations, details)


from loopcheck.results import EnergyAudit  # noqa: E402


def slider_run(scene, t, shift=0.0):
    """The slider-driven slider-crank along s(t) = 0.4 − 0.1t + shift·sin(πt) (m)."""
    system = compile_linkage(scene.mechanism.linkage)
    q = 0.4 - 0.1 * t + shift * np.sin(math.pi * t)
    qd = -0.1 + shift * math.pi * np.cos(math.pi * t)
    qdd = -shift * math.pi ** 2 * np.sin(math.pi * t)
    x, X, V = np.asarray(scene.x0), [], []
    for qq, vv in zip(q, qd):
        x = assemble(system, float(qq), x)
        X.append(x)
        V.append(coefficients(system, x)[0] * vv)
    X, V = np.array(X), np.array(V)
    return (joint_trajectory(system.coordinate_names, t, X, V, assembly_modes(system, X)),
            Trajectory(t, q, qd, qdd))


def comparison_of(scene, reference, other):
    """What loopcheck.compare.run.judge builds, from two constructed runs (the engines not run)."""
    (rj, rt), (oj, ot) = reference, other
    diff = compare_trajectories(rt, ot, horizon=float(rt.t[-1]))
    modes = compare_modes(rj, oj)
    tolerances = Tolerances(q_atol=1e-3, omega_atol=0.1)
    fields = dict(scene=scene, reference=engine_result("reduced", rj, rt),
                  other=engine_result("mujoco", oj, ot, 1e-9), diff=diff, modes=modes,
                  gate=gate(diff, tolerances, modes, unit=scene.input_unit))
    from loopcheck.compare.run import Comparison

    return Comparison(**fields)


def test_a_slider_driven_comparison_speaks_in_metres(tmp_path, monkeypatch):
    """Table, gate, report.json and CSV of a prismatic input give q in m and q̇ in m/s, the
    mode per loop; write_outputs writes every file, the strip and (asked for) the GIF."""
    import json

    from loopcheck.compare.report import ANIMATION_FILE, REPORT_FILES, report_dict, write_outputs
    from loopcheck.compare.text import comparison_lines
    from test_draw import slider_crank_scene

    scene = slider_crank_scene(0.4, prismatic_input=True)
    assert scene.input_unit == "m"
    t = np.linspace(0.0, 1.0, 201)
    c = comparison_of(scene, slider_run(scene, t), slider_run(scene, t, shift=0.002))
    lines = comparison_lines(c)
    rows = {line.split("  ")[0]: line for line in lines}
    assert "peak qdot (m/s)" in rows and "max |dq| (m)" in rows and "max |dqdot| (m/s)" in rows
    assert rows["mode mismatches (per loop)"].split()[-1] == "0"
    assert f"({', '.join(f'{v:+d}' for v in scene.mode)})" in rows["assembly mode at q0"]
    assert lines[0].startswith("scene: slider_crank (<memory>); input slide (m)")
    assert not any("rad" in line for line in lines), lines
    report = report_dict(c)
    assert report["schema_version"] == 7
    assert report["scene"]["input_unit"] == "m" and report["scene"]["input_joint"] == "slide"
    assert report["scene"]["mode"] == list(scene.mode)
    assert report["diff"]["mode_mismatches"] == [0] and report["diff"]["mode_mismatch_first_times"] == [None]
    import loopcheck.compare.draw

    monkeypatch.setattr(loopcheck.compare.draw, "ANIMATION_FRAMES", 4)  # a short GIF: this test is about the set
    paths = write_outputs(c, tmp_path / "out", animate=True)
    assert sorted(p.name for p in paths) == sorted(REPORT_FILES + (ANIMATION_FILE,))
    header = (tmp_path / "out" / "reduced.csv").read_text().split("\n")[0].split(",")
    assert header[:4] == ["t_s", "q_m", "qdot_m_per_s", "qddot_m_per_s2"] and "slide_m" in header  # then every joint
    assert json.loads((tmp_path / "out" / "report.json").read_text())["diff"]["mode_mismatches_total"] == 0
    assert (tmp_path / "out" / "mechanism.png").read_bytes()[:8] == PNG_SIGNATURE
    assert (tmp_path / "out" / ANIMATION_FILE).read_bytes()[:6] == b"GIF89a"


def test_a_mode_mismatch_reaches_the_table_and_the_report(scene):
    t = np.linspace(0.0, 1.0, 101)
    right = watt_run(scene, t)
    other_j, other_t = watt_run(scene, t, second_mode=-1)
    wrong_j = dataclasses.replace(right[0], x=np.vstack([right[0].x[:60], other_j.x[60:]]),
                                  mode=np.vstack([right[0].mode[:60], other_j.mode[60:]]))
    from loopcheck.compare.report import report_dict
    from loopcheck.compare.text import comparison_lines

    c = comparison_of(scene, right, (wrong_j, right[1]))
    assert not c.gate.passed
    rows = {line.split("  ")[0]: line for line in comparison_lines(c)}
    assert rows["mode mismatches (per loop)"].endswith("0, 41")
    assert report_dict(c)["diff"]["mode_mismatches"] == [0, 41]
    assert any("loop 2: 41 sample(s) from t = 0.6 s" in f for f in c.gate.failures)


def test_command_lines_of_a_slider_driven_scene_give_metres():
    """What ``loopcheck reduced``, ``loopcheck mujoco`` and ``loopcheck check`` print (loopcheck.compare.text) names
    the input joint and gives its unit."""
    from loopcheck.compare.text import check_lines, result_lines
    from test_draw import slider_crank_scene

    scene = slider_crank_scene(0.4, prismatic_input=True)
    t = np.linspace(0.0, 1.0, 51)
    run = slider_run(scene, t)
    red = result_lines(scene, engine_result("reduced", *run))
    mj = result_lines(scene, engine_result("mujoco", *run, violation=1e-9))
    for lines in (red, mj):
        assert lines[1].startswith("input            slide (q in m, mode (")
        peak = next(line for line in lines if line.startswith("peak qdot"))
        assert peak.endswith(" s (largest |qdot|)") and " m/s at t = " in peak
        assert not any("rad" in line for line in lines), lines
    c = comparison_of(scene, run, slider_run(scene, t, shift=0.002))
    head, *failures = check_lines(c)
    assert head.startswith("FAIL  <memory>: peak_omega_rel") and " m (tol 0.001)" in head and " m/s (tol 0.1)" in head
    # Δq = 0.002 sin(πt) m: Δq̇ peaks at 0.002π = 6.283e-3 m/s, max |Δq| is 2.000e-3 m.
    assert failures == ["      peak_omega_abs = 6.283e-03 m/s > tolerance peak_omega_rtol·|peak| + "
                        "peak_omega_atol = 1.000e-05 m/s (peak_omega_rel = 6.283e-02 > tolerance 1.000e-04)",
                        "      q_max_abs = 2.000e-03 m > tolerance 1.000e-03 m"]


@pytest.mark.parametrize("animate", [False, True])
def test_run_refuses_a_folder_where_an_output_goes_before_any_work(tmp_path, monkeypatch, capsys, animate):
    """``loopcheck run [--animate]`` checks every file it will write (mechanism.png, and
    mechanism.gif when animating) before reading the scene."""
    from loopcheck.compare import cli

    monkeypatch.setattr(cli, "_scene", lambda path: pytest.fail("the scene was read"))
    out = tmp_path / "out"
    out.mkdir()
    (out / ("mechanism.gif" if animate else "mechanism.png")).mkdir()
    assert cli.main(["run", "--out", str(out)] + (["--animate"] if animate else [])) == 2
    line, = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("loopcheck: error: --out") and "mechanism." in line and "is a folder" in line, line
