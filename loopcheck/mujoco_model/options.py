"""The options of a MuJoCo-family model (MuJoCo C, MJX, MJWarp): integrator, timestep, the loop
constraints' softness and the solver's, declared once for every engine that runs the model built
by :mod:`loopcheck.mujoco_model.build`; each engine's ``Settings`` extends :class:`ModelOptions`.

Light on purpose: it imports nothing of MuJoCo, so that reading a scene file and printing the
command line's help cost nothing of an engine (MuJoCo's impedance limits are written here and
checked against ``mujoco.mjMINIMP`` and ``mjMAXIMP`` by the tests).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from numbers import Integral

from loopcheck.settings import field_number, option

INTEGRATORS = ("euler", "implicit", "implicitfast", "rk4")
# MuJoCo's constraint-solver iterations per step: Newton on a loop's rows converges in a handful;
# 10 000 already means a solver that is not converging, and keeps the binding's C int (2**31
# raises a TypeError there) far away. One limit for the scene file, the CLI and the settings.
MAX_ITERATIONS = 10_000
MIN_IMPEDANCE, MAX_IMPEDANCE = 1e-4, 0.9999  # mujoco.mjMINIMP, mjMAXIMP: MuJoCo clamps solimp's d to them
# The defaults are chosen for accuracy (docs/engines.md, "MuJoCo's defaults and loopcheck's").
DEFAULT_INTEGRATOR = "rk4"
DEFAULT_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
DEFAULT_ITERATIONS = 100
DEFAULT_TOLERANCE = 1e-12


@dataclass(frozen=True)
class ModelOptions:
    """What changes a MuJoCo-family engine's answer through the model it runs; every such
    engine's settings extend it (and record it with every result).

    Parameters
    ----------
    integrator : one of ``INTEGRATORS``.
    timestep : s, finite and positive; None: the engine chooses it from the scene.
    solref : (time constant s, damping ratio), both finite and positive; None is
        (2·timestep, 1). MuJoCo's direct form (negative stiffness and damping) is not supported.
    solimp : (dmin, dmax, width, midpoint, power) with mjMINIMP ≤ dmin ≤ dmax ≤ mjMAXIMP
        (1e-4, 0.9999: MuJoCo clamps the impedance to that range), width > 0 (m),
        0 < midpoint < 1, power ≥ 1 (MuJoCo, "Solver parameters").
    iterations : int in [1, MAX_ITERATIONS].
    tolerance : solver tolerance, finite ≥ 0.
    refsafe, diagexact : MuJoCo's flags of those names.
    max_constraint_violation : m; a larger loop-closure gap fails the run (constraint drift).
    max_energy_residual : largest |energy residual| / energy scale a run may have, else it
        fails (energy imbalance).
    """

    integrator: str = option(DEFAULT_INTEGRATOR, "MuJoCo's integrator", "choice", choices=INTEGRATORS)
    timestep: float | None = option(None, "MuJoCo's timestep", "number", unit="s", limit="step",
                                    within_horizon=True, default_text="chosen from the scene")
    solref: tuple[float, float] | None = option(None, "the loop constraints' solref (time constant, damping ratio), "
                                                "both positive", "numbers", parts=("timeconst", "dampratio"),
                                                default_text="[2·timestep, 1]")
    solimp: tuple[float, float, float, float, float] = option(
        DEFAULT_SOLIMP, f"the loop constraints' solimp: {MIN_IMPEDANCE:g} ≤ dmin ≤ dmax ≤ {MAX_IMPEDANCE:g}, "
        "width > 0 (m), 0 < midpoint < 1, power ≥ 1", "numbers", parts=("dmin", "dmax", "width", "midpoint", "power"))
    iterations: int = option(DEFAULT_ITERATIONS, "constraint solver iterations", "whole", low=1, high=MAX_ITERATIONS)
    tolerance: float = option(DEFAULT_TOLERANCE, "constraint solver tolerance", "number")
    refsafe: bool = option(True, "MuJoCo's refsafe (it raises solref time constants below 2·timestep to 2·timestep)",
                           "bool")
    diagexact: bool = option(False, "MuJoCo's exact constraint-diagonal flag", "bool")
    max_constraint_violation: float = option(1e-3, "the largest loop-closure gap a run may have; beyond it the "
                                             "run fails as drifted", "number", unit="m")
    max_energy_residual: float = option(3e-3, "the largest |energy residual| / energy scale a run may have; "
                                        "beyond it the run fails", "number")

    def __post_init__(self) -> None:
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")
        if self.timestep is not None:
            if field_number(self.timestep, "timestep") <= 0.0:
                raise ValueError(f"timestep must be positive, got {self.timestep!r}")
        if self.solref is not None:
            if len(self.solref) != 2:
                raise ValueError(f"solref must be two numbers (time constant, damping ratio), got {self.solref!r}")
            for value, name in zip(self.solref, ("time constant", "damping ratio")):
                if field_number(value, f"solref {name}") <= 0.0:
                    raise ValueError(f"solref {name} must be positive (the direct negative form is not "
                                     f"supported), got {value!r}")
        if len(self.solimp) != 5:
            raise ValueError(f"solimp must be five numbers (dmin, dmax, width, midpoint, power), got {self.solimp!r}")
        dmin, dmax, width, midpoint, power = (field_number(v, f"solimp {n}") for v, n in
                                              zip(self.solimp, ("dmin", "dmax", "width", "midpoint", "power")))
        if not MIN_IMPEDANCE <= dmin <= dmax <= MAX_IMPEDANCE:
            raise ValueError(f"solimp dmin, dmax must satisfy {MIN_IMPEDANCE:g} ≤ dmin ≤ dmax ≤ "
                             f"{MAX_IMPEDANCE:g}, got {dmin!r}, {dmax!r}")
        if not width > 0.0:
            raise ValueError(f"solimp width must be positive, got {width!r}")
        if not 0.0 < midpoint < 1.0:
            raise ValueError(f"solimp midpoint must be in (0, 1), got {midpoint!r}")
        if not power >= 1.0:
            raise ValueError(f"solimp power must be at least 1, got {power!r}")
        if (isinstance(self.iterations, bool) or not isinstance(self.iterations, Integral)
                or not 1 <= self.iterations <= MAX_ITERATIONS):
            raise ValueError(f"iterations must be a whole number in [1, {MAX_ITERATIONS}], got {self.iterations!r}")
        if field_number(self.tolerance, "tolerance") < 0.0:
            raise ValueError(f"tolerance must be at least 0, got {self.tolerance!r}")
        for name in ("refsafe", "diagexact"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")
        for name in ("max_constraint_violation", "max_energy_residual"):
            if field_number(getattr(self, name), name) <= 0.0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)!r}")

    @property
    def automatic(self) -> bool:
        """True when the timestep is chosen from the scene."""
        return self.timestep is None

    @property
    def effective_solref(self) -> tuple[float, float] | None:
        """The loop's solref (s, 1); follows the timestep. None while the timestep is automatic
        and solref is not given (a run records the one it used in ``result.settings``)."""
        if self.solref is not None:
            return tuple(self.solref)
        return None if self.timestep is None else (2.0 * self.timestep, 1.0)

    def as_dict(self) -> dict:
        d = asdict(self)
        solref = self.effective_solref
        d["solref"] = None if solref is None else list(solref)
        d["solimp"] = list(self.solimp)
        return d


# The accuracy ladders of `loopcheck cost` for the engines of this family (their settings modules'
# accuracy_ladder; loopcheck.registry.Engine.ladder).
SWEEP_VIOLATION_LIMIT = 0.1  # m: a ladder measures soft constraints rather than rejecting them
SWEEP_ENERGY_LIMIT = 1.0  # of the energy scale: likewise for first-order integrators' energy error
HARD = {"solref": None, "solimp": DEFAULT_SOLIMP}  # solref (2·timestep, 1): loopcheck's default
MUJOCO_DEFAULT_SOFTNESS = {"solref": (0.02, 1.0), "solimp": (0.9, 0.95, 0.001, 0.5, 2.0)}
SOFTNESS = {"hard": HARD, "mujoco-default": MUJOCO_DEFAULT_SOFTNESS}


def fixed_step_ladder(base, name: str, integrators, softnesses, timesteps) -> list:
    """Rungs of ``base`` (a ModelOptions: the scene's settings) at each integrator × softness
    (:data:`SOFTNESS`' keys) × timestep (s), series ``"NAME INTEGRATOR (SOFTNESS)"``. Each runs with
    the ladder's loose limits (:data:`SWEEP_VIOLATION_LIMIT`, :data:`SWEEP_ENERGY_LIMIT`), so that
    it is measured where ``loopcheck run`` refuses it; its verdict is run's, at ``base``'s limits."""
    from dataclasses import replace

    from loopcheck.registry import Rung

    rungs = []
    for integrator in integrators:
        for softness in softnesses:
            for h in timesteps:
                point = replace(base, integrator=integrator, timestep=h, **SOFTNESS[softness])
                loose = replace(point, max_constraint_violation=SWEEP_VIOLATION_LIMIT,
                                max_energy_residual=SWEEP_ENERGY_LIMIT)
                rungs.append(Rung(f"{name} {integrator} ({softness})", h, loose, "h", run_settings=point))
    return rungs


# What the MuJoCo-family engines (MuJoCo C, MJX, MJWarp) declare for the studies
# (loopcheck.registry.Engine's optional declarations; each engine's settings module names them).

PROBE_TIMESTEPS = (1e-3, 1e-4, 1e-5)  # s: ``loopcheck stress``'s integrator × timestep probes


def integrator_probes(base: ModelOptions, integrators: tuple[str, ...] = INTEGRATORS,
                      timesteps: tuple[float, ...] = PROBE_TIMESTEPS) -> tuple:
    """``stress_probes``: ``base`` (the scene's settings) at each of ``integrators`` and each of
    ``timesteps``, one :class:`loopcheck.registry.Rung` each (series the integrator, parameter the
    step): ``loopcheck stress`` reports the status of each where a case asks for its probes."""
    from dataclasses import replace

    from loopcheck.registry import Rung

    return tuple(Rung(integrator, h, replace(base, integrator=integrator, timestep=h))
                 for integrator in integrators for h in timesteps)


def grid_step(settings: ModelOptions) -> float | None:
    """``fixed_step``: the timestep, every step of the run on its grid (None while the engine has
    still to choose it: a run's ``result.settings`` has it)."""
    return None if settings.timestep is None else float(settings.timestep)
