"""The comparison over n coordinates (issue 40) on the five-bar robot (scenes/mechanisms/five_bar_robot.toml,
two inputs O1 and O5): every input's difference and peak, the gate over the inputs naming the
failing one, report.json's ``inputs`` and every joint, the table and check lines, the plots in
small multiples. Until the reduced engine runs several inputs, the two runs compared are MuJoCo's
at 0.25 ms (as the reference) and at 1 ms, through the comparison's own code (``judge``,
``write_outputs``, the text functions): what a comparison of two engines does with them.

The two runs' differences (measured): O1 max |Δq| 6.2e-5 rad, O5 9.95e-5 rad; max |Δq̇| 4.0e-3
and 1.8e-3 rad/s. A q_atol of 8e-5 rad lies between the two inputs' figures, so the gate fails on
O5 alone.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from loopcheck.compare.diff import compare_trajectories, gate, gate_inputs
from loopcheck.compare.report import SCHEMA_VERSION, write_outputs
from loopcheck.compare.run import judge
from loopcheck.compare.text import check_lines, comparison_lines
from loopcheck.reference_models.run import simulate_mujoco
from loopcheck.reference_models.settings import MujocoSettings
from loopcheck.scene import Tolerances
from loopcheck.scenefile import load_scene
from loopcheck.trajectory import Trajectory

from helpers import plots_left_out

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "mechanisms", "five_bar_robot.toml")
BETWEEN = Tolerances(q_atol=8e-5)  # rad: above O1's max |Δq| (6.2e-5), below O5's (9.95e-5)


@pytest.fixture(scope="module")
def runs():
    scene = load_scene(SCENE)
    return (scene, simulate_mujoco(scene, MujocoSettings(timestep=2.5e-4)),
            simulate_mujoco(scene, MujocoSettings(timestep=1e-3)))


def test_every_input_has_its_own_difference_and_peak(runs):
    scene, fine, coarse = runs
    c = judge(scene, fine, coarse, Tolerances())
    assert len(c.diffs) == 2 and c.diffs[0] is c.diff
    for d, (ref, _), (oth, _) in zip(c.diffs, fine.inputs, coarse.inputs):
        alone = compare_trajectories(ref, oth, horizon=scene.horizon, peak_floor=d.peak_floor)
        assert d.figures() == alone.figures()
    o1, o5 = c.diffs
    assert o1.peak_omega_reference > 20.0 and o5.peak_omega_reference < -15.0  # each input's own peak
    assert 5e-5 < o1.q_max_abs < 8e-5 < o5.q_max_abs < 1.2e-4
    assert c.gate.passed


def test_the_gate_judges_every_input_and_names_the_failing_one(runs):
    scene, fine, coarse = runs
    c = judge(scene, fine, coarse, BETWEEN)
    assert not c.gate.passed
    assert len(c.gate.failures) == 1 and c.gate.failures[0].startswith("O5: q_max_abs = 9.9")
    lines = comparison_lines(c)
    assert lines[0].endswith("inputs O1 (rad), O5 (rad); effects: actuator, gravity")
    assert any(line.startswith("O5 max |dq| (rad)") for line in lines)
    assert any(line.startswith("O1 peak qdot (rad/s)") for line in lines)
    assert lines[-1] == "  " + c.gate.failures[0]
    check = check_lines(c)
    assert check[0].startswith("FAIL") and check[0].endswith(": 2 inputs")
    assert check[1].startswith("      O1: peak_omega_rel") and check[2].startswith("      O5: peak_omega_rel")
    assert check[-1] == "      " + c.gate.failures[0]


def test_a_run_that_records_one_input_of_two_is_refused(runs):
    scene, fine, coarse = runs
    with pytest.raises(ValueError, match="records 1 input trajectories, the scene has 2 inputs"):
        judge(scene, fine, dataclasses.replace(coarse, other_inputs=()), BETWEEN)


def _trajectory(scale: float) -> Trajectory:
    t = np.linspace(0.0, 1.0, 101)
    return Trajectory(t, scale * np.sin(t), scale * np.cos(t), -scale * np.sin(t))


def test_inputs_of_mixed_units_are_each_judged_in_their_own_unit():
    """An angle and a displacement: q_atol is read in rad for the one and in m for the other (the
    one-input rule), and each failure names its input and its unit."""
    ref = _trajectory(1.0)
    diffs = (compare_trajectories(ref, _trajectory(1.0 + 5e-4)),  # |Δq| 4.2e-4 rad: within 1e-3
             compare_trajectories(ref, _trajectory(1.0 + 5e-3)))  # |Δq| 4.2e-3 m: above 1e-3
    tolerances = Tolerances(peak_omega_rtol=0.1)  # the peaks (5e-4, 5e-3 apart) are not judged here
    verdict = gate_inputs(diffs, tolerances, units=("rad", "m"), names=("crank", "slide"))
    assert verdict.failures == (f"slide: q_max_abs = {diffs[1].q_max_abs:.3e} m > tolerance 1.000e-03 m",)
    one = gate_inputs(diffs[1:], tolerances, units=("m",), names=("slide",))
    assert one == gate(diffs[1], tolerances, unit="m")  # one input: today's gate, unnamed
    assert one.failures[0].startswith("q_max_abs")


def test_report_json_has_every_input_and_every_joint(runs, tmp_path):
    scene, fine, coarse = runs
    c = judge(scene, fine, coarse, BETWEEN)
    with plots_left_out():  # the CSVs and report.json are read here; the plots below
        write_outputs(c, tmp_path)
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["schema_version"] == SCHEMA_VERSION == 7
    assert report["scene"]["inputs"] == ["O1", "O5"] and report["scene"]["initial_q"] == [1.8, 1.3]
    assert report["scene"]["initial_qdot"] == [0.5, -0.3] and report["scene"]["input_units"] == ["rad", "rad"]
    assert [i["name"] for i in report["inputs"]] == ["O1", "O5"]
    for entry, d in zip(report["inputs"], c.diffs):
        assert entry["unit"] == "rad" and entry["diff"]["q_max_abs"] == d.q_max_abs
        assert entry["reference"]["peak_omega"] == d.peak_omega_reference
        assert entry["other"]["peak_omega"] == d.peak_omega_other
    assert report["diff"]["q_max_abs"] == c.diffs[0].q_max_abs  # the top level stays the first input's
    assert [j["name"] for j in report["joints"]] == ["O1", "A", "P", "B", "O5"]
    assert report["gate"]["failures"] == list(c.gate.failures)
    header = (tmp_path / "mujoco.csv").read_text().splitlines()[0].split(",")
    assert "O5_rad" in header and "O5_rate_rad_per_s" in header  # the second input's trajectory


def test_the_plots_have_a_column_per_input(runs, tmp_path):
    """Small multiples: one column per input, wider than the one-input figure (8 in); each
    column's axes name their input; the strip shows each input's peak and the worst input's |Δq|."""
    from PIL import Image

    from loopcheck.compare import plots
    from loopcheck.compare.draw import strip_moments

    scene, fine, coarse = runs
    c = judge(scene, fine, coarse, BETWEEN)
    labels = []
    real_save = plots._save

    def keep(fig, path):
        labels.append([ax.get_ylabel() for ax in fig.axes])
        real_save(fig, path)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(plots, "_save", keep)
        for name, plot in (("trajectories.png", plots.plot_trajectories), ("differences.png", plots.plot_differences),
                           ("omega_vs_q.png", plots.plot_omega_vs_q)):
            plot(c, tmp_path / name)
            with Image.open(tmp_path / name) as image:
                assert image.size[0] == round((plots.COLUMN_INCHES * 2 + 1.0) * plots.DPI), name
    for axes in labels:
        assert len(axes) == 4 and "O1" in axes[0] and "O5" in axes[1], axes
    assert [label for label, _ in strip_moments(c)] == ["peak speed of O1", "peak speed of O5",
                                                        "largest |Δq| (of O5)"]


def test_draw_names_every_input_and_its_q0():
    from loopcheck.compare.draw import start_labels

    at, labels = start_labels(load_scene(SCENE))
    assert at == "q0 = (O1 1.8 rad, O5 1.3 rad)"
    assert labels == {"O1": "input 1, q0 = 1.8 rad", "O5": "input 2, q0 = 1.3 rad"}


def test_check_engines_lines_give_every_inputs_figures(runs):
    """``loopcheck check --engines``' lines (an EnginesCheck of real runs): the reference's peak of
    every input, and each engine's figures of every input, named."""
    from loopcheck.compare.engines import EngineVerdict, EnginesCheck, engines_lines

    scene, fine, coarse = runs
    c = judge(scene, fine, coarse, BETWEEN)
    check = EnginesCheck(scene, fine, (EngineVerdict("mujoco", BETWEEN, c),), None, {})
    lines = engines_lines(check)
    assert lines[0].startswith("FAIL") and f"O1 {fine.peak.omega:.10g} rad/s, O5 " in lines[0]
    assert lines[1].split()[:3] == ["mujoco", "FAIL", "O1:"]
    assert lines[2].split()[0] == "O5:" and f"max |dq| {c.diffs[1].q_max_abs:.2e} rad" in lines[2]
    assert lines[3].strip() == c.gate.failures[0]
