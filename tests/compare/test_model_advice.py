"""The advice `loopcheck check model.xml` prints must hold up: every snippet loads in MuJoCo, and
pasting it alone gives the model the options it names."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import mujoco
import pytest

from loopcheck.mujoco_model.options import INTEGRATORS
from loopcheck.reference_models.mjcf_import import import_mjcf
from loopcheck.reference_models.user_model import ModelOptions

DATA = Path(__file__).parent.parent / "data" / "mjcf"


def paste(text: str, snippet: str) -> str:
    """The model's text with the snippet pasted in as a user would: the snippet's <option>
    attributes over the model's, its <default> entries into the model's top default, and each
    <connect> line's attributes onto the model's connect of that name."""
    root = ET.fromstring(text)
    pasted = ET.fromstring(f"<snippet>{snippet}</snippet>")
    for element in pasted:
        if element.tag == "option":
            option = root.find("option")
            if option is None:
                option = ET.SubElement(root, "option")
            option.attrib.update(element.attrib)
        elif element.tag == "default":
            default = root.find("default")
            if default is None:
                default = ET.Element("default")
                root.insert(0, default)
            default.extend(list(element))
        elif element.tag == "connect":
            targets = [c for c in root.iter("connect") if c.get("name") == element.get("name")]
            assert len(targets) == 1, f"the snippet's connect {element.get('name')!r} is not one connect of the model"
            targets[0].attrib.update(element.attrib)
        else:
            raise AssertionError(f"the snippet has a <{element.tag}> element, which paste() does not know")
    return ET.tostring(root, encoding="unicode")


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_every_snippet_loads_in_mujoco_and_sets_what_it_names(integrator):
    """For each integrator loopcheck can suggest, the snippet is MJCF MuJoCo accepts (its
    integrator keywords are case-sensitive: "euler" is refused, "Euler" is not), and the model
    with it pasted in runs with exactly the suggested options (planted: the integrator written
    in lower case fails MuJoCo's parser for Euler and RK4)."""
    text = (DATA / "fourbar_xz_degrees.xml").read_text()
    written = ModelOptions.as_written(mujoco.MjModel.from_xml_string(text))
    suggested = ModelOptions(integrator, 0.0005, ((0.001, 1.0),) * len(written.solref),
                             ((0.9999, 0.9999, 0.001, 0.5, 2.0),) * len(written.solimp),
                             written.iterations, written.tolerance)
    model = mujoco.MjModel.from_xml_string(paste(text, suggested.mjcf()))
    assert ModelOptions.as_written(model) == suggested


def _unnamed(tmp_path: Path, old: str, new: str) -> Path:
    text = (DATA / "fourbar_xz_degrees.xml").read_text().replace('<connect name="B"', '<connect')
    assert old in text
    path = tmp_path / "unnamed.xml"
    path.write_text(text.replace(old, new))
    return path


def test_an_unnamed_connect_is_named_by_kind_ordinal_and_what_it_joins(tmp_path):
    """The model's second connect, unnamed, joins two sites of the rocker and of an unnamed body
    welded to it: the refusal names it `connect #2 (tip_a–tip_b)`, words the user finds in the
    file, not MuJoCo's index (planted: the old fallback, `equality1`, fails it)."""
    from loopcheck.reference_models.mjcf_import import MjcfError

    path = _unnamed(tmp_path, '<geom class="link" fromto="0 0 0 0.7 0 0"/>',
                    '<geom class="link" fromto="0 0 0 0.7 0 0"/><site name="tip_a" pos="0.7 0 0"/>'
                    '<body pos="0.7 0 0"><geom size="0.01" type="sphere"/><site name="tip_b"/></body>')
    path.write_text(path.read_text().replace('anchor="0.9 0 0"/>',
                                             'anchor="0.9 0 0"/>\n    <connect site1="tip_a" site2="tip_b"/>'))
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path)
    message = str(caught.value)
    assert "connect #2 (tip_a–tip_b) joins two points of one rigid body" in message, message
    assert "equality" not in message


def test_unnamed_geoms_touching_at_the_start_are_named_by_the_bodies_they_are_on(tmp_path):
    """Contacts left on, the coupler's and the rocker's capsules overlapping at their loop joint:
    the refusal names `geom #2 (on coupler)` and `geom #3 (on rocker)`, not `geom1` and `geom2`
    (planted: the old fallback)."""
    from loopcheck.reference_models.mjcf_import import MjcfError

    path = _unnamed(tmp_path, ' contype="0" conaffinity="0"', "")
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path)
    message = str(caught.value)
    assert "geom #2 (on coupler) and geom #3 (on rocker) touch (distance -0.04 m" in message, message


def _own_softness(tmp_path: Path) -> Path:
    """The seed's four-bar with its connect setting its own softness, as Menagerie's grippers do
    (solref 0.02 1, solimp 0.9 0.95 0.001 on the connect itself, a default class beside it)."""
    text = (DATA / "fourbar_xz_degrees.xml").read_text().replace(
        '<connect name="B" body1="coupler" body2="rocker" anchor="0.9 0 0"/>',
        '<connect name="B" body1="coupler" body2="rocker" anchor="0.9 0 0" solref="0.02 1" solimp="0.9 0.95 0.001"/>')
    path = tmp_path / "own_softness.xml"
    path.write_text(text)
    return path


def test_pasting_the_snippet_alone_fixes_a_connect_with_its_own_solref(tmp_path):
    """The connect's own solref/solimp beat any <default>: the snippet writes the new values on
    the connect by name, and the model with the snippet pasted in (and nothing else) runs with the
    suggested options and passes (planted: the snippet without its <connect> line leaves the loop
    soft, the options read back differ and the model fails)."""
    from loopcheck.compare.model_check import check_model
    from loopcheck.reference_models.model_check import diagnosis_lines
    from loopcheck.reference_models.mjcf_import import Control

    pulse = Control((0.0, 1.0), (250.0, 0.0))
    path = _own_softness(tmp_path)
    imported = import_mjcf(path, control=pulse, horizon=1.0)
    assert [c.own for c in imported.connects] == [True]
    check = check_model(imported)
    assert not check.passed and check.cheapest is not None
    snippet = check.cheapest.options.mjcf(imported.connects)
    assert '<connect name="B" solref=' in snippet
    assert any("connect of that name" in line for line in diagnosis_lines(check))
    from loopcheck.reference_models.model_check import check_lines
    assert "      horizon: every run simulates 1 s (--horizon)" in check_lines(check, str(path))
    fixed = tmp_path / "fixed.xml"
    fixed.write_text(paste(path.read_text(), snippet))
    again = import_mjcf(fixed, control=pulse, horizon=1.0)
    assert ModelOptions.as_written(again.model) == check.cheapest.options
    assert check_model(again).passed


def test_a_connect_without_its_own_softness_gets_the_default_only():
    """The seed's file: its connect takes the default class's softness, so the snippet is the
    <option> and the <default> alone (no <connect> line a user would have to place)."""
    imported = import_mjcf(DATA / "fourbar_xz_degrees.xml")
    assert [(c.label, c.name, c.own) for c in imported.connects] == [("connect 'B'", "B", False)]
    snippet = ModelOptions.as_written(imported.model).stiff_loops().mjcf(imported.connects)
    assert "<connect" not in snippet and "<default><equality" in snippet


def test_the_import_line_gives_q0_as_the_joints_qpos_and_the_sign_of_the_rates(tmp_path, capsys):
    """The hand-written four-bar is authored with its crank's frame turned by 0.2 rad (euler) and
    qpos 0: the import line gives the MuJoCo joint's qpos, 0, how the scene's q = 0.2 rad is made of
    it, and that the rates printed are that joint's qvel (planted: the old `at q0 = 0.2 rad`), and
    the horizon."""
    from loopcheck.compare.cli import main

    assert main(["import-mjcf", str(DATA / "fourbar_xz_degrees.xml"), "-o", str(tmp_path / "s.toml")]) == 0
    out = capsys.readouterr().out
    assert ("input 'O1': joint 'O1' at qpos 0 rad (q = qpos + 0.2 rad; every rate and peak printed is qvel of "
            "joint 'O1')") in out, out
    assert "horizon 1 s" in out


def _variant(tmp_path: Path, name: str, option: str, own: bool) -> Path:
    text = (DATA / "fourbar_xz_degrees.xml").read_text().replace(
        '<option timestep="0.001" integrator="RK4" gravity="0 0 0"/>', option)
    if own:
        text = text.replace('anchor="0.9 0 0"/>', 'anchor="0.9 0 0" solref="0.02 1" solimp="0.9 0.95 0.001"/>')
    path = tmp_path / f"{name}.xml"
    path.write_text(text)
    return path


MARGIN_MODELS = {
    # name: (option, connect sets its own softness, horizon s, tolerances loosened by)
    "own softness, Euler 4 ms, tolerances x2": ('<option timestep="0.004" integrator="Euler" gravity="0 0 0"/>', True,
                                                1.0, 2.0),
    "MuJoCo's defaults, 2 s": ('<option gravity="0 0 0"/>', False, 2.0, 1.0),
    "own softness, implicitfast 2 ms": ('<option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>', True,
                                        1.0, 1.0),
}


@pytest.mark.parametrize("name", MARGIN_MODELS)
def test_the_suggestion_passes_with_margin_at_its_step_and_half_of_it_and_pasted(name, tmp_path):
    """Three four-bars of the seed's (the pulse, 250 N·m for 1 s) that fail as written: the
    suggestion's every difference is at most half its tolerance over the stated horizon, at its
    step and at half of it; the next doubled step (when tried) misses that margin; the output
    states the margin; the model with the snippet pasted in passes as written with the same margin
    (the same options: the same run). Planted: the search stopping at a step that merely passes
    (the old rule) suggests RK4 8 ms for the first model, 0.89 of its tolerance."""
    from loopcheck.compare.model_check import check_model
    from loopcheck.reference_models.model_check import MARGIN, diagnosis_lines
    from loopcheck.reference_models.mjcf_import import Control
    from loopcheck.scene import Tolerances

    option, own, horizon, loosen = MARGIN_MODELS[name]
    pulse = Control((0.0, 1.0), (250.0, 0.0))
    base = Tolerances()
    tolerances = Tolerances(peak_omega_rtol=base.peak_omega_rtol * loosen, q_atol=base.q_atol * loosen,
                            omega_atol=base.omega_atol * loosen)
    path = _variant(tmp_path, "model", option, own)
    imported = import_mjcf(path, control=pulse, horizon=horizon)
    check = check_model(imported, tolerances=tolerances)
    assert not check.passed
    best, half = check.cheapest, check.cheapest_half
    assert best.excess <= MARGIN and half.excess <= MARGIN
    assert half.options == replace(best.options, timestep=best.options.timestep / 2).stiff_loops()
    doubled = [t for t in check.tried if t.options == replace(best.options, timestep=2 * best.options.timestep).stiff_loops()]
    assert all(not t.with_margin for t in doubled)
    assert doubled or 2 * best.options.timestep > horizon / 10 or best.options.timestep < check.as_written.options.timestep
    lines = diagnosis_lines(check)
    assert any(f"margin: every difference at most {best.excess:.2g} of its tolerance over {horizon:g} s, "
               f"{half.excess:.2g} at half the step (required: 0.5)" in line for line in lines)
    fixed = tmp_path / "fixed.xml"
    fixed.write_text(paste(path.read_text(), best.options.mjcf(imported.connects)))
    again = check_model(import_mjcf(fixed, control=pulse, horizon=horizon), tolerances=tolerances)
    assert again.passed and again.as_written.options == best.options
    assert again.as_written.excess == pytest.approx(best.excess, rel=1e-9)  # the same run: round-off apart
    print(f"{name}: {best.options.text()}, margin {best.excess:.3g} (half step {half.excess:.3g}), "
          f"pasted: {again.as_written.excess:.3g}")


def test_an_unnamed_connect_with_its_own_softness_is_named_in_a_comment(tmp_path):
    """A connect with its own solref and no name cannot be addressed by a <connect name=...>
    line: the snippet names it as the messages do and gives the values to set on it (planted:
    the comment dropped, the default alone, which does not reach it)."""
    path = _variant(tmp_path, "unnamed_own", '<option gravity="0 0 0"/>', True)
    path.write_text(path.read_text().replace('<connect name="B"', "<connect"))
    imported = import_mjcf(path)
    assert [(c.label, c.name, c.own) for c in imported.connects] == [("connect #1 (coupler–rocker)", None, True)]
    snippet = ModelOptions.as_written(imported.model).stiff_loops().mjcf(imported.connects)
    assert ('<!-- connect #1 (coupler–rocker): set solref="0.004 1" solimp="0.9999 0.9999 0.001 0.5 2" on it -->'
            in snippet), snippet


def test_a_value_of_an_unnamed_joint_is_refused_under_the_name_the_messages_use(tmp_path):
    """The value checks run before MuJoCo compiles the model (on its spec), the other refusals
    after: an unnamed joint is `joint #3 (world–rocker)` in both (planted: the old `joint #2
    (unnamed, in body 'rocker')`, 0-based)."""
    from loopcheck.reference_models.mjcf_import import MjcfError, element_label

    path = _unnamed(tmp_path, '<joint name="O3"/>', '<joint damping="-1"/>')
    with pytest.raises(MjcfError) as caught:
        import_mjcf(path)
    assert "joint #3 (world–rocker): damping=\"-1\" cannot be represented" in str(caught.value), str(caught.value)
    compiled = mujoco.MjModel.from_xml_path(str(_unnamed(tmp_path, '<joint name="O3"/>', "<joint/>")))
    assert element_label(compiled, mujoco.mjtObj.mjOBJ_JOINT, 2) == "joint #3 (world–rocker)"
