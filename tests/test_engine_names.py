"""An engine is named only where it lives (issue 39, "Engine names in code").

A registered engine's name, as a string literal (``"mujoco"``), and its package or its settings
type, as an import (``from loopcheck.reference_models import simulate_mujoco``,
``from ..pin.settings import PinSettings``), appear in loopcheck's code only in the engine's own
package, the registry (:mod:`loopcheck.registry`), the API's named settings (:mod:`loopcheck.api`)
and ``loopcheck/__init__.py``'s docstring. Everything else reaches an engine through the registry
(``ENGINES``, ``REFERENCE``, ``DEFAULT_ENGINES``, ``Engine.label`` and the declarations), so that a
sixth engine reaches every command by being registered.

Found from the registry's built-ins (:data:`loopcheck.registry.BUILT_IN`): a new engine is covered
without editing this file. Read by ``ast`` (docstrings and comments may name engines: only whole
string literals and imports count).
"""

from __future__ import annotations

import ast
from pathlib import Path

from loopcheck.registry import BUILT_IN

from helpers import ROOT

PACKAGE = ROOT / "loopcheck"

# Where every engine may be named: the registry, the API's named settings, the package's docstring.
EVERYWHERE = ("loopcheck/registry.py", "loopcheck/api.py", "loopcheck/__init__.py")
# MuJoCo's family: the model layer its ports share and the ports themselves run MuJoCo's model (a
# port's settings take the scene's [mujoco] values as its defaults: its INHERITS declaration).
FAMILY = {"mujoco": ("loopcheck.mujoco_model", "loopcheck.mjx", "loopcheck.mjwarp")}
# Packages of an engine's that are not registered under a name of their own.
OWNED = {"loopcheck.mujoco_model": "mujoco"}

EXEMPT: tuple[str, ...] = ()  # files left out of the check: none (every module of loopcheck is checked)


def _module(path: Path, top: Path) -> str:
    parts = list(path.relative_to(top).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported(node: ast.ImportFrom | ast.Import, module: str, is_package: bool) -> list[str]:
    """The modules (and ``module.name`` for each name) an import statement reads."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = node.module or ""
    if node.level:
        parts = module.split(".") if is_package else module.split(".")[:-1]
        parts = parts[:len(parts) - (node.level - 1)]
        base = ".".join(parts + ([node.module] if node.module else []))
    return [base, *(f"{base}.{alias.name}" for alias in node.names)]


def _owner(name: str, packages: dict[str, str]) -> str | None:
    """The engine whose package ``name`` (a module) lies in."""
    for package, engine in packages.items():
        if name == package or name.startswith(package + "."):
            return engine
    return None


def names_outside(top: Path = ROOT, exempt=EXEMPT) -> list[str]:
    """Each place outside an engine's home that names it, in the package ``top/loopcheck``:
    ``file:line: what``."""
    packages = {**{e.package: e.name for e in BUILT_IN}, **OWNED}
    settings_types = {e.settings.__name__: e.name for e in BUILT_IN}
    names = {e.name for e in BUILT_IN}
    found = []
    for path in sorted((top / "loopcheck").rglob("*.py")):
        relative = path.relative_to(top).as_posix()
        if relative in EVERYWHERE or relative in exempt:
            continue
        module = _module(path, top)
        home = _owner(module, packages)
        allowed = {home} | {engine for engine, family in FAMILY.items() if _owner(module, dict.fromkeys(family, engine))}
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            hits = []
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
                hits.append((node.value, f"the string '{node.value}'"))
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                for name in _imported(node, module, path.name == "__init__.py"):
                    engine = _owner(name, packages)
                    if engine is not None:
                        hits.append((engine, f"an import of {name}"))
                for alias in node.names:
                    if alias.name in settings_types:
                        hits.append((settings_types[alias.name], f"an import of {alias.name}"))
            for engine, what in hits:
                if engine not in allowed:
                    found.append(f"{relative}:{node.lineno}: {what} (engine '{engine}')")
    return sorted(set(found))


def test_an_engine_is_named_only_in_its_own_package_the_registry_and_the_api():
    found = names_outside()
    assert not found, "engine names outside their homes:\n" + "\n".join(found)


def test_the_check_finds_a_planted_name(tmp_path):
    """The check itself, on a copy of a clean module of the comparison with an engine's name and an
    engine's import planted in it (and the same names in the engine's own package, allowed)."""
    assert not [line for line in names_outside() if line.startswith("loopcheck/compare/diff.py")]
    source = (PACKAGE / "compare" / "diff.py").read_text(encoding="utf-8")
    (tmp_path / "loopcheck" / "compare").mkdir(parents=True)
    (tmp_path / "loopcheck" / "pin").mkdir(parents=True)
    plant = "\nOTHER = 'pin'\nfrom ..pin.settings import PinSettings\nfrom loopcheck.reduced import simulate\n"
    (tmp_path / "loopcheck" / "compare" / "diff.py").write_text(source + plant, encoding="utf-8")
    (tmp_path / "loopcheck" / "pin" / "own.py").write_text("OTHER = 'pin'\nfrom .settings import PinSettings\n",
                                                        encoding="utf-8")
    found = names_outside(tmp_path)
    assert sorted(line.split(": ", 1)[1] for line in found) == [
        "an import of PinSettings (engine 'pin')", "an import of loopcheck.pin.settings (engine 'pin')",
        "an import of loopcheck.pin.settings.PinSettings (engine 'pin')",
        "an import of loopcheck.reduced (engine 'reduced')", "an import of loopcheck.reduced.simulate (engine 'reduced')",
        "the string 'pin' (engine 'pin')"], found
    assert all(line.startswith("loopcheck/compare/diff.py:") for line in found), found
