"""The compiled kernels depend on their own package's sources alone.

numba freezes the module globals a kernel reads (constants, tables) into its machine code, and
the on-disk cache of the kernels is stamped with a hash of ``reduced/kernels/`` only
(``reduced/kernels/_cache.py``). A kernel module that imported a constant from elsewhere in the
project would keep running the old value from the cache after that constant was edited. The
constants both paths share (``RESTART_STEPS``, the RKN4 stability margins) therefore live in the
kernels, and the Python paths import them from there.
"""

from __future__ import annotations

import ast
from pathlib import Path

KERNELS = Path(__file__).resolve().parents[1] / "reduced" / "kernels"
PROJECT_PACKAGES = ("reduced", "compare", "reference_models", "scenes", "benchmarks")


def _imports_from_outside(path: Path) -> list[str]:
    """The imports of one kernel module that reach a project module outside the kernels."""
    outside = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level >= 2 or (node.level == 0 and (node.module or "").split(".")[0] in PROJECT_PACKAGES):
                outside.append(f"{path.name}:{node.lineno}: from {'.' * node.level}{node.module or ''} import ...")
        elif isinstance(node, ast.Import):
            outside += [f"{path.name}:{node.lineno}: import {a.name}" for a in node.names
                        if a.name.split(".")[0] in PROJECT_PACKAGES]
    return outside


def test_the_kernels_import_nothing_of_the_project_outside_their_package():
    modules = sorted(KERNELS.glob("**/*.py"))
    assert len(modules) >= 8  # the package is where the test thinks it is
    outside = [line for m in modules for line in _imports_from_outside(m)]
    assert not outside, "kernel modules importing project code the cache stamp does not cover:\n" + "\n".join(outside)
