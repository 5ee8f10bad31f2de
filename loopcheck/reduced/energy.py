"""Energy audit of a reduced-model run.

Kinetic ½ 𝔍 ẋ_i² and potential V at every sample; the work of the input load and of the
point forces over q and over t and of the actuators ∫ (T dq/dx_i + Σ F e·K_P + Σ gear f dl/dx_i) ẋ_i dt
(the audit's ``torque_work``) and the damper
dissipation ∫ Σ b K_D² ẋ_i² dt.

The compiled runs integrate the two power integrals alongside the state, with the
integrator's own stages and weights (:meth:`loopcheck.reduced.kernels.physics.Chart.power` and
:meth:`~loopcheck.reduced.kernels.physics.Chart.dissipation`): DOP853's
order-8 quadrature and dense output, RKN4's order-4 weights of q̇. Nothing is evaluated
again. scipy's runs (the independent cross-check) have no such by-product: their integrals
are taken by 3-point Gauss-Legendre quadrature on each sample interval of the chart's quintic
Hermite interpolant (exact for polynomials of degree 5; every quarter solver step is a
sample, so the quadrature adds far less than the integrator's own error, and on every
shipped scene 3 points give the 4-point residual to the digits printed). The tests check
the two against each other. A run that switched coordinates is audited chart by chart, each
in its own coordinate.
"""

from __future__ import annotations

import numpy as np

from .dynamics import MechanismModel
from .kernels import physics
from loopcheck.results import EnergyAudit

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(3)


def _fields(chart, values: np.ndarray, *names: int) -> tuple[np.ndarray, ...]:
    """Coefficient fields (:mod:`loopcheck.reduced.kernels.physics` indices) at each coordinate value,
    walking the chart from its start (compiled)."""
    fields, _ = chart.walk(values)
    return tuple(fields[:, k] for k in names)


def quadrature_energy(model: MechanismModel, chart, trajectory) -> np.ndarray:
    """The work done (load and point forces) and the energy dissipated since the chart's first
    sample (m, 2), J, by Gauss-Legendre quadrature of the power over the samples' interpolant."""
    t = trajectory.t
    h = np.diff(t)
    live = h > 0
    mid = 0.5 * (t[:-1] + t[1:])
    nodes = (mid[:, None] + 0.5 * h[:, None] * _NODES[None, :])[live].ravel()
    xn, vn, _ = trajectory.interpolate(nodes)
    # dq/dx_i, Σ b K_D², Σ F e·K_P, then each timed force's e·K_P
    timed = model.scene.mechanism.timed_forces
    acts = model.scene.mechanism.actuators
    nt = physics.N_FIELDS + len(timed)
    input_rate, damping, point_force, *rates = _fields(chart, xn, physics.INPUT_RATE, physics.DAMPING,
                                                       physics.POINT_FORCE,
                                                       *(physics.N_FIELDS + p for p in range(len(timed))),
                                                       *(nt + k for k in range(2 * len(acts))))
    rates, lengths = rates[:len(timed)], rates[len(timed):]
    load = model.load.sample(nodes) if model.load is not None else np.zeros_like(nodes)
    w = (0.5 * h[live])[:, None] * _WEIGHTS[None, :]
    torque_step, damper_step = np.zeros_like(h), np.zeros_like(h)
    generalized = load * input_rate
    if np.any(point_force):
        generalized = generalized + point_force
    for force, rate in zip(timed, rates):  # the nodes lie inside the load pieces
        generalized = generalized + force.profile.sample(nodes) * rate
    for k, a in enumerate(acts):  # gear·f·dl/dx_i, f at l and l̇ = (dl/dx_i) ẋ_i
        length, slope = lengths[2 * k], lengths[2 * k + 1]
        generalized = generalized + a.gear * a.force(a.control_values(nodes), length, slope * vn) * slope
    torque_step[live] = np.sum(w * (generalized * vn).reshape(-1, len(_NODES)), axis=1)
    damper_step[live] = np.sum(w * (damping * vn * vn).reshape(-1, len(_NODES)), axis=1)
    energy = np.zeros((len(t), 2))
    energy[1:, 0] = np.cumsum(torque_step)
    energy[1:, 1] = np.cumsum(damper_step)
    return energy


def energy_audit(model: MechanismModel, solution) -> EnergyAudit:
    """The energy balance of a :class:`loopcheck.reduced.charts.PartitionedSolution` on its sample
    times: its recorded fields, and its integrated energy flows (or, for scipy's runs, their
    quadrature: :func:`quadrature_energy`)."""
    energy = solution.sample_energy
    if energy is None:
        energy = [quadrature_energy(model, chart, s.trajectory) for chart, s in solution.segments]
    t = np.concatenate([s.trajectory.t for _, s in solution.segments])
    v = np.concatenate([s.trajectory.qdot for _, s in solution.segments])
    fields = np.concatenate(solution.sample_fields)
    kinetic = 0.5 * fields[:, physics.INERTIA] * v * v
    # Each chart's flows start at zero; its first sample follows the previous chart's last at
    # the same instant, so the charts' flows add up.
    offset = np.cumsum([np.zeros(2)] + [e[-1] for e in energy[:-1]], axis=0)
    flows = np.concatenate([e + o for e, o in zip(energy, offset)])
    return EnergyAudit(t=t, kinetic=kinetic, potential=fields[:, physics.POTENTIAL], torque_work=flows[:, 0],
                       damper_dissipation=flows[:, 1])
