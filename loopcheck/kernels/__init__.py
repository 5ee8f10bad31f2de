"""The mechanism layer's compiled core: the loop kinematics (:mod:`loopcheck.kernels.loops`, Cython 3).

Each module here is an ordinary Python file annotated for Cython's pure-Python mode, as the
reduced engine's kernels are (:mod:`loopcheck.reduced.kernels`); the package's build (``setup.py``,
run by ``pip install``) compiles each into a C extension of the same name, which Python imports
in preference to the source beside it. Nothing is compiled or cached at run time.

Debugging: ``LOOPCHECK_PURE_PYTHON=1`` (set before the first import of ``loopcheck``'s kernels) imports the
``.py`` sources instead, here and in :mod:`loopcheck.reduced.kernels`: the same algorithms run as plain
Python (the slow reference). Where a module was never compiled (a checkout without
``pip install``), its source is imported anyway.
"""

import importlib.machinery
import importlib.util
import os
import sys

PURE_PYTHON = os.environ.get("LOOPCHECK_PURE_PYTHON", "") not in ("", "0")
# the packages whose modules run as their sources under LOOPCHECK_PURE_PYTHON
COMPILED_PACKAGES = ("loopcheck.kernels", "loopcheck.reduced.kernels")


class _SourcesFirst(importlib.machinery.PathFinder):
    """Finds the submodules of the compiled packages among their ``.py`` sources only."""

    @classmethod
    def find_spec(cls, fullname, path=None, target=None):
        package, _, name = fullname.rpartition(".")
        if package not in COMPILED_PACKAGES or not path:
            return None
        source = os.path.join(list(path)[0], name + ".py")
        if not os.path.isfile(source):
            return None
        return importlib.util.spec_from_file_location(fullname, source)


if PURE_PYTHON and not any(f is _SourcesFirst for f in sys.meta_path):
    if importlib.util.find_spec("cython") is None:  # the sources' annotations come from Cython's shadow module
        raise ImportError("LOOPCHECK_PURE_PYTHON=1 runs the kernels' sources, which import Cython's pure-Python "
                          "module: pip install cython (the `test` extra has it)")
    sys.meta_path.insert(0, _SourcesFirst)


def compiled() -> bool:
    """Whether the kinematics kernel runs compiled (False: its Python source, ``LOOPCHECK_PURE_PYTHON``)."""
    from . import loops

    return not loops.__file__.endswith(".py")
