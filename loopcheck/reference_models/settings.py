"""The MuJoCo engine's settings: its ``[mujoco]`` table of the scene file and its flags.

Light on purpose: it does not import MuJoCo, so that reading a scene file and printing the
command line's help cost nothing of the engine. Its fields are the MuJoCo-family model's options
(:mod:`loopcheck.mujoco_model.options`), with the automatic timestep search's default.
"""

from __future__ import annotations

from dataclasses import dataclass

from loopcheck.mujoco_model.options import (DEFAULT_INTEGRATOR, DEFAULT_ITERATIONS, DEFAULT_SOLIMP, DEFAULT_TOLERANCE,
                                       INTEGRATORS, MAX_IMPEDANCE, MAX_ITERATIONS, MIN_IMPEDANCE, ModelOptions)
from loopcheck.settings import option


@dataclass(frozen=True)
class MujocoSettings(ModelOptions):
    """Everything that changes MuJoCo's answer; recorded with every result: the model's options
    (:class:`~loopcheck.mujoco_model.options.ModelOptions`, shared with MJX and MJWarp).

    The defaults are chosen for accuracy (docs/engines.md, "MuJoCo's defaults and loopcheck's"): RK4;
    the timestep chosen from the scene (``timestep=None``: load edges on the step grid, confirmed
    by step halving, see :func:`simulate_mujoco`); a hard loop constraint, solimp (0.9999,
    0.9999, 0.001, 0.5, 2) and solref with time constant 2·timestep (the smallest that
    ``refsafe`` allows) and critical damping; Newton solver tolerance 1e-12.

    ``max_energy_residual``'s default 3e-3 is about 12x the worst run measured over every scene in
    scenes/ and scenes/hard/ with its own [mujoco] settings (2.55e-4, long_conservative at 0.5 ms
    over 45 s; next fast_crank 3.9e-5 at 2e-5 s; the seed at its automatic 0.5 ms: 3.2e-5), so a
    balance 5 % off fails.
    """

    timestep: float | None = option(None, "MuJoCo's timestep", "number", unit="s", limit="step",
                                    within_horizon=True,
                                    default_text="chosen from the scene: load edges on the step grid, confirmed by "
                                                 "step halving")


Settings = MujocoSettings  # the name every engine's settings have (loopcheck.registry)

# How tables and plots name and draw the engine (loopcheck.registry.Engine.label, .colour).
LABEL = "MuJoCo"
COLOUR = "tab:orange"
# A user's own model run as written (loopcheck.reference_models.user_model) is MuJoCo's run too:
# labelled, drawn and filed as this engine (loopcheck.registry.Engine.runs).
USER_MODEL = "model"
RUNS = (USER_MODEL,)
# A user's own MuJoCo model (MJCF) is read as a scene and run as written (loopcheck.registry.Engine.model_files;
# the commands reach it through loopcheck.reference_models.models).
MODEL_FILES = (".xml",)
# Linkages of several degrees of freedom run (loopcheck.registry.Engine.several_dof): one motor per
# loaded joint, every input recorded (EngineResult.other_inputs), the step search judging every input.
SEVERAL_DOF = True


def gate_notes(scene, result, failures) -> tuple[str, ...]:
    """A failed gate of a MuJoCo run at a fixed timestep also names where the step came from: the
    automatic step would have been chosen for the gate's tolerances, a fixed one was not
    (loopcheck.registry.Engine.gate_notes)."""
    accuracy = ("peak_omega_abs", "q_max_abs", "omega_max_abs", "omega_vs_q_max_abs")
    if (result.engine != "mujoco" or result.details.timestep_automatic
            or not any(f.startswith(accuracy) for f in failures)):
        return ()
    h = result.settings.timestep
    source = ("the scene's [mujoco] timestep" if scene.engine_table("mujoco").get("timestep") == h
              else "the settings (--timestep)")
    return (f"MuJoCo ran at the fixed timestep {h:g} s from {source}, not a step chosen for these tolerances: "
            f"without it the step is chosen automatically for them",)


__all__ = ["DEFAULT_INTEGRATOR", "DEFAULT_ITERATIONS", "DEFAULT_SOLIMP", "DEFAULT_TOLERANCE", "INTEGRATORS",
           "MAX_IMPEDANCE", "MAX_ITERATIONS", "MIN_IMPEDANCE", "MujocoSettings", "Settings", "LABEL", "COLOUR",
           "USER_MODEL", "RUNS", "MODEL_FILES", "gate_notes", "accuracy_ladder", "fixed_step",
           "stress_probes", "peak_accuracy", "PEAK_ACCURACY"]


# The study declarations (loopcheck.registry.Engine; docs/engines.md, "What an engine may declare").

def accuracy_ladder(scene, base, quick: bool = False):
    """``loopcheck cost``'s points: every integrator, the hard loop constraint and MuJoCo's default
    softness, timesteps 1e-3 … 1e-5 s (``quick``: 1e-3 and 2.5e-4), each with the ladder's loose limits
    (:func:`loopcheck.mujoco_model.options.fixed_step_ladder`)."""
    from loopcheck.mujoco_model.options import SOFTNESS, fixed_step_ladder

    timesteps = (1e-3, 2.5e-4) if quick else (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)
    return fixed_step_ladder(base, "MuJoCo", INTEGRATORS, tuple(SOFTNESS), timesteps)


# What the MuJoCo engine declares for the studies (loopcheck.registry.Engine's optional declarations):
# the model's (loopcheck.mujoco_model.options), shared with its ports.
from loopcheck.mujoco_model.options import grid_step as fixed_step, integrator_probes  # noqa: E402


def stress_probes(scene, base: MujocoSettings) -> tuple:
    """The scene's settings at each integrator and each of 1 ms, 0.1 ms, 10 µs."""
    return integrator_probes(base, INTEGRATORS)


# Sensitivity's ε: the part of MuJoCo's peak error that is not smooth in a parameter, at a frozen
# timestep. As the parameter moves the summit across the step grid, the peak's error changes with
# where the summit falls between two steps: MuJoCo's peak, as a function of the parameter, is a
# smooth curve plus a sawtooth of about one step's period. Measured on the seed (RK4 at its automatic
# 0.5 ms, peak at 1.154 s, over 1.3 s): the residual of a cubic through nine runs of the coupler mass
# 3e-4, 1e-3 and 3e-3 of it apart is at most 2.5e-6 of the peak (1.3e-6 rms), where 1e-9 to 1e-6
# apart it is round-off (at most 8.6e-13) and the local slope is 2.6 % off the smooth curve's; the
# damper coefficient moves the summit less (2.8e-11 at 1e-4 apart). So ε = 3e-6: the steps
# (|p0| ε^(1/3), 1.4 % of p0) span many periods of the sawtooth and the error bar includes it.
PEAK_ACCURACY = 3e-6


def peak_accuracy(settings: MujocoSettings) -> float:
    """ε: ``PEAK_ACCURACY``, measured at RK4 on the seed (the comment above)."""
    return PEAK_ACCURACY
