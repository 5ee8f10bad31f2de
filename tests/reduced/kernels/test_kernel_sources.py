"""The compiled core's modules import in one direction, and nothing of the project outside it.

The integrators (:mod:`loopcheck.reduced.kernels.fixed_step`, :mod:`loopcheck.reduced.kernels.adaptive`) know only the
interface of a right-hand side and the output buffers (``problem``, ``output``; DOP853 its
tableau): nothing of linkages. The physics knows the interface and nothing of the integrators.
Only the chart switching (``partition``) knows both. And the core imports nothing of the project
outside ``loopcheck/reduced/kernels`` but the mechanism layer's compiled kinematics (``loopcheck/kernels``:
the physics cimports :class:`loopcheck.kernels.loops.Loops`), which imports nothing of the project at
all: both are compiled on their own, and their sources are their whole behaviour.
Read from the sources (both the ``import`` and the ``cimport`` lines of Cython's pure-Python mode).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from helpers import ROOT

KERNELS = ROOT / "loopcheck" / "reduced" / "kernels"
MECHANISM_KERNELS = ROOT / "loopcheck" / "kernels"
PROJECT_PACKAGES = ("loopcheck", "scenes", "benchmarks")
# what each kernel module may import of the others
ALLOWED = {
    "problem": set(),
    "output": set(),
    "dop853_tableau": set(),
    "fixed_step": {"problem", "output"},
    "adaptive": {"problem", "output", "dop853_tableau"},
    "physics": {"problem", "output", "loopcheck.kernels.loops"},
    "partition": {"adaptive", "fixed_step", "output", "physics", "problem"},
    "vector_problem": {"problem"},
    "vector_output": set(),
    "vector_adaptive": {"vector_problem", "vector_output", "output", "adaptive"},
    "vector_fixed_step": {"vector_problem", "vector_output", "output", "fixed_step"},
    "several": {"physics", "vector_problem", "loopcheck.kernels.loops"},
}


def _imports(path: Path) -> tuple[set[str], list[str]]:
    """The kernel modules one module imports, and its imports of project code outside the kernels."""
    siblings, outside = set(), []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if module.startswith("cython.cimports."):
                module = module[len("cython.cimports."):]
            if node.level == 1:
                siblings |= {module.split(".")[0]} if module else {a.name for a in node.names}
            elif node.level == 0 and module.startswith("loopcheck.kernels.") and path.parent == KERNELS:
                siblings.add(module)  # the mechanism layer's compiled kinematics, by its full name
            elif node.level == 0 and module.startswith("loopcheck.reduced.kernels"):
                rest = module[len("loopcheck.reduced.kernels"):].lstrip(".")
                siblings |= {rest.split(".")[0]} if rest else {a.name for a in node.names}
            elif node.level >= 2 or (node.level == 0 and module.split(".")[0] in PROJECT_PACKAGES):
                outside.append(f"{path.name}:{node.lineno}: from {'.' * node.level}{module} import ...")
        elif isinstance(node, ast.Import):
            outside += [f"{path.name}:{node.lineno}: import {a.name}" for a in node.names
                        if a.name.split(".")[0] in PROJECT_PACKAGES]
    return siblings, outside


@pytest.mark.parametrize("name", sorted(ALLOWED))
def test_a_kernel_module_imports_only_what_its_layer_allows(name):
    siblings, outside = _imports(KERNELS / f"{name}.py")
    assert not outside, "kernel modules importing project code outside the compiled core:\n" + "\n".join(outside)
    assert siblings <= ALLOWED[name], f"{name} imports {sorted(siblings - ALLOWED[name])} of the core"


def test_every_kernel_module_is_listed():
    assert {p.stem for p in KERNELS.glob("*.py")} - {"__init__"} == set(ALLOWED)


@pytest.mark.parametrize("path", sorted(set(MECHANISM_KERNELS.glob("*.py")) - {MECHANISM_KERNELS / "__init__.py"}), ids=lambda p: p.name)
def test_the_mechanism_layers_kernels_import_nothing_of_the_project(path):
    siblings, outside = _imports(path)
    assert not outside and not siblings, (siblings, outside)


def test_every_mechanism_kernel_is_built():
    """Each kernel of loopcheck/kernels has its .pxd (setup.py compiles the modules that have one)."""
    assert {p.stem for p in MECHANISM_KERNELS.glob("*.pxd")} == {
        p.stem for p in MECHANISM_KERNELS.glob("*.py")} - {"__init__"}
