"""A sweep's specification against the scene it varies: read a scene file with its ``[sweep]``
table, and refuse up front a specification that does not fit the scene (every key must lead to
a number of the scene, every extreme must give a valid scene). The specification language itself
(keys, grids, distributions, the table's own keys) is :mod:`loopcheck.sweep_spec`, part of the
scene format; this module builds scenes with it, so it sits above the scene format."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from loopcheck.errors import type_name
from loopcheck.scene import SceneError
from loopcheck.scenefile import scene_from_dict
from loopcheck.toml_reader import parse_toml, read_text

from .sweep_engines import sweep_engines
from loopcheck.sweep_spec import (MISSING, SWEEP_TABLE, SweepSpec, SweepSpecError, apply, lookup,
                                     spec_from_table)


def load_sweep(path: str | Path) -> tuple[dict[str, Any], SweepSpec | None]:
    """A scene file's TOML data and the specification of its ``[sweep]`` table (None without
    one). The file is read as :func:`loopcheck.scenefile.load_scene` reads it (SceneError)."""
    path = Path(path)
    data = parse_toml(read_text(path), path)
    spec = spec_from_table(data[SWEEP_TABLE], str(path)) if SWEEP_TABLE in data else None
    return data, spec


# -- checking against the scene ----------------------------------------------------------

def check(data: Mapping[str, Any], spec: SweepSpec, source: str = "<memory>") -> None:
    """Refuse, before any work, a specification that does not fit the scene ``data``.

    Each key must lead to a number of the scene, or to a place the scene format accepts one;
    the scene is built (:func:`loopcheck.scenefile.scene_from_dict`) at the nominal values (as
    written; a key the file does not give at its spec's centre) and at each key's extremes
    (the others nominal); the engines must be registered, the reference among them. Raises
    SweepSpecError naming the key (with ``source`` in front);
    a SceneError of the scene as written propagates unchanged.
    """
    prefix = f"{source}: " if source else ""
    try:
        sweep_engines(spec.engines)
    except SweepSpecError as exc:
        raise SweepSpecError(prefix + str(exc)) from None
    base = {k: v for k, v in data.items() if k != SWEEP_TABLE}
    scene_from_dict(base, source)  # the scene as written: its own errors are not the sweep's
    given = nominal_values(base, spec, source)
    nominal = {k: v for k, v in given.items() if lookup(base, k) is MISSING}
    for key, value in nominal.items():  # each key the file does not give, alone
        _build(base, {key: value}, key, f"{value:g} (its nominal value)", prefix, source)
    _build(base, nominal, None, "", prefix, source)
    for v in spec.varies:
        for value, which in v.extremes:
            _build(base, {**nominal, v.key: value}, v.key, f"{value:g} ({which})", prefix, source)


def nominal_values(data: Mapping[str, Any], spec: SweepSpec, source: str = "<memory>") -> dict[str, float]:
    """Each varied key's nominal value: the scene's own, or its spec's centre where the file
    does not give it. SweepSpecError (naming the key) where the scene has no number there."""
    prefix = f"{source}: " if source else ""
    nominal: dict[str, float] = {}
    for v in spec.varies:
        try:
            current = lookup(data, v.key)
        except SweepSpecError as exc:
            raise SweepSpecError(prefix + str(exc)) from None
        if current is MISSING:
            nominal[v.key] = v.centre
        elif isinstance(current, bool) or not isinstance(current, (int, float)):
            shown = f" \"{current}\"" if isinstance(current, str) else ""
            raise SweepSpecError(f"{prefix}sweep key '{v.key}' is not a number: the scene has "
                                 f"{type_name(current)}{shown} there")
        else:
            nominal[v.key] = float(current)
    return nominal


def _build(base: dict, values: dict[str, float], key: str | None, shown: str, prefix: str, source: str) -> None:
    try:
        scene_from_dict(apply(base, values), source)
    except SceneError as exc:
        message = str(exc)
        if key is None:
            keys = ", ".join(f"'{k}'" for k in values)
            raise SweepSpecError(f"{prefix}sweep keys {keys} at their nominal values make the scene invalid: "
                                 f"{message}") from None
        if message.startswith("unknown key"):
            raise SweepSpecError(f"{prefix}unknown key '{key}': the scene does not give it and the scene format "
                                 f"does not accept it there ({message})") from None
        raise SweepSpecError(f"{prefix}sweep key '{key}' = {shown} makes the scene invalid: {message}") from None
