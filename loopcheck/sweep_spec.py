"""Sweep specifications: which numbers of a scene file vary, over which values.

A sweep is a family of scenes made from one scene file by changing some of its numbers. Each
varied number is named by a KEY, a dotted path into the scene file's TOML data: table keys by
name, entries of an array by their index from 0 (``bodies.coupler.mass``,
``dampers.0.coefficient``, ``linkage.c2``, ``torque.value``, ``initial.qdot``,
``bodies.coupler.com.1``, ``mujoco.timestep``, ``reduced.rtol``). A key need not be written in
the file if the scene format accepts it there (``initial.qdot``, ``mujoco.timestep`` — a missing
table is created); :func:`loopcheck.compare.sweep_scene.check` tells which.

SPEC, the values of one key (:func:`parse_vary` reads ``KEY=SPEC``):

- a grid: ``lo:hi:n`` (n points from lo to hi, as ``numpy.linspace``; n ≥ 1, lo ≤ hi; n = 1
  gives lo), or a list ``[a, b, c]`` or ``a,b,c`` (kept in its order);
- a distribution, for Monte Carlo: ``normal(mu, sigma)`` (sigma ≥ 0) or ``uniform(lo, hi)``
  (lo ≤ hi).

Several keys: all grids make the full grid, their product, the LAST key varying fastest; all
distributions make a joint sample of ``samples`` variants, each key drawn independently from
``numpy.random.default_rng(seed)`` in a fixed order (key by key in the order given, all
``samples`` draws of one key before the next), so a seed reproduces the sweep exactly. Grids and
distributions in one sweep are refused (a grid with a Monte Carlo sample on top is two sweeps).
``samples`` (≥ 1) is required by distributions and refused with grids (a grid's size is its n);
``seed`` (an integer ≥ 0) defaults to 0. At most :data:`MAX_VARIANTS` variants.

``engines`` says what runs on each variant: a list of registered engines' names, the reduced
reference among them (``"reduced,mujoco,mjx"`` or a TOML array ``["reduced", "mjx"]``; each other
engine compared with the reference and gated at its own tolerances, as ``loopcheck check
--engines`` does), or one of the two words of :class:`Engines`: ``both`` (the default: the
design card's pair, the reduced solver and MuJoCo, compared and gated as ``loopcheck run`` does)
or ``reduced`` (the reduced solver alone, with its own error and energy checks; no comparison, no
gate). The specification keeps the names (:attr:`SweepSpec.engines`, a tuple: ``both`` is
``("reduced", "mujoco")``); which names are registered engines is the sweep's check
(:func:`loopcheck.compare.sweep_scene.check`), above the registry.

The same in a scene file, a ``[sweep]`` table (:func:`spec_from_table`)::

    [sweep]
    engines = "reduced"            # optional: "both" (default), "reduced", or a list "reduced,mujoco,mjx"
    [sweep.vary]                   # KEY = SPEC, in the order of the sweep
    "dampers.0.coefficient" = "40:70:7"
    "linkage.c2" = [0.85, 0.9, 0.95]   # a TOML array of numbers is a list grid

or, for Monte Carlo (distributions only)::

    [sweep]
    samples = 100
    seed = 1                       # optional, default 0
    [sweep.vary]
    "bodies.coupler.mass" = "normal(40, 2)"

``vary`` may also be an inline table (``vary = { "linkage.c2" = "0.8:1.0:5" }``); a bare dotted
key (``bodies.coupler.mass = "..."`` without quotes) is TOML for nested tables and is read as
the same KEY. The scene itself ignores its ``[sweep]`` table; variants do not carry it. The scene
format reads the table with :func:`spec_from_table` (a bad table makes the file invalid).

Everything is refused up front, before any work, by :class:`SweepSpecError` (a ValueError, one
line naming the key): an unknown ``engines``, a malformed SPEC, lo > hi, n < 1, sigma < 0, a
non-finite number, a key given twice, grids mixed with distributions, a missing or needless
``samples``, too many variants (the specification, where defined); and, against the scene
(:func:`loopcheck.compare.sweep_scene.check`), an unknown
key, a key whose value is not a number (``linkage.type``), and a value that makes the scene
invalid at the nominal scene or at an extreme of a key (a grid's smallest and largest values,
``uniform``'s bounds, ``normal``'s mu ± 4 sigma, not clipped: a normal distribution whose
4-sigma range leaves the key's valid range is refused). Variants between the extremes that
cannot be assembled are the sweep's to report and count, not refusals.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from enum import Enum
from typing import Any, Iterator, Mapping, NamedTuple, Union

import numpy as np

from .errors import type_name
from .registry import DEFAULT_ENGINES, REFERENCE


MAX_VARIANTS = 1_000_000
"""The most variants a sweep may have (a grid's product, or ``samples``)."""
NORMAL_PROBE_SIGMAS = 4.0
""":func:`check` builds the scene at mu ± this many sigma of a normal distribution."""
KINDS = ("normal", "uniform")
SWEEP_TABLE = "sweep"


class SweepSpecError(ValueError):
    """A sweep specification that cannot be run; the message is one line naming the key."""


class Engines(str, Enum):
    """What runs on each variant of a sweep (compares equal to its value string)."""

    BOTH = "both"  # the design card's pair (the reference and MuJoCo C), compared and gated (as loopcheck run)
    REDUCED = REFERENCE  # the reference alone (its name): its own error and energy checks, no gate

    def __str__(self) -> str:
        return self.value

    @property
    def runs(self) -> tuple[str, ...]:
        """The engines run on each variant, by their names in sweep.csv's columns."""
        return (REFERENCE,) if self is Engines.REDUCED else DEFAULT_ENGINES


ENGINE_CHOICES = tuple(e.value for e in Engines)
"""The two words ``--engines`` and ``sweep.engines`` take beside a list of engine names."""
_ENGINE_NAME = re.compile(r"[a-z][a-z0-9_]*")  # an engine's name (loopcheck.registry checks the same)


def engine_names(value: Any) -> tuple[str, ...]:
    """The engines a sweep runs, by name, from ``sweep.engines`` or ``--engines``: a word of
    :data:`ENGINE_CHOICES`, a comma-separated list, or a list of names. SweepSpecError (one line)
    for anything else, an empty list, a malformed name or a name given twice."""
    what = "sweep engines (--engines or sweep.engines)"
    if isinstance(value, str) and value.strip() in ENGINE_CHOICES:
        return Engines(value.strip()).runs
    if isinstance(value, str):
        names = tuple(n.strip() for n in value.split(","))
    elif isinstance(value, (list, tuple)) and all(isinstance(n, str) for n in value):
        names = tuple(n.strip() for n in value)
    else:
        raise SweepSpecError(f"{what} must be {', '.join(ENGINE_CHOICES)} or a list of engine names such as "
                             f"\"reduced,mujoco,mjx\", got {value!r}")
    if not names or not all(names):
        raise SweepSpecError(f"{what}: an empty engine name in {value!r}")
    bad = [n for n in names if not _ENGINE_NAME.fullmatch(n)]
    if bad:
        raise SweepSpecError(f"{what}: '{bad[0]}' is not an engine name (lower-case letters, digits and _)")
    if len(set(names)) != len(names):
        raise SweepSpecError(f"{what}: an engine is named twice in {','.join(names)!r}")
    return names


# -- keys ------------------------------------------------------------------------------

def split_key(key: str) -> tuple[str, ...]:
    """The parts of a dotted KEY; refuses an empty part or the ``[sweep]`` table itself."""
    if not isinstance(key, str):
        raise SweepSpecError(f"a sweep key must be a dotted path such as 'bodies.coupler.mass', got {key!r}")
    parts = tuple(key.strip().split("."))
    if not key.strip() or not all(parts):
        raise SweepSpecError(f"sweep key '{key}' is not a dotted path such as 'bodies.coupler.mass'"
                             " (an empty part)")
    if parts[0] == SWEEP_TABLE:
        raise SweepSpecError(f"sweep key '{key}' is in the [sweep] table itself; vary the scene's numbers")
    return parts


def _finite(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SweepSpecError(f"{what} must be a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:
        raise SweepSpecError(f"{what} must be a finite number, got an integer too large for a float") from None
    if not math.isfinite(value):
        raise SweepSpecError(f"{what} must be a finite number, got {value}")
    return value


def _number_text(text: str, what: str) -> float:
    try:
        value = float(text.strip())
    except ValueError:
        raise SweepSpecError(f"{what}: {text.strip()!r} is not a number") from None
    if not math.isfinite(value):
        raise SweepSpecError(f"{what}: {text.strip()!r} is not a finite number")
    return value


# -- the specification -------------------------------------------------------------------

@dataclass(frozen=True)
class Grid:
    """The values of ``key`` on a grid, in their order (``lo:hi:n`` expanded, or a list)."""

    key: str
    values: tuple[float, ...]

    def __post_init__(self):
        split_key(self.key)
        values = tuple(self.values) if isinstance(self.values, (list, tuple, np.ndarray)) else self.values
        if not isinstance(values, tuple):
            raise SweepSpecError(f"sweep key '{self.key}': a grid's values must be a list of numbers")
        if len(values) < 1:
            raise SweepSpecError(f"sweep key '{self.key}': the grid has no values (n must be at least 1)")
        if len(values) > MAX_VARIANTS:
            raise SweepSpecError(f"sweep key '{self.key}': the grid has {len(values)} values; at most {MAX_VARIANTS}")
        values = tuple(_finite(v, f"sweep key '{self.key}': value {i}") for i, v in enumerate(values))
        object.__setattr__(self, "values", values)

    @property
    def extremes(self) -> tuple[tuple[float, str], ...]:
        """(value, description) of the smallest and largest value."""
        return ((min(self.values), "the grid's smallest value"), (max(self.values), "the grid's largest value"))

    @property
    def centre(self) -> float:
        """A middle value (the median of the values; for a key the scene does not give)."""
        return sorted(self.values)[len(self.values) // 2]

    def __str__(self) -> str:
        return f"{self.key}=[{', '.join(f'{v:g}' for v in self.values)}]"


@dataclass(frozen=True)
class Distribution:
    """``key`` drawn from ``normal(a = mu, b = sigma)`` or ``uniform(a = lo, b = hi)``."""

    key: str
    kind: str
    a: float
    b: float

    def __post_init__(self):
        split_key(self.key)
        if self.kind not in KINDS:
            raise SweepSpecError(f"sweep key '{self.key}': distribution must be normal or uniform, got {self.kind!r}")
        names = ("mu", "sigma") if self.kind == "normal" else ("lo", "hi")
        a = _finite(self.a, f"sweep key '{self.key}': {self.kind} {names[0]}")
        b = _finite(self.b, f"sweep key '{self.key}': {self.kind} {names[1]}")
        if self.kind == "normal" and b < 0.0:
            raise SweepSpecError(f"sweep key '{self.key}': normal({a:g}, {b:g}) has a negative sigma")
        if self.kind == "uniform" and a > b:
            raise SweepSpecError(f"sweep key '{self.key}': uniform({a:g}, {b:g}) has lo > hi")
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)

    @property
    def extremes(self) -> tuple[tuple[float, str], ...]:
        if self.kind == "uniform":
            return ((self.a, f"the lower bound of {self}"), (self.b, f"the upper bound of {self}"))
        k = NORMAL_PROBE_SIGMAS
        return ((self.a - k * self.b, f"mu - {k:g} sigma of {self}"), (self.a + k * self.b, f"mu + {k:g} sigma of {self}"))

    @property
    def centre(self) -> float:
        return self.a if self.kind == "normal" else 0.5 * (self.a + self.b)

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind == "normal":
            return rng.normal(self.a, self.b, n)
        return rng.uniform(self.a, self.b, n)

    def __str__(self) -> str:
        return f"{self.kind}({self.a:g}, {self.b:g})"


Vary = Union[Grid, Distribution]


@dataclass(frozen=True)
class SweepSpec:
    """The varied keys (in order), ``samples`` (distributions only), ``seed`` and the
    ``engines`` run on each variant, by name (a word of :data:`ENGINE_CHOICES` or a list is
    converted by :func:`engine_names`).

    All grids: the product of their values, the last key fastest. All distributions: a sample
    of ``samples`` variants from ``default_rng(seed)``. Mixing the two is refused.
    """

    varies: tuple[Vary, ...]
    samples: int | None = None
    seed: int = 0
    engines: tuple[str, ...] = Engines.BOTH.runs

    def __post_init__(self):
        varies = tuple(self.varies) if isinstance(self.varies, (list, tuple)) else self.varies
        if not isinstance(varies, tuple) or not varies:
            raise SweepSpecError("a sweep needs at least one varied key (--vary KEY=SPEC or [sweep.vary])")
        seen = set()
        for v in varies:
            if not isinstance(v, (Grid, Distribution)):
                raise SweepSpecError(f"a sweep varies Grid or Distribution values, got {v!r}")
            if v.key in seen:
                raise SweepSpecError(f"sweep key '{v.key}' is varied twice")
            seen.add(v.key)
        object.__setattr__(self, "varies", varies)
        grids = [v.key for v in varies if isinstance(v, Grid)]
        dists = [v.key for v in varies if isinstance(v, Distribution)]
        if grids and dists:
            raise SweepSpecError(f"sweep key '{grids[0]}' is a grid and '{dists[0]}' a distribution: a sweep is "
                                 "either a full grid or a Monte Carlo sample, not both")
        object.__setattr__(self, "engines", engine_names(self.engines))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SweepSpecError(f"sweep seed (--seed or sweep.seed) must be an integer ≥ 0, got {self.seed!r}")
        if dists:
            if self.samples is None:
                raise SweepSpecError(f"sweep key '{dists[0]}' is a distribution: give the number of variants "
                                     "(--samples or sweep.samples)")
            if isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 1:
                raise SweepSpecError(f"sweep samples (--samples or sweep.samples) must be an integer ≥ 1, "
                                     f"got {self.samples!r}")
            if self.samples > MAX_VARIANTS:
                raise SweepSpecError(f"sweep samples (--samples or sweep.samples) = {self.samples} is more than "
                                     f"{MAX_VARIANTS} variants")
        else:
            if self.samples is not None:
                raise SweepSpecError(f"sweep samples (--samples or sweep.samples) is for distributions: the grid of "
                                     f"'{grids[0]}' has its own n")
            n = math.prod(len(v.values) for v in varies)
            if n > MAX_VARIANTS:
                sizes = " × ".join(f"'{v.key}' {len(v.values)}" for v in varies)
                raise SweepSpecError(f"the sweep grid has {n} variants ({sizes}); at most {MAX_VARIANTS}: "
                                     f"use fewer points of '{max(varies, key=lambda v: len(v.values)).key}'")

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(v.key for v in self.varies)

    @property
    def is_grid(self) -> bool:
        return isinstance(self.varies[0], Grid)


class Variant(NamedTuple):
    """One scene of a sweep: its index (from 0), the varied values by key, and the scene
    file's data with those values applied (a deep copy, without the ``[sweep]`` table)."""

    index: int
    values: dict[str, float]
    data: dict[str, Any]


# -- parsing -----------------------------------------------------------------------------

_DIST = re.compile(r"^\s*(\w+)\s*\((.*)\)\s*$", re.S)
_GRID_ROW = re.compile(r"^[^:]*:[^:]*:[^:]*$")


def parse_spec(key: str, spec: Any) -> Vary:
    """The values of ``key`` from SPEC: a string (module docstring) or a list of numbers."""
    split_key(key)
    if isinstance(spec, (list, tuple)):
        return Grid(key, tuple(_finite(v, f"sweep key '{key}': value {i}") for i, v in enumerate(spec)))
    if isinstance(spec, bool) or isinstance(spec, (int, float)):
        return Grid(key, (_finite(spec, f"sweep key '{key}'"),))
    if not isinstance(spec, str):
        raise SweepSpecError(f"sweep key '{key}': SPEC must be a string such as \"40:70:7\" or "
                             f"\"normal(40, 2)\", or an array of numbers")
    text = spec.strip()
    what = f"sweep key '{key}'"
    m = _DIST.match(text)
    if m:
        kind, args = m.group(1), m.group(2).split(",")
        if kind not in KINDS:
            raise SweepSpecError(f"{what}: unknown distribution {kind!r} in {text!r}: normal(mu, sigma) or "
                                 "uniform(lo, hi)")
        if len(args) != 2:
            raise SweepSpecError(f"{what}: {kind} takes two numbers, got {text!r}")
        return Distribution(key, kind, *(_number_text(x, f"{what} in {text!r}") for x in args))
    if ":" in text:
        if not _GRID_ROW.match(text):
            raise SweepSpecError(f"{what}: a grid is lo:hi:n, got {text!r}")
        lo_t, hi_t, n_t = text.split(":")
        lo, hi = _number_text(lo_t, f"{what} in {text!r}"), _number_text(hi_t, f"{what} in {text!r}")
        try:
            n = int(n_t.strip())
        except ValueError:
            raise SweepSpecError(f"{what}: the n of lo:hi:n must be a whole number, got {n_t.strip()!r}") from None
        if n < 1:
            raise SweepSpecError(f"{what}: grid {text!r} has n = {n}; n must be at least 1")
        if lo > hi:
            raise SweepSpecError(f"{what}: grid {text!r} has lo > hi ({lo:g} > {hi:g})")
        if n > MAX_VARIANTS:
            raise SweepSpecError(f"{what}: grid {text!r} has n = {n}; at most {MAX_VARIANTS}")
        return Grid(key, tuple(float(v) for v in np.linspace(lo, hi, n)))
    if text.startswith("[") != text.endswith("]"):
        raise SweepSpecError(f"{what}: unbalanced brackets in {text!r}")
    body = text[1:-1] if text.startswith("[") else text
    items = body.split(",")
    if not body.strip():
        raise SweepSpecError(f"{what}: the list {text!r} has no values (n must be at least 1)")
    return Grid(key, tuple(_number_text(x, f"{what} in {text!r}") for x in items))


def parse_vary(text: str) -> Vary:
    """``KEY=SPEC`` (the argument of ``--vary``) as a :class:`Grid` or :class:`Distribution`."""
    if not isinstance(text, str) or "=" not in text:
        raise SweepSpecError(f"--vary {text!r} must be KEY=SPEC, e.g. bodies.coupler.mass=38:42:5")
    key, spec = text.split("=", 1)
    return parse_spec(key.strip(), spec)


def spec_from_args(varies: list[str], samples: int | None = None, seed: int | None = None) -> SweepSpec:
    """The specification of ``--vary KEY=SPEC ... [--samples N] [--seed S]``."""
    return SweepSpec(tuple(parse_vary(v) for v in varies), samples, 0 if seed is None else seed)


def _flatten(table: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    for name, value in table.items():
        key = f"{prefix}.{name}" if prefix else str(name)
        if isinstance(value, dict):
            yield from _flatten(value, key)
        else:
            yield key, value


def spec_from_table(table: Any, source: str = "<memory>") -> SweepSpec:
    """The specification of a scene file's ``[sweep]`` table (module docstring); messages
    start with ``source`` (unless empty) and name the table's key."""
    try:
        if not isinstance(table, dict):
            raise SweepSpecError("'sweep' must be a table ([sweep])")
        unknown = sorted(set(table) - {"vary", "samples", "seed", "engines"})
        if unknown:
            raise SweepSpecError(f"unknown key 'sweep.{unknown[0]}': [sweep] has vary, samples, seed and engines")
        vary = table.get("vary")
        if not isinstance(vary, dict) or not vary:
            raise SweepSpecError("'sweep.vary' must be a table of KEY = SPEC, e.g. "
                                 "[sweep.vary] \"bodies.coupler.mass\" = \"38:42:5\"")
        samples, seed = table.get("samples"), table.get("seed", 0)
        for name, value in (("samples", samples), ("seed", seed)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
                raise SweepSpecError(f"'sweep.{name}' must be a whole number, got {value!r}")
        return SweepSpec(tuple(parse_spec(k, v) for k, v in _flatten(vary)), samples, seed,
                         table.get("engines", Engines.BOTH.value))
    except SweepSpecError as exc:
        raise SweepSpecError(f"{source}: {exc}" if source else str(exc)) from None


# -- applying ----------------------------------------------------------------------------

MISSING = object()  # a key the data does not give (lookup)


def lookup(data: Mapping[str, Any], key: str) -> Any:
    """The value at ``key``, ``MISSING`` if a table on the way lacks it (the format may still
    accept it); SweepSpecError if the path cannot exist (through a number, past an array)."""
    node: Any = data
    parts = split_key(key)
    for depth, part in enumerate(parts):
        where = ".".join(parts[:depth]) or "the scene"
        if isinstance(node, dict):
            if part not in node:
                return MISSING
            node = node[part]
        elif isinstance(node, list):
            if not part.isdigit():
                raise SweepSpecError(f"unknown key '{key}': '{where}' is an array; index it by a number from 0")
            if int(part) >= len(node):
                raise SweepSpecError(f"unknown key '{key}': '{where}' has {len(node)} entries (indices from 0)")
            node = node[int(part)]
        else:
            raise SweepSpecError(f"unknown key '{key}': '{where}' is {type_name(node)}, not a table or array")
    return node


def _toml_value(value: float) -> int | float:
    """An integral value as an integer (keys such as ``mujoco.iterations`` need one; numbers
    read both), others as floats."""
    value = float(value)
    return int(value) if value.is_integer() and abs(value) < 2.0 ** 53 else value


def _copy(node: Any) -> Any:
    """A deep copy of TOML data (tables, arrays, scalars; dates are immutable)."""
    if isinstance(node, dict):
        return {k: _copy(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_copy(v) for v in node]
    return node


def apply(data: Mapping[str, Any], values: Mapping[str, float]) -> dict[str, Any]:
    """A deep copy of ``data`` without its ``[sweep]`` table and with ``values`` (by KEY) set;
    missing tables on a key's path are created."""
    out = _copy({k: v for k, v in data.items() if k != SWEEP_TABLE})
    for key, value in values.items():
        parts = split_key(key)
        node: Any = out
        for part in parts[:-1]:
            if isinstance(node, list):
                node = node[int(part)]
            else:
                node = node.setdefault(part, {})
        last = parts[-1]
        if isinstance(node, list):
            node[int(last)] = _toml_value(value)
        else:
            node[last] = _toml_value(value)
    return out


def count(spec: SweepSpec) -> int:
    """The number of variants of ``spec``."""
    if spec.is_grid:
        return math.prod(len(v.values) for v in spec.varies)
    return spec.samples


def sample(spec: SweepSpec) -> dict[str, np.ndarray]:
    """The values of every key for every variant, in variant order (each an array of
    :func:`count` values). A Monte Carlo sample draws key after key from
    ``default_rng(spec.seed)``, all of one key's draws at once."""
    if spec.is_grid:
        grids = np.meshgrid(*(np.asarray(v.values) for v in spec.varies), indexing="ij")
        return {v.key: g.reshape(-1) for v, g in zip(spec.varies, grids)}
    rng = np.random.default_rng(spec.seed)
    return {v.key: v.draw(rng, spec.samples) for v in spec.varies}


def variant_values(spec: SweepSpec) -> Iterator[dict[str, float]]:
    """The varied values of each variant, in order (grids: the last key fastest)."""
    if spec.is_grid:
        for combo in itertools.product(*(v.values for v in spec.varies)):
            yield dict(zip(spec.keys, combo))
        return
    drawn = sample(spec)
    for i in range(spec.samples):
        yield {k: float(drawn[k][i]) for k in spec.keys}


def variants(data: Mapping[str, Any], spec: SweepSpec) -> Iterator[Variant]:
    """The variants of the scene file's ``data`` (parsed TOML), one at a time."""
    for i, values in enumerate(variant_values(spec)):
        yield Variant(i, values, apply(data, values))
