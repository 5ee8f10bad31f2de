"""The MJWarp engine's settings: its ``[mjwarp]`` table of the scene file and its flags.

Light on purpose: it imports neither warp nor MuJoCo. The fields are the MuJoCo-family model's
options (:mod:`loopcheck.mujoco_model.options`), the same as the MuJoCo engine's, with the grid step
as the default timestep (MJWarp runs once; the MuJoCo engine's automatic search confirms its step
by halving, which would cost MJWarp a run per step). There is no precision field: MJWarp 4.0
computes in float32 only.
"""

from __future__ import annotations

from dataclasses import dataclass

from loopcheck.mujoco_model.options import ModelOptions
from loopcheck.settings import option, options


@dataclass(frozen=True)
class MjwarpSettings(ModelOptions):
    """Everything that changes MJWarp's answer; recorded with every result.

    The model's options (:class:`~loopcheck.mujoco_model.options.ModelOptions`) as the MuJoCo
    engine's (a scene's ``[mujoco]`` values of them are this engine's defaults:
    :func:`loopcheck.compare.settings.engine_settings`), except ``timestep``: None is the grid step
    (the largest step ≤ 1 ms and ≤ 1/100 of
    the horizon that puts every load edge on the grid), not a search.

    MJWarp is float32 only (its arrays are warp's ``float``, float32; it has no float64 switch),
    and its ``put_model`` raises the solver's ``tolerance`` to at least 1e-6. Its results carry
    float32 round-off, amplified by the loop constraints' stiffness: on the seed about 3e-4 on the
    peak over 2 s (docs/engines.md, "MJWarp"), against MuJoCo C's 3e-6 with the same model.
    """

    timestep: float | None = option(None, "MJWarp's timestep", "number", unit="s", limit="step", within_horizon=True,
                                    default_text="[mujoco] timestep, else the grid step, the MuJoCo engine's "
                                                 "first candidate (load edges on the grid)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.diagexact is True:
            raise ValueError("diagexact: MJWarp does not implement MuJoCo's exact constraint diagonal "
                             "(mjENBL_DIAGEXACT)")


Settings = MjwarpSettings  # the name every engine's settings have (loopcheck.registry)

# How tables and plots name the engine (loopcheck.registry.Engine.label; its colour is the registry's).
LABEL = "MJWarp"
# The scene's [mujoco] values of the model's options are this port's defaults, under its own table
# (loopcheck.registry.Engine.inherits): it runs the model the MuJoCo engine builds.
INHERITS = ("mujoco", tuple(o.name for o in options(ModelOptions)))

# Linkages of several degrees of freedom run (loopcheck.registry.Engine.several_dof): the MuJoCo engine's
# model (one motor per loaded joint, every input at its initial rate), every input recorded by MuJoCo C at
# the port's states (EngineResult.other_inputs); its known defect stated as on one DOF.
SEVERAL_DOF = True

# The study declarations (loopcheck.registry.Engine; docs/engines.md, "What an engine may declare").

def accuracy_ladder(scene, base, quick: bool = False):
    """``loopcheck cost``'s points: fixed timesteps 2e-3 … 2.5e-4 s (``quick``: 1e-3 and 5e-4: on a
    CPU MJWarp takes ~20 ms a step), the scene's integrator (default RK4) with the hard loop constraint, each with the
    ladder's loose limits (:func:`loopcheck.mujoco_model.options.fixed_step_ladder`)."""
    from loopcheck.mujoco_model.options import fixed_step_ladder

    timesteps = (1e-3, 5e-4) if quick else (2e-3, 1e-3, 5e-4, 2.5e-4)
    return fixed_step_ladder(base, "MJWarp", (base.integrator,), ("hard",), timesteps)

BATCH_SIZE = 16
"""Variants a sweep hands ``simulate_batch`` at once (MJWarp's worlds; ``loopcheck sweep
--batch-size`` overrides it). A CPU's default: a step launches some hundred kernels whatever the
number of worlds, so a batch amortises their launch, while a CPU's cores share the worlds' work;
on a GPU give thousands (docs/performance.md)."""

# What the MJWarp engine declares for the studies (loopcheck.registry.Engine's optional declarations):
# the MuJoCo-family model's (loopcheck.mujoco_model.options).
from loopcheck.mujoco_model.options import INTEGRATORS, grid_step as fixed_step, integrator_probes  # noqa: E402


def stress_probes(scene, base: MjwarpSettings) -> tuple:
    """The scene's settings at each integrator and each of 1 ms, 0.1 ms, 10 µs."""
    return integrator_probes(base, INTEGRATORS)


# Sensitivity's ε: MJWarp computes in float32, whose round-off the loop constraints' stiffness
# amplifies (on the seed about 3e-4 on the peak over 2 s, against MuJoCo C's 3e-6 with the same model:
# docs/engines.md, "MJWarp"); at a frozen step that round-off is the peak's noise against a parameter.
# Measured on the seed over 1.3 s at its grid step 1 ms (warp on the CPU): five runs of the coupler mass
# 1e-6 of it apart (where the true peak moves by 4e-7 of itself) scatter about a parabola by 1.2e-4 of the
# peak rms, 2.1e-4 at most. So ε = 3e-4, and the sensitivity's steps are |p0| ε^(1/3), 6.7 % of p0.
PEAK_ACCURACY = 3e-4


def peak_accuracy(settings: MjwarpSettings) -> float:
    """ε: ``PEAK_ACCURACY`` (float32 round-off, measured)."""
    return PEAK_ACCURACY
