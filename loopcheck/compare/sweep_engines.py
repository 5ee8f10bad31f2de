"""Which engines a sweep runs and how each is judged: the list of :attr:`SweepSpec.engines
<loopcheck.sweep_spec.SweepSpec.engines>` checked against the registry (the reduced reference first),
the engines judged against it, the list as sweep.json says it, and the scene an engine is run
and judged on (its own tolerances). The module docstring of :mod:`loopcheck.compare.sweep` says
what a sweep of several engines writes."""

from __future__ import annotations

from loopcheck.registry import ENGINES, REFERENCE
from loopcheck.sweep_spec import Engines, SweepSpec, SweepSpecError


def sweep_engines(engines: tuple[str, ...]) -> tuple[str, ...]:
    """A sweep's engines (:attr:`SweepSpec.engines`) checked against the registry, the reduced
    reference first, the others in their order. SweepSpecError (one line) for an unknown engine
    or a list without the reference."""
    unknown = [n for n in engines if n not in ENGINES]
    if unknown:
        raise SweepSpecError(f"sweep engines (--engines or sweep.engines): unknown engine '{unknown[0]}' "
                             f"(engines: {', '.join(ENGINES)})")
    if REFERENCE not in engines:
        raise SweepSpecError(f"sweep engines (--engines or sweep.engines) must include '{REFERENCE}', the reference "
                             f"every engine is judged against, got {','.join(engines)!r}")
    return (REFERENCE, *(n for n in engines if n != REFERENCE))


def judged(spec: SweepSpec) -> tuple[str, ...]:
    """The engines a sweep judges against the reference, in order (none: the reference alone)."""
    return sweep_engines(spec.engines)[1:]


def engines_value(engines: tuple[str, ...]) -> str | list[str]:
    """A sweep's engines as sweep.json and the journal say them: the word of
    :class:`~loopcheck.sweep_spec.Engines` they are (``both``, ``reduced``), else the list."""
    for word in Engines:
        if tuple(engines) == word.runs:
            return word.value
    return list(engines)


def judged_scene(scene, engine: str):
    """``scene`` as ``engine`` runs it and is judged on it: with its own tolerances
    (:meth:`loopcheck.scene.Scene.tolerances_for`; MuJoCo's automatic step is chosen for them)."""
    from dataclasses import replace

    return replace(scene, tolerances=scene.tolerances_for(engine))


