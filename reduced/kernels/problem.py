"""What the compiled integrators see of a problem: functions of an opaque (problem, chart).

- ``acceleration(problem, chart, load, t, q, v) -> float``: q̈ of the chart's coordinate with
  the piece's constant load; NaN when the problem cannot be evaluated there;
- ``stop_margin(problem, chart, t, q, v) -> float``: > 0 while the chart serves; the run ends
  where it crosses to ≤ 0;
- ``observe(problem, chart, out)``: what the problem records at a sample, right after the
  sample's ``acceleration`` (``observation_size(problem)`` floats), returned with the samples;
- ``power(problem, chart, load, v) -> (P, D)``: right after an ``acceleration``, the rates of
  the two energy flows the integrators integrate alongside the state (the work done on the
  system and the energy dissipated, W), for the energy audit.

The integrators (:mod:`.fixed_step`, :mod:`.adaptive`) import these names and nothing else
of the physics, which supplies them for a linkage chart (:mod:`.physics`).
"""

from .physics import acceleration, observation_size, observe, power, stop_margin

__all__ = ["acceleration", "observation_size", "observe", "power", "stop_margin"]
