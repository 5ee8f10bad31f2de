"""Compiled (numba) kernels of the reduced solver: physics, integrators, partitioning."""
