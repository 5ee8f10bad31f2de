"""xval: the dynamics of one-DOF planar linkages solved independent ways, and how far apart they are.

Subpackages: :mod:`xval.reduced` (Eksergian's equation, the exact reference, with its compiled
core), :mod:`xval.reference_models` (the same mechanism in MuJoCo), :mod:`xval.compare` (the
comparison, the gate, the studies and the command line ``xval``); the shipped scenes are
:mod:`xval.scenes`' package data.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("xval")
except PackageNotFoundError:  # a checkout that was never installed
    __version__ = "0+unknown"
