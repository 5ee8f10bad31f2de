"""Every joint's own coordinate and rate in reduced.csv, mujoco.csv and report.json: a revolute
joint's relative angle θ_b − θ_a (cut joints included), a prismatic joint's displacement; all
joints of a scene of at most 12 joints in the CSVs, else the inputs' and those ``loopcheck run --joints`` names;
every joint in report.json (schema 7).

Oracles: a joint's relative angle is the difference of its two bodies' angles, taken here by
name from the reduced solver's coordinates and from MuJoCo's own forward kinematics (the bodies'
orientations, mj_kinematics), not from the joint rows the outputs use; and the two engines'
columns agree."""

from __future__ import annotations

import json
import math
import re
import tomllib

import mujoco
import numpy as np
import pytest

from loopcheck.compare import report
from loopcheck.compare.cli import main
from loopcheck.compare.run import compare_engines
from loopcheck.reduced import ReducedSettings
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.mechanism import GROUND, PrismaticJoint
from loopcheck.reference_models import MujocoSettings, build_model, joint_positions

from helpers import ROOT, plots_left_out


def _scene(file: str, horizon: float):
    with open(ROOT / "scenes" / "mechanisms" / file, "rb") as f:
        data = tomllib.load(f)
    data["simulation"] = {"horizon": horizon}
    return scene_from_dict(data)


@pytest.fixture(scope="module", params=[("stephenson3_sixbar.toml", 0.3, 2e-4), ("slider_crank_gas.toml", 0.05, 1e-4)],
                ids=["six_bar", "slider_crank"])
def written(request, tmp_path_factory):
    file, horizon, step = request.param
    scene = _scene(file, horizon)
    c = compare_engines(scene, reduced=ReducedSettings(method="dop853", rtol=1e-12),
                        mujoco=MujocoSettings(integrator="rk4", timestep=step))
    out = tmp_path_factory.mktemp("out")
    with plots_left_out():  # the CSVs and report.json are read here
        report.write_outputs(c, out)
    tables = {}
    for engine in ("reduced", "mujoco"):
        with open(out / f"{engine}.csv") as f:
            header = f.readline().strip().split(",")
        tables[engine] = dict(zip(header, np.loadtxt(out / f"{engine}.csv", delimiter=",", skiprows=1).T))
    return scene, c, tables, json.loads((out / "report.json").read_text())


def _column(scene, name: str) -> str:
    return f"{name}_{'m' if isinstance(scene.mechanism.linkage.joint_map[name], PrismaticJoint) else 'rad'}"


def test_every_joint_has_its_columns(written):
    scene, _, tables, data = written
    names = [j.name for j in scene.mechanism.linkage.joints]
    for engine, table in tables.items():
        unit = scene.input_unit
        assert list(table)[:4] == ["t_s", f"q_{unit}", f"qdot_{unit}_per_s", f"qddot_{unit}_per_s2"]
        expected = [c for n in names for c in (_column(scene, n), _column(scene, n).replace(f"{n}_", f"{n}_rate_") + "_per_s")]
        assert list(table)[4:] == expected, engine
        # the input joint's columns are q and q̇ (to round-off: q is drive·x, the column row·x)
        inp = scene.mechanism.linkage.input_joint
        assert np.max(np.abs(table[_column(scene, inp)] - table[f"q_{unit}"])) <= 1e-12 * max(1.0, np.max(np.abs(table[f"q_{unit}"])))
    assert [j["name"] for j in data["joints"]] == names
    assert [j["cut"] for j in data["joints"]] == [n in scene.mechanism.linkage.cut_joints for n in names]


def test_relative_angle_is_the_difference_of_the_bodies_angles(written):
    """Reduced: θ_b − θ_a from its coordinates by body name. MuJoCo: from each body's
    orientation in MuJoCo's forward kinematics at the run's qpos (every 25th sample), the
    whole turns taken from the column (MuJoCo gives an angle mod 2π). Round-off: measured
    ≤ 4e-15 rad (reduced), ≤ 2e-15 rad (MuJoCo); bound 1e-12 rad."""
    scene, c, tables, _ = written
    linkage = scene.mechanism.linkage
    revolute = [j for j in linkage.joints if not isinstance(j, PrismaticJoint)]
    joints = c.reference.joints
    index = np.minimum(np.searchsorted(joints.t, tables["reduced"]["t_s"]), len(joints.t) - 1)

    def angle(x, body):
        return 0.0 if body == GROUND else x[:, joints.names.index(f"{body}.angle")]
    for j in revolute:
        x = joints.x[index]
        expected = angle(x, j.body_b) - angle(x, j.body_a)
        assert np.max(np.abs(tables["reduced"][f"{j.name}_rad"] - expected)) <= 1e-12, j.name

    model = build_model(scene, MujocoSettings(integrator="rk4", timestep=1e-4)).model
    data = mujoco.MjData(model)
    mj = c.other.joints
    rows = np.arange(0, len(mj.t), 25)
    mj_index = np.searchsorted(tables["mujoco"]["t_s"], mj.t[rows])
    worst = 0.0
    for r, k in zip(rows, mj_index):
        data.qpos[:] = joint_positions(scene, mj.x[r])
        mujoco.mj_kinematics(model, data)

        def body_angle(body):
            if body == GROUND:
                return 0.0
            w, _, _, z = data.xquat[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)]
            return 2.0 * math.atan2(z, w)
        for j in revolute:
            column = tables["mujoco"][f"{j.name}_rad"][k]
            wrapped = body_angle(j.body_b) - body_angle(j.body_a)
            turns = round((column - wrapped) / (2 * math.pi))
            worst = max(worst, abs(column - wrapped - 2 * math.pi * turns))
    assert worst <= 1e-12, worst


def test_both_engines_joint_columns_agree(written):
    """MuJoCo's columns against the reduced reference's (cubic Hermite in time on its own samples).
    Measured max |Δu|: six-bar 3.3e-5 rad (its input's own |Δq| 3.0e-5), slider-crank 1.2e-7 rad
    and 2.2e-9 m; bounds 5x the input's gate figure q_max_abs of the same run, which the report
    states beside them (a joint can swing more than the input: the six-bar's coupler pin A)."""
    scene, c, tables, data = written
    q_diff = data["diff"]["q_max_abs"]
    for j in data["joints"]:
        assert j["diff_max_abs"] is not None and j["diff_max_abs"] <= 5 * max(q_diff, 1e-9), (j["name"], j["diff_max_abs"], q_diff)
        assert abs(j["reduced"]["final"] - j["mujoco"]["final"]) <= 5 * max(q_diff, 1e-9), j["name"]
    inp = scene.mechanism.linkage.input_joint
    row = next(j for j in data["joints"] if j["name"] == inp)
    # the input joint's figure is the gate's q_max_abs but for the reference's interpolant (cubic
    # Hermite in u, u̇ here, quintic in q, q̇, q̈ there): measured 0.14 % apart; bound 1 %
    assert row["diff_max_abs"] == pytest.approx(q_diff, rel=1e-2)


def test_joints_flag_chooses_the_columns(tmp_path):
    """--joints B: the input's columns and B's; an unknown name is one line, exit 2, nothing written."""
    scene_file = tmp_path / "six.toml"
    text = (ROOT / "scenes" / "mechanisms" / "stephenson3_sixbar.toml").read_text()
    short = re.sub(r"(?m)^horizon = .*$", "horizon = 0.05", text)
    assert short != text
    scene_file.write_text(short)
    out = tmp_path / "out"
    with plots_left_out():  # the CSV and report.json are read here
        status = main(["run", str(scene_file), "--out", str(out), "--joints", "B"])
    assert status in (0, 1)
    header = (out / "reduced.csv").read_text().splitlines()[0].split(",")
    assert header[4:] == ["O2_rad", "O2_rate_rad_per_s", "B_rad", "B_rate_rad_per_s"]
    # report.json lists every joint whatever the CSVs carry (schema 7: no cap)
    assert [j["name"] for j in json.loads((out / "report.json").read_text())["joints"]] == [
        j.name for j in load_scene(scene_file).mechanism.linkage.joints]
    fresh = tmp_path / "fresh"
    assert main(["run", str(scene_file), "--out", str(fresh), "--joints", "nope"]) == 2
    assert not fresh.exists()


def test_a_scene_above_the_default_count_gets_the_input_alone(monkeypatch):
    scene = _scene("stephenson3_sixbar.toml", 0.1)
    assert report.joint_columns(scene) == tuple(j.name for j in scene.mechanism.linkage.joints)
    monkeypatch.setattr(report, "JOINTS_BY_DEFAULT", 6)  # the six-bar has 7 joints
    assert report.joint_columns(scene) == ("O2",)
    assert report.joint_columns(scene, ["O6", "C"]) == ("O2", "C", "O6")
    with pytest.raises(ValueError, match="--joints: 'X' is not a joint of the scene"):
        report.joint_columns(scene, ["X"])
