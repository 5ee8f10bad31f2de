"""Keyframes read when none is named (issue 36): the model's only keyframe is used and said,
several are refused and listed unless --keyframe or --qpos0 is given, and a refusal of an open
qpos0 names a keyframe that closes the loops.

The models are written by hand in the style of MuJoCo Menagerie (default classes, bodies placed in
their assembled pose, a body-form connect, a keyframe "home" that holds the actuator's control).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loopcheck.loads import ConstantLoad
from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf

DATA = Path(__file__).parent.parent / "data" / "mjcf"

# A crank-rocker in a horizontal plane (gravity along the hinge axes does no work): its only load
# is the keyframe's ctrl on the crank motor. Crank 0.1 m at 90°, coupler 0.3 m, rocker 0.25 m
# pivoted 0.3 m from the crank's pivot; B = (0.26150623, 0.24701868) closes the loop at qpos0.
LINKAGE = """\
<mujoco model="planar_linkage">
  <compiler angle="degree" autolimits="true"/>
  <option timestep="0.002"/>
  <default>
    <default class="linkage">
      <joint type="hinge" axis="0 0 1" damping="0.01"/>
      <geom type="capsule" size="0.008" contype="0" conaffinity="0" density="2700"/>
      <default class="driver">
        <motor gear="1" ctrlrange="-5 5"/>
      </default>
    </default>
  </default>
  <worldbody>
    <body name="base" childclass="linkage">
      <body name="crank" euler="0 0 90">
        <joint name="crank_joint"/>
        <geom fromto="0 0 0 0.1 0 0"/>
        <body name="coupler" pos="0.1 0 0" euler="0 0 -60.65532520005005">
          <joint name="coupler_joint"/>
          <geom fromto="0 0 0 0.3 0 0"/>
        </body>
      </body>
      <body name="rocker" pos="0.3 0 0" euler="0 0 98.85735968522755">
        <joint name="rocker_joint"/>
        <geom fromto="0 0 0 0.25 0 0"/>
      </body>
    </body>
  </worldbody>
  <equality>
    <connect name="coupler_rocker" body1="coupler" body2="rocker" anchor="0.3 0 0"/>
  </equality>
  <actuator>
    <motor name="crank_motor" class="driver" joint="crank_joint"/>
  </actuator>
  <keyframe>
{keys}
  </keyframe>
</mujoco>
"""
HOME = '    <key name="home" qpos="0 0 0" ctrl="2"/>'


def _write(tmp_path: Path, keys: str, name: str = "linkage.xml") -> Path:
    path = tmp_path / name
    path.write_text(LINKAGE.format(keys=keys))
    return path


def test_the_only_keyframe_is_read_and_said(tmp_path):
    """Without --keyframe, the model's only keyframe gives the load (2 N·m, gear 1); before, it
    was ignored and the scene had no load at all."""
    imported = import_mjcf(_write(tmp_path, HOME))
    assert imported.keyframe == "home"
    assert imported.scene.load == ConstantLoad(2.0)
    assert len(imported.said) == 1 and "'home'" in imported.said[0] and "only keyframe" in imported.said[0]
    at_rest = import_mjcf(_write(tmp_path, HOME), qpos0=True)
    assert at_rest.keyframe is None and at_rest.scene.load is None and at_rest.said == ()


def test_an_unnamed_only_keyframe_is_read(tmp_path):
    imported = import_mjcf(_write(tmp_path, '    <key qpos="0 0 0" ctrl="-1.5"/>'))
    assert imported.scene.load == ConstantLoad(-1.5) and "unnamed" in imported.said[0]


def test_several_keyframes_are_refused_and_listed(tmp_path):
    path = _write(tmp_path, HOME + '\n    <key name="push" qpos="0 0 0" ctrl="4"/>\n    <key ctrl="1"/>')
    with pytest.raises(MjcfError) as refused:
        import_mjcf(path)
    text = str(refused.value)
    assert "3 keyframes" in text and "'home'" in text and "'push'" in text and "#3 (unnamed)" in text
    assert "--keyframe" in text and "--qpos0" in text and "\n" not in text
    assert import_mjcf(path, keyframe="push").scene.load == ConstantLoad(4.0)
    assert import_mjcf(path, qpos0=True).scene.load is None
    with pytest.raises(MjcfError, match="both given"):
        import_mjcf(path, keyframe="push", qpos0=True)


def test_an_open_qpos0_names_the_keyframe_that_closes_it(tmp_path):
    """The four-bar laid out straight at qpos0 is assembled by its keyframe 'assembled': read at
    qpos0, the refusal names it; a keyframe that leaves the loop open is not named."""
    path = DATA / "fourbar_sites_keyframe.xml"
    with pytest.raises(MjcfError) as refused:
        import_mjcf(path, qpos0=True)
    assert "is open by" in str(refused.value) and "keyframe 'assembled' closes the loops" in str(refused.value)
    assert import_mjcf(path).keyframe == "assembled"  # its only keyframe, read without --keyframe
    open_only = tmp_path / "open_keys.xml"
    open_only.write_text(path.read_text().replace(
        '<key name="assembled"', '<key name="straight" qpos="0 0 0"/>\n    <key name="assembled"'))
    with pytest.raises(MjcfError) as refused:
        import_mjcf(open_only, keyframe="straight")
    assert "closes the loops" not in str(refused.value)  # a keyframe named is read, not second-guessed
    with pytest.raises(MjcfError) as refused:
        import_mjcf(open_only, qpos0=True)
    assert "keyframe 'assembled' closes" in str(refused.value) and "'straight'" not in str(refused.value)


def test_cli_says_which_keyframe_it_read(tmp_path, capsys):
    from loopcheck.compare.cli import main

    model = _write(tmp_path, HOME)
    out = tmp_path / "scene.toml"
    assert main(["import-mjcf", str(model), "-o", str(out)]) == 0
    said = [line for line in capsys.readouterr().out.splitlines() if "only keyframe" in line]
    assert len(said) == 1 and "'home'" in said[0]
    several = _write(tmp_path, HOME + '\n    <key name="push" ctrl="4"/>', "several.xml")
    assert main(["import-mjcf", str(several), "-o", str(tmp_path / "s.toml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 keyframes" in err and not (tmp_path / "s.toml").exists()
    assert main(["import-mjcf", str(several), "--qpos0", "-o", str(tmp_path / "s.toml")]) == 0


def _exported(tmp_path: Path) -> Path:
    """The shipped seed (a 250 N·m pulse for 1 s, horizon 2 s, MJWarp's own tolerances) exported."""
    from loopcheck.reference_models import MujocoSettings, mjcf_text
    from loopcheck.shipped_scenes import default_scene_path
    from loopcheck.scenefile import load_scene

    path = tmp_path / "seed.xml"
    path.write_text(mjcf_text(load_scene(default_scene_path()), MujocoSettings(timestep=1e-3)))
    return path


def test_the_arguments_come_before_the_custom_numerics(tmp_path):
    """Flags, then <custom>, then defaults: --horizon and --ctrl over the exported horizon and load
    table; without them, the file's (2 s; 250 N·m until 1 s); a model without them, 1 s."""
    from loopcheck.loads import PiecewiseConstantLoad
    from loopcheck.reference_models.mjcf_import import Control

    path = _exported(tmp_path)
    plain = import_mjcf(path)
    assert plain.scene.horizon == 2.0 and plain.scene.load == PiecewiseConstantLoad((0.0, 1.0), (250.0, 0.0))
    assert plain.scene.engine_tolerances["mjwarp"]["q_atol"] == 0.01
    flagged = import_mjcf(path, horizon=0.5, control=Control.constant(3.0))
    assert flagged.scene.horizon == 0.5 and flagged.scene.load == ConstantLoad(3.0)
    assert import_mjcf(_write(tmp_path, HOME)).scene.horizon == 1.0  # no <custom>: the default


@pytest.mark.parametrize("numeric, says", [
    ('<numeric name="loopcheck.horizon" data="nan"/>', "not finite"),
    ('<numeric name="loopcheck.horizn" data="2"/>', "not a numeric loopcheck writes"),
    ('<numeric name="loopcheck.ctrl" data="0 1 2"/>', "pairs"),
    ('<numeric name="loopcheck.ctrl" data="1 5 0 1"/>', "increase strictly"),
    ('<numeric name="loopcheck.tolerances.q_atol" data="-1"/>', "must be > 0"),
    ('<numeric name="loopcheck.horizon" data="1 2"/>', "not one"),
])
def test_bad_custom_numerics_are_refused_by_name(tmp_path, numeric, says):
    path = tmp_path / "bad.xml"
    path.write_text(LINKAGE.format(keys=HOME).replace("</mujoco>", f"  <custom>{numeric}</custom>\n</mujoco>"))
    with pytest.raises(MjcfError) as refused:
        import_mjcf(path)
    assert "custom numeric 'loopcheck." in str(refused.value) and says in str(refused.value)


def test_a_users_own_numeric_is_not_read(tmp_path):
    path = tmp_path / "own.xml"
    path.write_text(LINKAGE.format(keys=HOME).replace(
        "</mujoco>", '  <custom><numeric name="gripper_width" data="0.085"/></custom>\n</mujoco>'))
    assert import_mjcf(path).scene.horizon == 1.0


def test_cli_export_then_import_with_no_flags_gives_the_scene_back(tmp_path, capsys):
    """`export-mjcf -o m.xml` then `import-mjcf m.xml` (the seed): before, the load, the horizon
    (2 s → 1 s) and the tolerances were lost; now the scene file written has them."""
    from loopcheck.compare.cli import main
    from loopcheck.scenefile import load_scene
    from loopcheck.shipped_scenes import default_scene_path

    seed = load_scene(default_scene_path())
    model, back = tmp_path / "m.xml", tmp_path / "back.toml"
    assert main(["export-mjcf", "-o", str(model), "--timestep", "0.001"]) == 0
    assert main(["import-mjcf", str(model), "-o", str(back)]) == 0
    assert "read at keyframe 'home', the model's only keyframe" in capsys.readouterr().out
    scene = load_scene(back)
    assert (scene.horizon, scene.q0, scene.qdot0, scene.tolerances) == (seed.horizon, seed.q0, seed.qdot0,
                                                                        seed.tolerances)
    assert dict(scene.engine_tolerances["mjwarp"]) == dict(seed.engine_tolerances["mjwarp"])
    times = np.linspace(0.0, seed.horizon, 2001)
    np.testing.assert_array_equal(scene.load.sample(times), seed.load.sample(times))
