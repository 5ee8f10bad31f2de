"""The engines, by name: one line each.

An engine is a package with two names (``docs/engines.md`` has the recipe):

- ``Settings``: a frozen dataclass whose fields are :func:`loopcheck.settings.option` s. They define
  the engine's table of the scene file (``[NAME]``) and its command-line flags. It lives in the
  package's ``settings`` module, which imports nothing of the engine, so that reading a scene
  file or printing the help loads no engine;
- ``simulate(scene, settings) -> EngineResult``.

The registry names packages and imports them only when asked (``importlib``): the scene format
reads each engine's table through it, and the comparison and the command line run engines
through it, without a static import of any engine.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from .results import EngineResult
from .scene import Scene


@dataclass(frozen=True)
class Engine:
    """One engine: its ``name`` (the scene file's table, the results' label), the ``package``
    that holds it and a one-line ``title``."""

    name: str
    package: str
    title: str

    @property
    def settings(self) -> type:
        """The engine's ``Settings`` type (its ``settings`` module only: no engine is loaded)."""
        return importlib.import_module(f"{self.package}.settings").Settings

    def load(self) -> None:
        """Import the engine (ImportError in one line, the engine's own, when an optional extra
        is missing: checked before any work)."""
        importlib.import_module(self.package).simulate

    def simulate(self, scene: Scene, settings: Any) -> EngineResult:
        """Run the engine on ``scene`` with ``settings`` (a ``self.settings``)."""
        return importlib.import_module(self.package).simulate(scene, settings)


ENGINES: dict[str, Engine] = {e.name: e for e in (
    Engine("reduced", "loopcheck.reduced", "Eksergian's equation, solved in one coordinate (the exact reference)"),
    Engine("mujoco", "loopcheck.reference_models", "MuJoCo: the open chain closed by equality constraints"),
    Engine("pin", "loopcheck.pin", "Pinocchio: the tree's constrained dynamics, loops closed by point constraints"),
    Engine("mjx", "loopcheck.mjx", "MJX, MuJoCo's JAX port: the MuJoCo engine's model, stepped by JAX (CPU or GPU)"),
    Engine("mjwarp", "loopcheck.mjwarp", "MJWarp, MuJoCo's Warp port: the MuJoCo engine's model, stepped in float32 (CPU or GPU)"),
)}


REFERENCE = "reduced"  # the exact reference every other engine is judged against (it has no [tolerances.reduced])
DEFAULT_ENGINES = (REFERENCE, "mujoco")  # the default comparison: the design card's pair (others by --engines)


def judged_engines() -> tuple[str, ...]:
    """The engines judged against the reference, by name: every registered engine but it (each may
    have its own tolerances, ``[tolerances.NAME]``)."""
    return tuple(name for name in ENGINES if name != REFERENCE)


def engine_of(settings: Any) -> Engine:
    """The engine whose ``Settings`` ``settings`` are.

    Raises
    ------
    TypeError
        If they are no registered engine's.
    """
    for engine in ENGINES.values():
        if isinstance(settings, engine.settings):
            return engine
    names = ", ".join(e.settings.__name__ for e in ENGINES.values())
    raise TypeError(f"settings of an engine ({names}), not {type(settings).__name__}")
