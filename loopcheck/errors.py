"""Numerical failures: detected, named and raised, never returned as a result."""

from __future__ import annotations

from enum import Enum
from typing import Any


class FailureReason(str, Enum):
    """Why a run did not produce a trustworthy result (compares equal to its value string)."""

    UNSTABLE = "unstable"  # outside the stability region, runaway speed, MuJoCo reset the state
    SINGULAR = "singular"  # a position no coordinate can drive, or the solver could not go on
    NON_FINITE = "non-finite"  # NaN or inf in the state
    STEP_SIZE = "step-size"  # the adaptive solver's step collapsed
    CONSTRAINT_DRIFT = "constraint-drift"  # MuJoCo's loop opened beyond its bound
    INACCURATE = "inaccurate"  # the run's own error estimate is above the requested tolerance
    ENERGY_IMBALANCE = "energy-imbalance"  # the energy balance does not close within its bound
    INITIAL_STATE = "initial-state"  # the initial state violates the loop constraints
    INCOMPLETE = "incomplete"  # the run or the comparison did not cover the horizon
    CONTACT = "contact"  # two geoms touched: the exact reference has no contacts
    RANGE_REACHED = "range-reached"  # a joint reached a bound of its range: the exact solution stops there

    def __str__(self) -> str:
        return self.value


class NumericalFailure(RuntimeError):
    """A run that did not produce a trustworthy result.

    Attributes
    ----------
    reason : FailureReason
        The cause; a plain string is converted (and must be one of the reasons' values).
    time : float or None
        Simulation time (s) at which it was detected.
    partial : EngineResult or None
        The run as far as the engine got, when it got a result that a check then failed (a loop
        gap or an energy balance beyond its bound): its trajectory (trustworthy up to ``time``) and
        its known defects travel with the failure (:func:`with_partial`); else None.
    joint : str or None
        The scene joint whose range a RANGE_REACHED failure reached; else None.
    """

    partial = None
    joint = None  # the scene joint a RANGE_REACHED failure names

    def __init__(self, reason: FailureReason | str, message: str, time: float | None = None):
        super().__init__(message)
        self.reason = FailureReason(reason)
        self.time = time


def with_partial(check, result):
    """Run ``check()`` (a run's own gate); a NumericalFailure it raises carries ``result`` (the
    run it failed, :attr:`NumericalFailure.partial`). Returns ``result``."""
    try:
        check()
    except NumericalFailure as exc:
        exc.partial = result
        raise
    return result


class IgnoredSettingWarning(UserWarning):
    """A setting was given that the chosen method does not use (it has no effect)."""


def type_name(value: Any) -> str:
    """A TOML value's type in words, for messages: "a boolean", "an integer", "an array", ..."""
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "an array", dict: "a table"}.get(type(value), type(value).__name__)
