"""The reduced solver's compiled core: physics, integrators, chart switching (Cython 3).

Each module here is an ordinary Python file annotated for Cython's pure-Python mode; the
package's build (``setup.py``, run by ``pip install``) compiles each into a C extension of the
same name, which Python imports in preference to the source beside it. Nothing is compiled or
cached at run time.

Debugging: ``LOOPCHECK_PURE_PYTHON=1`` (set before the first import of ``reduced``) imports the
``.py`` sources instead, where the compiled modules exist too: the same algorithms run as plain
Python (slow: a seed run takes minutes), and can be stepped through and printed from. Where a
module was never compiled (a checkout without ``pip install``), its source is imported anyway.
"""

# the switch and the finder of the sources are the mechanism layer's (loopcheck.kernels), which
# serves this package too: importing it installs the finder under LOOPCHECK_PURE_PYTHON
from loopcheck.kernels import PURE_PYTHON  # noqa: F401


def compiled() -> bool:
    """Whether the kernels run compiled (False: their Python sources, ``LOOPCHECK_PURE_PYTHON``)."""
    from . import problem

    return not problem.__file__.endswith(".py")
