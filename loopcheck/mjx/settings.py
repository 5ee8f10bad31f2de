"""The MJX engine's settings: its ``[mjx]`` table of the scene file and its flags.

Light on purpose: it imports neither JAX nor MuJoCo. The fields are the MuJoCo-family model's
options (:mod:`loopcheck.mujoco_model.options`), the same as the MuJoCo engine's, with the grid step
as the default timestep (MJX runs once; the MuJoCo engine's automatic search confirms its step by
halving, which would cost MJX a compilation per step), and the precision.
"""

from __future__ import annotations

from dataclasses import dataclass

from loopcheck.mujoco_model.options import DEFAULT_INTEGRATOR, ModelOptions
from loopcheck.settings import option, options

PRECISIONS = ("float64", "float32")
INTEGRATORS = ("euler", "implicitfast", "rk4")  # MJX 3.17's (mjx types.IntegratorType: no implicit)


@dataclass(frozen=True)
class MjxSettings(ModelOptions):
    """Everything that changes MJX's answer; recorded with every result.

    The model's options (:class:`~loopcheck.mujoco_model.options.ModelOptions`) as the MuJoCo
    engine's (a scene's ``[mujoco]`` values of them are this engine's defaults:
    :func:`loopcheck.compare.settings.engine_settings`), except ``timestep``: None is the grid step
    (the largest step ≤ 1 ms and ≤ 1/100 of
    the horizon that puts every load edge on the grid), not a search. ``precision``: JAX's
    float64 (``jax_enable_x64``) or float32. What MJX does not implement is refused here: the
    implicit integrator (``implicitfast`` it has) and MuJoCo's exact constraint diagonal
    (``diagexact``).
    """

    integrator: str = option(DEFAULT_INTEGRATOR, "MJX's integrator (MJX has no implicit)", "choice",
                             choices=INTEGRATORS)

    timestep: float | None = option(None, "MJX's timestep", "number", unit="s", limit="step", within_horizon=True,
                                    default_text="[mujoco] timestep, else the grid step, the MuJoCo engine's "
                                                 "first candidate (load edges on the grid)")
    precision: str = option("float64", "JAX's floating-point precision", "choice", choices=PRECISIONS)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)} (MJX has no implicit integrator), "
                             f"got {self.integrator!r}")
        if self.diagexact is True:
            raise ValueError("diagexact: MJX does not implement MuJoCo's exact constraint diagonal (mjENBL_DIAGEXACT)")
        if self.precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {self.precision!r}")


Settings = MjxSettings  # the name every engine's settings have (loopcheck.registry)

# How tables and plots name the engine (loopcheck.registry.Engine.label; its colour is the registry's).
LABEL = "MJX"
# The scene's [mujoco] values of the model's options are this port's defaults, under its own table
# (loopcheck.registry.Engine.inherits): it runs the model the MuJoCo engine builds.
INHERITS = ("mujoco", tuple(o.name for o in options(ModelOptions)))

# Linkages of several degrees of freedom run (loopcheck.registry.Engine.several_dof): the MuJoCo engine's
# model (one motor per loaded joint, every input at its initial rate), every input recorded by MuJoCo C at
# the port's states (EngineResult.other_inputs); its known defect stated as on one DOF.
SEVERAL_DOF = True

# The study declarations (loopcheck.registry.Engine; docs/engines.md, "What an engine may declare").

def accuracy_ladder(scene, base, quick: bool = False):
    """``loopcheck cost``'s points: fixed timesteps 2e-3 … 2.5e-4 s (``quick``: 1e-3 and 5e-4, each
    a compilation), the scene's integrator (default RK4) with the hard loop constraint, each with the
    ladder's loose limits (:func:`loopcheck.mujoco_model.options.fixed_step_ladder`)."""
    from loopcheck.mujoco_model.options import fixed_step_ladder

    timesteps = (1e-3, 5e-4) if quick else (2e-3, 1e-3, 5e-4, 2.5e-4)
    return fixed_step_ladder(base, "MJX", (base.integrator,), ("hard",), timesteps)

BATCH_SIZE = 16
"""Variants a sweep hands ``simulate_batch`` at once (one ``vmap``; ``loopcheck sweep --batch-size``
overrides it). A CPU's default: each batch size is a compilation of its own (about 35 s on a
2-core CPU), paid once per sweep as the last chunk is padded to it, and a CPU gains little from a
wider ``vmap`` beyond amortising the dispatch of each step; on a GPU give thousands
(docs/performance.md)."""

# What the MJX engine declares for the studies (loopcheck.registry.Engine's optional declarations):
# the MuJoCo-family model's (loopcheck.mujoco_model.options), over MJX's integrators.
from loopcheck.mujoco_model.options import grid_step as fixed_step, integrator_probes  # noqa: E402


def stress_probes(scene, base: MjxSettings) -> tuple:
    """The scene's settings at each of MJX's integrators and each of 1 ms, 0.1 ms, 10 µs (each a
    compilation and a run: minutes on a CPU)."""
    return integrator_probes(base, INTEGRATORS)


# Sensitivity's ε: MJX runs the MuJoCo engine's model with its RK4 in float64 and MuJoCo C reads its
# states and refines the peak as for MuJoCo (loopcheck.mujoco_model.port), so its peak carries the
# same sawtooth against a parameter as the summit crosses the step grid: MuJoCo's figure
# (loopcheck.reference_models.settings.PEAK_ACCURACY, 3e-6). Measured for MJX (CPU, float64) on the seed
# over 0.2 s, the damper coefficient (the peak at the horizon, where no summit crosses the grid): five
# runs 1e-7, 1e-5 and 1e-3 of it apart lie on a parabola within 7e-14 of the peak, round-off as MuJoCo C's.
# The seed's summit (1.154 s) lies past MJX's loop failure there (1.01 s, its known defect), so the
# sawtooth is taken as MuJoCo's, whose mechanism (the refinement of the summit between samples) it shares.
PEAK_ACCURACY = 3e-6
PEAK_ACCURACY_FLOAT32 = 3e-4  # float32: MJWarp's figure (its settings module), the same round-off


def peak_accuracy(settings: MjxSettings) -> float:
    """ε: ``PEAK_ACCURACY`` in float64, ``PEAK_ACCURACY_FLOAT32`` in float32."""
    return PEAK_ACCURACY if settings.precision == "float64" else PEAK_ACCURACY_FLOAT32
