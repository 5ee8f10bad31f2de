"""Settings declared once: an engine's ``Settings`` dataclass marks each field with
:func:`option`, and everything else is read from that one definition — the engine's table of the
scene file (keys, types, units), its command-line flags (names, types, defaults, help) and the
scene-format reference (``docs/scene-format.md``).

The dataclass's ``__post_init__`` still owns the rules between values (a range, a combination);
this module checks what one value must be on its own (a number, a whole number, one of the
choices) and names the key or flag that gave it.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import warnings
from dataclasses import dataclass, field
from numbers import Real
from typing import Any, Mapping

from .errors import type_name
from .scene import LIMITS, SceneError
from .toml_reader import finite_number, number

KINDS = ("choice", "number", "whole", "bool", "numbers")


@dataclass(frozen=True)
class Option:
    """One setting: a field of an engine's ``Settings``, a key of its scene table, a flag.

    name : the field's name, the table's key; the flag is ``--name`` with ``_`` as ``-``.
    default : the field's default (None: chosen by the engine; ``default_text`` says how).
    help : one phrase, without the default (the flag's help and the reference add it).
    kind : "choice" (one of ``choices``), "number" (finite; positive unless ``signed``),
        "whole" (an integer in [low, high]), "bool", "numbers" (``len(parts)`` finite numbers,
        ``parts`` naming each).
    unit : the SI unit, for the help and the reference ("" for none).
    limit : a :data:`loopcheck.scene.LIMITS` kind the value must lie in (e.g. "step").
    within_horizon : the value is a time step and may not exceed the scene's horizon.
    flag : False: not on the command line (an API-only setting).
    table : False: not in the scene file.
    """

    name: str
    default: Any
    help: str
    kind: str
    choices: tuple[str, ...] = ()
    parts: tuple[str, ...] = ()
    unit: str = ""
    low: int = 0
    high: int = 0
    signed: bool = False
    limit: str | None = None
    within_horizon: bool = False
    default_text: str | None = None
    flag: bool = True
    table: bool = True

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Option {self.name}: kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if (self.kind == "choice") != bool(self.choices):
            raise ValueError(f"Option {self.name}: choices go with kind 'choice'")
        if (self.kind == "numbers") != bool(self.parts):
            raise ValueError(f"Option {self.name}: parts go with kind 'numbers'")
        if self.kind == "whole" and not self.low <= self.high:
            raise ValueError(f"Option {self.name}: a whole number needs low ≤ high")
        if self.limit is not None and self.limit not in LIMITS:
            raise ValueError(f"Option {self.name}: limit must be one of {', '.join(LIMITS)}")

    @property
    def flag_name(self) -> str:
        return self.name.replace("_", "-")

    @property
    def type_text(self) -> str:
        """What the value must be, in words (the reference's column)."""
        if self.kind == "choice":
            return "one of " + ", ".join(f'"{c}"' for c in self.choices)
        if self.kind == "whole":
            return f"whole number in [{self.low}, {self.high}]"
        if self.kind == "bool":
            return "true or false"
        if self.kind == "numbers":
            return f"array of {len(self.parts)} numbers ({', '.join(self.parts)})"
        text = "number" if self.signed else "positive number"
        if self.limit is not None:
            text += f" in {LIMITS[self.limit].text()}"
        if self.within_horizon:
            text += ", at most `simulation.horizon`"
        return text

    @property
    def default_words(self) -> str:
        if self.default_text is not None:
            return self.default_text
        if isinstance(self.default, bool):
            return "true" if self.default else "false"
        if isinstance(self.default, tuple):
            return "[" + ", ".join(f"{v:g}" for v in self.default) + "]"
        if isinstance(self.default, float):
            return f"{self.default:g}"
        return str(self.default)

    def read(self, value: Any, key: str) -> Any:
        """The scene file's ``value`` for this option, checked on its own (SceneError naming ``key``)."""
        if self.kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                got = f'"{value}"' if isinstance(value, str) else type_name(value)
                raise SceneError(f"'{key}' must be one of {', '.join(self.choices)}, got {got}")
            return value
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise SceneError(f"'{key}' must be true or false, got {type_name(value)}")
            return value
        if self.kind == "whole":
            if isinstance(value, bool) or not isinstance(value, int) or not self.low <= value <= self.high:
                raise SceneError(f"'{key}' must be a whole number from {self.low} to {self.high}")
            return value
        if self.kind == "numbers":
            if not isinstance(value, list) or len(value) != len(self.parts):
                raise SceneError(f"'{key}' must be an array of {len(self.parts)} numbers")
            return tuple(finite_number(v, f"{key}[{i}]") for i, v in enumerate(value))
        return number(value, key, positive=not self.signed, kind=self.limit)

    def parse(self, text: str) -> Any:
        """One command-line word for this option (an ``argparse`` type)."""
        if self.kind == "whole":
            return parse_whole(text, self.low, self.high)
        return parse_number(text, positive=self.kind == "number" and not self.signed)


def parse_number(text: str, *, positive: bool = False) -> float:
    """A command-line number, finite (and positive if asked); ``argparse.ArgumentTypeError``
    saying why otherwise. Every numeric flag is read by this or :func:`parse_whole`."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text}")
    if positive and not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def field_number(value: Any, what: str) -> float:
    """A settings field's number as a float: a real number (numpy's too, not a bool) and finite;
    ValueError ``"<what> must be a finite number, got ..."`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def parse_whole(text: str, low: int, high: int) -> int:
    """A command-line whole number in [low, high]; ``argparse.ArgumentTypeError`` otherwise."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(f"must be between {low} and {high}, got {value}")
    return value


def option(default: Any, help: str, kind: str, **spec: Any) -> Any:
    """A dataclass field of an engine's ``Settings`` that is also an :class:`Option`."""
    return field(default=default, metadata={"option": (help, kind, spec)})


def options(settings_type: type) -> tuple[Option, ...]:
    """The options of an engine's ``Settings``, in field order."""
    out = []
    for f in dataclasses.fields(settings_type):
        if "option" in f.metadata:
            help, kind, spec = f.metadata["option"]
            out.append(Option(name=f.name, default=f.default, help=help, kind=kind, **spec))
    return tuple(out)


def settings_dict(settings: Any) -> dict[str, Any]:
    """An engine's settings as run, for reports: its ``as_dict()`` where the engine declares one
    (a resolved value, such as MuJoCo's effective solref), by default each option's value (tuples
    as lists)."""
    if hasattr(settings, "as_dict"):
        return settings.as_dict()
    return {o.name: (list(v) if isinstance(v := getattr(settings, o.name), tuple) else v)
            for o in options(type(settings))}


def read_table(settings_type: type, table: Any, key: str) -> dict[str, Any]:
    """The keys given in a scene file's engine table, each checked on its own (SceneError
    naming ``key.name``); unknown keys refused. Rules between values are the settings' own
    (:func:`resolve`)."""
    if not isinstance(table, dict):
        raise SceneError(f"'{key}' must be a table, got {type_name(table)}")
    known = {o.name: o for o in options(settings_type) if o.table}
    unknown = sorted(set(table) - set(known))
    if unknown:
        raise SceneError(f"unknown key '{key}.{unknown[0]}' (the keys of [{key}]: {', '.join(known)})")
    return {name: known[name].read(value, f"{key}.{name}") for name, value in table.items()}


def resolve(settings_type: type, table: Mapping[str, Any], flags: Mapping[str, Any], where: str):
    """The settings: ``flags`` (None: not given) over the scene's ``table`` over the defaults.

    A table that the settings refuse is bad input naming ``where`` (``scene.toml: [mujoco]
    solimp ...``); a bad flag keeps the settings' own message, which names the field."""
    with warnings.catch_warnings():  # the combined settings below warn once, not twice
        warnings.simplefilter("ignore")
        try:
            settings_type(**table)
        except ValueError as exc:
            raise SceneError(f"{where} {exc}") from None
    return settings_type(**{**table, **{k: v for k, v in flags.items() if v is not None}})


def add_flags(parser: argparse.ArgumentParser, settings_type: type, *, title: str, prefix: str = "",
              table: str) -> None:
    """An argument group with a flag per option of ``settings_type`` (``--PREFIXNAME``), each
    defaulting to None (not given) and saying what applies then: ``table`` names the scene's
    table that comes before the settings' own default."""
    group = parser.add_argument_group(title)
    for o in options(settings_type):
        if not o.flag:
            continue
        unit = f" ({o.unit})" if o.unit else ""
        default = f"(default: the scene's [{table}] {o.name}, else {o.default_words})"
        dest = _dest(prefix, o)
        if o.kind == "bool":
            if o.default:
                group.add_argument(f"--no-{prefix}{o.flag_name}", dest=dest, action="store_const", const=False,
                                   default=None, help=f"turn off {o.help} {default}")
            else:
                group.add_argument(f"--{prefix}{o.flag_name}", dest=dest, action="store_const", const=True,
                                   default=None, help=f"{o.help} {default}")
        elif o.kind == "choice":
            group.add_argument(f"--{prefix}{o.flag_name}", dest=dest, choices=o.choices, default=None,
                               help=f"{o.help} {default}")
        else:  # numbers: each word through Option.parse, whose errors name the value
            shape = (dict(nargs=len(o.parts), metavar=tuple(p.upper() for p in o.parts)) if o.kind == "numbers"
                     else {})
            group.add_argument(f"--{prefix}{o.flag_name}", dest=dest, type=o.parse, default=None,
                               help=f"{o.help}{unit} {default}", **shape)


def given_flags(args: argparse.Namespace, settings_type: type, *, prefix: str = "") -> dict[str, Any]:
    """The flags of ``settings_type`` that were given (not None), by field name; lists as tuples."""
    out = {}
    for o in options(settings_type):
        value = getattr(args, _dest(prefix, o), None) if o.flag else None
        if value is not None:
            out[o.name] = tuple(value) if isinstance(value, list) else value
    return out


def reference_rows(settings_type: type, table: str) -> list[str]:
    """The scene-format reference's Markdown rows for ``[table]``: key, value, unit, default, meaning."""
    rows = ["| key | value | unit | default | meaning |", "|---|---|---|---|---|"]
    for o in options(settings_type):
        if o.table:
            cells = (f"`{table}.{o.name}`", o.type_text, o.unit or "–", o.default_words, o.help)
            rows.append(markdown_row(cells))
    return rows


def markdown_row(cells) -> str:
    """A row of a Markdown table, its cells' own ``|`` escaped (|q| stays in its cell)."""
    return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"


def _dest(prefix: str, o: Option) -> str:
    return f"{prefix}{o.name}".replace("-", "_")
