"""A user's MJCF with gravity compensation (``gravcomp``): loopcheck's description has none, so a
moving body's ``gravcomp`` other than 0, or a joint's ``actuatorgravcomp``, is refused in one line
naming the file, the element and the attribute, never dropped (issue 36: a Playground-style finger
with ``gravcomp="1"`` on every body got the same exact answer as without it). Zero stays absent; on
a body welded to the world it moves nothing and is accepted."""

from __future__ import annotations

from pathlib import Path

import pytest

from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf

FINGER = Path(__file__).parent.parent / "data" / "mjcf" / "gravcomp_finger.xml"  # gravcomp="1" on every body


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    text = FINGER.read_text()
    assert old in text
    path = tmp_path / "finger.xml"
    path.write_text(text.replace(old, new))
    return path


def _refusal(path: Path) -> str:
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path, keyframe="home")
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


def test_a_gravcomp_finger_is_refused_naming_the_body():
    """The finger as written: the first moving body's gravcomp is named (planted: the refusal
    removed, the import succeeds and the finger runs with its full weight, the silent wrong answer
    of issue 36). The base is welded to the world, so its gravcomp is not the one named."""
    assert _refusal(FINGER) == (f"{FINGER}: body 'proximal': gravcomp=\"1\" cannot be represented: loopcheck's "
                                "description has no gravity compensation (every body bears its full weight)")


@pytest.mark.parametrize("value", ["0.5", "-1", "1e-06", "nan"])
def test_any_other_gravcomp_on_one_moving_body_is_refused(tmp_path, value):
    """One body, any value other than 0 (a NaN is refused as not finite; planted as above)."""
    text = FINGER.read_text().replace(' gravcomp="1"', "")
    path = tmp_path / "finger.xml"
    path.write_text(text.replace('<body name="follower"', f'<body name="follower" gravcomp="{value}"'))
    words = "is not a finite number" if value == "nan" else "cannot be represented"
    assert f"body 'follower': gravcomp=\"{value}\" {words}" in _refusal(path)


def test_actuatorgravcomp_is_refused_naming_the_joint_and_its_class(tmp_path):
    """actuatorgravcomp="true", from the finger's default class (planted: that refusal removed, the
    import succeeds)."""
    text = FINGER.read_text().replace(' gravcomp="1"', "")
    path = tmp_path / "finger.xml"
    path.write_text(text.replace('damping="0.002"', 'damping="0.002" actuatorgravcomp="true"'))
    assert ("joint 'finger_joint': actuatorgravcomp=\"true\" (from default class 'finger') cannot be represented"
            in _refusal(path))


def test_zero_and_a_welded_body_stay_absent(tmp_path):
    """gravcomp="0" on every body, or gravcomp="1" on the base welded to the world only: the same
    mechanism as without gravcomp, and no refusal."""
    plain = import_mjcf(_variant(tmp_path, ' gravcomp="1"', ""), keyframe="home").scene
    zero = import_mjcf(_variant(tmp_path, 'gravcomp="1"', 'gravcomp="0"'), keyframe="home").scene
    text = FINGER.read_text().replace(' gravcomp="1"', "").replace('<body name="base"', '<body name="base" gravcomp="1"')
    welded_path = tmp_path / "welded.xml"
    welded_path.write_text(text)
    welded = import_mjcf(welded_path, keyframe="home").scene
    assert zero.mechanism == plain.mechanism and zero.gravity == plain.gravity
    assert welded.mechanism == plain.mechanism and welded.gravity == plain.gravity
