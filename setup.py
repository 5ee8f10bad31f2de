"""Build of the compiled core: the loop kinematics and the reduced solver's kernels (Cython 3, pure-Python mode).

The kernels are ordinary ``.py`` files annotated for Cython (``loopcheck/kernels``, ``loopcheck/reduced/kernels``); ``pip install``
and ``pip wheel`` compile each into a C extension of the same module name, which Python imports
in preference to the ``.py`` beside it (``LOOPCHECK_PURE_PYTHON=1`` imports the ``.py`` instead:
``loopcheck/reduced/kernels/__init__.py``). Everything else about the package is in ``pyproject.toml``.

Flags (the README's "Compiled core" says why): ``-ffp-contract=off`` (no fused multiply-add:
a*b+c rounds twice, as numpy and scipy compute it, on every compiler and CPU) and no fast-math
(IEEE semantics: NaN and inf propagate, no reassociation); Cython's ``cdivision`` gives C's IEEE
division (x/0 is inf or NaN, as in numpy, instead of Python's ZeroDivisionError).
``LOOPCHECK_CHECKED_BUILD=1`` builds with bounds checks on every array index (an out-of-range index
raises IndexError instead of reading past a buffer): CI runs the kernel tests on such a build.
"""

import os
import sys
import tempfile

from Cython.Build import cythonize
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class ParallelBuildExt(build_ext):
    """build_ext compiling the modules side by side, one per core, unless told otherwise."""

    def finalize_options(self):
        super().finalize_options()
        if not self.parallel:
            self.parallel = os.cpu_count() or 1


# the compiled modules, by package: the mechanism layer's kinematics, the reduced engine's core
KERNELS = {"loopcheck.kernels": ("loops",),
           "loopcheck.reduced.kernels": ("problem", "output", "physics", "fixed_step", "adaptive", "partition", "vector_problem", "vector_output", "vector_adaptive", "vector_fixed_step", "several")}
CHECKED = os.environ.get("LOOPCHECK_CHECKED_BUILD", "") not in ("", "0")

DIRECTIVES = {
    "language_level": 3,
    "boundscheck": CHECKED,
    "wraparound": False,
    "initializedcheck": CHECKED,
    "cdivision": True,
    "embedsignature": True,
}
CFLAGS = ["-O2", "-ffp-contract=off", "-fno-fast-math"] + (["-O0", "-g"] if CHECKED else [])

# Cython's support code (memoryviews: ~25 000 lines of C) compiled once, in a module of its own
# that the kernels import, rather than into each of them (5 s of gcc per kernel)
SHARED = "loopcheck.kernels._cython"

# `pip install .` and `pip wheel .` build out of the source tree (setuptools' build/ and egg-info,
# Cython's C files in a temporary folder that is removed when the build ends); an editable install
# (`pip install -e .`) and `build_ext --inplace` build in place, where the compiled modules belong.
IN_PLACE = any(arg in ("editable_wheel", "develop", "--inplace", "-i") for arg in sys.argv[1:])
OUT_OF_TREE = None if IN_PLACE else tempfile.TemporaryDirectory(prefix="loopcheck-build-")
BUILD = "build" if IN_PLACE else OUT_OF_TREE.name
OPTIONS = {} if IN_PLACE else {"build": {"build_base": BUILD}, "egg_info": {"egg_base": BUILD}}

extensions = [Extension(SHARED, sources=[], extra_compile_args=CFLAGS)] + [
    Extension(f"{package}.{name}", [f"{package.replace('.', '/')}/{name}.py"], extra_compile_args=CFLAGS)
    for package, names in KERNELS.items() for name in names
    if os.path.exists(f"{package.replace('.', '/')}/{name}.pxd")
]

setup(cmdclass={"build_ext": ParallelBuildExt}, options=OPTIONS,
      ext_modules=cythonize(extensions, compiler_directives=DIRECTIVES, quiet=True, nthreads=os.cpu_count() or 1,
                            shared_utility_qualified_name=SHARED,
                            build_dir=f"{BUILD}/cython-checked" if CHECKED else f"{BUILD}/cython"))
