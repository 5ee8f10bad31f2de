"""docs/scenes.md's tables of the engines' settings, of [tolerances] and of the scene limits are
the ones written from the definitions (loopcheck.format_reference): a setting or a limit added, renamed
or re-documented without rewriting them fails here. (Planted: editing one cell of the file's generated part, and changing
an option's help in loopcheck/reference_models/settings.py, each failed this test.)"""

from __future__ import annotations

from loopcheck.format_reference import BEGIN, END, LIMITS_BEGIN, LIMITS_END, limits_table, main, tables
from loopcheck.registry import ENGINES
from loopcheck.scene import LIMITS
from loopcheck.settings import options

from helpers import ROOT

SCENES_DOC = ROOT / "docs" / "scenes.md"


def test_the_scene_format_reference_is_current(capsys):
    assert main([str(SCENES_DOC), "--check"]) == 0, capsys.readouterr().out


def test_every_table_option_has_its_row():
    text = SCENES_DOC.read_text(encoding="utf-8")
    generated = text[text.index(BEGIN):text.index(END)]
    assert generated.strip() == f"{BEGIN}\n{tables()}".strip()
    for name, engine in ENGINES.items():
        for o in options(engine.settings):
            assert (f"| `{name}.{o.name}` |" in generated) == o.table, o.name


def test_every_limit_has_its_row_with_the_engines_steps():
    text = SCENES_DOC.read_text(encoding="utf-8")
    generated = text[text.index(LIMITS_BEGIN):text.index(LIMITS_END)]
    assert generated.strip() == f"{LIMITS_BEGIN}\n{limits_table()}".strip()
    for kind, r in LIMITS.items():
        assert f"| {kind} |" in generated and r.text().replace("|", "\\|") in generated, kind
    step = next(line for line in generated.splitlines() if line.startswith("| step |"))
    assert "`mujoco.timestep`" in step and "`reduced.step`" in step
