"""The reduced solver's compiled core: physics, integrators, chart switching (Cython 3).

Each module here is an ordinary Python file annotated for Cython's pure-Python mode; the
package's build (``setup.py``, run by ``pip install``) compiles each into a C extension of the
same name, which Python imports in preference to the source beside it. Nothing is compiled or
cached at run time.

Debugging: ``XVAL_PURE_PYTHON=1`` (set before the first import of ``reduced``) imports the
``.py`` sources instead, where the compiled modules exist too: the same algorithms run as plain
Python (slow: a seed run takes minutes), and can be stepped through and printed from. Where a
module was never compiled (a checkout without ``pip install``), its source is imported anyway.
"""

import importlib.machinery
import os
import sys

PURE_PYTHON = os.environ.get("XVAL_PURE_PYTHON", "") not in ("", "0")


class _SourcesFirst(importlib.machinery.PathFinder):
    """Finds this package's submodules among their ``.py`` sources only."""

    @classmethod
    def find_spec(cls, fullname, path=None, target=None):
        if not fullname.startswith(__name__ + "."):
            return None
        name = fullname.rpartition(".")[2]
        source = os.path.join(os.path.dirname(__file__), name + ".py")
        if not os.path.isfile(source):
            return None
        return importlib.util.spec_from_file_location(fullname, source)


if PURE_PYTHON and not any(f is _SourcesFirst for f in sys.meta_path):
    import importlib.util

    if importlib.util.find_spec("cython") is None:  # the sources' annotations come from Cython's shadow module
        raise ImportError("XVAL_PURE_PYTHON=1 runs the kernels' sources, which import Cython's pure-Python "
                          "module: pip install cython (the `test` extra has it)")
    sys.meta_path.insert(0, _SourcesFirst)


def compiled() -> bool:
    """Whether the kernels run compiled (False: their Python sources, ``XVAL_PURE_PYTHON``)."""
    from . import problem

    return not problem.__file__.endswith(".py")
