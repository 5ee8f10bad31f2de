"""Local sensitivities of the peak input speed: d(peak |ω|)/dp at the nominal scene, by engine
(with several inputs, each input's: d(peak_i |ω|)/dp from the same runs, a table per input).

For each varied key p of a sweep (nominal p0: the scene's value, or the spec's centre where the
file gives none), central differences of an engine's continuous peak |ω| P(p) (the scene's own
settings of that engine; for the reference, :data:`loopcheck.registry.REFERENCE`, DOP853 at rtol
1e-12 by default) at two steps h and 2h:

    D(h) = (P(p0 + h) − P(p0 − h)) / 2h,    D = D(h) + (D(h) − D(2h)) / 3   (Richardson)

D(h) has a truncation error c h² and a noise error of about ε |P| / h, where ε is the peak's
relative accuracy the engine declares (:meth:`loopcheck.registry.Engine.peak_accuracy`; the
reference's is 10 × rtol). The step h = s ε^(1/3) balances the two (s = |p0|, or the spread of the
key's spec when p0 = 0, or 1). The estimate of D's error is |D(h) − D(2h)| / 3 (the truncation left
in D(h); D itself is better, O(h⁴)) plus ε |P| / h. A peak that jumps between two extrema inside
±2h makes D(h) and D(2h) disagree, and the estimate says so. Units: rad/s (m/s for a prismatic
input) per unit of the key.

Every engine of the list computes its own D, at its own ε, with what it chose by itself at the
nominal scene frozen for the runs at p0 ± h, ± 2h: a setting left to the engine (None in its
settings, e.g. an automatic timestep) takes the value its nominal run used
(:attr:`loopcheck.results.EngineResult.settings`), so that its step grid does not move with p. Its D
is its own peak's slope, printed beside the reference's: an engine whose peak depends on where
the summit falls on its step grid shows it there.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

from loopcheck.registry import ENGINES, REFERENCE
from loopcheck.sweep_spec import SWEEP_TABLE, SweepSpec, SweepSpecError, apply
from loopcheck.compare.sweep_scene import nominal_values


@dataclass(frozen=True)
class Sensitivity:
    """d(peak |ω|)/dp of one key at its nominal value p0, by central differences of one engine's runs."""

    key: str
    nominal: float      # p0
    step: float         # h
    peak: float         # the engine's peak |ω| at p0 (rad/s or m/s)
    derivative: float   # D, Richardson-extrapolated
    error: float        # estimate of |D − dP/dp|
    at_h: float         # D(h)
    at_2h: float        # D(2h)
    engine: str = REFERENCE
    frozen_step: float | None = None  # s: the engine's step grid, frozen at the nominal scene's (None: adaptive)
    input: str = ""     # a scene of several degrees of freedom: the input whose peak this is ("": the one input)

    def __post_init__(self):
        if not (self.step > 0.0 and math.isfinite(self.step)):
            raise ValueError(f"Sensitivity.step must be positive and finite, got {self.step!r}")
        if self.engine not in ENGINES:
            raise ValueError(f"Sensitivity.engine must be a registered engine, got {self.engine!r}")

    def as_dict(self) -> dict[str, float | str | None]:
        return {"key": self.key, "nominal": self.nominal, "step": self.step, "peak": self.peak,
                "derivative": self.derivative, "error": self.error, "at_h": self.at_h, "at_2h": self.at_2h,
                "engine": self.engine, "frozen_step": self.frozen_step, **({"input": self.input} if self.input else {})}


@dataclass(frozen=True)
class SensitivityFailure:
    """An engine other than the reference whose run failed or was refused at the nominal scene or
    near it: its line (``failure``, naming the key and value), in the place of its sensitivity to
    ``key``; the study goes on with the other engines (a failed run of the reference ends it)."""

    key: str
    engine: str
    failure: str

    def __post_init__(self):
        if self.engine == REFERENCE or self.engine not in ENGINES:
            raise ValueError(f"SensitivityFailure.engine must be a registered engine other than the reference, "
                             f"got {self.engine!r}")
        if not self.failure:
            raise ValueError("SensitivityFailure.failure must say why")

    def as_dict(self) -> dict[str, str]:
        return {"key": self.key, "engine": self.engine, "failure": self.failure}


def _where(key: str, values: Mapping[str, float]) -> str:
    return f"the sensitivity to '{key}' needs the scene at {key} = {values[key]:.10g}, near its nominal value"


def _scene(data: Mapping[str, Any], values: Mapping[str, float], key: str, source: str):
    from loopcheck.scene import SceneError
    from loopcheck.scenefile import scene_from_dict

    try:
        return scene_from_dict(apply(data, values), source)
    except SceneError as exc:  # bad input: exit 2
        raise SweepSpecError(f"{source}: {_where(key, values)}: {exc}") from None


def _frozen(engine: str, scene, nominal: Any | None):
    """The engine's settings for ``scene`` (its table over its defaults, judged by its tolerances),
    with each setting left to the engine (None) set to what its nominal run used (``nominal``)."""
    from .settings import engine_settings

    settings = engine_settings(engine, scene)
    if nominal is None:
        return settings
    chosen = {f.name: getattr(nominal, f.name) for f in dataclasses.fields(settings)
              if f.init and getattr(settings, f.name) is None and getattr(nominal, f.name, None) is not None}
    return replace(settings, **chosen) if chosen else settings


def _run(data, values, key: str, source: str, engine: str, nominal_settings: Any | None = None):
    """The engine's run of the scene at ``values``: its result (NumericalFailure naming the key and
    the engine when it fails there; ValueError naming them when the engine refuses it)."""
    from loopcheck.errors import NumericalFailure

    scene = _scene(data, values, key, source)
    if engine != REFERENCE:
        scene = replace(scene, tolerances=scene.tolerances_for(engine))  # as check --engines runs it
    who = "" if engine == REFERENCE else f"{engine}: "
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return ENGINES[engine].simulate(scene, _frozen(engine, scene, nominal_settings))
    except NumericalFailure as exc:  # a failed run: exit 1, with its reason
        raise NumericalFailure(exc.reason, f"{who}{_where(key, values)}: {exc}", exc.time) from None
    except ValueError as exc:  # the engine refuses the scene there: exit 2, naming it
        raise ValueError(f"{who}{_where(key, values)}: {exc}") from None


def _peaks(data: Mapping[str, Any], values: Mapping[str, float], key: str, source: str,
           engine: str = REFERENCE, nominal_settings: Any | None = None) -> tuple[float, ...]:
    """The engine's continuous peak |ω| of each input of the scene at ``values``, in its inputs' order."""
    return tuple(abs(peak.omega) for _, peak in _run(data, values, key, source, engine, nominal_settings).inputs)


def check_engines_declare(data: Mapping[str, Any], spec: SweepSpec, source: str,
                          engines: Sequence[str]) -> None:
    """Before any run: every engine of ``engines`` declares its peak accuracy (ValueError, the
    registry's one line, otherwise) and takes the nominal scene's settings."""
    from .settings import engine_settings

    base = {k: v for k, v in data.items() if k != SWEEP_TABLE}
    nominal = _scene(base, nominal_values(base, spec, source), spec.keys[0], source)
    for engine in engines:
        ENGINES[engine].peak_accuracy(engine_settings(engine, nominal))


def sensitivities(data: Mapping[str, Any], spec: SweepSpec, source: str = "<memory>",
                  engines: Sequence[str] = (REFERENCE,)) -> list[Sensitivity | SensitivityFailure]:
    """d(peak |ω|)/dp for every key of ``spec`` at the nominal scene (module docstring) and every
    engine of ``engines`` (the reference by default): for each, a nominal run, then four runs per
    key, the other keys at their nominal values; by key, the engines in the list's order. Another
    engine's failed or refused run is its :class:`SensitivityFailure` for the key (for every key when
    it is the nominal run), and the study goes on.

    Raises ValueError (before any run) when an engine declares no peak accuracy; SweepSpecError
    naming the key when the scene is invalid at p0 ± 2h; NumericalFailure (naming it) when a run
    of the reference fails there.
    """
    from loopcheck.errors import NumericalFailure

    engines = tuple(sorted(engines, key=lambda e: e != REFERENCE))  # the reference's rows first
    check_engines_declare(data, spec, source, engines)
    base = {k: v for k, v in data.items() if k != SWEEP_TABLE}
    nominal = nominal_values(base, spec, source)
    inputs = _scene(base, nominal, spec.keys[0], source).inputs
    names = inputs if len(inputs) > 1 else ("",)  # several: each input's own, named
    runs, failed = {}, {}
    for engine in engines:
        try:
            runs[engine] = _run(base, nominal, spec.keys[0], source, engine)
        except (NumericalFailure, ValueError) as exc:
            if engine == REFERENCE or isinstance(exc, SweepSpecError):
                raise
            failed[engine] = _failure_line(exc)
    out = []
    for v in spec.varies:
        p0 = nominal[v.key]
        (low, _), (high, _) = v.extremes
        scale = abs(p0) or (high - low) or 1.0
        for engine in engines:
            if engine in failed:
                out.append(SensitivityFailure(v.key, engine, failed[engine]))
                continue
            frozen = runs[engine].settings
            eps = ENGINES[engine].peak_accuracy(frozen)
            h = scale * eps ** (1.0 / 3.0)
            try:
                at = {k: _peaks(base, {**nominal, v.key: p0 + k * h}, v.key, source, engine, frozen)
                      for k in (-2, -1, 1, 2)}
            except (NumericalFailure, ValueError) as exc:
                if engine == REFERENCE or isinstance(exc, SweepSpecError):
                    raise
                out.append(SensitivityFailure(v.key, engine, _failure_line(exc)))
                continue
            for i, (name, (_, peak)) in enumerate(zip(names, runs[engine].inputs)):
                peak0 = abs(peak.omega)
                d_h = (at[1][i] - at[-1][i]) / (2.0 * h)
                d_2h = (at[2][i] - at[-2][i]) / (4.0 * h)
                out.append(Sensitivity(key=v.key, nominal=p0, step=h, peak=peak0, derivative=d_h + (d_h - d_2h) / 3.0,
                                       error=abs(d_h - d_2h) / 3.0 + eps * peak0 / h, at_h=d_h, at_2h=d_2h,
                                       engine=engine, frozen_step=ENGINES[engine].fixed_step(frozen), input=name))
    return out


def _failure_line(exc: Exception) -> str:
    from loopcheck.errors import NumericalFailure

    line = " ".join(str(exc).split())
    return f"numerical failure ({exc.reason}): {line}" if isinstance(exc, NumericalFailure) else f"refused: {line}"


def sensitivity_lines(items: list[Sensitivity | SensitivityFailure], unit: str = "rad/s",
                      units: Mapping[str, str] | None = None) -> list[str]:
    """A table: key, nominal value, step, d(peak)/dp and its error estimate; with several engines,
    each engine's row under the reference's with its difference from it (relative to it), and the
    engines' nominal peaks and frozen steps. A scene of several degrees of freedom (items of
    named inputs): a table per input, headed by the input's name, in its unit (``units``: each
    input's speed unit, rad/s or m/s; default ``unit``); an engine's failure is in each table."""
    named = list(dict.fromkeys(s.input for s in items if isinstance(s, Sensitivity) and s.input))
    if named:
        lines = []
        for name in named:
            unit_k = (units or {}).get(name, unit)
            lines.append(f"input {name} ({unit_k}):")
            part = [s if isinstance(s, SensitivityFailure) else replace(s, input="")  # its own table
                    for s in items if isinstance(s, SensitivityFailure) or s.input == name]
            lines += ["  " + line for line in sensitivity_lines(part, unit_k)]
        return lines
    engines = list(dict.fromkeys(s.engine for s in items))
    if len(engines) <= 1:
        lines = [f"d(peak |omega|)/dp at the nominal scene (peak {items[0].peak:.10g} {unit}; central differences "
                 f"at h and 2h, Richardson):" if items else "no sensitivities",
                 f"  {'key':32s} {'nominal':>12s} {'step h':>10s} {'d(peak)/dp':>14s} {'error est.':>10s}"]
        for s in items:
            lines.append(f"  {s.key:32s} {s.nominal:12.6g} {s.step:10.3g} {s.derivative:14.8g} {s.error:10.2g}")
        return lines
    first = {}
    for s in items:
        if isinstance(s, Sensitivity):
            first.setdefault(s.engine, s)
    peaks = ", ".join(f"{e} {first[e].peak:.10g}" + (f" (step frozen at {first[e].frozen_step:g} s)"
                                                      if first[e].frozen_step is not None else "") for e in first)
    lines = [f"d(peak |omega|)/dp at the nominal scene, each engine's own (central differences at h and 2h, "
             f"Richardson); peaks in {unit}: {peaks}",
             f"  {'key':32s} {'engine':>8s} {'nominal':>12s} {'step h':>10s} {'d(peak)/dp':>14s} {'error est.':>10s} "
             f"{'vs reference':>12s}"]
    reference = {s.key: s for s in items if s.engine == REFERENCE}
    shown = set()
    for s in items:
        key = "" if s.key in shown else s.key
        shown.add(s.key)
        if isinstance(s, SensitivityFailure):
            lines.append(f"  {key:32s} {s.engine:>8s} {s.failure}")
            continue
        ref = reference.get(s.key)
        versus = ("" if s.engine == REFERENCE or ref is None else
                  f"{(s.derivative - ref.derivative) / abs(ref.derivative):+12.2e}" if ref.derivative else "-")
        lines.append(f"  {key:32s} {s.engine:>8s} {s.nominal:12.6g} "
                     f"{s.step:10.3g} {s.derivative:14.8g} {s.error:10.2g} {versus:>12s}".rstrip())
    return lines
