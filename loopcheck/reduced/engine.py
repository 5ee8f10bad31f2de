"""The reduced engine's entry point: scene in, :class:`EngineResult` out."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from .dynamics import MechanismModel, clamped_actuators
from .energy import energy_audit
from loopcheck.errors import FailureReason, NumericalFailure
from .integrators import solve_adaptive
from .kernels.fixed_step import RKN4
from .charts import PartitionedSolution, Switch, integrate_dop853, integrate_partitioned, integrate_rkn4
from .settings import ReducedSettings
from loopcheck.results import EngineResult
from loopcheck.scene import Scene
from loopcheck.trajectory import Trajectory

_log = logging.getLogger("loopcheck.reduced")  # a run's cost, at DEBUG (`loopcheck --verbose`)

# Work refused up front. Measured: a sample costs ~100 µs (RKN4 on the seed: integration,
# joint angles, energy audit; DOP853 on long_conservative: 142 000 samples in 14 s) and
# ~0.7 kB of memory (long_conservative peaks at 180 MB, 77 MB of it the imports). 5e5
# samples (≈ 1 min, ≈ 0.4 GB) is the most a run may hold. An adaptive run's samples beyond
# its grid (4 per solver step) are bounded by integrators.MAX_EVALUATIONS.
MAX_SAMPLES = 500_000

# Energy balance: relative residual allowed, as a multiple of the run's rtol. Adaptive runs
# of every shipped scene at their own rtol measure 8–140 × rtol (seed 12, dead_centre 70,
# fast_crank 104, long_conservative 141, stiff_damper 29); 1000 × rtol leaves 7× above the
# worst. RKN4 on the seed (0.25–4 ms, over 0.7 s and 2 s): residual ≤ 1.2 × its own error
# estimate, so a run that meets rtol balances to ~1.2 rtol; 10 × rtol leaves 8×.
ENERGY_FACTOR = {"dop853": 1000.0, "scipy-dop853": 1000.0, "radau": 1000.0, "rkn4": 10.0}
# Below ~1e-9 the audit itself is the limit, not the integration: on random four-bars that
# start near a dead centre (many coordinate switches), DOP853 at rtol 1e-12 leaves 1.2e-9 and
# 1.5e-9 of the energy, and 3.9e-9 at 1e-11 — the residual stops falling with rtol. The bound
# is therefore never tighter than ENERGY_FLOOR (6.5x the worst of those); a dropped term
# (a damper's dissipation) shows as ~1e-2.
ENERGY_FLOOR = 1e-8


SCIPY_NAMES = {"scipy-dop853": "DOP853", "radau": "Radau"}  # the methods run by scipy's solve_ivp

# Caps on the adaptive step (fractions of a chart's time span) for a chart that failed at a
# singular position. Measured: they get a fast triple rocker through (a regression test); on
# 100 random near-dead-centre scenes they changed nothing. The compiled DOP853 applies them in
# compiled code (loopcheck.reduced.kernels.partition); scipy's methods here.
CHART_RETRY_MAX_STEP = (1e-3, 1e-4)


def scipy_chart_integrator(settings: ReducedSettings, breakpoints: tuple[float, ...]):
    """The scipy method the settings name (radau, scipy-dop853), as a function of one chart's
    equation."""
    method = SCIPY_NAMES[settings.method]

    def run(rhs_on_piece, span, x0, v0, stop):
        # A trial stage of a long step can land past the reach of the chart's coordinate
        # (no closed loop there: a singular position) before the switch event fires. The
        # chart is then integrated again with the step capped to a fraction of its span.
        for cap in (math.inf, *CHART_RETRY_MAX_STEP):
            try:
                return solve_adaptive(rhs_on_piece, span, x0, v0, rtol=settings.rtol, method=method,
                                      breakpoints=breakpoints, sample_interval=settings.sample_interval,
                                      stop=stop, max_step=cap * (span[1] - span[0]))
            except NumericalFailure as exc:
                if exc.reason is not FailureReason.SINGULAR or cap == CHART_RETRY_MAX_STEP[-1]:
                    raise
    return run


def integrate(model: MechanismModel, settings: ReducedSettings, step: float | None = None,
              summary: bool = False) -> PartitionedSolution:
    """Run the integrator the settings name, switching coordinates at dead centres (``step``
    overrides the RKN4 step: the error estimate's runs at twice and half the step; ``summary``:
    the compiled DOP853 sampled for the summaries only, :func:`simulate`)."""
    if settings.method == "rkn4":
        return integrate_rkn4(model, settings.step if step is None else step)
    if settings.method == "dop853":
        return integrate_dop853(model, settings.rtol, settings.sample_interval, CHART_RETRY_MAX_STEP, summary)
    return integrate_partitioned(model, scipy_chart_integrator(settings, model.load_edges))


def check_work(scene: Scene, settings: ReducedSettings) -> None:
    """Refuse, before any work, a run the settings cannot do: one that would hold more than
    ``MAX_SAMPLES`` samples, or joint friction, ranges or a clamp of a state-dependent force with a
    method of scipy's (their events are the compiled core's).

    Raises
    ------
    ValueError
        Naming the setting or scene key to change.
    """
    mech = scene.mechanism
    if scene.dof > 1:  # imported here: a one-DOF run loads nothing of the several-DOF engine
        from .several import check_scene

        check_scene(scene)  # (its ranges are an event of every method, its clamps and friction refused)
    events = [e.name for e in mech.joint_frictions] + [j.name for j in mech.linkage.joints if j.range is not None]
    if scene.dof == 1 and events and settings.method not in ("dop853", "rkn4"):
        raise ValueError(f"the reduced engine's method {settings.method} does not run joint friction or joint "
                         f"ranges ({', '.join(events)}): their events are the compiled core's; use method dop853 "
                         "or rkn4")
    clamped = [a.name for a in clamped_actuators(mech)]
    if scene.dof == 1 and clamped and settings.method not in ("dop853", "rkn4"):
        raise ValueError(f"the reduced engine's method {settings.method} does not run a forcerange clamp on a "
                         f"force that depends on the state (actuator {', '.join(map(repr, clamped))}): its "
                         "switching is an event of the compiled core; use method dop853 or rkn4")
    horizon, edges = scene.horizon, len(scene.load_edges)
    if settings.method == "rkn4":
        samples = horizon / settings.step + 2 * edges
        if samples > MAX_SAMPLES:
            raise ValueError(
                f"an RKN4 run of {horizon:g} s at step {settings.step:g} s needs {samples:.3g} steps "
                f"(the limit is {MAX_SAMPLES:.0e}): increase `step` (`--step`, `[reduced] step`) to at least "
                f"{horizon / MAX_SAMPLES:.3g} s or shorten `simulation.horizon`")
    else:
        samples = horizon / settings.sample_interval
        if samples > MAX_SAMPLES:
            key = ("`sample_interval`" if "sample_interval" in settings.given else "`simulation.horizon`")
            raise ValueError(
                f"a run of {horizon:g} s sampled every {settings.sample_interval:g} s needs {samples:.3g} "
                f"samples (the limit is {MAX_SAMPLES:.0e}): shorten {key}"
                + (" or increase `sample_interval`" if key == "`simulation.horizon`" else ""))


@dataclass(frozen=True)
class ErrorEstimate:
    """RKN4's step-doubling estimate of its own global error, and what it is judged against.

    q_abs (rad), qdot_abs (rad/s): largest |y_h − y_2h| / (2⁴ − 1) on the run at 2h's
    samples (or 2⁴ |y_h − y_h/2| / (2⁴ − 1) on h's when the run at 2h is unstable); q_scale (rad), qdot_scale (rad/s): the run's largest |q|, |q̇|, at least 1;
    relative: the larger of q_abs/q_scale and qdot_abs/qdot_scale; tolerance: rtol.
    """

    q_abs: float
    qdot_abs: float
    q_scale: float
    qdot_scale: float
    tolerance: float
    step: float
    wall_s: float
    unit: str = "rad"  # of q (the keys of as_dict keep their historical "_rad" names)

    method = "step doubling (Richardson, order 4)"

    @property
    def relative(self) -> float:
        return max(self.q_abs / self.q_scale, self.qdot_abs / self.qdot_scale)

    def as_dict(self) -> dict:
        return {"q_abs_rad": self.q_abs, "qdot_abs_rad_per_s": self.qdot_abs, "q_scale_rad": self.q_scale,
                "qdot_scale_rad_per_s": self.qdot_scale, "relative": self.relative,
                "tolerance": self.tolerance, "method": self.method,
                "step_s": self.step, "wall_s": self.wall_s, "unit": self.unit}


def richardson_estimate(fine: Trajectory, coarse: Trajectory, weight: float) -> tuple[float, float]:
    """weight × the largest |q_fine − q_coarse| and |q̇_fine − q̇_coarse| over the coarse
    run's sample times (the fine run interpolated there)."""
    times, idx = np.unique(coarse.t, return_index=True)
    q, v, _ = fine.interpolate(times)
    return (weight * float(np.max(np.abs(q - coarse.q[idx]))),
            weight * float(np.max(np.abs(v - coarse.qdot[idx]))))


def estimate_error(model: MechanismModel, settings: ReducedSettings, solution: PartitionedSolution) -> ErrorEstimate:
    """RKN4's global error by step doubling: the same partitioned run at twice the step
    (error of y_h ≈ (y_h − y_2h)/15). If the run at 2h fails (outside the stability
    region), at half the step instead (error of y_h ≈ 16 (y_h − y_h/2)/15)."""
    start = time.perf_counter()
    fine = solution.trajectory
    factor = 2.0 ** RKN4.order
    try:
        coarse = integrate(model, settings, step=2.0 * settings.step).trajectory
        q_abs, v_abs = richardson_estimate(fine, coarse, 1.0 / (factor - 1.0))
    except NumericalFailure:
        try:
            finer = integrate(model, settings, step=0.5 * settings.step).trajectory
            q_abs, v_abs = richardson_estimate(finer, fine, factor / (factor - 1.0))
        except NumericalFailure as exc:
            if settings.check_error:
                raise NumericalFailure(
                    "inaccurate", f"RKN4's error estimate needs the same run at half the step "
                    f"({settings.step / 2:g} s), which failed ({exc.reason}: {exc}); use a smaller step "
                    "(`--step`, `[reduced] step`)", exc.time) from None
            q_abs = v_abs = math.nan
    return ErrorEstimate(q_abs, v_abs, max(1.0, float(np.max(np.abs(fine.q)))),
                         max(1.0, float(np.max(np.abs(fine.qdot)))), settings.rtol, settings.step,
                         time.perf_counter() - start, model.scene.input_unit)


def simulate(scene: Scene, settings: ReducedSettings = ReducedSettings(), *, summary: bool = False) -> EngineResult:
    """Solve the scene's Eksergian equation, estimate its error and audit its energy.

    ``summary`` (a sweep's reduced-only rows, :mod:`loopcheck.compare.sweep`): a run whose
    summaries alone are kept (the peak, its time, the energy residual, the steps, the status).
    With the compiled DOP853 (the default method) its samples are the solver's step ends, cut as
    usual only in the steps beside each local maximum of |q̇| over the steps
    (:func:`loopcheck.reduced.charts.integrate_dop853`): the full run's peak and steps to
    round-off (its chart walks to fewer positions, and the steps follow the last bits of where a
    load piece starts: tests/reduced/test_summary_runs.py states the bounds), the energy audited at
    the step ends (the flows are the solver's own there) instead of at every sample. q̈ is
    evaluated only at the samples cut beside the peaks (about 140 on the seed at rtol 1e-12)
    instead of at least four a step (a step end's is its last stage's), and the dense output
    (3 evaluations a step) is made only for the steps cut and a step the stop event needs: on
    the seed at rtol 1e-12, 9 187 evaluations where a full run makes 10 864 and 2 887 more at
    its samples. Its trajectory holds those samples only and it has no joints' trajectory
    (``joints`` is None: neither their assembly modes, 0.14 ms of a seed variant's 4 ms, nor
    their rates are made): not for plots or comparisons; ``n_evaluations`` counts what it
    evaluated. Other methods ignore it.

    Returns
    -------
    EngineResult
        ``engine="reduced"``; ``wall_s`` times the integration only (not the loading of its
        compiled code, nor RKN4's error estimate, whose time is in it); ``settings`` are the
        resolved settings; ``details`` (:class:`ReducedDetails`) hold the coordinate switches,
        RKN4's error estimate, the energy bound and the scale it is relative to.

    Raises
    ------
    ValueError
        If the run would need more than ``MAX_SAMPLES`` samples (refused before any work).
    NumericalFailure
        If the integration blows up, leaves the stability region, becomes non-finite,
        reaches a position no coordinate can drive, or its step collapses; and, with
        ``settings.check_error``, if RKN4's error estimate exceeds rtol (INACCURATE) or the
        energy balance does not close within its bound (ENERGY_IMBALANCE).
    """
    if scene.dof > 1:  # Eksergian's reduction in several coordinates (loopcheck.reduced.several)
        return simulate_several(scene, settings)
    check_work(scene, settings)
    model = MechanismModel(scene)
    start = time.perf_counter()
    solution = integrate(model, settings, summary=summary)
    wall = time.perf_counter() - start
    _log.debug("reduced %s on %s: %d steps, %d evaluations of q̈, %.3g s", solution.method, scene.name,
               solution.n_steps, solution.n_evaluations, wall)
    trajectory = solution.trajectory
    estimate = None
    if settings.method == "rkn4":
        estimate = estimate_error(model, settings, solution)
        unit = scene.input_unit
        if settings.check_error and not estimate.relative <= settings.rtol:
            raise NumericalFailure(
                "inaccurate", f"RKN4 at step {settings.step:g} s estimates its own error (step doubling) at "
                f"{estimate.relative:.2e} of the run's scale ({estimate.q_abs:.2e} {unit} in q, "
                f"{estimate.qdot_abs:.2e} {unit}/s in q̇ at speeds up to {estimate.qdot_scale:.4g} {unit}/s), above "
                f"the tolerance rtol = {settings.rtol:g}: use a smaller step (`--step`, `[reduced] step`; about "
                f"{settings.step * (settings.rtol / estimate.relative / 2) ** 0.25:.2g} s) or a looser rtol")
    audit = energy_audit(model, solution)
    bound = max(ENERGY_FACTOR[settings.method] * settings.rtol, ENERGY_FLOOR)
    scale = energy_scale(audit, solution)
    if settings.check_error and not audit.max_abs_residual <= bound * scale:
        raise NumericalFailure(
            "energy-imbalance", f"the energy balance does not close: residual {audit.max_abs_residual:.3e} J, "
            f"{audit.max_abs_residual / scale:.2e} of the run's {scale:.4g} J, above the bound {bound:.1e} "
            f"(the larger of {ENERGY_FACTOR[settings.method]:g} × rtol and {ENERGY_FLOOR:g}): use a tighter rtol"
            + (" or a smaller step (`--step`, `[reduced] step`)" if settings.method == "rkn4" else ""))
    details = ReducedDetails(solver=solution.method, switches=tuple(solution.switches), error_estimate=estimate,
                             energy_bound=bound, energy_scale=scale, friction_events=solution.friction_events,
                             clamp_events=solution.clamp_events)
    return EngineResult(
        engine="reduced", trajectory=trajectory, joints=solution.joints, peak=trajectory.peak_rate(),
        audit=audit, wall_s=wall, n_steps=solution.n_steps, n_evaluations=solution.n_evaluations,
        settings=settings, effects=tuple(model.effects), details=details)


def estimate_error_several(scene: Scene, settings: ReducedSettings, run) -> ErrorEstimate:
    """RKN4's global error by step doubling on a scene of several DOF, as :func:`estimate_error` on
    one: the same run at twice the step (or at half the step where that one fails), every input
    compared at the coarser run's samples; the largest over the inputs (q_scale, qdot_scale: the
    run's largest |q|, |q̇| over the inputs, each at least 1; the unit the inputs', "rad/m" where
    they mix)."""
    from .several import run_several

    start = time.perf_counter()
    factor = 2.0 ** RKN4.order
    fine = [tr for tr, _ in run.inputs]

    def largest(pairs, weight):
        found = [richardson_estimate(a, b, weight) for a, b in pairs]
        return max(q for q, _ in found), max(v for _, v in found)

    try:
        coarse = [tr for tr, _ in run_several(scene, settings, step=2.0 * settings.step).inputs]
        q_abs, v_abs = largest(zip(fine, coarse), 1.0 / (factor - 1.0))
    except NumericalFailure:
        try:
            finer = [tr for tr, _ in run_several(scene, settings, step=0.5 * settings.step).inputs]
            q_abs, v_abs = largest(zip(finer, fine), factor / (factor - 1.0))
        except NumericalFailure as exc:
            if settings.check_error:
                raise NumericalFailure(
                    "inaccurate", f"RKN4's error estimate needs the same run at half the step "
                    f"({settings.step / 2:g} s), which failed ({exc.reason}: {exc}); use a smaller step "
                    "(`--step`, `[reduced] step`)", exc.time) from None
            q_abs = v_abs = math.nan
    units = sorted(set(scene.input_units()))
    return ErrorEstimate(q_abs, v_abs, max(1.0, max(float(np.max(np.abs(tr.q))) for tr in fine)),
                         max(1.0, max(float(np.max(np.abs(tr.qdot))) for tr in fine)), settings.rtol, settings.step,
                         time.perf_counter() - start, "/".join(units))


def simulate_several(scene: Scene, settings: ReducedSettings) -> EngineResult:
    """A scene of several DOF (:mod:`loopcheck.reduced.several`): its run, RKN4's error estimate
    (:func:`estimate_error_several`), gated on it and on its energy balance as :func:`simulate`
    gates a one-DOF run (the energy scale's floor ½ max diag 𝔍0 (1 rad/s)²)."""
    from .several import run_several

    check_work(scene, settings)
    run = run_several(scene, settings)
    estimate = None
    if settings.method == "rkn4":
        estimate = estimate_error_several(scene, settings, run)
        if settings.check_error and not estimate.relative <= settings.rtol:
            raise NumericalFailure(
                "inaccurate", f"RKN4 at step {settings.step:g} s estimates its own error (step doubling) at "
                f"{estimate.relative:.2e} of the run's scale ({estimate.q_abs:.2e} {estimate.unit} in the inputs' "
                f"q, {estimate.qdot_abs:.2e} {estimate.unit}/s in their q̇ at speeds up to "
                f"{estimate.qdot_scale:.4g} {estimate.unit}/s), above the tolerance rtol = {settings.rtol:g}: use a "
                f"smaller step (`--step`, `[reduced] step`; about "
                f"{settings.step * (settings.rtol / estimate.relative / 2) ** 0.25:.2g} s) or a looser rtol")
    audit = run.audit
    bound = max(ENERGY_FACTOR[settings.method] * settings.rtol, ENERGY_FLOOR)
    scale = max(audit.scale, run.kinetic_scale)
    if settings.check_error and not audit.max_abs_residual <= bound * scale:
        raise NumericalFailure(
            "energy-imbalance", f"the energy balance does not close: residual {audit.max_abs_residual:.3e} J, "
            f"{audit.max_abs_residual / scale:.2e} of the run's {scale:.4g} J, above the bound {bound:.1e} "
            f"(the larger of {ENERGY_FACTOR[settings.method]:g} × rtol and {ENERGY_FLOOR:g}): use a tighter rtol"
            + (" or a smaller step (`--step`, `[reduced] step`)" if settings.method == "rkn4" else ""))
    details = ReducedDetails(solver=run.solver, switches=run.switches, error_estimate=estimate, energy_bound=bound,
                             energy_scale=scale, friction_events=run.friction_events)
    (first, peak), *others = run.inputs
    return EngineResult(engine="reduced", trajectory=first, joints=run.joints, peak=peak, audit=audit,
                        wall_s=run.wall_s, n_steps=run.n_steps, n_evaluations=run.n_evaluations, settings=settings,
                        effects=tuple(scene.effects), details=details, other_inputs=tuple(others))


@dataclass(frozen=True)
class ReducedDetails:
    """The reduced engine's own record of a run (:attr:`EngineResult.details`).

    solver : the integrator that ran ("DOP853", "RKN4", scipy's "Radau", ...).
    switches : each change of independent coordinate at a dead centre, in time order.
    error_estimate : RKN4's step-doubling estimate of its own error; None for the adaptive methods.
    energy_bound : the largest relative energy residual the run may have.
    energy_scale : J, what the residual is relative to (:func:`energy_scale`).
    friction_events : each change of the joint friction between stick and slip, in time order.
    clamp_events : each change of an actuator's forcerange clamp (free, upper, lower), in time order.
    """

    solver: str
    switches: tuple[Switch, ...]
    error_estimate: ErrorEstimate | None
    energy_bound: float
    energy_scale: float
    friction_events: tuple = ()
    clamp_events: tuple = ()

    def as_dict(self) -> dict:
        return {"solver": self.solver, "switches": [asdict(s) for s in self.switches],
                "error_estimate": None if self.error_estimate is None else self.error_estimate.as_dict(),
                "energy_bound": self.energy_bound, "energy_scale_J": self.energy_scale,
                "friction_events": [asdict(e) for e in self.friction_events],
                "clamp_events": [asdict(e) for e in self.clamp_events]}


def energy_scale(audit, solution: PartitionedSolution) -> float:
    """The energy (J) the gate's relative residual is measured against: the audit's scale
    (largest |W_torque|, T, |V − V0|), but at least the kinetic energy ½ 𝔍0 (1 rad/s or 1 m/s)² of the
    initial configuration at unit speed, so that a run in which almost nothing moves (a pulse
    of 1e-12 s, a 1e30 kg coupler: scales of 1e-21 J and less) is judged by round-off, not by a
    relative figure of nothing. The floor is the same as the error estimate's |q̇| ≥ 1 rad/s.
    𝔍0 is the one the run started from (:attr:`PartitionedSolution.start_inertia`)."""
    return max(audit.scale, 0.5 * abs(solution.start_inertia))

