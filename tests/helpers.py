"""Shared by the tests: scene builders (real scenes, built from the seed file), scipy summed in the
compiled DOP853's order, and closed-form problems for the compiled integrators (ClosedForm)."""

from __future__ import annotations

import contextlib
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from loopcheck.scene import Scene
from loopcheck.scenefile import scene_from_dict
from loopcheck.reduced.kernels.problem import RightHandSide

ROOT = Path(__file__).resolve().parent.parent
SEED_SCENE = ROOT / "scenes" / "seed_fourbar.toml"
DATA = ROOT / "tests" / "data"  # the tests' data files, wherever a test module sits under tests/


def seed_dict() -> dict:
    with open(SEED_SCENE, "rb") as f:
        return tomllib.load(f)


def variant(*, drop: tuple[str, ...] = (), **changes) -> Scene:
    """The seed scene with top-level tables removed or replaced."""
    data = seed_dict()
    for key in drop:
        data.pop(key, None)
    data.update(changes)
    return scene_from_dict(data)


def conservative(qdot0: float = 10.0, horizon: float = 2.0) -> Scene:
    """Seed linkage, no damper, no torque, no gravity, started with speed qdot0 (rad/s)."""
    return variant(drop=("torque", "dampers", "tolerances"), initial={"q": 0.2, "qdot": qdot0},
                   simulation={"horizon": horizon})


def _locate(data, path: str):
    """(container, key) of a dotted path such as 'dampers[0].body_point[1]' inside parsed TOML."""
    parts = re.findall(r"[^.\[\]]+|\[\d+\]", path)
    node = data
    for part in parts[:-1]:
        node = node[int(part[1:-1])] if part.startswith("[") else node.setdefault(part, {})
    last = parts[-1]
    return node, int(last[1:-1]) if last.startswith("[") else last


DELETE = object()  # a patch value that removes the key


def patched(patch: dict) -> dict:
    """The seed scene's data with each dotted path set to its value (DELETE removes it)."""
    data = seed_dict()
    for path, value in patch.items():
        node, key = _locate(data, path)
        if value is DELETE:
            del node[key]
        else:
            node[key] = value
    return data


def coefficients_along(model, qs) -> list:
    """The model's coefficients at each input q of ``qs`` in turn, evaluated afresh
    (:meth:`MechanismModel.coefficients_at`) at the configuration that a chart of the input
    coordinate, walked from the scene's x0, reaches there: what ``model.coefficients(q)`` gives
    near q0 (MechanismModel.assemble is Newton from x0 and does not converge half a revolution
    away). Not the walked chart's own coefficients: those come from A factored before Newton's
    last step, up to ~1e-10 of V from the ones at the x it returns. The input must be a coordinate."""
    from loopcheck.reduced.charts import Chart

    chart = Chart(model, model.input_coordinate, model.x0)
    return [model.coefficients_at(chart.kinematics(float(q)).x) for q in qs]


def short_seed_file(folder: Path, horizon: str = "0.3") -> Path:
    """The seed scene file with a shorter horizon (s), written into ``folder``: a quick sweep."""
    text = SEED_SCENE.read_text()
    short = re.sub(r"(?m)^horizon = 2\.0.*$", f"horizon = {horizon}", text)
    assert short != text
    path = folder / "short.toml"
    path.write_text(short)
    return path


@contextlib.contextmanager
def plots_left_out():
    """``loopcheck run`` and ``loopcheck sweep`` (in this process) write their output sets without the plots
    while inside: for a test that reads only report.json, the CSVs or sweep.csv/sweep.json. The
    plots take most of a short run's time (~0.3 s each, ~2 s a set); they are tested where they
    are the subject: tests/compare/test_startup.py (every plot of a run drawn once, nothing cut
    off), test_compare.py and test_cli.py (the whole set written), test_sweep.py (every sweep
    plot, the worst variant's, the set written)."""
    import loopcheck.compare.report
    import loopcheck.compare.sweep

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(loopcheck.compare.report, "PLOTS", {})
        patch.setattr(loopcheck.compare.sweep, "plot_files", lambda spec: ())
        yield



class _NumpyInKernelOrder:
    """numpy, but for the sums of scipy's DOP853 on a 2-vector state: np.dot of the stages
    (2 × s by s) and of the dense output (D by K) and np.linalg.norm of a 2-vector, summed in the
    compiled kernel's fixed order (loopcheck.reduced.kernels.adaptive: _dot_kt, _dense_coefficients,
    _norm2). numpy hands these to the BLAS, whose order depends on the CPU (OpenBLAS picks its
    kernels at run time: on an AMD EPYC 1085 of 2000 random 2 × s products differ from the
    kernel's order in the last bit, and DOP853 at rtol 1e-12 turns such bits into other steps).
    The order is a convention both sides share, not a result under test."""

    def __init__(self):
        import numpy
        from types import SimpleNamespace

        self._np = numpy
        self.linalg = SimpleNamespace(**{k: getattr(numpy.linalg, k) for k in dir(numpy.linalg)
                                         if not k.startswith("__")})
        self.linalg.norm = self._norm

    def __getattr__(self, name):
        return getattr(self._np, name)

    def _norm(self, x, *args, **kwargs):
        from loopcheck.reduced.kernels.adaptive import _norm2

        x = self._np.asarray(x)
        if x.shape == (2,) and not args and not kwargs:
            return _norm2(float(x[0]), float(x[1]))
        return self._np.linalg.norm(x, *args, **kwargs)

    def dot(self, a, b):
        from loopcheck.reduced.kernels.adaptive import _dot_kt

        np_ = self._np
        a, b = np_.asarray(a), np_.asarray(b)
        if a.ndim == 2 and b.ndim == 1 and a.shape[0] == 2:  # K[:s].T · a[:s]
            out = np_.empty(2)
            _dot_kt(np_.ascontiguousarray(a.T), np_.ascontiguousarray(b, dtype=float), b.shape[0], out)
            return out
        if a.ndim == 2 and b.ndim == 2 and b.shape[1] == 2:  # D · K, each entry summed over j in turn
            out = np_.empty((a.shape[0], 2))
            for r in range(a.shape[0]):
                for c in range(2):
                    acc = 0.0
                    for j in range(a.shape[1]):
                        acc += a[r, j] * b[j, c]
                    out[r, c] = acc
            return out
        return np_.dot(a, b)


def scipy_in_kernel_order():
    """A context in which scipy's RK solvers (and select_initial_step) sum as the compiled
    DOP853 does (:class:`_NumpyInKernelOrder`): for the tests that compare them step for step."""
    import contextlib
    from unittest import mock

    from scipy.integrate._ivp import common, rk

    stack = contextlib.ExitStack()
    ordered = _NumpyInKernelOrder()
    for module in (rk, common):
        stack.enter_context(mock.patch.object(module, "np", ordered))
    return stack


class _NumpyInVectorKernelOrder:
    """numpy, but for scipy's DOP853 sums of any number of components: np.dot of the stages
    (2n × s by s) by vector_adaptive._dot_kt, np.dot of the dense output (D by K) each entry summed
    over j in turn, np.linalg.norm of a vector by vector_adaptive._norm (plainly from the first
    component). The order is a convention both sides share (:class:`_NumpyInKernelOrder` at n = 1)."""

    def __init__(self):
        from types import SimpleNamespace

        self.linalg = SimpleNamespace(**{k: getattr(np.linalg, k) for k in dir(np.linalg) if not k.startswith("__")})
        self.linalg.norm = self._norm

    def __getattr__(self, name):
        return getattr(np, name)

    @staticmethod
    def _norm(x, *args, **kwargs):
        from loopcheck.reduced.kernels import vector_adaptive

        x = np.asarray(x)
        if x.ndim == 1 and not args and not kwargs:
            return vector_adaptive._norm(np.ascontiguousarray(x, dtype=float))
        return np.linalg.norm(x, *args, **kwargs)

    @staticmethod
    def dot(a, b):
        from loopcheck.reduced.kernels import vector_adaptive

        a, b = np.asarray(a), np.asarray(b)
        if a.ndim == 2 and b.ndim == 1:  # K[:s].T · a[:s]
            out = np.empty(a.shape[0])
            vector_adaptive._dot_kt(np.ascontiguousarray(a.T), np.ascontiguousarray(b, dtype=float), b.shape[0], out)
            return out
        if a.ndim == 2 and b.ndim == 2:  # D · K
            out = np.empty((a.shape[0], b.shape[1]))
            for r in range(a.shape[0]):
                for c in range(b.shape[1]):
                    acc = 0.0
                    for j in range(a.shape[1]):
                        acc += a[r, j] * b[j, c]
                    out[r, c] = acc
            return out
        return np.dot(a, b)


def scipy_in_vector_kernel_order():
    """A context in which scipy's RK solvers (and select_initial_step) sum as the compiled
    n-coordinate DOP853 does (:class:`_NumpyInVectorKernelOrder`): for the tests that compare them
    step for step (tests/reduced/kernels/test_vector_integrators.py, tests/reduced/test_several_dof.py)."""
    from unittest import mock

    from scipy.integrate._ivp import common, rk

    stack = contextlib.ExitStack()
    ordered = _NumpyInVectorKernelOrder()
    for module in (rk, common):
        stack.enter_context(mock.patch.object(module, "np", ordered))
    return stack


def without_dyad_plans(model):
    """``model``'s kernel arrays with every chart's dyad plan switched off: Newton's method alone
    closes the loops (loopcheck.reduced.kernels.physics._close)."""
    from loopcheck.reduced.kernels import physics

    I = model.arrays.I.copy()
    start = int(I[physics.DYAD_PLAN])
    I[start:start + len(model.coordinate_names)] = -1
    return physics.Model(model.arrays.F, I)


# ---------------------------------------------------------------- signals and child processes
# A suite started in the background (`pytest &`) inherits SIGINT ignored, and a child inherits
# that too: the tests that send signals set the disposition they need, in this process and in
# each child, and kill whatever child they started, whatever the outcome.

def default_signal_disposition() -> None:
    """``preexec_fn`` of a child that is to be interrupted: SIGINT and SIGTERM at their
    defaults (Python then turns SIGINT into KeyboardInterrupt), whatever the parent ignores."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@pytest.fixture
def interruptible():
    """SIGINT raises KeyboardInterrupt in this process for the test, as in a foreground shell."""
    import signal

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture
def spawn():
    """``spawn(args, **popen_kwargs)``: a ``subprocess.Popen`` with SIGINT and SIGTERM at their
    defaults in the child; every one still running at the end of the test is killed (its whole
    process group with ``start_new_session=True``: the forked writers too) and waited for."""
    import os
    import signal
    import subprocess

    started: list = []

    def start(args, **kwargs):
        proc = subprocess.Popen(args, preexec_fn=default_signal_disposition, **kwargs)
        started.append((proc, kwargs.get("start_new_session", False)))
        return proc

    yield start
    for proc, own_group in started:
        if own_group:  # the group outlives its leader while a member runs; pgid = the leader's pid
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=60)


class ClosedForm(RightHandSide):
    """A closed-form problem for the compiled integrators (loopcheck.reduced.kernels.fixed_step, .adaptive):
    q̈ = f(t, q, q̇, u) with u = values[load] constant on each load piece; the energy flows
    P = power(u, q̇) (default u q̇: u a force doing work) and D = dissipation(q̇) (default 0);
    the stop margin stop(t, q, q̇) (default: never). A Python subclass of RightHandSide: the
    kernels call it through the interpreter (about 1 µs an evaluation), so keep runs short."""

    def __init__(self, f, values=(0.0,), *, power=None, dissipation=None, stop=None):
        self.f, self.values = f, [float(u) for u in values]
        self._power, self._dissipation, self._stop = power, dissipation, stop

    def acceleration(self, load, t, q, v):
        return self.f(t, q, v, self.values[load])

    def power(self, load, v):
        return self.values[load] * v if self._power is None else self._power(self.values[load], v)

    def dissipation(self, v):
        return 0.0 if self._dissipation is None else self._dissipation(v)

    def stop_margin(self, t, q, v):
        return 1.0 if self._stop is None else self._stop(t, q, v)


def run_rkn(rhs, edges, q0, v0, step, *, tableau=None, loads=None, t0=None, speed_limit=1e6, stability=True,
            use_stop=False):
    """rkn_chart from edges[0] (or t0) on the pieces ``edges`` (load k on piece k unless given):
    (Outcome, t, q, v, a, energy (m, 2))."""
    from loopcheck.reduced.kernels.fixed_step import RKN4, rkn_chart
    from loopcheck.reduced.kernels.output import Samples

    edges = np.ascontiguousarray(edges, dtype=float)
    loads = np.arange(len(edges) - 1, dtype=np.intp) if loads is None else np.asarray(loads, dtype=np.intp)
    out = Samples(rhs.observation_size())
    outcome = rkn_chart(rhs, RKN4 if tableau is None else tableau, edges, loads,
                        float(edges[0] if t0 is None else t0), float(q0), float(v0), float(step),
                        float(speed_limit), stability, use_stop, out)
    t, q, v, a, _, energy = out.arrays()
    return outcome, t, q, v, a, energy


def run_dop853(rhs, edges, q0, v0, *, rtol=1e-12, atol=None, loads=None, sample_interval=0.05, per_step=4,
               speed_limit=1e6, max_evaluations=1_000_000, max_step=np.inf, use_stop=False, steps=None):
    """dop853_run on the pieces ``edges`` (load k on piece k unless given):
    (Outcome, t, q, v, a, energy (m, 2))."""
    from loopcheck.reduced.kernels.adaptive import Steps, dop853_run
    from loopcheck.reduced.kernels.output import Samples

    edges = np.ascontiguousarray(edges, dtype=float)
    loads = np.arange(len(edges) - 1, dtype=np.intp) if loads is None else np.asarray(loads, dtype=np.intp)
    out = Samples(rhs.observation_size())
    outcome = dop853_run(rhs, edges, loads, float(q0), float(v0), rtol, rtol if atol is None else atol,
                         sample_interval, per_step, speed_limit, max_evaluations, max_step, use_stop, out,
                         Steps() if steps is None else steps)
    t, q, v, a, _, energy = out.arrays()
    return outcome, t, q, v, a, energy
