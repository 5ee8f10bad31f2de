"""The MJWarp engine on the seed over a short horizon (0.2 s at 1 ms): against the reduced engine
and MuJoCo C with the same model, its energy audit, a batch of two variants in one run (nworld=2),
and what it refuses.

Oracles: the reduced engine (DOP853 at rtol 1e-12: Eksergian's equation in one coordinate, exact
to ~1e-12 here) and MuJoCo C (float64, the same MJCF and options: RK4 at 1 ms), interpolated at
MJWarp's sample times.

Tolerances. MJWarp computes in float32 only; its difference from C is float32 round-off amplified
by the loop's stiffness (docs/engines.md, "MJWarp"), well above RK4's truncation at 1 ms (C's own
difference from the reduced engine over 0.2 s: 1.2e-5 on the peak). Measured (2026-11-26, MJWarp
4.0.0, warp 1.19.0, CPU) against the reduced engine: peak 3.7e-5 relative, max |Δq| 4.2e-5 rad,
max |Δq̇| 4.5e-4 rad/s; against C: 2.5e-5, 4.2e-5 rad, 4.0e-4 rad/s; loop gap 3.6e-7 m (C: 1.1e-7 m,
float32 resolves ~1.2e-7 m at 1 m); energy residual 4.2e-5 of the scale (C: 9.4e-6). The bounds
below are ~5× each (float32 sums depend on the order of operations, which another CPU or a GPU
changes; 5× covers that without admitting a model error: dropping the controls puts the peak 100 % off).

The batch: worlds share MJWarp's kernels and differ in their own model values (here
``tendon_damping``), so a world's run is the same arithmetic as the single run; measured equal
bit for bit. The bound is 2 float32 spacings of the values (2 × 2⁻²³ relative, i.e. ~2.4e-7 of
|q| and |q̇|), enough for a reordering of sums between nworld = 1 and 2 and far below any model
difference (the two dampers' runs differ by more than 1e-3 rad/s, asserted).

Planted: the controls not copied to the device (the ``wp.copy(dw.ctrl, ...)`` line of
loopcheck/mjwarp/run.py) fails test_agrees_with_the_reduced_engine and test_agrees_with_mujoco_c
(the crank stays at rest: peak off by 100 %); the per-world model values not assigned (``getattr(mw,
name).assign(...)`` in ``_model``) fails test_a_batch_equals_its_single_runs (world 1 runs with
damper 55 while MuJoCo C audits damper 30: its energy gate fails, residual 0.0037 of the scale).

Cost: MJWarp's kernels compile on first use (~60 s on a 2-core CPU; warp caches them in
~/.cache/warp), then each 200-step run takes ~10 s here (~50 ms a step: MJWarp on the CPU is
kernel-launch bound), so the module is marked slow.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp", reason="the mjwarp engine's extra is not installed (pip install -e '.[mjwarp]' in loopcheck's checkout)")
pytest.importorskip("mujoco_warp", reason="MJWarp is not installed (pip install --no-deps mujoco-warp)")

import loopcheck  # noqa: E402
from loopcheck.mjwarp import MjwarpSettings, simulate, simulate_batch  # noqa: E402
from loopcheck.mujoco_model.port import PortRefusal, prepare  # noqa: E402
from loopcheck.reference_models import MujocoSettings, simulate_mujoco  # noqa: E402
from loopcheck.scene import Tolerances  # noqa: E402

from helpers import ROOT, seed_dict, variant  # noqa: E402

pytestmark = pytest.mark.slow

H = 1e-3  # s, the grid step of the seed
HORIZON = 0.2  # s
SETTINGS = MjwarpSettings(timestep=H)
# ~5x the measured figures (module docstring); peak relative, q rad, q̇ rad/s.
AGAINST_REDUCED = Tolerances(peak_omega_rtol=2e-4, q_atol=2e-4, omega_atol=2.5e-3)
AGAINST_C = Tolerances(peak_omega_rtol=1.5e-4, q_atol=2e-4, omega_atol=2e-3)
MAX_GAP = 2e-6  # m, measured 3.6e-7
MAX_ENERGY_RESIDUAL = 2e-4  # of the audit's scale, measured 4.2e-5
BATCH_RTOL = 2 * 2.0 ** -23  # two float32 spacings


def _seed(damper: float = 55.0):
    data = seed_dict()
    return variant(simulation={**data["simulation"], "horizon": HORIZON},
                   dampers=[{**data["dampers"][0], "coefficient": damper}])


@pytest.fixture(scope="module")
def seed():
    return _seed()


@pytest.fixture(scope="module")
def run(seed):
    return simulate(seed, SETTINGS)


@pytest.fixture(scope="module")
def reduced(seed):
    return loopcheck.simulate(seed, loopcheck.ReducedSettings(method="dop853", rtol=1e-12))


def _figures(reference, result):
    q, qdot, _ = reference.trajectory.interpolate(result.trajectory.t)
    return (abs(result.peak.omega - reference.peak.omega) / abs(reference.peak.omega),
            float(np.max(np.abs(q - result.trajectory.q))), float(np.max(np.abs(qdot - result.trajectory.qdot))))


def _within(seed, reference, result, tolerances: Tolerances):
    peak, dq, dqdot = _figures(reference, result)
    assert peak <= tolerances.peak_omega_rtol, peak
    assert dq <= tolerances.q_atol, dq
    assert dqdot <= tolerances.omega_atol, dqdot
    verdict = loopcheck.compare_results(seed, reference, result, tolerances=tolerances).gate
    assert verdict.passed, verdict.failures


def test_agrees_with_the_reduced_engine(seed, run, reduced):
    _within(seed, reduced, run, AGAINST_REDUCED)


def test_agrees_with_mujoco_c(seed, run):
    c = simulate_mujoco(seed, MujocoSettings(timestep=H))
    _within(seed, c, run, AGAINST_C)


def test_its_loops_and_energy_audit(run):
    assert run.engine == "mjwarp" and run.n_steps == round(HORIZON / H)
    assert run.constraint_violation.max <= MAX_GAP
    assert abs(run.audit.relative_residual) <= MAX_ENERGY_RESIDUAL


def test_details(run):
    details = run.details.as_dict()
    assert details["precision"] == "float32" and details["batch"] == 1 and details["batched_fields"] == []
    assert details["device"] == "cpu" or details["device"].startswith("cuda")
    assert details["compile_s"] > 0.0 and set(details["versions"]) == {"mujoco_warp", "warp", "mujoco"}
    assert run.settings.timestep == H and run.n_evaluations == 4 * run.n_steps
    # the defect found for issue 28 travels with every run of a scene with loops (docs/engines.md)
    assert len(run.caveats) == 1 and "J̇·q̇ from the previous evaluation's body velocities" in run.caveats[0]


def test_a_batch_equals_its_single_runs(run):
    """Dampers 55 and 30 N·s/m as two worlds of one run: each equals its single run."""
    other = _seed(30.0)
    batch = simulate_batch([_seed(), other], SETTINGS)
    single = simulate(other, SETTINGS)
    assert batch[0].details.batched_fields == ("tendon_damping",) and batch[0].details.batch == 2
    for world, alone in zip(batch, (run, single)):
        for name in ("q", "qdot"):
            got, want = getattr(world.trajectory, name), getattr(alone.trajectory, name)
            assert np.max(np.abs(got - want)) <= BATCH_RTOL * np.max(np.abs(want)), name
    # the worlds did differ: the batch ran each variant's own damper
    assert np.max(np.abs(batch[0].trajectory.qdot - batch[1].trajectory.qdot)) > 1e-3


def test_a_batch_refuses_a_field_mjwarp_shares_between_worlds(seed):
    """A variant differing in a model field that MJWarp keeps once for all worlds is refused in
    one line naming it (checked before any step: the model is changed by hand here)."""
    from loopcheck.mjwarp.run import _batched_fields

    runs = [prepare(seed, SETTINGS, "MJWarp", "mjwarp") for _ in range(2)]
    runs[1].port_model.actuator_ctrllimited[0] = 1
    with pytest.raises(PortRefusal, match=r"^MJWarp shares the model's actuator_ctrllimited between the worlds"):
        _batched_fields(runs)
    runs[1].port_model.actuator_ctrllimited[0] = runs[0].port_model.actuator_ctrllimited[0]
    runs[1].port_model.body_mass[2] *= 2.0
    assert _batched_fields(runs) == (("body_mass",), ())


def test_point_forces_are_refused_in_one_line():
    scene = loopcheck.load_scene(ROOT / "scenes" / "mechanisms" / "slider_crank_gas.toml")  # a gas force on the piston
    with pytest.raises(PortRefusal, match=r"^MJWarp does not run point or timed forces \(.+\): MuJoCo applies them"):
        simulate(scene, SETTINGS)
