"""The optional engines in a sweep (``loopcheck sweep --engines reduced,ENGINE``): MuJoCo's ports
(MJX, MJWarp) in batches, Pinocchio variant by variant. Each test skips, with the reason, when its
engine's extra is not installed (CI runs them in its extras venv: .ci/run's extras_job).

- A port's batch of n variants equals its n single runs: MJWarp bit for bit (q, q̇ and q̈ at every
  sample); MJX within :data:`MJX_ULPS` ulps of each trajectory's scale, max |x| over the run (XLA
  compiles a batch's shape otherwise than one run's: over these 200 steps the three variants were
  off by up to 112 ulps in q and 541 in q̇, 1.2e-13 of the peak speed, measured on this 2-core
  CPU; MuJoCo C's q̈ at those states is not compared), and a
  variant that fails inside a batch is that variant's outcome, the others unchanged.
- A sweep's rows with the port in batches (--batch-size 2, three variants: the last batch padded)
  equal its rows at --batch-size 1 (each variant alone), cell for cell but the wall times (MJX:
  numbers within 1e-9 relative, the differences of its states carried into the figures).
- Pinocchio, which declares no batch, sweeps variant by variant at its own tolerances.

The seed over 0.2 s (200 steps), the horizon and batch size of tests/mjx and tests/mjwarp, so that
their compiled scans serve here in one pytest process (MJX compiles each batch shape, ~35 s on a
CPU: slow)."""

from __future__ import annotations

import importlib.util
import re

import numpy as np
import pytest

from loopcheck.compare.cli import main
from loopcheck.compare.settings import engine_settings
from loopcheck.compare.sweep_scene import load_sweep
from loopcheck.compare.sweep_table import CSV_FILE, read_rows
from loopcheck.errors import NumericalFailure
from loopcheck.registry import ENGINES
from loopcheck.scenefile import scene_from_dict
from loopcheck.sweep_spec import apply

from helpers import SEED_SCENE, plots_left_out

SHORT = re.sub(r"(?m)^horizon = 2\.0.*$", "horizon = 0.2", SEED_SCENE.read_text())
DAMPERS = (40.0, 50.0, 60.0)
# torque 1e6 N·m against a damper of 1e-6 N·s/m: the ports' loops open by metres (CONSTRAINT_DRIFT)
BLOWN = {"torque.value": 1e6, "dampers.0.coefficient": 1e-6}


def _have(*modules: str) -> bool:
    return all(importlib.util.find_spec(m) is not None for m in modules)


def _port(name: str, *modules: str):
    return pytest.param(name, marks=[pytest.mark.slow, pytest.mark.skipif(
        not _have(*modules), reason=f"the {name} engine's extra is not installed (docs/engines.md)")])


PORTS = [_port("mjx", "jax", "mujoco.mjx"), _port("mjwarp", "warp", "mujoco_warp")]
MJX_ULPS = 4096  # of max |x| over the run, for q and q̇ (module docstring: measured 112 and 541)
ROWS_RTOL = {"mjx": 1e-9, "mjwarp": 0.0}


@pytest.fixture(scope="module")
def short_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("ports") / "short.toml"
    path.write_text(SHORT)
    return path


def _scene(path, **values):
    data, _ = load_sweep(path)
    return scene_from_dict(apply(data, values), str(path))


@pytest.mark.parametrize("name", PORTS)
def test_a_ports_batch_equals_its_single_runs_bit_for_bit(name, short_file):
    """Three variants (dampers 40, 50, 60 N·s/m) as one batch, and each alone: MJWarp equal to the
    last bit (q, q̇, q̈), MJX's states within MJX_ULPS of their scale (module docstring). With
    ``each``, a variant that fails (BLOWN: the loops open) inside the batch is its own
    NumericalFailure and the others are the same runs, in the same one batch (planted: a failure
    raised for the batch, which then runs variant by variant, fails this)."""
    engine = ENGINES[name]
    scenes = [_scene(short_file, **{"dampers.0.coefficient": c}) for c in DAMPERS]
    settings = engine_settings(name, scenes[0])
    batch = engine.simulate_batch(scenes, settings)
    ulps = {}  # (variant, field) -> max |batch - alone| in ulps of the run's max |x|
    for k, (in_batch, scene) in enumerate(zip(batch, scenes)):
        alone = engine.simulate(scene, settings)
        for field in ("q", "qdot", "qddot") if name == "mjwarp" else ("q", "qdot"):
            got, want = getattr(in_batch.trajectory, field), getattr(alone.trajectory, field)
            ulps[k, field] = float(np.max(np.abs(got - want)) / (np.finfo(float).eps * np.max(np.abs(want))))
    assert max(ulps.values()) <= (0 if name == "mjwarp" else MJX_ULPS), ulps
    assert batch[0].peak.omega != batch[2].peak.omega  # each ran its own damper
    outcomes = engine.simulate_batch([scenes[0], _scene(short_file, **BLOWN), scenes[2]], settings, each=True)
    assert isinstance(outcomes[1], NumericalFailure), outcomes[1]
    assert [o.details.batch for o in (outcomes[0], outcomes[2])] == [3, 3]  # one batch, not each alone
    for got, want in zip((outcomes[0], outcomes[2]), (batch[0], batch[2])):
        assert np.allclose(got.trajectory.qdot, want.trajectory.qdot, rtol=0.0,
                           atol=MJX_ULPS * np.finfo(float).eps * np.max(np.abs(want.trajectory.qdot)))


def _sweep(capsys, path, out, name, batch_size, *vary):
    with plots_left_out():  # the rows are the subject
        status = main(["sweep", str(path), "--out", str(out), "--workers", "1", "--engines", f"reduced,{name}",
                       "--batch-size", str(batch_size), "--vary", *vary])
    printed = capsys.readouterr()
    rows = [{k: v for k, v in row.items() if not k.endswith("wall_s")} for row in read_rows(out / CSV_FILE)]
    return status, printed.out + printed.err, rows


@pytest.mark.parametrize("name", PORTS)
def test_a_ports_batch_rows_equal_its_variant_rows(name, short_file, tmp_path, capsys):
    """Three variants at --batch-size 2 (a batch of 2, then 1 padded to 2) and at --batch-size 1:
    the same rows (every figure, status and reason; the ports fail the seed's gate by their known
    defects, which is what the rows say either way)."""
    vary = f"dampers.0.coefficient=[{', '.join(map(str, DAMPERS))}]"
    status2, printed, batched = _sweep(capsys, short_file, tmp_path / "b2", name, 2, vary)
    assert f"{ENGINES[name].label} in batches of 2" in printed, printed
    status1, printed, alone = _sweep(capsys, short_file, tmp_path / "b1", name, 1, vary)
    assert "in batches" not in printed
    assert [r["dampers.0.coefficient"] for r in batched] == list(DAMPERS)
    assert all(r["status"] in ("passed", "gate_failed") for r in batched), [r["reason"] for r in batched]
    assert status2 == status1 and len(batched) == len(alone)
    for got, want in zip(batched, alone):
        assert got.keys() == want.keys()
        for key, value in want.items():
            if isinstance(value, float) and ROWS_RTOL[name]:
                assert got[key] == pytest.approx(value, rel=ROWS_RTOL[name], abs=1e-300), key
            elif key != "reason" or not ROWS_RTOL[name]:
                assert got[key] == value, key


@pytest.mark.skipif(not _have("pinocchio"), reason="the pin engine's extra is not installed (docs/engines.md)")
def test_pinocchio_sweeps_variant_by_variant_at_its_own_tolerances(short_file, tmp_path, capsys):
    """--engines reduced,mujoco,pin over three variants: each engine judged (diff.ENGINE.*, gate.ENGINE.*),
    Pinocchio passing its gate on each (measured ~1e-8 of its peak tolerance), one line per engine."""
    with plots_left_out():
        status = main(["sweep", str(short_file), "--out", str(tmp_path / "p"), "--workers", "1",
                       "--engines", "reduced,mujoco,pin", "--vary", "dampers.0.coefficient=[40, 50, 60]"])
    printed = capsys.readouterr().out
    assert status == 0, printed
    rows = list(read_rows(tmp_path / "p" / CSV_FILE))
    assert [r["gate.pin.passed"] for r in rows] == [True] * 3 and [r["gate.mujoco.passed"] for r in rows] == [True] * 3
    assert all(r["gate.pin.peak_ratio"] < 1e-3 for r in rows)
    assert re.search(r"(?m)^  \S+: 3 passed its gate, 0 failed it, 0 failed numerically", printed), printed
    assert "diff.peak_omega_abs" not in rows[0] and "pin.peak_omega" in rows[0]


@pytest.mark.slow  # JAX's import and MJX's put_model: ~13 s on the loaded 2-core machine
@pytest.mark.skipif(not _have("jax", "mujoco.mjx"), reason="the mjx engine's extra is not installed (docs/engines.md)")
def test_mjx_batches_variants_of_a_load_and_of_an_initial_state(short_file):
    """Variants of the torque or of the initial speed differ in model fields MJX compiles in but
    never steps with (the keyframes, the numeric data holding the control sequence): their models
    stack into one batch, and each run's own model, which MuJoCo C reads back, keeps its values
    (planted: without the alignment the stack raises, and the sweep ran each such variant alone)."""
    import jax
    from mujoco import mjx

    from loopcheck.mjx.run import _stepped_model
    from loopcheck.mujoco_model.port import prepare

    def run(**values):
        scene = _scene(short_file, **values)
        return prepare(scene, engine_settings("mjx", scene), "MJX", "mjx")

    first = run()
    for values in ({"torque.value": 240.0}, {"initial.qdot": 1.0}):
        other = run(**values)
        own = {n: np.array(getattr(other.port_model, n)) for n in ("key_qvel", "key_ctrl", "numeric_data")}
        with jax.enable_x64(True):
            stacked = jax.tree_util.tree_map(lambda *leaves: jax.numpy.stack(leaves),
                                             mjx.put_model(_stepped_model(first, first)),
                                             mjx.put_model(_stepped_model(other, first)))
        assert stacked.body_mass.shape[0] == 2, values
        assert all(np.array_equal(getattr(other.port_model, n), v) for n, v in own.items()), values
