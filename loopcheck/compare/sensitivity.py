"""Local sensitivities of the peak input speed: d(peak |ω|)/dp at the nominal scene.

For each varied key p of a sweep (nominal p0: the scene's value, or the spec's centre where the
file gives none), central differences of the reduced solver's continuous peak |ω| P(p) (the
scene's own reduced settings, DOP853 at rtol 1e-12 by default) at two steps h and 2h:

    D(h) = (P(p0 + h) − P(p0 − h)) / 2h,    D = D(h) + (D(h) − D(2h)) / 3   (Richardson)

D(h) has a truncation error c h² and a noise error of about ε |P| / h, where ε is the peak's
relative accuracy (``PEAK_ACCURACY_FACTOR`` × rtol). The step h = s ε^(1/3) balances the two
(s = |p0|, or the spread of the key's spec when p0 = 0, or 1). The estimate of D's error is
|D(h) − D(2h)| / 3 (the truncation left in D(h); D itself is better, O(h⁴)) plus ε |P| / h.
A peak that jumps between two extrema inside ±2h makes D(h) and D(2h) disagree, and the
estimate says so. Units: rad/s (m/s for a prismatic input) per unit of the key.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

from loopcheck.sweep_spec import SWEEP_TABLE, SweepSpec, SweepSpecError, apply
from loopcheck.compare.sweep_scene import nominal_values

# The peak's relative accuracy against rtol: DOP853 at rtol 1e-11 and 1e-12 differ by 4.1e-11 in
# peak ω on the seed (benchmarks/results/compiled_core.txt), about 10 × rtol.
PEAK_ACCURACY_FACTOR = 10.0


@dataclass(frozen=True)
class Sensitivity:
    """d(peak |ω|)/dp of one key at its nominal value p0, by central differences."""

    key: str
    nominal: float      # p0
    step: float         # h
    peak: float         # peak |ω| at p0 (rad/s or m/s)
    derivative: float   # D, Richardson-extrapolated
    error: float        # estimate of |D − dP/dp|
    at_h: float         # D(h)
    at_2h: float        # D(2h)

    def __post_init__(self):
        if not (self.step > 0.0 and math.isfinite(self.step)):
            raise ValueError(f"Sensitivity.step must be positive and finite, got {self.step!r}")

    def as_dict(self) -> dict[str, float | str]:
        return {"key": self.key, "nominal": self.nominal, "step": self.step, "peak": self.peak,
                "derivative": self.derivative, "error": self.error, "at_h": self.at_h, "at_2h": self.at_2h}


def _peak(data: Mapping[str, Any], values: Mapping[str, float], key: str, source: str) -> float:
    from loopcheck.scene import SceneError
    from loopcheck.scenefile import scene_from_dict
    from loopcheck.reduced import simulate
    from loopcheck.errors import NumericalFailure

    from .settings import reduced_settings

    where = f"the sensitivity to '{key}' needs the scene at {key} = {values[key]:.10g}, near its nominal value"
    try:
        scene = scene_from_dict(apply(data, values), source)
    except SceneError as exc:  # bad input: exit 2
        raise SweepSpecError(f"{source}: {where}: {exc}") from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return abs(simulate(scene, reduced_settings(scene)).peak.omega)
    except NumericalFailure as exc:  # a failed run: exit 1, with its reason
        raise NumericalFailure(exc.reason, f"{where}: {exc}", exc.time) from None


def sensitivities(data: Mapping[str, Any], spec: SweepSpec, source: str = "<memory>") -> list[Sensitivity]:
    """d(peak |ω|)/dp for every key of ``spec`` at the nominal scene (module docstring): four
    reduced runs per key, the other keys at their nominal values.

    Raises SweepSpecError naming the key when the scene is invalid at p0 ± 2h, NumericalFailure
    (naming it too) when its run fails there.
    """
    from loopcheck.scenefile import scene_from_dict

    from .settings import reduced_settings

    base = {k: v for k, v in data.items() if k != SWEEP_TABLE}
    nominal = nominal_values(base, spec, source)
    rtol = reduced_settings(scene_from_dict(apply(base, nominal), source)).rtol
    eps = PEAK_ACCURACY_FACTOR * rtol
    peak0 = _peak(base, nominal, spec.keys[0], source)
    out = []
    for v in spec.varies:
        p0 = nominal[v.key]
        (low, _), (high, _) = v.extremes
        scale = abs(p0) or (high - low) or 1.0
        h = scale * eps ** (1.0 / 3.0)
        at = {k: _peak(base, {**nominal, v.key: p0 + k * h}, v.key, source) for k in (-2, -1, 1, 2)}
        d_h = (at[1] - at[-1]) / (2.0 * h)
        d_2h = (at[2] - at[-2]) / (4.0 * h)
        out.append(Sensitivity(key=v.key, nominal=p0, step=h, peak=peak0, derivative=d_h + (d_h - d_2h) / 3.0,
                               error=abs(d_h - d_2h) / 3.0 + eps * peak0 / h, at_h=d_h, at_2h=d_2h))
    return out


def sensitivity_lines(items: list[Sensitivity], unit: str = "rad/s") -> list[str]:
    """A table: key, nominal value, step, d(peak)/dp and its error estimate."""
    lines = [f"d(peak |omega|)/dp at the nominal scene (peak {items[0].peak:.10g} {unit}; central differences "
             f"at h and 2h, Richardson):" if items else "no sensitivities",
             f"  {'key':32s} {'nominal':>12s} {'step h':>10s} {'d(peak)/dp':>14s} {'error est.':>10s}"]
    for s in items:
        lines.append(f"  {s.key:32s} {s.nominal:12.6g} {s.step:10.3g} {s.derivative:14.8g} {s.error:10.2g}")
    return lines
