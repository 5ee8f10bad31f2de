"""The automatic MuJoCo timestep: the first candidate (:func:`grid_timestep`) and the search by
step halving that confirms or refines it (:func:`search_timestep`; the rule is in
:func:`loopcheck.reference_models.run.simulate_mujoco`'s docstring). The search judges runs; making
them is the caller's (``attempt``), so this module imports nothing of the run."""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.results import EngineResult
from loopcheck.mujoco_model.steps import step_count
from loopcheck.scene import Scene

_log = logging.getLogger("loopcheck.mujoco")  # progress of the automatic step search

# Automatic timestep: the first candidate is the grid step (loopcheck.mujoco_model.steps.grid_timestep);
# a run at h and one at h/2 must differ by at most HALVING_FRACTION of the tolerances. The first
# failing check halves h; after two, the search jumps to the halving of the first step that the
# fitted order predicts (with the margin STEP_MARGIN), and it stops only when a check would take
# it past MAX_SEARCH_STEPS steps in all (a Stephenson six-bar near its toggle needs 7.8e-6 s, a
# check of 96 000 steps).
HALVING_FRACTION = 0.25
STEP_MARGIN = 0.85
MIN_ORDER = 0.5
MAX_SEARCH_STEPS = 5_000_000


def search_timestep(scene: Scene, h0: float, attempt: Callable[[float], EngineResult | NumericalFailure],
                    fits: Callable[[float], bool]) -> EngineResult:
    """The automatic step search of :func:`loopcheck.reference_models.run.simulate_mujoco` (its
    docstring says the rule) from the first candidate ``h0`` (:func:`grid_timestep`): ``attempt(h)``
    runs the model at step h, returning a numerical failure rather than raising it; ``fits(h)``
    says whether a run at h is within the run's work limits. Returns the accepted check's finer
    run, its details with the checks and the search's cost."""
    tol = scene.tolerances
    evidence: list[TimestepCheck] = []
    runs: list[EngineResult | NumericalFailure] = []

    def attempted(h: float) -> EngineResult | NumericalFailure:
        runs.append(attempt(h))
        return runs[-1]

    h = h0
    coarse = attempted(h)
    while True:
        if not fits(h / 2) or _search_steps(runs) + step_count(scene, h / 2) > MAX_SEARCH_STEPS:
            raise _search_failure(scene, coarse, evidence, runs, h, None)
        fine = attempted(h / 2)
        record = _confirm_after_failure(evidence, _check(scene, tol, h, coarse, fine))
        evidence.append(record)
        if record.accepted:
            done = [r for r in runs if isinstance(r, EngineResult)]
            cost = SearchCost(len(runs), sum(r.n_steps for r in done), sum(r.wall_s for r in done))
            return replace(fine, details=replace(fine.details, timestep_automatic=True,
                                                 timestep_checks=tuple(evidence), search_cost=cost))
        wanted, order = _predicted_step(evidence)
        if order is not None:
            record = evidence[-1] = replace(record, order=order)
        # the next check's coarse step: the largest halving of h0 at or below the prediction
        # (load edges stay on the grid), and at least one halving finer than this check's
        halvings = max(round(math.log2(h0 / h)) + 1,
                       math.ceil(math.log2(h0 / wanted) - 1e-9) if wanted is not None else 0)
        step = h0 / 2 ** halvings
        needed = step_count(scene, step) * (3 if step < h / 2 else 2)  # a new coarse run too, or the fine one reused
        if (not fits(step / 2)
                or _search_steps(runs) + needed > MAX_SEARCH_STEPS):
            raise _search_failure(scene, coarse if step == h / 2 else fine, evidence, runs, h, wanted)
        _log.info("MuJoCo timestep %.4g s against %.4g s: %s; %s", h, h / 2, _describe(record),
                  f"next check at {step:.4g} s ({step_count(scene, step / 2):,} steps)"
                  + (f", from the fitted order {record.order:.2g}" if order is not None else ""))
        coarse, h = (fine, h / 2) if step == h / 2 else (attempted(step), step)


class CheckOutcome(enum.Enum):
    """How one check of the automatic step search ended."""

    ACCEPTED = "accepted"  # the differences met their limits: the search stops at this check
    EXCEEDED = "exceeded"  # a difference above its limit: the search goes finer
    UNCONFIRMED = "unconfirmed"  # within the limits right after a failed check: one halving more
    FAILED = "failed"  # a run of the check failed (loop drift, energy imbalance, instability)


@dataclass(frozen=True)
class MeasuredCheck:
    """A check whose two runs (at ``timestep`` and its half) both ran: their differences against
    HALVING_FRACTION of the tolerances.

    timestep : s, the coarse step.
    unit : the input coordinate's unit, "rad" or "m"; the differences are in it (rates per s).
    max_dq, max_domega, dpeak : max |Δq|, max |Δq̇| on the coarse grid and |Δ peak q̇|.
    limits : the three differences' limits, in the same order and units.
    outcome : ACCEPTED, EXCEEDED or UNCONFIRMED.
    order : the order fitted from this check and the measured one before it, when the search
        jumped by it to its next step; None otherwise.
    inputs, units : with several inputs, the input each of the three differences is of (the one
        nearest its limit, :func:`_check`) and its unit ("rad" or "m"); empty with one input, whose
        unit is ``unit``.
    """

    timestep: float
    unit: str
    max_dq: float
    max_domega: float
    dpeak: float
    limits: tuple[float, float, float]
    outcome: CheckOutcome
    order: float | None = None
    inputs: tuple[str, ...] = ()
    units: tuple[str, ...] = ()

    def __post_init__(self):
        if self.inputs and (len(self.inputs) != 3 or len(self.units) != 3):
            raise ValueError(f"a check names the input and unit of each of its three differences, not "
                             f"{len(self.inputs)} and {len(self.units)}")
        if self.outcome is CheckOutcome.FAILED:
            raise ValueError("a measured check's outcome cannot be FAILED (that is a FailedCheck)")
        if len(self.limits) != 3:
            raise ValueError(f"a check has three limits (q, q̇, peak), not {len(self.limits)}")

    @property
    def accepted(self) -> bool:
        return self.outcome is CheckOutcome.ACCEPTED

    @property
    def differences(self) -> tuple[float, float, float]:
        return self.max_dq, self.max_domega, self.dpeak

    def as_dict(self) -> dict:
        """report.json's record of the check (``details.timestep_check``)."""
        out = {"timestep": self.timestep, "unit": self.unit, "max_dq": self.max_dq, "max_domega": self.max_domega,
               "dpeak": self.dpeak, "limits": list(self.limits), "accepted": self.accepted}
        if self.outcome is CheckOutcome.UNCONFIRMED:
            out["unconfirmed"] = True
        if self.order is not None:
            out["order"] = self.order
        if self.inputs:
            out["inputs"], out["units"] = list(self.inputs), list(self.units)
        return out


@dataclass(frozen=True)
class FailedCheck:
    """A check one of whose runs failed: ``failure`` is its reason and message."""

    timestep: float  # s, the coarse step
    unit: str
    failure: str

    @property
    def outcome(self) -> CheckOutcome:
        return CheckOutcome.FAILED

    @property
    def accepted(self) -> bool:
        return False

    def as_dict(self) -> dict:
        """report.json's record of the check (``details.timestep_check``)."""
        return {"timestep": self.timestep, "unit": self.unit, "failure": self.failure, "accepted": False}


TimestepCheck = MeasuredCheck | FailedCheck  # one check of the automatic step search


def _check(scene: Scene, tol, h: float, coarse, fine) -> TimestepCheck:
    """The record of one check: runs at h and h/2 compared against HALVING_FRACTION of the
    tolerances (or the failure of either run). With several inputs every input is judged, each in
    its own unit against the same tolerances (a value is read in each input's unit, rad or m, as
    for one input), and the record keeps, for each of the three differences, the input nearest its
    limit (the largest difference / limit), named in ``inputs``."""
    if isinstance(coarse, NumericalFailure) or isinstance(fine, NumericalFailure):
        failed = coarse if isinstance(coarse, NumericalFailure) else fine
        return FailedCheck(h, scene.input_unit, f"{failed.reason.value}: {failed}")
    per_input = []
    for k, (unit, (_, peak)) in enumerate(zip(scene.input_units(), fine.inputs)):
        limits = (HALVING_FRACTION * tol.q_atol, HALVING_FRACTION * tol.omega_atol,
                  HALVING_FRACTION * tol.peak_bound(abs(peak.omega)))
        per_input.append((_halving_difference(coarse, fine, k), limits, unit))
    if len(per_input) == 1:
        (dq, dw, dpeak), limits, _ = per_input[0]
        names: tuple[str, ...] = ()
        units: tuple[str, ...] = ()
    else:  # each difference from the input nearest its limit
        worst = [max(range(len(per_input)), key=lambda k, j=j: per_input[k][0][j] / per_input[k][1][j])
                 for j in range(3)]
        dq, dw, dpeak = (per_input[k][0][j] for j, k in enumerate(worst))
        limits = tuple(per_input[k][1][j] for j, k in enumerate(worst))
        names = tuple(scene.inputs[k] for k in worst)
        units = tuple(per_input[k][2] for k in worst)
    met = all(d <= lim for d, lim in zip((dq, dw, dpeak), limits))
    return MeasuredCheck(h, scene.input_unit, dq, dw, dpeak, limits,
                         CheckOutcome.ACCEPTED if met else CheckOutcome.EXCEEDED, inputs=names, units=units)


def _confirm_after_failure(evidence: list[TimestepCheck], record: TimestepCheck) -> TimestepCheck:
    """A check that meets its limits right after a check whose run failed (loop drift, energy
    imbalance, instability) is not accepted alone: its coarse step is at the edge of where
    MuJoCo's run works, where the differences of one halving need not fall as the step does
    (measured on a fast crank: 1.25e-4 s against 6.25e-5 s differ by < 0.125 rad/s while each
    is 1.6 rad/s off the converged run, and 6.25e-5 s against 3.125e-5 s by 1.2 rad/s). Such a
    record is returned ``UNCONFIRMED`` and the search halves once more: the next check, measured
    after a measured one, is accepted on its own limits."""
    if record.accepted and evidence and isinstance(evidence[-1], FailedCheck):
        return replace(record, outcome=CheckOutcome.UNCONFIRMED)
    return record


def _predicted_step(evidence: list[TimestepCheck]) -> tuple[float | None, float | None]:
    """The coarse step (s) at which the differences would meet their limits, from the last two
    checks, and the order fitted: each difference falls as h^p with the order p fitted between
    them (the loop's softness follows the step, so p is not RK4's 4: measured 1.9–4 on the
    six-bars). (None, None) before two measured checks, or when no difference falls (p <
    MIN_ORDER): then the search halves. The prediction is taken with the margin STEP_MARGIN;
    the order is the smallest of those fitted."""
    measured = [r for r in evidence if isinstance(r, MeasuredCheck)]
    if len(measured) < 2 or measured[-1] is not evidence[-1]:
        return None, None
    prev, last = measured[-2], measured[-1]
    steps, orders = [], []
    for d1, d2, limit in zip(prev.differences, last.differences, last.limits):
        if d2 <= limit:
            continue
        if not (d1 > 0.0 and d2 > 0.0 and d1 > d2):
            return None, None
        p = math.log(d1 / d2) / math.log(prev.timestep / last.timestep)
        if p < MIN_ORDER:
            return None, None
        orders.append(p)
        steps.append(last.timestep * (limit / d2) ** (1.0 / p))
    if not steps:
        return None, None
    return STEP_MARGIN * min(steps), min(orders)


def _search_steps(runs) -> int:
    """Steps the search has taken so far (a failed run counts its whole grid)."""
    return sum(r.n_steps if isinstance(r, EngineResult) else 0 for r in runs)


def _search_failure(scene: Scene, coarse, evidence: list[TimestepCheck], runs, h: float,
                    wanted: float | None) -> NumericalFailure:
    """Why the automatic search stops at coarse step h: the step the tolerances need (when
    fitted) and its cost against the work limits."""
    if isinstance(coarse, NumericalFailure) and not evidence:
        return NumericalFailure(coarse.reason, f"{coarse} (at the first automatic MuJoCo timestep {h:g} s)",
                                coarse.time)
    last = evidence[-1] if evidence else None
    done = [r for r in runs if isinstance(r, EngineResult) and r.n_steps]
    rate = sum(r.wall_s for r in done) / sum(r.n_steps for r in done) if done else None
    if wanted is not None:
        n = step_count(scene, wanted / 2)
        cost = f", about {n * 3 / 2 * rate:.2g} s here" if rate else ""
        order = last.order if isinstance(last, MeasuredCheck) and last.order is not None else 0
        need = (f"the tolerances need a step of about {wanted:.2g} s (order {order:.2g} fitted "
                f"from the last two checks): a check of {n * 3 // 2:,} steps{cost}, beyond the search's "
                f"work limit of {MAX_SEARCH_STEPS:,} steps")
    else:
        need = f"a finer check would exceed the search's work limit of {MAX_SEARCH_STEPS:,} steps"
    return NumericalFailure(FailureReason.INACCURATE,
                            f"no automatic MuJoCo timestep meets the tolerances: {need} (last check, "
                            f"h = {h if last is None else last.timestep:g} s against h/2: {_describe(last)}); "
                            "set [mujoco] timestep (--timestep) or loosen [tolerances] (--q-atol, --omega-atol, "
                            "--peak-rtol)")


def _describe(record: TimestepCheck | None) -> str:
    if record is None:
        return "not run"
    if isinstance(record, FailedCheck):
        return record.failure
    if record.inputs:  # several inputs: each difference's input and unit
        (q_in, w_in, p_in), units = record.inputs, record.units
        text = (f"max |Δq| {record.max_dq:.3g} {units[0]} of {q_in}, max |Δω| {record.max_domega:.3g} {units[1]}/s "
                f"of {w_in}, |Δ peak| {record.dpeak:.3g} {units[2]}/s of {p_in}")
    else:
        unit = record.unit  # the input coordinate's: rad or m
        text = (f"max |Δq| {record.max_dq:.3g} {unit}, max |Δω| {record.max_domega:.3g} {unit}/s, "
                f"|Δ peak| {record.dpeak:.3g} {unit}/s")
    return (f"{text} against limits {', '.join(f'{v:.3g}' for v in record.limits)}"
            + (", within them but after a failed coarser run: to be confirmed at h/2"
               if record.outcome is CheckOutcome.UNCONFIRMED else ""))


def _halving_difference(coarse: EngineResult, fine: EngineResult, k: int = 0) -> tuple[float, float, float]:
    """max |Δq|, max |Δω| on the coarse grid (every second fine state) and |Δ peak ω| of input k
    (the first by default; ``details.other_grid`` and ``other_inputs`` hold the others)."""
    def grid(result):
        return ((result.details.grid_q, result.details.grid_qdot) if k == 0
                else result.details.other_grid[k - 1])

    (qc, wc), (qf, wf) = grid(coarse), grid(fine)
    qf, wf = qf[::2], wf[::2]
    n = min(len(qc), len(qf))
    return (float(np.max(np.abs(qc[:n] - qf[:n]))), float(np.max(np.abs(wc[:n] - wf[:n]))),
            abs(coarse.inputs[k][1].omega - fine.inputs[k][1].omega))


@dataclass(frozen=True)
class SearchCost:
    """What the automatic timestep's choice took: its runs, their steps and rollout time (s)."""

    runs: int
    steps: int
    wall_s: float
