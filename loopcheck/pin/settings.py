"""The Pinocchio engine's settings: its ``[pin]`` table of the scene file and its flags.

Light on purpose: it imports nothing of Pinocchio (nor scipy), so that reading a scene file and
printing the command line's help cost nothing of the engine.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from numbers import Integral

from loopcheck.settings import field_number, option

METHODS = ("dop853", "rk45", "radau")  # scipy's solve_ivp methods offered (SCIPY_NAMES), named as the reduced engine's
SCIPY_NAMES = {"dop853": "DOP853", "rk45": "RK45", "radau": "Radau"}
DEFAULT_RTOL = 1e-10
DEFAULT_ATOL = 1e-12
DEFAULT_SAMPLE_INTERVAL = 1e-3
DEFAULT_KP = 100.0
MAX_EVALUATIONS = 10_000_000
MAX_SAMPLES = 500_000


@dataclass(frozen=True)
class PinSettings:
    """Everything that changes the Pinocchio engine's answer; recorded with every result.

    Parameters
    ----------
    method : scipy's ``solve_ivp`` method (``METHODS``, scipy's ``SCIPY_NAMES``), restarted at every load edge.
    rtol, atol : its relative and absolute tolerances (atol in the state's units: rad, m, rad/s,
        m/s, and J for the two energy flows integrated alongside).
    sample_interval : s, the largest spacing of the samples taken from the solver's dense output.
    baumgarte_kp, baumgarte_kd : 1/s² and 1/s, the loop constraints' Baumgarte gains (Pinocchio's
        ``BaumgarteCorrectorParameters``): the constraint's acceleration is held at
        −Kp·gap − Kd·ġap, so a gap left by the integrator decays instead of growing. Kd None is
        2√Kp (critically damped).
    proximal_mu, proximal_accuracy, proximal_iterations : Pinocchio's ``ProximalSettings`` of
        ``constraintDynamics`` (the regularisation μ of its proximal iterations, their stopping
        accuracy and their largest number).
    max_evaluations : the largest number of evaluations of the dynamics a run may take.
    max_constraint_violation : m; a larger loop gap fails the run (``constraint-drift``).
    max_energy_residual : the largest |energy residual| / energy scale a run may have.
    """

    method: str = option("dop853", "scipy's solve_ivp method (DOP853, RK45 or Radau)", "choice", choices=METHODS)
    rtol: float = option(DEFAULT_RTOL, "the integrator's relative tolerance", "number")
    atol: float = option(DEFAULT_ATOL, "the integrator's absolute tolerance (rad, m, rad/s, m/s, J)", "number")
    sample_interval: float = option(DEFAULT_SAMPLE_INTERVAL, "largest spacing of the samples", "number", unit="s",
                                    limit="step", within_horizon=True)
    baumgarte_kp: float = option(DEFAULT_KP, "the loop constraints' Baumgarte position gain", "number", unit="1/s²")
    baumgarte_kd: float | None = option(None, "the loop constraints' Baumgarte velocity gain", "number", unit="1/s",
                                        default_text="2√Kp (critical damping)")
    proximal_mu: float = option(1e-12, "the proximal regularisation μ of Pinocchio's constraintDynamics", "number")
    proximal_accuracy: float = option(1e-12, "the stopping accuracy of its proximal iterations", "number")
    proximal_iterations: int = option(20, "the largest number of its proximal iterations", "whole", low=1, high=1000)
    max_evaluations: int = option(2_000_000, "the most evaluations of the dynamics a run may take", "whole", low=1,
                                  high=MAX_EVALUATIONS)
    max_constraint_violation: float = option(1e-6, "the largest loop gap a run may have; beyond it the run fails "
                                             "as drifted", "number", unit="m")
    max_energy_residual: float = option(1e-6, "the largest |energy residual| / energy scale a run may have; beyond "
                                        "it the run fails", "number")

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"PinSettings.method must be one of {', '.join(METHODS)}, got {self.method!r}")
        for name in ("rtol", "atol", "sample_interval", "proximal_mu", "proximal_accuracy",
                     "max_constraint_violation", "max_energy_residual"):
            if not field_number(getattr(self, name), f"PinSettings.{name}") > 0.0:
                raise ValueError(f"PinSettings.{name} must be positive, got {getattr(self, name)!r}")
        if not 1e-14 <= self.rtol <= 0.1:
            raise ValueError(f"PinSettings.rtol must be within [1e-14, 0.1], got {self.rtol!r}")
        if not field_number(self.baumgarte_kp, "PinSettings.baumgarte_kp") > 0.0:
            raise ValueError(f"PinSettings.baumgarte_kp must be positive, got {self.baumgarte_kp!r}")
        if self.baumgarte_kd is not None and not field_number(self.baumgarte_kd, "PinSettings.baumgarte_kd") > 0.0:
            raise ValueError(f"PinSettings.baumgarte_kd must be positive, got {self.baumgarte_kd!r}")
        for name, high in (("proximal_iterations", 1000), ("max_evaluations", MAX_EVALUATIONS)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, Integral) or not 1 <= value <= high:
                raise ValueError(f"PinSettings.{name} must be a whole number in [1, {high}], got {value!r}")

    @property
    def kd(self) -> float:
        """The Baumgarte velocity gain used (1/s): ``baumgarte_kd``, or 2√Kp."""
        return 2.0 * math.sqrt(self.baumgarte_kp) if self.baumgarte_kd is None else float(self.baumgarte_kd)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["baumgarte_kd"] = self.kd
        return d


Settings = PinSettings  # the name every engine's settings have (loopcheck.registry)

# How tables and plots name and draw the engine (loopcheck.registry.Engine.label, .colour).
LABEL = "Pinocchio"
COLOUR = "tab:green"

# Linkages of several degrees of freedom run (loopcheck.registry.Engine.several_dof): each input at its
# initial rate, its actuators as generalized forces, every input recorded (EngineResult.other_inputs).
SEVERAL_DOF = True

# The study declarations (loopcheck.registry.Engine; docs/engines.md, "What an engine may declare").
SWEEP_VIOLATION_LIMIT = 0.1  # m: a ladder measures an opening loop rather than rejecting it
SWEEP_ENERGY_LIMIT = 1.0  # of the energy scale: likewise for a loose tolerance's energy error


def accuracy_ladder(scene, base, quick: bool = False):
    """``loopcheck cost``'s points: the scene's method (default DOP853) over rtol 1e-4 … 1e-12
    (``quick``: 1e-6, 1e-9, 1e-12), each with loose limits so that it is measured where
    ``loopcheck run`` refuses it (its verdict: run's, at the scene's limits)."""
    from dataclasses import replace

    from loopcheck.registry import Rung

    rtols = (1e-6, 1e-9, 1e-12) if quick else tuple(10.0 ** -k for k in range(4, 13))
    rungs = []
    for rtol in rtols:
        point = replace(base, rtol=rtol)
        loose = replace(point, max_constraint_violation=SWEEP_VIOLATION_LIMIT, max_energy_residual=SWEEP_ENERGY_LIMIT)
        rungs.append(Rung(f"Pinocchio {SCIPY_NAMES[base.method]}", rtol, loose, "rtol", run_settings=point))
    return rungs

# What the Pinocchio engine declares for the studies (loopcheck.registry.Engine's optional declarations).

# Sensitivity's ε, the peak's relative accuracy, against rtol: scipy's DOP853, as the reduced engine's
# adaptive methods, so the same 10 × rtol. Measured on the seed over 1.3 s at the default rtol 1e-10
# (ε = 1e-9): the peak 3.7e-11 from the reduced reference's, and its noise as a function of the coupler
# mass (residual of a quadratic through nine runs 1e-5 of the mass apart) at most 1.5e-12 of it.
PEAK_ACCURACY_FACTOR = 10.0


def peak_accuracy(settings: PinSettings) -> float:
    """ε: ``PEAK_ACCURACY_FACTOR`` × rtol."""
    return PEAK_ACCURACY_FACTOR * settings.rtol
