"""Compile the reduced solver's kernels into numba's on-disk cache, before the first run.

numba compiles a kernel the first time it is called in a process that finds no cached copy;
for the whole reduced solver that takes about 30–60 s on a 2-core machine, once per install
(and again after an edit of ``reduced/kernels``). :func:`compile_kernels` pays it up front, in
two processes: the compiled run of the integrators (the largest kernel) in one, every other
entry point in the other. Later processes load the kernels from the cache in well under a second.
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

GROUPS = ("runs", "charts")  # the two halves compiled side by side


def kernels_cached() -> bool:
    """Whether numba's cache holds the compiled run for the current sources (False when it
    cannot tell: then the first run compiles, as without the cache)."""
    from .kernels import partition
    try:
        return bool(partition._run._cache._cache_file._load_index())  # numba internals
    except Exception:  # noqa: BLE001 - any change in numba's internals: say "not cached"
        return False


def _compile_group(group: str) -> float:
    """Call every kernel of one group on the seed scene (a short run); returns the seconds."""
    import warnings

    from .dynamics import MechanismModel
    from .engine import ReducedSettings, integrate
    from .scenefile import default_scene_path, load_scene

    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = MechanismModel(load_scene(default_scene_path()))
        if group == "runs":
            integrate(model, ReducedSettings(method="rkn4", step=0.1))
        else:  # the charts' own entry points, through the scipy path and the model's
            model.coefficients_at(model.x0)
            integrate(model, ReducedSettings(method="scipy-dop853", rtol=1e-3))
    return time.perf_counter() - start


def compile_kernels(processes: int = 2) -> dict[str, float]:
    """Compile every kernel into numba's cache; the seconds each group took (compiling in
    ``processes`` processes, 1 for in this one)."""
    if processes <= 1:
        return {g: _compile_group(g) for g in GROUPS}
    with ProcessPoolExecutor(max_workers=min(processes, len(GROUPS)), mp_context=get_context("spawn")) as pool:
        return dict(zip(GROUPS, pool.map(_compile_group, GROUPS)))
