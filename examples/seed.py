"""The seed's four-bar through both engines, and how far apart they are.

    python examples/seed.py
"""

import loopcheck

scene = loopcheck.load_scene("seed_fourbar")            # a file path works too
reduced = loopcheck.simulate(scene)                     # Eksergian's equation, the exact reference
mujoco = loopcheck.simulate(scene, loopcheck.mujoco_settings(scene))
comparison = loopcheck.compare_results(scene, reduced, mujoco)

print(f"peak speed: reduced {reduced.peak.omega:.8f} rad/s at {reduced.peak.time:.4f} s, "
      f"MuJoCo {mujoco.peak.omega:.8f} rad/s")
print(f"largest |Δq| {comparison.diff.q_max_abs:.2e} rad; gate {'passed' if comparison.gate.passed else 'FAILED'}")
