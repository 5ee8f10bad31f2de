"""The reduced solver's outputs on every shipped scene, for a regression fixture.

``tests/data/numba_core_outputs.json`` was recorded with :func:`outputs` from the numba-compiled
core, before it was replaced by the Cython one (the fixture's label names the commit and the
versions; numba has left the project, so it is not recorded again), so that the compiled core
is held to what the old one computed: peaks within 1e-10 relative, states within 1e-9 (a change
of compiler can move the order of operations and libm's last bits, nothing more). It is the old
core's answer, not an independent truth (the physics is checked against closed forms, energy
balances and MuJoCo elsewhere).

The fixture also holds each scene's x0 as the numpy kinematics assembled it when the runs were
recorded (``"x0"``; label ``"x0"``): since the kinematics are compiled (``loopcheck/kernels/loops.py``)
a scene's x0 is round-off away from it (its residual is summed in another order), and the
reduced runs, whose step sequences follow x0's last bits, start from the recorded x0 so that the
fixture still holds the core alone.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FIXTURE = ROOT / "tests" / "data" / "numba_core_outputs.json"
METHODS = ("dop853", "rkn4")
N_TIMES = 101  # states compared at these many times spread over the horizon


# Shipped scenes added after the numba core left the project, which therefore never ran them: the
# fixture cannot hold them; each one's own oracle test does (scene: that test).
NOT_RECORDED = {
    "mechanisms/parallelogram_redundant.toml": "tests/reduced/test_redundant_loop.py (closed form)",
    "mechanisms/seed_fourbar_geared_flywheel.toml": "tests/core/test_couplings.py (the seed with a joint inertia)",
    "mechanisms/servo_fourbar.toml": "tests/reduced/test_actuators.py (closed form), "
                                     "tests/reference_models/test_actuators_mjcf.py (MuJoCo, Pinocchio, audits)",
    "mechanisms/friction_fourbar.toml": "tests/reduced/test_friction_fourbar.py (stick, energy, halves)",
    "mechanisms/five_bar_robot.toml": "tests/reduced/test_several_dof.py (two DOF: the multibody oracle, energy)",
    "hard/five_bar_fold.toml": "tests/reduced/test_several_dof.py (two DOF through a singular configuration of "
                               "its inputs: the multibody oracle, energy)",
    "mechanisms/adaptive_finger.toml": "tests/reduced/test_catalogue_several_dof.py (two DOF: the multibody oracle, energy)",
    "mechanisms/three_rrr.toml": "tests/reduced/test_catalogue_several_dof.py (three DOF: the multibody oracle, energy)",
}


def recorded_scenes() -> list[Path]:
    """The shipped scenes the fixture holds: all but :data:`NOT_RECORDED`."""
    return [p for p in shipped_scenes() if key(p) not in NOT_RECORDED]


def shipped_scenes() -> list[Path]:
    scenes = ROOT / "scenes"
    return sorted([*scenes.glob("*.toml"), *scenes.glob("hard/*.toml"), *scenes.glob("mechanisms/*.toml")])


def outputs(path: Path, method: str, x0: list[float] | None = None) -> dict:
    """What the reduced solver gives for one scene and method: the peak, the cost, the states
    (q, q̇) at N_TIMES times over the horizon (the run's own interpolant), or its failure;
    started from ``x0`` (the same configuration to round-off) instead of the scene's x0 if given.
    The run's own accuracy check is off (``check_error=False``), so that RKN4 at its default
    step records a trajectory on the hard scenes too, where its estimate refuses the run."""
    from loopcheck.compare.settings import reduced_settings
    from loopcheck.errors import NumericalFailure
    from loopcheck.scenefile import load_scene
    from loopcheck.reduced import simulate

    scene = load_scene(path)
    if x0 is not None:
        scene = dataclasses.replace(scene, x0=tuple(float(v) for v in x0))
    try:
        run = simulate(scene, reduced_settings(scene, method=method, check_error=False))
    except NumericalFailure as failure:
        return {"failure": failure.reason.value}
    times = np.linspace(0.0, float(run.trajectory.t[-1]), N_TIMES)
    q, qdot, _ = run.trajectory.interpolate(times)
    return {"peak_omega": run.peak.omega, "peak_time": run.peak.time, "steps": run.n_steps,
            "evaluations": run.n_evaluations, "t": times.tolist(), "q": q.tolist(), "qdot": qdot.tolist()}


def key(path: Path) -> str:
    return path.relative_to(ROOT / "scenes").as_posix()
