"""export-mjcf writes every number of the new element kinds at full precision (issue 37's review:
MuJoCo's writer prints 6 digits, so a friction of 30.123456789 N·m came back 30.1235, a range
-1.123456789 came back -1.12346, a joint inertia 0.0123456789 came back 0.0123457). Oracle: the
values written in the scene; the import gives them back exactly (a range on the cut joint B, which
MuJoCo holds on a tendon over the tree joints, within 4 ulps of its size: the coordinate map's
round-off, measured 1.1e-16). Planted: the tendon attributes and joint ranges left to MuJoCo's
writer (the 6-digit values came back)."""
from __future__ import annotations

import pytest

from loopcheck.reference_models import MujocoSettings, mjcf_text
from loopcheck.reference_models.mjcf_import import import_mjcf
from loopcheck.api import scene_from_string

from helpers import ROOT

FRICTION = (ROOT / "scenes" / "mechanisms" / "friction_fourbar.toml").read_text()


def _edited(*replacements: tuple[str, str]) -> str:
    text = FRICTION
    for old, new in replacements:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    text = _edited(("friction = 30.0", "friction = 30.123456789"),
                   ('name = "O1"\n', 'name = "O1"\nrange = [-1.123456789, 3.0]\n'),
                   ('name = "B"\n', 'name = "B"\nrange = [-0.287654321, 2.0]\n'),
                   ("inertia = 5.0 ", "inertia = 5.0123456789 "))
    text += '\n[[joint_inertias]]\nname = "rotor"\njoint = "O1"\ninertia = 0.0123456789\n'
    scene = scene_from_string(text)
    path = tmp_path_factory.mktemp("precision") / "friction.xml"
    path.write_text(mjcf_text(scene, MujocoSettings(timestep=1e-3)))
    return scene, import_mjcf(path, horizon=scene.horizon).scene


def test_frictions_come_back_exactly(round_trip):
    scene, back = round_trip
    assert sorted(e.coefficient for e in back.mechanism.joint_frictions) == \
        sorted(e.coefficient for e in scene.mechanism.joint_frictions) == [5.0, 30.123456789]


def test_ranges_come_back_exactly_on_tree_joints_and_to_round_off_on_cut_ones(round_trip):
    scene, back = round_trip
    ranges = {j.name: j.range for j in back.mechanism.linkage.joints if j.range is not None}
    assert ranges["O1"] == (-1.123456789, 3.0)
    assert ranges["B"] == pytest.approx((-0.287654321, 2.0), abs=4 * 2.2e-16 * 2.0)


def test_inertias_come_back_exactly(round_trip):
    scene, back = round_trip
    assert back.mechanism.linkage.body_map["coupler"].inertia == 5.0123456789
    assert [e.coefficient for e in back.mechanism.joint_inertias] == [0.0123456789]
