"""Names a package gives on first use (PEP 562): ``import loopcheck`` and the engines' packages stay
light, and a name loads its module only when it is read."""

from __future__ import annotations

import importlib
from typing import Callable, Mapping


def lazy_names(package: str, homes: Mapping[str, str | tuple[str, str]],
               namespace: dict) -> tuple[Callable[[str], object], Callable[[], list[str]], list[str]]:
    """The ``__getattr__``, ``__dir__`` and ``__all__`` of ``package`` whose names live in
    ``homes``: name -> module (relative to ``package`` when it starts with a dot), or
    (module, attribute) for a name the module spells otherwise. ``namespace`` is the package's
    ``globals()``, where a name is kept once loaded."""
    names = sorted(homes)

    def __getattr__(name: str):
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attribute = home if isinstance(home, tuple) else (home, name)
        value = getattr(importlib.import_module(module, package), attribute)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__, names
