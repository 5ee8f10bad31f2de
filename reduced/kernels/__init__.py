"""Compiled (numba) kernels of the reduced solver."""
