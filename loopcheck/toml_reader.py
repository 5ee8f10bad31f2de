"""Reading a TOML scene file's text and tables, with every error one line naming the file or key.

:class:`Table` tracks the keys a reader used, so that the unknown ones are reported; the number
readers check each value against its kind's range (:data:`loopcheck.scene.LIMITS`). Nothing here knows
what a scene holds: :mod:`loopcheck.scenefile` reads the scene with these.
"""

from __future__ import annotations

import math
import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from .errors import type_name
from .scene import LIMITS, MAX_ELEMENTS, MAX_NAME_CHARS, MAX_SCENE_BYTES, MAX_TABLE_ENTRIES, Range, SceneError


class Table:
    """A TOML table being read: tracks used keys so unknown ones can be reported."""

    def __init__(self, data: Any, path: str):
        if not isinstance(data, dict):
            raise SceneError(f"'{path}' must be a table, got {type_name(data)}")
        self.data = data
        self.path = path
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = ...) -> Any:
        self.used.add(name)
        if name not in self.data:
            if default is ...:
                raise SceneError(f"missing key '{self.key(name)}'")
            return default
        return self.data[name]

    def number(self, name: str, default: Any = ..., *, positive: bool = False,
               nonnegative: bool = False, kind: str | None = None) -> float:
        value = self.raw(name, default)
        if value is default and default is not ...:
            return value
        return number(value, self.key(name), positive=positive, nonnegative=nonnegative, kind=kind)

    def point(self, name: str, default: Any = ..., *, kind: str = "position") -> tuple[float, float]:
        value = self.raw(name, default)
        if value is default and default is not ...:
            return value
        return point(value, self.key(name), kind=kind)

    def string(self, name: str, default: Any = ...) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise SceneError(f"'{self.key(name)}' must be a string, got {type_name(value)}")
        return value

    def choice(self, name: str, options: tuple[str, ...]) -> str:
        """A string that must be one of ``options``."""
        value = self.string(name)
        if value not in options:
            raise SceneError(f"'{self.key(name)}' must be one of {', '.join(options)}, got \"{value}\"")
        return value

    def table(self, name: str) -> "Table":
        return Table(self.raw(name), self.key(name))

    def close(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise SceneError(f"unknown key '{self.key(unknown[0])}'")


def number(value: Any, key: str, *, positive: bool = False, nonnegative: bool = False,
            kind: str | None = None) -> float:
    value = finite_number(value, key)
    if positive and value <= 0.0:
        raise SceneError(f"'{key}' must be positive, got {value}")
    if nonnegative and value < 0.0:
        raise SceneError(f"'{key}' must not be negative, got {value}")
    if kind is not None:
        check_range(value, key, LIMITS[kind])
    return value


def check_range(value: float, key: str, r: Range, what: str = "") -> None:
    inside = r.low <= value <= r.high if r.low else abs(value) <= r.high
    if not inside:
        raise SceneError(f"'{key}'{what} = {value:g} is out of range: {r.kind} must be in {r.text()}")


def point(value: Any, key: str, *, kind: str = "position") -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise SceneError(f"'{key}' must be an array of two numbers [x, y]")
    return (number(value[0], f"{key}[0]", kind=kind), number(value[1], f"{key}[1]", kind=kind))


def text_value(t: "Table", name: str, default: str, limit: int) -> str:
    """A one-line, printable string of at most ``limit`` characters (names stay plain text)."""
    value = t.string(name, default)
    if len(value) > limit:
        raise SceneError(f"'{t.key(name)}' has {len(value)} characters; at most {limit}")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise SceneError(f"'{t.key(name)}' must be printable text, got the control character {bad!r}")
    return value


def count(items: list, key: str, limit: int, what: str) -> None:
    if len(items) > limit:
        raise SceneError(f"'{key}' has {len(items)} {what}; at most {limit}")


def table_pair(t: Table, first: str, second: str, kind_first: str, kind_second: str):
    xs, ys = t.raw(first), t.raw(second)
    if not isinstance(xs, list) or not isinstance(ys, list):
        raise SceneError(f"'{t.key(first)}' and '{t.key(second)}' must be arrays")
    if len(xs) != len(ys) or not xs:
        raise SceneError(f"'{t.key(first)}' and '{t.key(second)}' must have the same, non-zero length")
    if len(xs) > MAX_TABLE_ENTRIES:
        raise SceneError(f"'{t.key(first)}' has {len(xs)} entries; at most {MAX_TABLE_ENTRIES}")
    return (tuple(number(v, f"{t.key(first)}[{i}]", kind=kind_first) for i, v in enumerate(xs)),
            tuple(number(v, f"{t.key(second)}[{i}]", kind=kind_second) for i, v in enumerate(ys)))


def array_of_tables(top: Table, name: str, limit: int = MAX_ELEMENTS) -> list[Table]:
    items = top.raw(name, [])
    if not isinstance(items, list):
        raise SceneError(f"'{name}' must be an array of tables ([[{name}]])")
    count(items, name, limit, "entries")
    return [Table(item, f"{name}[{i}]") for i, item in enumerate(items)]


def name_key(value: str, key: str) -> str:
    if not value or len(value) > MAX_NAME_CHARS or not all(c.isalnum() or c in "_-" for c in value):
        raise SceneError(f"'{key}' = {value!r} is not a usable name: letters, digits, '_' and '-', "
                         f"1 to {MAX_NAME_CHARS} characters")
    return value


def finite_number(value: Any, key: str) -> float:
    """A TOML number, finite, as a float (SceneError naming ``key`` otherwise)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"'{key}' must be a number, got {type_name(value)}")
    try:
        number = float(value)
    except OverflowError:  # a TOML integer beyond the float range
        raise SceneError(f"'{key}' must be finite, got an integer of about"
                         f" {int(value.bit_length() * math.log10(2)) + 1} digits") from None
    if not math.isfinite(number):
        raise SceneError(f"'{key}' must be finite, got {number}")
    return number


def read_text(path: Path) -> str:
    """The file's text: regular files only, at most MAX_SCENE_BYTES read, UTF-8 with or without BOM."""
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer; it is refused below.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise SceneError(f"cannot read scene file '{path}': {exc.strerror}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        what = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise SceneError(f"cannot read scene file '{path}': it is {what}")
    with os.fdopen(fd, "rb") as f:
        try:
            raw = f.read(MAX_SCENE_BYTES + 1)
        except OSError as exc:
            raise SceneError(f"cannot read scene file '{path}': {exc.strerror}") from None
    if len(raw) > MAX_SCENE_BYTES:
        raise SceneError(f"'{path}' is larger than {MAX_SCENE_BYTES} bytes; a scene is a short text file")
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise SceneError(f"'{path}' is UTF-16 text (byte-order mark); save it as UTF-8")
    try:
        return raw.decode("utf-8-sig")  # strips a UTF-8 byte-order mark
    except UnicodeDecodeError as exc:
        raise SceneError(f"'{path}' is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start});"
                         " save it as UTF-8") from None


def parse_toml(text: str, path: Path) -> dict[str, Any]:
    """``tomllib.loads`` with its errors as one-line SceneErrors naming the file."""
    try:
        return tomllib.loads(text)
    except ValueError as exc:  # TOMLDecodeError, or an integer past Python's 4300-digit limit
        raise SceneError(f"'{path}' is not valid TOML: {exc}") from None
    except RecursionError:
        raise SceneError(f"'{path}' is not a usable scene: its arrays or tables are nested too deeply") from None
