"""A user's MJCF: its values refused when non-finite or outside the description's ranges (never read
as "absent"), a model path that is not a regular file refused before MuJoCo opens it, welded bodies
merged with the parallel-axis terms, the keyframe asked for read; and MuJoCo's warnings (real
MuJoCo, a model that makes it warn) kept off the terminal and the working folder, a run stopped at
MuJoCo's first reset of the state."""

from __future__ import annotations

import dataclasses
import logging
import os
import threading
from pathlib import Path

import pytest

from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.reference_models import MujocoSettings
from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf
from loopcheck.reference_models.run import ROLLOUT_CHUNK, simulate_mujoco
from loopcheck.reference_models.user_model import ModelOptions, run_model
from loopcheck.scenefile import load_scene

from helpers import ROOT

DATA = Path(__file__).parent.parent / "data" / "mjcf"
SEED = DATA / "fourbar_sites_keyframe.xml"  # the seed's four-bar: a tendon damper of 55 N·s/m, a motor on O1


def _write(tmp_path: Path, text: str, name: str = "model.xml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _seed(old: str, new: str) -> str:
    text = SEED.read_text()
    assert old in text
    return text.replace(old, new)


# (the file's change, the words the one-line refusal must hold: element, MJCF attribute, what)
BAD_VALUES = {
    "tendon damping nan": (('damping="55"', 'damping="nan"'), "tendon 'damper': damping=\"nan\" is not a finite"),
    "tendon damping inf": (('damping="55"', 'damping="inf"'), "tendon 'damper': damping=\"inf\" is not a finite"),
    "tendon damping negative": (('damping="55"', 'damping="-55"'),
                                "tendon 'damper': damping=\"-55\" cannot be represented: a damper's coefficient must "
                                "be ≥ 0"),
    "tendon stiffness nan": (('damping="55"', 'damping="55" stiffness="nan"'), "tendon 'damper': stiffness=\"nan\""),
    "joint damping from a default class": (
        ('<site size="0.01"/>', '<site size="0.01"/><default class="soft"><joint damping="nan"/></default>'),
        None),  # the class is used below
    "joint stiffness negative": (('<joint name="A"/>', '<joint name="A" stiffness="-3"/>'),
                                 "joint 'A': stiffness=\"-3\" cannot be represented: a spring's stiffness must be ≥ 0"),
    "joint armature nan": (('<joint name="A"/>', '<joint name="A" armature="nan"/>'), "joint 'A': armature=\"nan\""),
    "hinge axis nan": (('<joint name="A"/>', '<joint name="A" axis="nan 0 1"/>'), "joint 'A': axis=\"nan 0 1\""),
    "motor gear nan": (('<motor name="drive" joint="O1"/>', '<motor name="drive" joint="O1" gear="nan"/>'),
                       "actuator 'drive': gear=\"nan\""),
    "centre of mass nan": (('pos="0.5111 0.1333 0"', 'pos="nan 0.1333 0"'),
                           "body 'coupler': inertial pos=\"nan 0.1333 0\" is not a finite"),
    "mass negative": (('mass="40"', 'mass="-40"'), "body 'coupler': inertial mass=\"-40\""),
    "body euler nan": (('<body name="rocker" pos="1 0 0">', '<body name="rocker" pos="1 0 0" euler="0 0 nan">'),
                       "body 'rocker': euler=\"0 0 nan\""),
    "frame pos nan": ((('<body name="rocker" pos="1 0 0">', '<frame name="shift" pos="0 nan 0"><body name="rocker" pos="1 0 0">'),
                       ('</body>\n  </worldbody>', '</body></frame>\n  </worldbody>')),
                      "frame 'shift': pos=\"0 nan 0\""),
    "fullinertia nan": (('mass="40" diaginertia="5 5 5"', 'mass="40" fullinertia="5 5 nan 0 0 0"'),
                        "body 'coupler': inertial fullinertia=\"5 5 nan 0 0 0\""),
    "geom density negative": (('<site name="rocker_B" pos="0.7 0 0"/>',
                               '<site name="rocker_B" pos="0.7 0 0"/><geom size="0.1" density="-1000" contype="0" '
                               'conaffinity="0"/>'),
                              "geom #1 (on rocker): density=\"-1000\" cannot be represented"),
    "geom mass nan": (('<site name="rocker_B" pos="0.7 0 0"/>',
                       '<site name="rocker_B" pos="0.7 0 0"/><geom name="lump" size="0.1" mass="nan" contype="0" '
                       'conaffinity="0"/>'), "geom 'lump': mass=\"nan\" is not a finite"),
    "keyframe ctrl nan": (('ctrl="250"', 'ctrl="nan"'), "key 'assembled': ctrl=\"nan\""),
    "gravity nan": (('gravity="0 0 0"', 'gravity="0 nan 0"'), "option: gravity=\"0 nan 0\""),
    # finite, and outside the scene format's ranges (loopcheck.scene.LIMITS): named by the model's
    # element, not by the scene key it would land in ('dampers[0].coefficient', 'initial.qdot', ...)
    "damping above the range": (('damping="55"', 'damping="1e308"'),
                                "tendon 'damper': damping = 1e+308 cannot be represented: damping must be in "
                                "[1e-09, 1e+07] N·s/m"),
    "mass above the range": (('mass="40"', 'mass="1e308"'), "body 'coupler': mass = 1e+308 cannot be represented"),
    "keyframe qvel above the range": (('ctrl="250"', 'ctrl="250" qvel="1e308 0 0"'),
                                      "keyframe 'assembled': the input joint's qvel = 1e+308 cannot be represented: "
                                      "speed must be in ±10000 rad/s"),
    "gear above the range": (('<motor name="drive" joint="O1"/>', '<motor name="drive" joint="O1" gear="1e308"/>'),
                             "actuator 'drive': gear × gain × control (gear × gain 1e+308, control 250) = inf cannot "
                             "be represented: torque must be in ±1e+06 N·m"),
    "site beyond the range": (('<site name="damper_ground" pos="1.3 0.12 0"/>', '<site name="damper_ground" pos="2000 0.12 0"/>'),
                              "the world: point 'damper_ground' (a site, joint or anchor), x in its plane frame = 2000 "
                              "cannot be represented: position must be in ±1000 m"),
    "springref beyond the range": (('<joint name="O3"/>', '<joint name="O3" stiffness="1" springref="1e6"/>'),
                                   "joint 'O3': springref: the spring's rest = 17453.3 cannot be represented: angle "
                                   "must be in ±1000 rad"),  # 1e6 degrees (MJCF's default unit)
    "polynomial damping": (('damping="55"', 'damping="55 1"'), "tendon 'damper': damping=\"55 1\" cannot be "
                                                               "represented: loopcheck's springs and dampers are linear"),
}


@pytest.mark.parametrize("case", sorted(BAD_VALUES))
def test_a_bad_value_is_refused_naming_the_element_and_attribute(case, tmp_path):
    """NaN, inf and out-of-range values are refused in one line naming the file, the element and
    the MJCF attribute (planted: the check removed, ``damping="nan"`` or ``"-55"`` reads as no
    damper and the import succeeds; a NaN axis is refused as 'initial.qdot', a NaN gear as
    'ConstantLoad.amplitude')."""
    change, words = BAD_VALUES[case]
    text = SEED.read_text()
    for old, new in (change if isinstance(change[0], tuple) else (change,)):
        assert old in text
        text = text.replace(old, new)
    if words is None:
        text = text.replace('<joint name="A"/>', '<joint name="A" class="soft"/>')
        words = "joint 'A': damping=\"nan\" (from default class 'soft') is not a finite number"
    path = _write(tmp_path, text)
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path, keyframe="assembled")
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and words in message and "\n" not in message


def test_zero_stays_absent(tmp_path):
    """damping="0": no damper, and no refusal."""
    imported = import_mjcf(_write(tmp_path, _seed('damping="55"', 'damping="0"')), keyframe="assembled")
    assert not imported.scene.mechanism.elements


def test_a_path_that_is_not_a_regular_file_is_refused(tmp_path):
    """A FIFO is refused at once (planted without the check, MuJoCo's read blocks: the import,
    in a thread, is still waiting after 10 s, and the test then writes to the FIFO to free it);
    a folder is named a folder, not an empty file; a missing file says so."""
    fifo = tmp_path / "pipe.xml"
    os.mkfifo(fifo)
    outcome = []

    def read():
        try:
            import_mjcf(fifo)
        except MjcfError as exc:
            outcome.append(str(exc))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout=10.0)
    if reader.is_alive():
        with open(fifo, "w"):
            pass  # the writer's close ends the blocked read
        reader.join(timeout=10.0)
        pytest.fail("importing a FIFO blocked")
    assert len(outcome) == 1 and outcome[0].endswith("pipe.xml': it is not a regular file")
    folder = tmp_path / "folder.xml"
    folder.mkdir()
    with pytest.raises(MjcfError, match=r"folder.xml': it is a folder"):
        import_mjcf(folder)
    with pytest.raises(MjcfError, match=r"missing.xml': No such file"):
        import_mjcf(tmp_path / "missing.xml")


def test_welded_bodies_merge_with_the_parallel_axis_terms(tmp_path):
    """A 2 kg body (izz 0.5 kg·m²) welded to the crank (1 kg, izz 1.5, com on its pivot) 0.25 m out:
    one body of 3 kg, com 1/6 m out, inertia about it 1.5 + 0.5 + 1·(1/6)² + 2·(1/12)²
    = 1.5416667 kg·m² (planted without the m·d² terms: 2.0). Exact up to round-off (1e-12)."""
    text = _seed('<inertial pos="0 0 0" mass="1" diaginertia="1.5 1.5 1.5"/>',
                 '<inertial pos="0 0 0" mass="1" diaginertia="1.5 1.5 1.5"/>'
                 '<body name="weight" pos="0.25 0 0"><inertial pos="0 0 0" mass="2" diaginertia="0.5 0.5 0.5"/></body>')
    crank = import_mjcf(_write(tmp_path, text), keyframe="assembled").scene.mechanism.linkage.body_map["crank"]
    assert crank.mass == pytest.approx(3.0, rel=1e-12)
    assert crank.com[0] == pytest.approx(0.25 * 2 / 3, rel=1e-12) and abs(crank.com[1]) < 1e-12
    assert crank.inertia == pytest.approx(1.5 + 0.5 + 1 * (1 / 6) ** 2 + 2 * (1 / 12) ** 2, rel=1e-12)


def test_the_keyframe_asked_for_is_read(tmp_path):
    """Two keyframes, the one asked for second: its control (250) and configuration are read, not
    keyframe 0's (a 100 N·m key at the same configuration; planted reading keyframe 0: 100)."""
    text = _seed('<key name="assembled"', '<key name="first" qpos="0.2 0.4958152707042334 1.309532019318043" '
                 'qvel="1 0 0" ctrl="100"/>\n    <key name="assembled"')
    imported = import_mjcf(_write(tmp_path, text), keyframe="assembled")
    assert imported.keyframe == "assembled"
    assert imported.scene.load.amplitude == 250.0
    assert imported.scene.qdot0 == 0.0


# --- MuJoCo's warnings (real MuJoCo) -----------------------------------------------------------

def test_a_warning_while_loading_is_the_imports_own_and_nothing_is_printed(tmp_path, monkeypatch, capfd):
    """A NaN where loopcheck reads nothing (a custom numeric) makes MuJoCo's parser warn; the import
    goes on, the warning is one of its own, in loopcheck's words; MuJoCo prints nothing and writes no
    MUJOCO_LOG.TXT in the working folder (planted with MuJoCo's default handler while loading: a
    `WARNING: XML contains a 'NaN'` line on stdout, and the log file)."""
    path = _write(tmp_path, _seed("<keyframe>", '<custom><numeric name="note" data="nan"/></custom><keyframe>'))
    monkeypatch.chdir(tmp_path)
    imported = import_mjcf(path, keyframe="assembled")
    out, err = capfd.readouterr()
    assert imported.warnings == ("MuJoCo's parser found 'NaN' in the file",)
    assert "WARNING" not in out + err and not (tmp_path / "MUJOCO_LOG.TXT").exists()


def _unstable(tmp_path: Path) -> Path:
    """The seed's four-bar run by Euler at 50 ms: MuJoCo finds a huge qacc and resets the state."""
    return _write(tmp_path, _seed('timestep="0.001" integrator="RK4"', 'timestep="0.05" integrator="Euler"'))


def test_a_model_that_makes_mujoco_warn_leaves_no_log_and_prints_no_warning(tmp_path, monkeypatch, capfd):
    """`loopcheck check` of a model MuJoCo resets: it fails, naming the reset and its time, in
    loopcheck's words; no raw `WARNING:` line reaches stdout or stderr, and no MUJOCO_LOG.TXT is
    written to the working folder (planted with MuJoCo's default handler during the run: both)."""
    from loopcheck.compare.cli import main

    path = _unstable(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    status = main(["check", str(path), "--keyframe", "assembled", "--horizon", "2"])
    out, err = capfd.readouterr()
    assert status == 1
    assert "reset the state" in out + err and "t = " in out + err
    assert "WARNING:" not in out + err
    assert not (work / "MUJOCO_LOG.TXT").exists() and not (ROOT / "MUJOCO_LOG.TXT").exists()


def test_a_model_run_stops_at_mujocos_first_reset(tmp_path, monkeypatch):
    """The user model's run stops at the step where MuJoCo first reset the state (MuJoCo calls the
    handler once per kind of warning, so the steps taken are counted: real mj_step, counted by a
    wrapper), failed as UNSTABLE with its time (planted running on: all 40 steps of 2 s)."""
    import mujoco

    imported = import_mjcf(_unstable(tmp_path), keyframe="assembled", horizon=2.0)
    steps = []
    real = mujoco.mj_step
    monkeypatch.setattr(mujoco, "mj_step", lambda m, d: (steps.append(1), real(m, d))[1])
    with pytest.raises(NumericalFailure) as caught:
        run_model(imported, ModelOptions.as_written(imported.model))
    failure = caught.value
    assert failure.reason == FailureReason.UNSTABLE and failure.time is not None
    assert "reset the state" in str(failure) and f"t = {failure.time:.6g} s" in str(failure)
    assert len(steps) == round(failure.time / 0.05) + 1 < 40


def test_a_scene_run_stops_after_the_chunk_of_mujocos_first_reset(monkeypatch):
    """The scene's run (mujoco.rollout in chunks of ROLLOUT_CHUNK steps) stops after the chunk of
    the first reset: over 20 chunks, one call of the real rollout, counted by a wrapper (planted
    running on: 20), and the failure gives the reset's text and time."""
    from loopcheck.reference_models import run

    calls = []
    real = run.rollout.rollout
    monkeypatch.setattr(run.rollout, "rollout", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    scene = dataclasses.replace(load_scene(ROOT / "scenes" / "seed_fourbar.toml"), horizon=20 * ROLLOUT_CHUNK * 0.05)
    with pytest.raises(NumericalFailure) as caught:
        simulate_mujoco(scene, MujocoSettings(integrator="euler", timestep=0.05))
    failure = caught.value
    assert failure.reason == FailureReason.UNSTABLE and f"at t = {failure.time:.6g} s and reset the state" in str(failure)
    assert failure.time < ROLLOUT_CHUNK * 0.05 and len(calls) == 1


def test_a_compiler_warning_is_caught_too(tmp_path, monkeypatch, capfd, recwarn):
    """A body with two hinges makes MuJoCo's compiler warn (a singular mass matrix), which MuJoCo's
    Python package raises as a Python warning in MuJoCo's words: the import refuses the body by
    name, and neither a Python warning, a `WARNING:` line nor MUJOCO_LOG.TXT gets out (planted
    with `spec.compile()` in place of the handler's compile_spec: the Python warning gets out)."""
    path = _write(tmp_path, '<mujoco><worldbody><body name="b"><joint name="j1" axis="0 0 1"/>'
                            '<joint name="j2" axis="0 0 1"/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
                            '</body></worldbody></mujoco>')
    monkeypatch.chdir(tmp_path)
    with pytest.raises(MjcfError, match="body 'b' has 2 joints"):
        import_mjcf(path)
    out, err = capfd.readouterr()
    assert not [w for w in recwarn if "singular" in str(w.message)]
    assert "WARNING" not in out + err and not (tmp_path / "MUJOCO_LOG.TXT").exists()


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root reads a file without permission")
def test_an_unreadable_model_is_named_so(tmp_path):
    """A file without read permission: the system's reason, not an empty model."""
    path = _write(tmp_path, SEED.read_text())
    path.chmod(0)
    with pytest.raises(MjcfError, match=r"cannot read MJCF file '.*model.xml': Permission denied"):
        import_mjcf(path)


def test_the_handler_reports_warnings_and_leaves_resets_to_the_run(tmp_path, caplog):
    """Real MuJoCo inside one handler block: a parser warning (a NaN in a custom numeric) is kept in
    loopcheck's words and reported at WARNING; a reset of the state (the seed by Euler at 50 ms) is
    counted as a reset and not reported (the run it happens in fails with its own message; planted
    reporting resets too, an automatic timestep search that went on to a smaller step would report
    a reset of a run it discarded)."""
    import mujoco

    from loopcheck.mujoco_model.warning_handler import mujoco_warnings

    with caplog.at_level(logging.WARNING, logger="loopcheck.mujoco"):
        with mujoco_warnings() as said:
            mujoco.MjSpec.from_string('<mujoco><custom><numeric name="n" data="nan"/></custom></mujoco>')
            model = mujoco.MjModel.from_xml_path(str(_unstable(tmp_path)))
            data = mujoco.MjData(model)
            mujoco.mj_resetDataKeyframe(model, data, 0)
            for _ in range(40):
                mujoco.mj_step(model, data)
        said.report("here")
    assert said.lines == ["MuJoCo's parser found 'NaN' in the file"] and said.count == 1
    assert said.resets >= 1 and data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number >= 1
    assert [r.getMessage() for r in caplog.records] == ["warning: here: MuJoCo's parser found 'NaN' in the file"]
