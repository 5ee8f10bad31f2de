"""Run a scene's MuJoCo model with MJWarp (:func:`simulate_mjwarp`), or a batch of variants of it
as MJWarp's worlds, one per variant (:func:`simulate_batch`), and return
:class:`~loopcheck.results.EngineResult` s.

The step loop: the controls of every step and every world go to the device once; per step one
copy sets ``ctrl`` of every world, ``mjw.step`` steps them all, and two copies append qpos and
qvel to arrays that stay on the device until the run ends (one copy back to the host). Warp
compiles MJWarp's kernels on first use (about 60 s on a 2-core CPU) and keeps them in its kernel
cache (``~/.cache/warp``); one step before the run, on a scratch copy of the data, pays that and
is recorded as ``compile_s``, announced first with the last compile's time
(:mod:`loopcheck.mujoco_model.compile_record`). What warp prints (its banner, its CUDA warning on a
machine without a driver) is kept and logged in loopcheck's words
(:mod:`loopcheck.mujoco_model.foreign_output`). MuJoCo C reads the states back (:func:`loopcheck.mujoco_model.port.finish`):
the energy audit and the loop gap are MuJoCo C's functions at MJWarp's states (MJWarp computes no
energy here).

What a batch may vary: the model's values that MJWarp keeps per world (the fields of
``mujoco_warp.Model`` and of its ``opt`` whose shape starts with ``*``: masses, inertias, body
frames, the dampers' ``tendon_damping``, ``eq_data`` of the loops, gravity, ...: :data:`BATCHED_FIELDS`
after the first run), and the state and the controls, which are per world in ``Data``. A variant
whose model differs in a field that MJWarp shares between worlds is refused in one line naming it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from dataclasses import dataclass, replace
from importlib import metadata
from pathlib import Path

import numpy as np

from loopcheck.mujoco_model.build import check_mujoco_version
from loopcheck.mujoco_model.compile_record import compiling
from loopcheck.mujoco_model.foreign_output import foreign_output
from loopcheck.mujoco_model.port import (MAX_STATE_BYTES, PortRefusal, PortRun, finish, finished, known_defects,
                                         model_structure, prepare, prepared, refusing_unimplemented, stack_runs,
                                         states_limit)
from loopcheck.results import EngineResult
from loopcheck.scene import Scene

from .settings import MjwarpSettings

_LOGGERS = ("warp", "mujoco_warp")  # warp's and MJWarp's loggers

try:
    with foreign_output("mjwarp", "Warp", _LOGGERS):  # what warp says as it loads, in loopcheck's words (foreign_output)
        import warp as wp

        # Warp prints a line per kernel module it compiles or loads (hundreds for one step of
        # MJWarp), and its banner at init: an engine's run prints nothing of its own (the CLI's
        # output is the report).
        wp.config.quiet = True
        wp.config.log_level = wp.LOG_WARNING  # warp 1.19 prints each module load at LOG_INFO, its default
        import mujoco_warp as mjw
except ModuleNotFoundError as exc:  # the optional extra
    raise ModuleNotFoundError("the mjwarp engine needs warp and MJWarp: pip install -e '.[mjwarp]' in loopcheck's checkout, then "
                              "pip install --no-deps mujoco-warp (docs/engines.md, 'MJWarp')", name=exc.name) from exc

import mujoco  # noqa: E402  (after the extra's check: the message above names what is missing)

check_mujoco_version(mujoco.__version__)  # installing MJWarp with pip's resolver can replace MuJoCo (docs/engines.md)

MJWARP_VERSION = metadata.version("mujoco-warp")
# The defect found for issue 28 (docs/engines.md, "MJWarp"): MJWarp 4.0.0's make_constraint reads
# cvel and cdof_dot for the loops' J̇·q̇ before fwd_velocity recomputes them, so every evaluation
# uses the previous one's velocities (refreshing them first cut the seed's max |Δq| 3.4x).
KNOWN_DEFECT = ("MJWarp {version} computes the loop constraints' J̇·q̇ from the previous evaluation's body "
                "velocities (make_constraint runs before fwd_velocity), and runs in float32: expect errors of "
                "order 1e-4 on closed loops (docs/engines.md)")
DEFECT_CHECKED = "4.0.0"  # the newest MJWarp release found to have it
with foreign_output("mjwarp", "Warp", _LOGGERS):  # warp's start: its CUDA warning from C++ on stderr, its banner
    wp.init()

# Model fields that differ between variants but that mjw.step does not read: the keyframes
# (read by reset_data_keyframe only; the port sets the state itself) and dof_length (read by
# sleeping only, which the model does not enable).
_UNREAD_PREFIXES = ("key_",)
_UNREAD = frozenset({"dof_length"})


def _spec_batched(field_type) -> bool:
    shape = getattr(field_type, "shape", None)
    return isinstance(shape, tuple) and len(shape) > 0 and shape[0] == "*"


def _is_array_spec(field_type) -> bool:
    return isinstance(getattr(field_type, "shape", None), tuple)


# name -> whether MJWarp keeps it per world, for the model's arrays and its options' (mjw.Model.opt)
_MODEL_ARRAYS = {f.name: _spec_batched(f.type) for f in dataclasses.fields(mjw.Model) if _is_array_spec(f.type)}
_OPTIONS = {f.name: _spec_batched(f.type) for f in dataclasses.fields(mjw.Model.__dataclass_fields__["opt"].type)}
BATCHED_FIELDS = frozenset((*(name for name, batched in _MODEL_ARRAYS.items() if batched),
                            *(f"opt.{name}" for name, batched in _OPTIONS.items() if batched)))


@dataclass(frozen=True)
class MjwarpDetails:
    """The MJWarp engine's own record of a run (:attr:`EngineResult.details`).

    device : warp's device that ran it ("cpu", "cuda:0", ...): warp's default device, the GPU
        when warp sees one. precision : "float32" (MJWarp's only one).
    batch : the worlds run together (1 for :func:`simulate_mjwarp`).
    batched_fields : the model's fields given per world (those in which the batch's variants
        differ), e.g. ("tendon_damping",); empty for one run.
    compile_s : s, the first step's time, on a scratch copy of the data: warp's kernel compile,
        or loading them from warp's cache (~/.cache/warp). Wall time per variant is
        ``EngineResult.wall_s`` (the batch's run divided by ``batch``).
    initial_residuals : MuJoCo C's loop residuals at the start.
    edge_warnings : one note per load edge off the step grid.
    versions : MJWarp's, warp's and MuJoCo C's (which built the model and reads the states back).
    """

    device: str
    precision: str
    batch: int
    batched_fields: tuple[str, ...]
    compile_s: float
    initial_residuals: dict
    edge_warnings: tuple[str, ...]
    versions: dict

    def as_dict(self) -> dict:
        return {"device": self.device, "precision": self.precision, "batch": self.batch,
                "batched_fields": list(self.batched_fields), "compile_s": self.compile_s,
                "initial_residuals": dict(self.initial_residuals), "edge_warnings": list(self.edge_warnings),
                "versions": dict(self.versions)}


def simulate_mjwarp(scene: Scene, settings: MjwarpSettings = MjwarpSettings()) -> EngineResult:
    """Step the scene's MuJoCo model with MJWarp to the horizon (float32).

    Raises
    ------
    PortRefusal (a ValueError)
        What MJWarp does not run (point forces), or a run beyond the limits, in one line.
    NumericalFailure
        INITIAL_STATE, NON_FINITE, CONSTRAINT_DRIFT, ENERGY_IMBALANCE (MuJoCo C's checks at MJWarp's states).
    """
    return simulate_batch([scene], settings)[0]


def simulate_batch(scenes: list[Scene], settings: MjwarpSettings = MjwarpSettings(), *,
                   each: bool = False) -> list[EngineResult]:
    """Step variants of one model together, one MJWarp world each: the same structure and step
    count; values may differ where MJWarp keeps them per world (module docstring), and the
    initial state and the loads. Each result's ``wall_s`` is the batch's run time divided by the
    batch's size.

    With ``each``, one outcome per scene: its result or the exception its own run raises
    (a refusal or NumericalFailure of one variant sinks no other; a variant refused before the
    run has its world filled by another's run, so the batch keeps its size).

    Raises
    ------
    PortRefusal (a ValueError)
        Scenes of other structures in one batch, variants differing in a model field that MJWarp
        shares between worlds, or what :func:`simulate_mjwarp` refuses.
    NumericalFailure
        As :func:`simulate_mjwarp`, for the first variant that fails (without ``each``).
    """
    if not scenes:
        raise ValueError("simulate_batch needs at least one scene")
    outcomes, ready = prepared(scenes, lambda scene: prepare(scene, settings, "MJWarp", "mjwarp"), each)
    if not ready:
        return outcomes
    stack_runs([run for _, run in ready], "MJWarp")
    runs = [run for _, run in ready] + [ready[-1][1]] * (len(scenes) - len(ready))  # the batch's size
    model_fields, opt_fields = _batched_fields(runs)
    need = 4 * len(runs) * (runs[0].port_model.nq + runs[0].port_model.nv) * runs[0].n_steps
    if need > MAX_STATE_BYTES:
        raise PortRefusal(f"MJWarp batch of {len(runs)} runs of {runs[0].n_steps} steps needs about "
                          f"{need / 1024 ** 3:.3g} GiB of states on the device, more than "
                          f"{MAX_STATE_BYTES / 1024 ** 3:g} GiB: split the batch")
    wp.init()
    qpos, qvel, compile_s, wall = _rollout(runs, model_fields, opt_fields)
    batch = MjwarpDetails(device=str(wp.get_device()), precision="float32", batch=len(runs),
                          batched_fields=tuple(sorted((*model_fields, *(f"opt.{n}" for n in opt_fields)))),
                          compile_s=compile_s, initial_residuals={}, edge_warnings=(),
                          versions={"mujoco_warp": MJWARP_VERSION, "warp": wp.__version__, "mujoco": mujoco.__version__})
    per_step = 4 if settings.integrator == "rk4" else 1
    defect = KNOWN_DEFECT.format(version=MJWARP_VERSION)
    for j, (k, run) in enumerate(ready):
        details = replace(batch, initial_residuals=run.initial, edge_warnings=run.edge_notes)
        caveats = known_defects(run, MJWARP_VERSION, DEFECT_CHECKED, defect)
        outcomes[k] = finished(lambda: finish(run, qpos[:, j], qvel[:, j], name="mjwarp", engine="MJWarp",
                                              wall_s=wall / len(runs), evaluations_per_step=per_step,
                                              details=details, caveats=caveats), each)
    return outcomes


def batch_limit(scene: Scene, settings: MjwarpSettings = MjwarpSettings()) -> int:
    """The most variants of ``scene``'s structure one batch holds: the device's memory (warp's
    ``total_memory`` of a GPU, half of it for the stored states) and the host's
    (:data:`~loopcheck.mujoco_model.port.MAX_STATE_BYTES`, which also bounds the states kept on
    the device) over one variant's states, its model's nq + nv × its steps, in float32."""
    run = prepare(scene, settings, "MJWarp", "mjwarp")
    wp.init()
    device = wp.get_device()
    return states_limit(run, 4, getattr(device, "total_memory", 0) if device.is_cuda else None)


def _differs(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape != b.shape or not np.array_equal(a, b)


def _batched_fields(runs: list[PortRun]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The model's fields and the options' fields in which the batch's variants differ, each one
    MJWarp keeps per world.

    Raises
    ------
    PortRefusal
        A variant differs from the first in a field that MJWarp shares between worlds.
    """
    m0 = runs[0].port_model
    model, opt = set(), set()
    for k, run in enumerate(runs[1:], start=1):
        m = run.port_model
        for name, batched in _MODEL_ARRAYS.items():
            if not hasattr(m0, name) or not _differs(getattr(m0, name), getattr(m, name)):
                continue
            if batched:
                model.add(name)
            elif not (name in _UNREAD or name.startswith(_UNREAD_PREFIXES)):
                raise _refusal(runs, k, name)
        for name, batched in _OPTIONS.items():
            if not hasattr(m0.opt, name) or not _differs(getattr(m0.opt, name), getattr(m.opt, name)):
                continue
            if batched:
                opt.add(name)
            else:
                raise _refusal(runs, k, f"opt.{name}")
    return tuple(sorted(model)), tuple(sorted(opt))


def _refusal(runs: list[PortRun], k: int, name: str) -> PortRefusal:
    return PortRefusal(f"MJWarp shares the model's {name} between the worlds of a batch, and scene {k} "
                       f"({runs[k].scene.name}) differs from scene 0 ({runs[0].scene.name}) there: run them "
                       "in separate batches")


def _per_world(runs: list[PortRun], field: str, owner=lambda m: m) -> np.ndarray:
    return np.stack([np.asarray(getattr(owner(run.port_model), field), dtype=float) for run in runs])


def _model(runs: list[PortRun], model_fields: tuple[str, ...], opt_fields: tuple[str, ...]):
    """MJWarp's model of the batch: the first run's, with ``model_fields`` and ``opt_fields``
    given per world."""
    nworld = len(runs)
    with refusing_unimplemented("MJWarp"):
        mw = mjw.put_model(runs[0].port_model, batch_sizes={name: nworld for name in model_fields})
    for name in model_fields:
        getattr(mw, name).assign(_per_world(runs, name))
    for name in opt_fields:
        old = getattr(mw.opt, name)
        values = _per_world(runs, name, owner=lambda m: m.opt)
        if name == "tolerance":
            values = np.maximum(values, 1e-6)  # as put_model raises it (MJWarp is float32)
        new = wp.array(values, dtype=old.dtype, shape=(nworld,), device=old.device)
        new._is_batched = True  # as mujoco_warp's put_model marks its batched arrays (warp_util.mark_batched)
        setattr(mw.opt, name, new)
    return mw


def _data(runs: list[PortRun], mw):
    """MJWarp's data for the batch's worlds: each world's initial state (qpos, qvel and the
    solver's warm start) from its own run, and one ``mjw.forward`` of every world.

    The forward pass is needed: MJWarp 4.0.0's ``make_constraint`` (in ``fwd_position``) reads
    ``cvel`` and ``cdof_dot`` for the loops' J̇·q̇ before ``fwd_velocity`` recomputes them, so a
    step starts from the velocities its data already holds; ``put_data`` tiles the first run's
    into every world. Measured: without it a variant of another initial state differed from its
    single run by 1.1e-4 rad in q over 0.2 s.
    """
    first = runs[0]
    dw = mjw.put_data(first.port_model, first.data, nworld=len(runs))
    for name in ("qpos", "qvel", "qacc_warmstart"):
        getattr(dw, name).assign(np.stack([np.asarray(getattr(run.data, name), dtype=float) for run in runs]))
    mjw.forward(mw, dw)
    return dw


def _rollout(runs: list[PortRun], model_fields, opt_fields) -> tuple[np.ndarray, np.ndarray, float, float]:
    """qpos and qvel after every step of every world, (n_steps, nworld, nq|nv), with the first
    step's time on scratch data (the kernels' compile, s) and the run's time (s)."""
    nworld, n = len(runs), runs[0].n_steps
    m0 = runs[0].port_model
    nq, nv, nu = m0.nq, m0.nv, m0.nu
    with foreign_output("mjwarp", "Warp", _LOGGERS):
        mw = _model(runs, model_fields, opt_fields)

    # the kernels' compile (or their load from warp's cache), said first with the last one's time
    # (compile_record) when this process has not run the structure yet; warp's talk kept meanwhile
    structure = model_structure(m0)
    announce = compiling("mjwarp", str(wp.get_device()), _cache_dir(), runs[0].scene.name) \
        if structure not in _STEPPED else contextlib.nullcontext()
    with announce, foreign_output("mjwarp", "Warp", _LOGGERS):
        start = time.perf_counter()
        scratch = _data(runs, mw)
        mjw.step(mw, scratch)
        wp.synchronize()
        compile_s = time.perf_counter() - start
        del scratch
    _STEPPED.add(structure)

    with foreign_output("mjwarp", "Warp", _LOGGERS):
        dw = _data(runs, mw)
        device = dw.qpos.device
        ctrl = np.stack([run.ctrl for run in runs], axis=1) if nu else np.zeros((n, nworld, 0))
        ctrl_all = wp.array(ctrl.reshape(n, nworld * nu), dtype=float, device=device)
        qpos_all = wp.empty((n, nworld * nq), dtype=float, device=device)
        qvel_all = wp.empty((n, nworld * nv), dtype=float, device=device)
        start = time.perf_counter()
        for k in range(n):
            if nu:
                wp.copy(dw.ctrl, ctrl_all, src_offset=k * nworld * nu, count=nworld * nu)
            mjw.step(mw, dw)
            wp.copy(qpos_all, dw.qpos, dest_offset=k * nworld * nq, count=nworld * nq)
            wp.copy(qvel_all, dw.qvel, dest_offset=k * nworld * nv, count=nworld * nv)
        qpos = qpos_all.numpy().reshape(n, nworld, nq).astype(float)
        qvel = qvel_all.numpy().reshape(n, nworld, nv).astype(float)
        wall = time.perf_counter() - start
    return qpos, qvel, compile_s, wall


# The model structures this process has stepped: warp has their kernels loaded,
# and another batch of them compiles nothing (nor is a compile announced).
_STEPPED: set = set()


def _cache_dir() -> Path:
    """Where the compile's time is recorded (compile_record): beside warp's kernel cache
    (``WARP_CACHE_PATH``/<warp's version>, by default ``~/.cache/warp/<version>``), which
    ``wp.init()`` resolves."""
    return Path(wp.config.kernel_cache_dir)
