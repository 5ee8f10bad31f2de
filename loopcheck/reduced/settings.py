"""The reduced engine's settings: its ``[reduced]`` table of the scene file and its flags.

Light on purpose: it imports neither the compiled core nor scipy, so that reading a scene file
and printing the command line's help cost nothing of the engine.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from numbers import Real

from loopcheck.errors import IgnoredSettingWarning
from loopcheck.settings import option

METHODS = ("dop853", "rkn4", "radau", "scipy-dop853")
ADAPTIVE = ("dop853", "scipy-dop853", "radau")

# Default accuracy requests. The adaptive methods are the reference: 1e-12 (scipy's floor is
# 100 ε ≈ 2.2e-14). RKN4's error is estimated by step doubling and judged against
# rtol × the run's largest |q̇| (and |q|, each at least 1). RKN4's default, 1e-5, is a tenth
# of the tightest shipped comparison tolerance (peak_omega_rtol 1e-4), so an RKN4 reference
# that passes cannot use up a gate. Its default step is the largest halving of 1 ms that
# meets it on the seed scene: the estimate there is 2.4e-5 at 1 ms (failing) and 5.7e-7 at
# 0.5 ms (the true largest errors: 8.6e-6 and 7.2e-8 of the peak speed).
DEFAULT_METHOD = "dop853"
DEFAULT_RTOL = {"dop853": 1e-12, "scipy-dop853": 1e-12, "radau": 1e-12, "rkn4": 1e-5}
DEFAULT_STEP = 5e-4  # s, RKN4
DEFAULT_SAMPLE_INTERVAL = 1e-3  # s, largest spacing of the adaptive methods' samples
EPSILON = 2.0 ** -52
RTOL_RANGE = (100 * EPSILON, 0.1)  # scipy raises rtol below 100 ε to it, with a warning


def _rtol_defaults() -> str:
    """The methods' default tolerances, e.g. ``1e-12 (dop853, radau, scipy-dop853), 1e-05 (rkn4)``."""
    by_value: dict[float, list[str]] = {}
    for method in METHODS:
        by_value.setdefault(DEFAULT_RTOL[method], []).append(method)
    return ", ".join(f"{value:g} ({', '.join(sorted(methods))})" for value, methods in by_value.items())


@dataclass(frozen=True)
class ReducedSettings:
    """How to integrate Eksergian's equation.

    A field left at None takes its method's default; a field given that the method does not
    use raises an :class:`IgnoredSettingWarning` (``given`` lists the fields that were set).

    method : "dop853" (adaptive reference, compiled), "rkn4" (the seed's fixed-step method,
        corrected, compiled), "radau" (implicit, for stiff dampers; scipy) or "scipy-dop853"
        (scipy's DOP853 on the same compiled equation: an independent check of the compiled
        integrator).
    rtol : the accuracy requested. Adaptive methods: their relative (and absolute) tolerance
        (default 1e-12). RKN4: the largest step-doubling error estimate allowed, relative to
        the run's largest |q| (rad) and |q̇| (rad/s), each at least 1 (default 1e-5).
        Within [100 ε, 0.1].
    step : RKN4's largest step (s); default 5e-4.
    sample_interval : largest spacing (s) of the adaptive methods' samples; default 1e-3.
    check_error : raise when the run's error estimate or energy balance is beyond its
        bound (True); False records them only (for cost studies of coarse settings).
    """

    method: str = option(DEFAULT_METHOD, "integrator: adaptive DOP853 or fixed-step RKN4 (both compiled), "
                         "implicit Radau, or scipy's DOP853 on the same equation as a cross-check",
                         "choice", choices=METHODS)
    rtol: float | None = option(None, f"accuracy requested, within [{RTOL_RANGE[0]:.3g}, {RTOL_RANGE[1]:g}]: "
                                "an adaptive method's relative tolerance; RKN4's largest step-doubling error "
                                "estimate, relative to the run's largest |q| and |q̇|", "number",
                                default_text=_rtol_defaults())
    step: float | None = option(None, "RKN4's step", "number", unit="s", limit="step", within_horizon=True,
                                default_text=f"{DEFAULT_STEP:g}")
    sample_interval: float | None = option(None, "largest spacing of an adaptive method's samples", "number",
                                           unit="s", limit="step", within_horizon=True,
                                           default_text=f"{DEFAULT_SAMPLE_INTERVAL:g}")
    check_error: bool = option(True, "fail a run whose error estimate or energy balance is beyond its bound "
                               "(False records them only, for cost studies)", "bool", flag=False, table=False)
    given: frozenset = field(default=frozenset(), init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"ReducedSettings.method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if not isinstance(self.check_error, bool):
            raise ValueError(f"ReducedSettings.check_error must be True or False, got {self.check_error!r}")
        given = frozenset(n for n in ("rtol", "step", "sample_interval") if getattr(self, n) is not None)
        for name in given:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, Real):  # numpy's numbers are Real too
                raise ValueError(f"ReducedSettings.{name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"ReducedSettings.{name} must be positive and finite, got {value!r}")
        if "rtol" in given and not RTOL_RANGE[0] <= self.rtol <= RTOL_RANGE[1]:
            raise ValueError(f"ReducedSettings.rtol must be within [{RTOL_RANGE[0]:.3g}, {RTOL_RANGE[1]:g}] "
                             f"(below 100 machine epsilons no method can honour it), got {self.rtol!r}")
        ignored = [n for n in sorted(given)
                   if (n == "step" and self.method in ADAPTIVE) or (n == "sample_interval" and self.method == "rkn4")]
        if ignored:
            warnings.warn(f"{', '.join(ignored)} has no effect with method {self.method!r}"
                          + (" (RKN4 samples every step)" if self.method == "rkn4" else
                             " (an adaptive method chooses its own steps; use rtol)"),
                          IgnoredSettingWarning, stacklevel=3)
        object.__setattr__(self, "given", given)
        object.__setattr__(self, "rtol", float(self.rtol) if "rtol" in given else DEFAULT_RTOL[self.method])
        if self.method == "rkn4":
            object.__setattr__(self, "step", float(self.step) if "step" in given else DEFAULT_STEP)
            object.__setattr__(self, "sample_interval", None)
        else:
            object.__setattr__(self, "step", None)
            object.__setattr__(self, "sample_interval", float(self.sample_interval) if "sample_interval" in given
                               else DEFAULT_SAMPLE_INTERVAL)

    def as_dict(self) -> dict:
        """The resolved settings (what the run used), for reports."""
        return {"method": self.method, "rtol": self.rtol, "step": self.step,
                "sample_interval": self.sample_interval, "check_error": self.check_error}


Settings = ReducedSettings  # the name every engine's settings have (loopcheck.registry)

# Scenes of several degrees of freedom run (loopcheck.registry.Engine.several_dof): Eksergian's reduction in
# k coordinates, loopcheck.reduced.several.
SEVERAL_DOF = True

# How tables and plots name and draw the engine (loopcheck.registry.Engine.label, .colour).
LABEL = "reduced"
COLOUR = "tab:blue"


def settings_text(result) -> str:
    """A run's settings in a few words (loopcheck.registry.Engine.settings_text): the method and its
    step (RKN4) or rtol."""
    used = result.settings
    return f"{result.details.solver} " + (f"h={used.step:g}s" if used.method == "rkn4" else f"rtol={used.rtol:g}")

# The study declarations (loopcheck.registry.Engine; docs/engines.md, "What an engine may declare").

def _rung(series: str, parameter: float, symbol: str, **fields):
    from loopcheck.registry import Rung

    # The ladder measures coarse settings: their error estimate and energy balance are recorded,
    # not enforced (check_error False); run's own check (the default) gives the point's verdict.
    return Rung(series, parameter, ReducedSettings(**fields, check_error=False), symbol,
                run_settings=ReducedSettings(**fields))


def accuracy_ladder(scene, base, quick: bool = False):
    """``loopcheck cost``'s points: RKN4 over steps 1e-2 … 1e-4 s and DOP853 over rtol 1e-3 … 1e-12
    (``quick``: three of each). Every field is the ladder's (the settings resolve per method), not
    the scene's table."""
    if quick:
        steps, rtols = (1e-2, 3e-3, 1e-3), (1e-4, 1e-7, 1e-10)
    else:
        steps = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)
        rtols = tuple(10.0 ** -k for k in range(3, 13))
    return ([_rung("RKN4", h, "h", method="rkn4", step=h) for h in steps]
            + [_rung("DOP853", r, "rtol", method="dop853", rtol=r) for r in rtols])


def truth():
    """The ground truth of the studies, as the reference (loopcheck.registry.Engine.truth): DOP853 at
    rtol 1e-12, checked against rtol 1e-11."""
    from loopcheck.registry import Rung

    return (Rung("DOP853", 1e-12, ReducedSettings(method="dop853", rtol=1e-12), "rtol"),
            Rung("DOP853", 1e-11, ReducedSettings(method="dop853", rtol=1e-11), "rtol"))

# What the reduced engine declares for the studies (loopcheck.registry.Engine's optional declarations).

# Sensitivity's ε, the peak's relative accuracy, against rtol: DOP853 at rtol 1e-11 and 1e-12 differ
# by 4.1e-11 in peak ω on the seed (benchmarks/results/compiled_core.txt), about 10 × rtol. For RKN4
# its rtol (the step-doubling error allowed) is a bound on the same scale, and a generous one at a
# frozen step.
PEAK_ACCURACY_FACTOR = 10.0
RKN4_PROBE_STEPS = (1e-3, 1e-4)  # s: the fixed-step method's stability, where a stress case asks


def peak_accuracy(settings: ReducedSettings) -> float:
    """ε: ``PEAK_ACCURACY_FACTOR`` × rtol."""
    return PEAK_ACCURACY_FACTOR * settings.rtol


def fixed_step(settings: ReducedSettings) -> float | None:
    """RKN4's step; None for the adaptive methods."""
    return settings.step if settings.method == "rkn4" else None


def stress_probes(scene, base: ReducedSettings) -> tuple:
    """RKN4 at each of ``RKN4_PROBE_STEPS`` with its default rtol (series "rkn4", parameter the step):
    whether the explicit fixed-step method runs, or detects that it cannot (a stiff damper)."""
    from loopcheck.registry import Rung

    return tuple(Rung("rkn4", h, ReducedSettings(method="rkn4", step=h)) for h in RKN4_PROBE_STEPS)
