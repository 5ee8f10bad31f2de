"""`loopcheck check --engines reduced,mujoco,pin`: every engine against the reduced solution, and,
when they disagree, the engine farthest from the others.

Each engine other than the reduced one runs with its scene table's settings (or, for MuJoCo, the
command line's flags) and is judged against the reduced reference by the same gate as
``loopcheck check`` (:func:`loopcheck.compare.run.judge`), at its own tolerances: the scene's
``[tolerances.ENGINE]`` over its ``[tolerances]`` (:meth:`loopcheck.scene.Scene.tolerances_for`). With three engines or more the peaks say which
one is the outlier: the engine whose peak input speed is farthest from the median of the other
engines' peaks. An engine that fails to run is the outlier by definition and is reported with its
failure.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace
from statistics import median
from typing import Any, Callable, Mapping, Sequence

from loopcheck.errors import NumericalFailure
from loopcheck.registry import DEFAULT_ENGINES, ENGINES, REFERENCE
from loopcheck.results import EngineResult
from loopcheck.scene import Scene, Tolerances

from .run import Comparison, judge
from .settings import engine_settings

_log = logging.getLogger(__name__)  # the command prints it on stderr as progress (loopcheck: ...)


@dataclass(frozen=True)
class EngineVerdict:
    """One engine against the reduced reference: its comparison, or why it did not run."""

    engine: str
    tolerances: Tolerances  # what it is judged by (had it run)
    comparison: Comparison | None
    failure: str | None = None
    # A run that a check of its own failed (a loop gap, the energy balance): the result as far as
    # it went (NumericalFailure.partial), trustworthy up to ``failed_at`` (s), travels with the
    # failure: its known defects are printed and engines.png draws it up to that time.
    partial: EngineResult | None = None
    failed_at: float | None = None
    ran: str | None = None  # what ran instead of the engine's model of the scene (a user's model as written)

    @property
    def passed(self) -> bool:
        return self.comparison is not None and self.comparison.gate.passed

    @property
    def known_defects(self) -> tuple[str, ...]:
        """The engine's known defects that bear on its run (:attr:`EngineResult.caveats`), whether
        it was compared or failed part-way; none when it did not run at all."""
        run = self.comparison.other if self.comparison is not None else self.partial
        return run.caveats if run is not None else ()


@dataclass(frozen=True)
class EnginesCheck:
    """Every engine of a scene against the reduced reference, and the outlier when they disagree
    (what ``loopcheck check --engines`` prints and ``loopcheck.check`` returns): ``passed`` (every
    engine passed its gate), ``verdicts`` (one per engine judged, in the list's order),
    ``outlier`` and :meth:`comparison` (one engine's comparison with the reference)."""

    scene: Scene
    reference: EngineResult
    verdicts: tuple[EngineVerdict, ...]
    outlier: str | None  # None while every engine passes, or with fewer than three engines
    spread: dict[tuple[str, str], float]  # |Δ peak| / |reference peak| of each pair that ran

    @property
    def passed(self) -> bool:
        return all(v.passed for v in self.verdicts)

    @property
    def engines(self) -> tuple[str, ...]:
        """The engines checked, by name: the reference's first."""
        return (self.reference.engine, *(v.engine for v in self.verdicts))

    def verdict(self, engine: str) -> EngineVerdict:
        """The verdict of the engine named ``engine`` (KeyError naming the engines judged otherwise)."""
        for v in self.verdicts:
            if v.engine == engine:
                return v
        raise KeyError(f"'{engine}' was not judged in this check (judged: {', '.join(v.engine for v in self.verdicts)})")

    def comparison(self, engine: str) -> Comparison:
        """The comparison of the engine named ``engine`` with the reference (``.reference``,
        ``.other``, ``.diff``, ``.gate``).

        Raises
        ------
        KeyError
            If the engine was not judged in this check.
        ValueError
            If it did not run to the end (its verdict's failure, in one line; :meth:`verdict` has
            the run as far as it went).
        """
        v = self.verdict(engine)
        if v.comparison is None:
            raise ValueError(f"{engine} has no comparison: {v.failure}")
        return v.comparison


def parse_engines(text: str) -> tuple[str, ...]:
    """``reduced,mujoco,pin`` (``--engines``) into engine names: known, no repeats, the reduced one
    included (the reference). ValueError saying which otherwise."""
    return engine_list(tuple(name.strip() for name in text.split(",") if name.strip()))


def engine_list(names: Sequence[str]) -> tuple[str, ...]:
    """Engine names checked as :func:`parse_engines` checks them (``loopcheck.check(scene,
    engines=[...])``): known, no repeats, the reduced reference included, another engine beside it."""
    if isinstance(names, str):
        raise TypeError(f"a list of engine names, not the string '{names}'")
    names = tuple(names)
    text = ",".join(names)
    unknown = [n for n in names if n not in ENGINES]
    if unknown:
        raise ValueError(f"unknown engine '{unknown[0]}' (engines: {', '.join(ENGINES)})")
    if len(set(names)) != len(names):
        raise ValueError(f"an engine is named twice in '{text}'")
    if REFERENCE not in names:
        raise ValueError(f"the list must include '{REFERENCE}', the reference every engine is judged against")
    if len(names) < 2:
        raise ValueError("name the reduced reference and at least one other engine")
    return names


def compared_engine(engines: tuple[str, ...]) -> str:
    """The engine whose comparison with the reference ``loopcheck run --engines`` writes as today's report
    files (CSV, plots, report.json's engine section): the default comparison's (MuJoCo,
    :data:`loopcheck.registry.DEFAULT_ENGINES`) when listed, else the first other engine."""
    default = next(name for name in DEFAULT_ENGINES if name != REFERENCE)
    return default if default in engines else next(name for name in engines if name != REFERENCE)


def check_engines(scene: Scene, engines: tuple[str, ...], settings: Mapping[str, Any] | None = None,
                  tolerances: Mapping[str, Tolerances] | None = None,
                  as_written: tuple[str, str, Callable[[], EngineResult]] | None = None,
                  refuse: Callable[[EngineResult], None] | None = None) -> EnginesCheck:
    """Run ``engines`` (``settings``: each engine's Settings by name, the reference's included; an
    engine not there runs with the scene's table over its defaults) on ``scene`` and judge each
    against the reduced reference by its tolerances: ``tolerances[name]``, by default the scene's
    for that engine (:meth:`loopcheck.scene.Scene.tolerances_for`).

    ``as_written``: (engine, what, run) where ``scene`` was read from a user's model: that engine
    (the one that read the file) runs the model as written, ``run()``, instead of its own model of
    the scene, and its verdict says ``what`` ran; the others run the scene as imported.
    ``refuse``: called with the reference's result before any other engine runs; what it raises
    (a check that could not fail) stops the check.

    Raises
    ------
    NumericalFailure
        If the reduced reference fails (another engine's failure is its verdict).
    """
    for name in engines:  # before any work or output: an engine that cannot take the scene's DOF
        ENGINES[name].check_dof(scene)
    settings = {name: (settings or {}).get(name) or engine_settings(name, scene) for name in engines}
    _log.info("%s: %s started (the reference)", scene.name, REFERENCE)
    start = time.perf_counter()
    reference = ENGINES[REFERENCE].simulate(scene, settings[REFERENCE])
    _log.info("%s: %s ended in %.3g s", scene.name, REFERENCE, time.perf_counter() - start)
    if refuse is not None:
        refuse(reference)
    verdicts = []
    for name in engines:
        if name == REFERENCE:
            continue
        own = (tolerances or {}).get(name) or scene.tolerances_for(name)
        judged = replace(scene, tolerances=own)  # MuJoCo's automatic step is chosen for the tolerances it is judged by
        _log.info("%s: %s started", scene.name, name)
        start = time.perf_counter()
        ran = as_written[1] if as_written is not None and as_written[0] == name else None
        try:
            result = as_written[2]() if ran is not None else ENGINES[name].simulate(judged, settings[name])
        except NumericalFailure as exc:
            verdicts.append(EngineVerdict(name, own, None, f"numerical failure ({exc.reason}): {exc}",
                                          partial=exc.partial, failed_at=exc.time, ran=ran))
        except ValueError as exc:  # what the engine does not run (an MJX refusal, ...): one line, its verdict
            verdicts.append(EngineVerdict(name, own, None, f"refused: {exc}", ran=ran))
        else:
            verdicts.append(EngineVerdict(name, own, judge(judged, reference, result, own), ran=ran))
        _log.info("%s: %s ended in %.3g s (%s)", scene.name, name, time.perf_counter() - start,
                  "passed" if verdicts[-1].passed else "failed" if verdicts[-1].comparison is not None
                  else verdicts[-1].failure.split(":")[0])
    # each input's peaks, relative to the reference's peak of that input (one input: as it was)
    compared = [v for v in verdicts if v.comparison is not None]
    relative = []
    for k, (_, peak) in enumerate(reference.inputs):
        scale = max(abs(peak.omega), 1e-300)
        relative.append({REFERENCE: peak.omega / scale,
                         **{v.engine: v.comparison.diffs[k].peak_omega_other / scale for v in compared}})
    names = list(relative[0])
    spread = {(a, b): max(abs(r[a] - r[b]) for r in relative) for i, a in enumerate(names) for b in names[i + 1:]}
    outlier = None
    if len(engines) >= 3 and not all(v.passed for v in verdicts):
        failed = [v.engine for v in verdicts if v.comparison is None]
        if failed:
            outlier = failed[0]
        else:
            outlier = farthest_from_the_others(relative)
    return EnginesCheck(scene, reference, tuple(verdicts), outlier, spread)


def farthest_from_the_others(peaks: Mapping[str, float] | Sequence[Mapping[str, float]]) -> str:
    """The engine whose peak is farthest from the median of the other engines' peaks (the
    issue's rule; with three engines, the one farthest from the mean of the other two). With
    several inputs, ``peaks`` is one mapping per input, each on a common scale (relative to the
    reference's peak of that input), and an engine's distance is its largest over the inputs."""
    per_input = [peaks] if isinstance(peaks, Mapping) else list(peaks)

    def distance(name: str) -> float:
        return max(abs(p[name] - median(v for other, v in p.items() if other != name)) for p in per_input)
    return max(per_input[0], key=distance)


def engines_lines(check: EnginesCheck) -> list[str]:
    """``loopcheck check --engines``' lines for one scene."""
    scene = check.scene
    status = "ok  " if check.passed else "FAIL"
    lines = [f"{status}  {scene.source}: reduced peak "
             + ", ".join(f"{f'{name} ' if scene.dof > 1 else ''}{p.omega:.10g} {u}/s"
                         for name, u, (_, p) in zip(scene.inputs, scene.input_units(), check.reference.inputs))]
    for v in check.verdicts:
        ran = [f"               ran {v.ran}"] if v.ran else []
        if v.comparison is None:
            lines.append(f"      {v.engine:8s} {v.failure}")
            lines += ran
            lines += [f"               known defect: {caveat}" for caveat in v.known_defects]
            continue
        t = v.comparison.gate.tolerances
        several = scene.dof > 1  # then each input's figures, named, the first on the engine's line
        for k, (name, u, d) in enumerate(zip(scene.inputs, scene.input_units(), v.comparison.diffs)):
            lead = f"      {v.engine:8s} {'ok  ' if v.passed else 'FAIL'}  " if k == 0 else " " * 20
            lines.append(f"{lead}{f'{name}: ' if several else ''}peak {d.peak_omega_other:.10g} "
                         f"({d.peak_omega_rel:.2e}, tol {t.peak_omega_rtol:g}), max |dq| {d.q_max_abs:.2e} {u} "
                         f"(tol {t.q_atol:g}), max |dq/dt| {d.omega_max_abs:.2e} {u}/s (tol {t.omega_atol:g})")
        lines += ran
        lines += [f"               {failure}" for failure in v.comparison.gate.failures]
        lines += [f"               known defect: {caveat}" for caveat in v.known_defects]
    if check.outlier is not None:
        pairs = ", ".join(f"{a}–{b} {d:.2e}" for (a, b), d in check.spread.items())
        lines.append(f"      farthest from the others: {check.outlier} (peaks apart, relative: {pairs})")
    return lines


__all__ = ["EngineVerdict", "EnginesCheck", "check_engines", "compared_engine", "engine_list", "engines_lines",
           "parse_engines"]
