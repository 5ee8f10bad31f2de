"""What the compiled integrators see of a problem: functions of an opaque (problem, chart).

- ``acceleration(problem, chart, load, t, q, v) -> float``: q̈ of the chart's coordinate on
  load piece ``load`` (its index: every load over time is constant on a piece); NaN when the
  problem cannot be evaluated there;
- ``stop_margin(problem, chart, t, q, v) -> float``: > 0 while the chart serves; the run ends
  where it crosses to ≤ 0;
- ``observe(problem, chart, out)``: what the problem records at a sample, right after the
  sample's ``acceleration`` (``observation_size(problem)`` floats), returned with the samples;
- ``power(problem, chart, load, v) -> (P, D)``: right after an ``acceleration``, the rates of
  the two energy flows the integrators integrate alongside the state (the work done on the
  system and the energy dissipated, W), for the energy audit;
- ``mark(problem, chart) -> marked`` and ``rewind(problem, chart, marked)``: the chart's state
  at a piece's start, and back to it, so that the piece's samples are evaluated in order from
  its start once it is integrated.

The integrators (:mod:`.fixed_step`, :mod:`.adaptive`) import these names and nothing else
of the physics, which supplies them for a linkage chart (:mod:`.physics`).
"""

from .physics import acceleration, mark, observation_size, observe, power, rewind, stop_margin

__all__ = ["acceleration", "mark", "observation_size", "observe", "power", "rewind", "stop_margin"]
