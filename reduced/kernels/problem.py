"""What the compiled integrators see of a problem: two functions of an opaque (problem, chart).

- ``acceleration(problem, chart, load, t, q, v) -> float``: q̈ of the chart's coordinate with
  the piece's constant load; NaN when the problem cannot be evaluated there;
- ``stop_margin(problem, chart, t, q, v) -> float``: > 0 while the chart serves; the run ends
  where it crosses to ≤ 0;
- ``observe(problem, chart, out)``: what the problem records at a sample, right after the
  sample's ``acceleration`` (``observation_size(problem)`` floats), returned with the samples.

The integrators (:mod:`.fixed_step`, :mod:`.adaptive`) import these names and nothing else
of the physics, which supplies them for a linkage chart (:mod:`.physics`).
"""

from .physics import acceleration, observation_size, observe, stop_margin

__all__ = ["acceleration", "observation_size", "observe", "stop_margin"]
