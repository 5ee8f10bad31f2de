"""Numerical failures: detected, named and raised, never returned as a result."""

from __future__ import annotations


class NumericalFailure(RuntimeError):
    """A run that did not produce a trustworthy result.

    Attributes
    ----------
    reason : str
        Short machine-readable cause: ``"unstable"``, ``"singular"``, ``"non-finite"``,
        ``"step-size"``, ``"constraint-drift"``.
    time : float or None
        Simulation time (s) at which it was detected.
    """

    def __init__(self, reason: str, message: str, time: float | None = None):
        super().__init__(message)
        self.reason = reason
        self.time = time
