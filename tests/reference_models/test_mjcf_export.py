"""The exported MJCF stands on its own: MuJoCo loads it with the loop closed (issue 11).

Every check here reads the file with MuJoCo alone (``mujoco.MjModel.from_xml_string``, no
loopcheck code) and judges it against the four-bar's closed-form assembly (``loopcheck.four_bar``),
an oracle independent of the MuJoCo builder. The loop gap is measured between the sites at B
on the coupler and on the rocker, which sit at the link lengths c2, c3 in each body's frame:
unlike the connect's own residual (MuJoCo places the rocker's anchor where B is at qpos0, so
that residual is zero by construction), the sites show whether the authored pose closes.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.four_bar import FourBar
from loopcheck.reference_models import BASE_BODY, HOME_KEY, MujocoSettings, build_model, mjcf_text

from helpers import SEED_SCENE, seed_dict

# Measured over CASES at the default state and at home: loop gap ≤ 6.2e-16 m, |A − A(q0)| and
# |B − B(q0)| ≤ 6.1e-16 m, connect efc_pos ≤ 2.2e-16 m (links of 0.5–1 m); the equality rows'
# efc_vel ≤ 1.2e-15 m/s at crank rates up to 5 rad/s. The issue asks 1e-9 m; the bounds sit
# ~8x above round-off, so a 6-digit export (~1e-6 m) or an unposed one (0.3 m) fails.
CLOSURE_ATOL = 5e-15  # m
VELOCITY_ATOL = 1e-14  # m/s
STEP = 1e-3  # s: an explicit timestep, so exporting runs no simulation

CASES = [(branch, q0, qdot0) for branch in (1, -1) for q0, qdot0 in ((0.2, 0.0), (1.3, 5.0), (2.9, -3.0),
                                                                     (4.4, 2.0))]


def scene_at(branch: int, q0: float, qdot0: float, **extra):
    data = seed_dict()
    data["linkage"]["branch"] = branch
    data["initial"] = {"q": q0, "qdot": qdot0}
    data.update(extra)
    return scene_from_dict(data)


def points(scene) -> tuple[np.ndarray, np.ndarray]:
    """A and B (m) of the closed-form assembly at q0 on the scene's branch."""
    g = scene.four_bar
    q, phi1, _ = FourBar(g).assemble(scene.q0)
    a = g.c1 * np.array([np.cos(q), np.sin(q), 0.0])
    return a, a + g.c2 * np.array([np.cos(phi1), np.sin(phi1), 0.0])


def loaded(text: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(text)
    return model, mujoco.MjData(model)


def equality_rows(model, data) -> np.ndarray:
    return np.flatnonzero(data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)


def check_closed(scene, model, data) -> float:
    """Assert the state in ``data`` (after mj_forward) is the assembly at q0; return the gap (m)."""
    a, b = points(scene)
    gap = float(np.linalg.norm(data.site("coupler.B").xpos - data.site("rocker.B").xpos))
    assert gap < CLOSURE_ATOL
    np.testing.assert_allclose(data.site("crank.A").xpos, a, rtol=0, atol=CLOSURE_ATOL)  # at q0
    np.testing.assert_allclose(data.site("rocker.B").xpos, b, rtol=0, atol=CLOSURE_ATOL)  # on the branch
    np.testing.assert_allclose(data.efc_pos[equality_rows(model, data)], 0.0, rtol=0, atol=CLOSURE_ATOL)
    return gap


@pytest.mark.parametrize("branch, q0, qdot0", CASES)
def test_exported_model_loads_assembled_at_its_default_state_and_home(branch, q0, qdot0):
    scene = scene_at(branch, q0, qdot0)
    model, data = loaded(mjcf_text(scene, MujocoSettings(timestep=STEP)))
    g = scene.four_bar

    mujoco.mj_forward(model, data)  # MuJoCo's default state: qpos0, zero velocity
    check_closed(scene, model, data)
    # The rocker's anchor, placed by MuJoCo where B is at qpos0, is B on the rocker (O3B = c3 on x).
    eq = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, "B")
    np.testing.assert_allclose(model.eq_data[eq, :6], [g.c2, 0, 0, g.c3, 0, 0], rtol=0, atol=CLOSURE_ATOL)

    mujoco.mj_resetDataKeyframe(model, data, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, HOME_KEY))
    mujoco.mj_forward(model, data)
    check_closed(scene, model, data)
    # The scene's initial state: the crank turns at q̇0, the other joints as the loop requires.
    assert data.qvel[0] == pytest.approx(qdot0, abs=1e-15)
    assert (np.max(np.abs(data.qvel[1:])) > 0.1 * abs(qdot0)) or qdot0 == 0.0
    np.testing.assert_allclose(data.efc_vel[equality_rows(model, data)], 0.0, rtol=0, atol=VELOCITY_ATOL)
    np.testing.assert_allclose(data.ctrl, [250.0])  # the pulse's value in the first step


def test_seed_export_with_the_automatic_step_is_closed_and_at_rest():
    """The file ``loopcheck export-mjcf`` writes for the default scene, as it is."""
    scene = load_scene(SEED_SCENE)
    model, data = loaded(mjcf_text(scene))
    for key in (None, HOME_KEY):
        if key is not None:
            mujoco.mj_resetDataKeyframe(model, data, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, key))
        mujoco.mj_forward(model, data)
        check_closed(scene, model, data)
    np.testing.assert_array_equal(data.qpos, 0.0)
    np.testing.assert_array_equal(data.qvel, 0.0)


def test_base_body_holds_every_chain_and_the_connect_names_bodies():
    """One body tree under <worldbody> (Pinocchio's MJCF reader keeps only the first), rooted at a
    fixed ``base``; the loop is a connect between bodies with an anchor, as in menagerie."""
    text = mjcf_text(scene_at(1, 0.2, 0.0), MujocoSettings(timestep=STEP))
    worldbody = ET.fromstring(text).find("worldbody")
    assert [b.get("name") for b in worldbody.findall("body")] == [BASE_BODY]
    assert worldbody.find("body").find("joint") is None and worldbody.find("site") is None
    model, _ = loaded(text)
    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, BASE_BODY)
    assert model.body_parentid[base] == 0 and model.body_jntnum[base] == 0
    np.testing.assert_array_equal(model.body_rootid[1:], base)  # every body but the world hangs from base
    connect = ET.fromstring(text).find("equality/connect")
    assert (connect.get("body1"), connect.get("body2")) == ("coupler", "rocker") and connect.get("anchor")
    assert connect.get("site1") is None


def test_round_trip_through_the_text_gives_the_same_model_and_motion():
    """MjSpec.from_string(xml).compile() equals the in-memory model bit for bit in the placed
    quantities, and 200 steps from home agree exactly (same model, same arithmetic)."""
    scene = scene_at(-1, 1.3, 5.0, springs=[{"stiffness": 500.0, "rest_length": 0.3, "ground_point": [1.3, 0.12],
                                             "body": "coupler", "body_point": [0.9, 0.0]}])
    settings = MujocoSettings(timestep=STEP)
    direct = build_model(scene, settings).model
    reread = mujoco.MjSpec.from_string(mjcf_text(scene, settings)).compile()
    for field in ("body_pos", "body_quat", "body_ipos", "body_inertia", "site_pos", "eq_data", "key_qpos",
                  "key_qvel", "key_ctrl", "tendon_lengthspring", "tendon_stiffness", "tendon_damping"):
        np.testing.assert_array_equal(getattr(reread, field), getattr(direct, field), err_msg=field)
    states = []
    for model in (direct, reread):
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        for _ in range(200):
            mujoco.mj_step(model, data)
        states.append(np.concatenate([data.qpos, data.qvel]))
    np.testing.assert_array_equal(states[0], states[1])


@pytest.mark.parametrize("branch, q0, qdot0", [CASES[0], CASES[5]])
def test_pinocchio_reads_both_chains_closed_at_its_neutral_configuration(branch, q0, qdot0, tmp_path):
    """A second reader: Pinocchio's MJCF parser (keeps only the first body tree under <worldbody>)
    finds all three hinges, and at its neutral configuration (q = 0) the sites at B meet where
    the closed form puts B (measured 2.5e-16 m and 3.9e-16 m with pin 4.1.0). Skipped where
    Pinocchio is not installed (it is not a dependency of loopcheck)."""
    pin = pytest.importorskip("pinocchio")
    scene = scene_at(branch, q0, qdot0)
    path = tmp_path / "model.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=STEP)), encoding="utf-8")
    model = pin.buildModelFromMJCF(str(path))
    assert model.nq == 3 and list(model.names)[1:] == ["O1", "A", "O3"]
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    coupler_b = data.oMf[model.getFrameId("coupler.B")].translation
    rocker_b = data.oMf[model.getFrameId("rocker.B")].translation
    np.testing.assert_allclose(coupler_b, points(scene)[1], rtol=0, atol=CLOSURE_ATOL)
    np.testing.assert_allclose(rocker_b, points(scene)[1], rtol=0, atol=CLOSURE_ATOL)


@pytest.mark.parametrize("version, refused", [("3.17.0", True), ("4.0.0", True), ("4.0.1", False), ("4.1.0", False),
                                               ("10.0.0", False)])
def test_the_engine_refuses_a_mujoco_older_than_it_needs(version, refused):
    """The GPU ports' pip installs can load MuJoCo 3.17 or 4.0.0 under mujoco-core 4.0.1's name
    (docs/engines-gpu-research.md): the engine checks the library loaded, by number, not text."""
    from loopcheck.mujoco_model.build import check_mujoco_version

    if refused:
        with pytest.raises(ImportError, match=f"loads {version}"):
            check_mujoco_version(version)
    else:
        check_mujoco_version(version)


def test_an_import_error_is_one_line(monkeypatch, capsys):
    """A missing or wrong engine library is bad setup: one line and exit 2, not a traceback."""
    from loopcheck.compare import cli

    def broken(args):
        raise ImportError("loopcheck's MuJoCo engine needs MuJoCo 4.0.1 or newer, but `import mujoco` loads 4.0.0")

    monkeypatch.setattr(cli, "cmd_engine", broken)  # every engine's own command (`loopcheck mujoco`)
    assert cli.main(["mujoco"]) == 2
    assert capsys.readouterr().err == ("loopcheck: error: loopcheck's MuJoCo engine needs MuJoCo 4.0.1 or newer, but "
                                       "`import mujoco` loads 4.0.0\n")
