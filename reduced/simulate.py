"""The reduced engine's entry point: scene in, :class:`EngineResult` out."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

from .dynamics import MechanismModel
from .energy import energy_audit
from .integrators import RKN4, solve_adaptive, solve_fixed_step
from .partition import PartitionedSolution, integrate_partitioned
from .result import EngineResult
from .scene import Scene

METHODS = ("dop853", "rkn4", "radau")


@dataclass(frozen=True)
class ReducedSettings:
    """How to integrate Eksergian's equation.

    method : "dop853" (adaptive reference), "rkn4" (the seed's fixed-step method,
        corrected) or "radau" (implicit, for stiff dampers).
    rtol : relative (and absolute) tolerance of the adaptive methods.
    step : largest step (s) of the fixed-step method.
    sample_interval : largest spacing (s) of saved samples for the adaptive methods.
    """

    method: str = "dop853"
    rtol: float = 1e-12
    step: float = 1e-3
    sample_interval: float = 1e-3

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        for name in ("rtol", "step", "sample_interval"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be positive")


def chart_integrator(settings: ReducedSettings, breakpoints: tuple[float, ...]):
    """The integrator the settings name, as a function of one chart's equation."""
    if settings.method == "rkn4":
        def run(rhs_on_piece, span, x0, v0, stop):
            return solve_fixed_step(rhs_on_piece, span, x0, v0, settings.step, breakpoints=breakpoints,
                                    tableau=RKN4, stop=stop)
    else:
        method = "DOP853" if settings.method == "dop853" else "Radau"

        def run(rhs_on_piece, span, x0, v0, stop):
            return solve_adaptive(rhs_on_piece, span, x0, v0, rtol=settings.rtol, method=method,
                                  breakpoints=breakpoints, sample_interval=settings.sample_interval,
                                  stop=stop)
    return run


def integrate(model: MechanismModel, settings: ReducedSettings) -> PartitionedSolution:
    """Run the integrator the settings name, switching coordinates at dead centres."""
    return integrate_partitioned(model, chart_integrator(settings, model.load_edges))


def simulate(scene: Scene, settings: ReducedSettings = ReducedSettings()) -> EngineResult:
    """Solve the scene's Eksergian equation and audit its energy.

    Returns
    -------
    EngineResult
        ``engine="reduced"``; ``wall_s`` times the integration only. ``diagnostics`` holds
        the coordinate switches and the trajectory of every joint angle.

    Raises
    ------
    NumericalFailure
        If the integration blows up, leaves the stability region, becomes non-finite or
        reaches a position no coordinate can drive.
    """
    model = MechanismModel(scene)
    start = time.perf_counter()
    solution = integrate(model, settings)
    wall = time.perf_counter() - start
    trajectory = solution.trajectory
    return EngineResult(
        engine="reduced", trajectory=trajectory, peak=trajectory.peak_angular_velocity(),
        audit=energy_audit(model, solution.segments), wall_s=wall, n_steps=solution.n_steps,
        n_evaluations=solution.n_evaluations, settings={**asdict(settings), "solver": solution.method},
        diagnostics={"effects": list(model.effects), "joints": solution.joints,
                     "switches": [asdict(s) for s in solution.switches]})
