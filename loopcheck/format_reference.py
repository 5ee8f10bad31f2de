"""The scene-format reference's tables, written from the definitions so that they cannot go
stale: each engine's table (its ``Settings``' options, :mod:`loopcheck.registry`), the gate's
``[tolerances]`` (the fields of :class:`loopcheck.scene.Tolerances`) with its engine tables
``[tolerances.ENGINE]`` and the scene limits
(:data:`loopcheck.scene.LIMITS`).

``python -m loopcheck.format_reference docs/scenes.md`` rewrites the part of that file between the
markers (two parts); ``--check`` only says whether it is current (``tests/test_format_reference.py`` runs it).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from .registry import ENGINES, REFERENCE, judged_engines
from .scene import LIMITS, Tolerances
from .settings import markdown_row, options, reference_rows

BEGIN = "<!-- begin: written by `python -m loopcheck.format_reference docs/scenes.md` -->"
END = "<!-- end: written by loopcheck.format_reference -->"
LIMITS_BEGIN = "<!-- begin: the limits, written by `python -m loopcheck.format_reference docs/scenes.md` -->"
LIMITS_END = "<!-- end: the limits, written by loopcheck.format_reference -->"


def tables() -> str:
    """The generated Markdown: one table per engine, then ``[tolerances]`` and its engine tables."""
    parts = []
    for name, engine in ENGINES.items():
        parts += [f"### `[{name}]`: {engine.description}", "", *reference_rows(engine.settings, name), ""]
    parts += ["### `[tolerances]`: what `loopcheck check` requires of the engines' agreement", "",
              "| key | value | unit | default | meaning |", "|---|---|---|---|---|"]
    for f in dataclasses.fields(Tolerances):
        default = "absent" if f.default is None else f"{f.default:g}"
        parts.append(markdown_row((f"`tolerances.{f.name}`", "positive number", f.metadata["unit"] or "–", default,
                                   f.metadata["help"])))
    tables = ", ".join(f"`[tolerances.{name}]`" for name in judged_engines())
    parts += ["", f"### {tables}: one engine's own agreement with the reduced reference", "",
              f"A table for each engine but the reference (`[tolerances.{REFERENCE}]` is refused), with the keys of "
              "`[tolerances]`: a key it gives is what `loopcheck check --engines` and `loopcheck run --engines` judge that "
              "engine by, a key it does not give is `[tolerances]`' value. `[tolerances.mujoco]` is MuJoCo's gate in "
              "every command; the command line's tolerance flags override every engine's value."]
    return "\n".join(parts) + "\n"


def limits_table() -> str:
    """The scene limits (:data:`loopcheck.scene.LIMITS`): each kind's keys, range and why; an engine's
    options of a kind (its steps) are listed with it."""
    rows = ["| kind | keys | range | why |", "|---|---|---|---|"]
    for kind, r in LIMITS.items():
        keys = [f"`{k}`" for k in r.keys]
        keys += [f"`{name}.{o.name}`" for name, engine in ENGINES.items() for o in options(engine.settings)
                 if o.limit == kind and o.table]
        rows.append(markdown_row((kind, ", ".join(keys), r.text(), r.why)))
    return "\n".join(rows) + "\n"


def rewritten(text: str) -> str:
    """``text`` with the parts between the markers replaced by :func:`tables` and :func:`limits_table`."""
    for begin, end, made in ((BEGIN, END, tables()), (LIMITS_BEGIN, LIMITS_END, limits_table())):
        head, found_begin, rest = text.partition(begin)
        _, found_end, tail = rest.partition(end)
        if not (found_begin and found_end):
            raise ValueError(f"the markers of a generated part are missing: {begin}")
        text = f"{head}{begin}\n{made}{end}{tail}"
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m loopcheck.format_reference", description=__doc__.split("\n\n")[0])
    parser.add_argument("file", type=Path)
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is not current; write nothing")
    args = parser.parse_args(argv)
    text = args.file.read_text(encoding="utf-8")
    new = rewritten(text)
    if args.check:
        if new != text:
            print(f"{args.file}: the generated reference is stale: run python -m loopcheck.format_reference {args.file}")
            return 1
        return 0
    if new != text:
        args.file.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
