"""numba options of the kernels: which run without numba's runtime.

numba counts references to every array a function receives: a call to ``NRT_incref`` at the
function's entry and to ``NRT_decref`` at its exit for each array argument, and again around
every callee inlined into it. The calls are never inlined (~1 ns each, even on the chart's
views, which own no memory), and the physics is small functions of many array arguments: on
the seed they were 35 % of an evaluation of q̈ (815 → 526 ns, ``benchmarks/compiled_core.py``).

A function compiled with :data:`NO_RUNTIME` runs without the runtime. It may read and write the
arrays it is given and views of them, but it must not allocate an array, and it must not return
one: nothing would free it. A function that does either is compiled with :data:`RUNTIME`, said
explicitly, since a callee otherwise inherits its caller's setting.

``_nrt`` is numba's own option (``numba.core.options.DefaultOptions``), not a documented one:
where a numba release lacks it, every kernel keeps the runtime, slower but the same results.
"""

from __future__ import annotations

try:
    from numba.core.options import DefaultOptions
except ImportError:  # pragma: no cover
    DefaultOptions = None

_HAS_RUNTIME_OPTION = DefaultOptions is not None and hasattr(DefaultOptions, "_nrt")

#: njit options of a kernel that allocates no array and returns none it did not receive
NO_RUNTIME = {"_nrt": False} if _HAS_RUNTIME_OPTION else {}
#: njit options of a kernel that allocates an array or returns a new view
RUNTIME = {"_nrt": True} if _HAS_RUNTIME_OPTION else {}
