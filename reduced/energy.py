"""Energy audit of a reduced-model trajectory.

The work of the torque ∫ T q̇ dt and the damper dissipation ∫ Σ b K_D² q̇² dt are
integrated with 4-point Gauss-Legendre quadrature on each sample interval of the
trajectory's quintic Hermite interpolant (exact for polynomials of degree 7), so the
quadrature adds far less than the integrator's own error.
"""

from __future__ import annotations

import numpy as np

from .dynamics import MechanismModel
from .result import EnergyAudit
from .trajectory import Trajectory

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(4)


def energy_audit(model: MechanismModel, trajectory: Trajectory) -> EnergyAudit:
    """Kinetic and potential energy at each sample, and the work terms accumulated to it."""
    t, q, v = trajectory.t, trajectory.q, trajectory.qdot
    coeffs = [model.coefficients(float(qi)) for qi in q]
    kinetic = 0.5 * np.array([c.generalized_inertia for c in coeffs]) * v * v
    potential = np.array([c.potential for c in coeffs])

    h = np.diff(t)
    live = h > 0
    mid = 0.5 * (t[:-1] + t[1:])
    nodes = mid[:, None] + 0.5 * h[:, None] * _NODES[None, :]  # (n-1, 4)
    flat = nodes[live].ravel()
    qn, vn, _ = trajectory.interpolate(flat)
    torque = model.torque.sample(flat) if model.torque is not None else np.zeros_like(flat)
    damping = np.array([model.coefficients(float(x)).damping for x in qn]) if model.scene.dampers \
        else np.zeros_like(flat)
    w = (0.5 * h[live])[:, None] * _WEIGHTS[None, :]
    torque_step = np.zeros_like(h)
    damper_step = np.zeros_like(h)
    torque_step[live] = np.sum(w * (torque * vn).reshape(-1, 4), axis=1)
    damper_step[live] = np.sum(w * (damping * vn * vn).reshape(-1, 4), axis=1)
    zero = np.zeros(1)
    return EnergyAudit(t=t, kinetic=kinetic, potential=potential,
                       torque_work=np.concatenate([zero, np.cumsum(torque_step)]),
                       damper_dissipation=np.concatenate([zero, np.cumsum(damper_step)]))
