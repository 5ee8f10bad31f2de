"""Compiled (numba) kernels of the reduced solver: physics, integrators, partitioning.

Debugging: ``NUMBA_DISABLE_JIT=1`` runs the same code as plain Python (slow, but it can be
stepped through and printed from).
"""

from ._cache import follow_the_whole_package

follow_the_whole_package()  # before any kernel is defined
