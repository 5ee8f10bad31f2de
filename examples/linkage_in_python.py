"""A linkage described in Python rather than in a file: a crank-rocker four-bar under gravity,
released from rest, solved by Eksergian's equation. The keys are those of a scene file
(README, "Scene files").

    python examples/linkage_in_python.py
"""

import loopcheck

scene = loopcheck.scene_from_dict({
    "name": "swinging_four_bar",
    "gravity": [0.0, -9.81],                                   # m/s²
    "linkage": {"type": "four_bar", "c1": 0.1, "c2": 0.35, "c3": 0.3, "c4": 0.4, "branch": 1},  # m
    "bodies": {                                                # kg, kg·m² about the centre, m
        "crank": {"mass": 1.0, "inertia": 0.002, "com": [0.05, 0.0]},
        "coupler": {"mass": 2.0, "inertia": 0.02, "com": [0.175, 0.0]},
        "rocker": {"mass": 1.5, "inertia": 0.012, "com": [0.15, 0.0]},
    },
    "initial": {"q": 0.3, "qdot": 0.0},                        # rad, rad/s
    "simulation": {"horizon": 1.0},                            # s
})
result = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-10))
t, q = result.trajectory.t, result.trajectory.q
print(f"{len(t)} samples over {t[-1]:.2f} s; q from {q.min():.4f} to {q.max():.4f} rad; "
      f"peak |q̇| {abs(result.peak.omega):.4f} rad/s at {result.peak.time:.4f} s; "
      f"energy residual {result.audit.relative_residual:.1e}")
