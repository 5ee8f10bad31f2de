"""The Pinocchio engine: a scene's linkage as Pinocchio's kinematic tree closed by one
``CONTACT_3D`` constraint per cut joint, its constrained forward dynamics
(``pinocchio.constraintDynamics``) integrated by scipy's ``solve_ivp`` (DOP853 by default).

The engine's interface (:mod:`loopcheck.registry`): ``Settings`` (:class:`PinSettings`, its ``[pin]``
table and flags) and ``simulate(scene, settings) -> EngineResult``. Pinocchio is an optional
extra (``pip install loopcheck[pin]``, the PyPI package ``pin``); names load from their submodule on
first use (PEP 562): reading the settings does not import Pinocchio.
"""

from __future__ import annotations

from loopcheck._lazy import lazy_names

_HOMES = {
    "result_lines": ".text",  # what `loopcheck NAME` prints (loopcheck.registry.Engine.result_lines)
    **dict.fromkeys(("METHODS", "PinSettings", "Settings"), ".settings"),
    **dict.fromkeys(("PinModel", "build"), ".model"),
    **dict.fromkeys(("PinDetails", "simulate_pin"), ".run"),
    "simulate": (".run", "simulate_pin"),  # the engine interface's name
}
__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES, globals())
