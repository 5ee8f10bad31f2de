"""The scene-format reference's tables, written from the definitions so that they cannot go
stale: each engine's table (its ``Settings``' options, :mod:`xval.registry`) and the gate's
``[tolerances]`` (the fields of :class:`xval.scene.Tolerances`).

``python -m xval.format_reference docs/scenes.md`` rewrites the part of that file between the
markers; ``--check`` only says whether it is current (``tests/test_format_reference.py`` runs it).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from .registry import ENGINES
from .scene import Tolerances
from .settings import markdown_row, reference_rows

BEGIN = "<!-- begin: written by `python -m xval.format_reference docs/scenes.md` -->"
END = "<!-- end: written by xval.format_reference -->"


def tables() -> str:
    """The generated Markdown: one table per engine, then ``[tolerances]``."""
    parts = []
    for name, engine in ENGINES.items():
        parts += [f"### `[{name}]`: {engine.title}", "", *reference_rows(engine.settings, name), ""]
    parts += ["### `[tolerances]`: what `xval check` requires of the engines' agreement", "",
              "| key | value | unit | default | meaning |", "|---|---|---|---|---|"]
    for f in dataclasses.fields(Tolerances):
        default = "absent" if f.default is None else f"{f.default:g}"
        parts.append(markdown_row((f"`tolerances.{f.name}`", "positive number", f.metadata["unit"] or "–", default,
                                   f.metadata["help"])))
    return "\n".join(parts) + "\n"


def rewritten(text: str) -> str:
    """``text`` with the part between the markers replaced by :func:`tables`."""
    head, begin, rest = text.partition(BEGIN)
    _, end, tail = rest.partition(END)
    if not (begin and end):
        raise ValueError("the markers of the generated part are missing")
    return f"{head}{BEGIN}\n{tables()}{END}{tail}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m xval.format_reference", description=__doc__.split("\n\n")[0])
    parser.add_argument("file", type=Path)
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is not current; write nothing")
    args = parser.parse_args(argv)
    text = args.file.read_text(encoding="utf-8")
    new = rewritten(text)
    if args.check:
        if new != text:
            print(f"{args.file}: the generated reference is stale: run python -m xval.format_reference {args.file}")
            return 1
        return 0
    if new != text:
        args.file.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
