"""Run a scene's MuJoCo model with MJX (:func:`simulate_mjx`), or a batch of variants of it as one
``jax.vmap`` (:func:`simulate_batch`), and return :class:`~loopcheck.results.EngineResult` s.

The step loop is one ``jax.lax.scan`` of ``mjx.step`` over the controls of every step, compiled
once per model structure and step count (``jax.jit``; JAX's persistent compilation cache, when
``JAX_COMPILATION_CACHE_DIR`` is set, keeps it across processes), announced first with the last
compile's time (:mod:`loopcheck.mujoco_model.compile_record`); what JAX and XLA say meanwhile is
kept and logged in loopcheck's words (:mod:`loopcheck.mujoco_model.foreign_output`). The states come back to the
host and MuJoCo C reads them (:func:`loopcheck.mujoco_model.port.finish`): the energy audit and the loop
gap are MuJoCo C's functions at MJX's states, as the issue's design asks (MJX computes no energy).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from importlib import metadata
from pathlib import Path

import numpy as np

from loopcheck.mujoco_model.build import check_mujoco_version
from loopcheck.mujoco_model.compile_record import compiling, user_cache_dir
from loopcheck.mujoco_model.foreign_output import foreign_output
from loopcheck.mujoco_model.port import (PortRun, finish, finished, known_defects, prepare, prepared,
                                         refusing_unimplemented, stack_runs, states_limit)
from loopcheck.results import EngineResult
from loopcheck.scene import Scene

from .settings import MjxSettings

_LOGGERS = ("jax", "jaxlib", "absl", "mujoco.mjx")  # JAX's, absl's (XLA's Python side) and MJX's loggers

try:
    with foreign_output("mjx", "JAX", _LOGGERS):  # what JAX says as it loads, in loopcheck's words (foreign_output)
        import jax
        from mujoco import mjx
except ModuleNotFoundError as exc:  # the optional extra
    raise ModuleNotFoundError("the mjx engine needs JAX and MJX: pip install -e '.[mjx]' in loopcheck's checkout, then "
                              "pip install --no-deps mujoco-mjx (docs/engines.md, 'Installing MJX and MJWarp')",
                              name=exc.name) from exc

import mujoco  # noqa: E402  (after the extra's check: the message above names what is missing)

check_mujoco_version(mujoco.__version__)  # installing MJX with pip's resolver can replace MuJoCo (docs/engines.md)

MJX_VERSION = metadata.version("mujoco-mjx")
# The defect found for issue 28 (docs/engines.md, "MJX and the connect constraint"): MJX 3.17.0's
# constraint reference acceleration omits J̇·q̇, which MuJoCo C subtracts for connect and weld rows
# (mj_Jdotv); a closed loop's pins then lag, and the run is off by about 3e-3 on the seed.
KNOWN_DEFECT = ("MJX {version} omits J̇·q̇ from the loop constraints' reference acceleration (MuJoCo C subtracts "
                "it: mj_Jdotv), so the loops close late: expect errors of order 1e-3 on closed loops "
                "(docs/engines.md)")
DEFECT_CHECKED = "3.17.0"  # the newest MJX release found to have it


@dataclass(frozen=True)
class MjxDetails:
    """The MJX engine's own record of a run (:attr:`EngineResult.details`).

    backend : JAX's platform that ran it ("cpu", "gpu", ...); precision : "float64" or "float32".
    batch : the variants run together (1 for :func:`simulate_mjx`).
    compile_s : s, the scan's compilation (0 when JAX's cache had it); wall time per variant is
        ``EngineResult.wall_s`` (the batch's run divided by ``batch``).
    initial_residuals : MuJoCo C's loop residuals at the start.
    edge_warnings : one note per load edge off the step grid.
    versions : MJX's, JAX's and MuJoCo C's (which reads the states back).
    """

    backend: str
    precision: str
    batch: int
    compile_s: float
    initial_residuals: dict
    edge_warnings: tuple[str, ...]
    versions: dict

    def as_dict(self) -> dict:
        return {"backend": self.backend, "precision": self.precision, "batch": self.batch,
                "compile_s": self.compile_s, "initial_residuals": dict(self.initial_residuals),
                "edge_warnings": list(self.edge_warnings), "versions": dict(self.versions)}


def simulate_mjx(scene: Scene, settings: MjxSettings = MjxSettings()) -> EngineResult:
    """Step the scene's MuJoCo model with MJX to the horizon.

    Raises
    ------
    PortRefusal (a ValueError)
        What MJX does not run (point forces), or a run beyond the limits, in one line.
    NumericalFailure
        INITIAL_STATE, NON_FINITE, CONSTRAINT_DRIFT, ENERGY_IMBALANCE (MuJoCo C's checks at MJX's states).
    """
    return simulate_batch([scene], settings)[0]


def simulate_batch(scenes: list[Scene], settings: MjxSettings = MjxSettings(), *,
                   each: bool = False) -> list[EngineResult]:
    """Step variants of one model (the same structure and step count; values may differ: masses,
    dampers, loads, initial state) together, as one ``jax.vmap`` of the scan. Each result's
    ``wall_s`` is the batch's run time divided by the batch's size.

    With ``each``, one outcome per scene: its result or the exception its own run raises
    (a refusal or NumericalFailure of one variant sinks no other; a variant refused before the
    run has its slot filled by another's run, so the batch keeps its compiled shape).

    Raises
    ------
    PortRefusal (a ValueError)
        Scenes of other structures in one batch, or what :func:`simulate_mjx` refuses.
    NumericalFailure
        As :func:`simulate_mjx`, for the first variant that fails (without ``each``).
    """
    if not scenes:
        raise ValueError("simulate_batch needs at least one scene")
    outcomes, runs = prepared(scenes, lambda scene: prepare(scene, settings, "MJX", "mjx"), each)
    if not runs:
        return outcomes
    stack_runs([run for _, run in runs], "MJX")
    filled = [run for _, run in runs] + [runs[-1][1]] * (len(scenes) - len(runs))  # the compiled shape
    with jax.enable_x64(settings.precision == "float64"):
        qpos, qvel, compile_s, wall = _scan(filled, settings.precision)
    details = MjxDetails(backend=jax.default_backend(), precision=settings.precision, batch=len(filled),
                         compile_s=compile_s, initial_residuals={}, edge_warnings=(),
                         versions={"mjx": MJX_VERSION, "jax": jax.__version__, "mujoco": mujoco.__version__})
    per_step = 4 if settings.integrator == "rk4" else 1
    defect = KNOWN_DEFECT.format(version=MJX_VERSION)
    for j, (k, run) in enumerate(runs):
        outcomes[k] = finished(lambda: finish(run, qpos[j], qvel[j], name="mjx", engine="MJX",
                                              wall_s=wall / len(filled), evaluations_per_step=per_step,
                                              details=replace(details, initial_residuals=run.initial,
                                                              edge_warnings=run.edge_notes),
                                              caveats=known_defects(run, MJX_VERSION, DEFECT_CHECKED, defect)),
                               each)
    return outcomes


def batch_limit(scene: Scene, settings: MjxSettings = MjxSettings()) -> int:
    """The most variants of ``scene``'s structure one batch holds: the device's memory (JAX's
    ``bytes_limit`` on a GPU, half of it for the scan's states) and the host's
    (:data:`~loopcheck.mujoco_model.port.MAX_STATE_BYTES` for the states read back) over one
    variant's states, its model's nq + nv × its steps."""
    run = prepare(scene, settings, "MJX", "mjx")
    itemsize = 8 if settings.precision == "float64" else 4
    stats = jax.devices()[0].memory_stats() or {}
    return states_limit(run, itemsize, stats.get("bytes_limit"))


# The compiled scans of this process, by the batch's structure and shapes (a compilation takes
# about 35 s on a CPU; another run of the same model structure and step count reuses it).
_COMPILED: dict = {}


def _rollout(m, d, us):
    """qpos and qvel after each step of MJX's ``m`` from ``d`` under the controls ``us``."""
    def body(d, u):
        new = mjx.step(m, d.replace(ctrl=u))
        # MJX 3.17 returns a few index fields (tendon wraps) as int64 under x64: keep the carry's types
        new = jax.tree_util.tree_map(lambda n, o: n.astype(o.dtype) if hasattr(o, "dtype") else n, new, d)
        return new, (new.qpos, new.qvel)
    return jax.lax.scan(body, d, us)[1]


# Model fields that mjx.step does not read but that MJX compiles in (static arrays of its Model):
# the keyframes (the port sets the state itself) and the numeric data (where the model records
# the control sequence; the scan takes the controls as its input). Variants of a load or of an
# initial state differ there: measured, without this their models did not stack into a batch.
_UNREAD_PREFIXES = ("key_",)
_UNREAD = ("numeric_data",)


def _stepped_model(run: PortRun, first: PortRun):
    """``run``'s model for the step, its unread fields (:data:`_UNREAD`) the first run's (a copy:
    the run's own is MuJoCo C's to read back)."""
    import copy

    m = run.port_model
    names = [n for n in dir(m) if n.startswith(_UNREAD_PREFIXES) or n in _UNREAD]
    differ = [n for n in names if isinstance(getattr(m, n), np.ndarray)
              and getattr(m, n).shape == getattr(first.port_model, n).shape
              and not np.array_equal(getattr(m, n), getattr(first.port_model, n))]
    if not differ:
        return m
    m = copy.copy(m)
    for name in differ:
        getattr(m, name)[...] = getattr(first.port_model, name)
    return m


def _scan(runs: list[PortRun], precision: str) -> tuple[np.ndarray, np.ndarray, float, float]:
    """qpos and qvel after every step of every run, (batch, n_steps, nq|nv), with the scan's
    compile time and run time (s)."""
    dtype = np.float64 if precision == "float64" else np.float32
    with foreign_output("mjx", "JAX", _LOGGERS), refusing_unimplemented("MJX"):  # JAX starts its device here
        models = [mjx.put_model(_stepped_model(run, runs[0])) for run in runs]
        datas = [mjx.put_data(run.port_model, run.data) for run in runs]
        stack = lambda *leaves: jax.numpy.stack(leaves)  # noqa: E731
        mx = jax.tree_util.tree_map(stack, *models)
        dx = jax.tree_util.tree_map(stack, *datas)
        nu = runs[0].port_model.nu
        ctrl = jax.numpy.asarray(np.stack([run.ctrl if nu else np.zeros((run.n_steps, 0)) for run in runs]),
                                 dtype=dtype)
        key = (jax.tree_util.tree_structure((mx, dx)),
               tuple((leaf.shape, str(leaf.dtype)) for leaf in jax.tree_util.tree_leaves((mx, dx, ctrl))))
    compile_s = 0.0
    compiled = _COMPILED.get(key)
    if compiled is None:  # said first, with the last compile's time (compile_record); JAX's talk kept meanwhile
        with compiling("mjx", jax.default_backend(), _cache_dir(), runs[0].scene.name) as timed, \
                foreign_output("mjx", "JAX", _LOGGERS):
            compiled = _COMPILED[key] = jax.jit(jax.vmap(_rollout)).lower(mx, dx, ctrl).compile()
        compile_s = timed.seconds
    with foreign_output("mjx", "JAX", _LOGGERS):
        start = time.perf_counter()
        qpos, qvel = jax.block_until_ready(compiled(mx, dx, ctrl))
        wall = time.perf_counter() - start
    return np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float), compile_s, wall


def _cache_dir() -> Path:
    """Where the compile's time is recorded (compile_record): beside JAX's persistent compilation
    cache (``JAX_COMPILATION_CACHE_DIR``, ``jax_compilation_cache_dir``), or, without one, in
    loopcheck's cache folder (each process then compiles afresh)."""
    configured = jax.config.jax_compilation_cache_dir
    return Path(configured) if configured else user_cache_dir() / "jax-without-cache"
