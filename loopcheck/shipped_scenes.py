"""The shipped scenes, by name: the package data of ``loopcheck.scenes`` (the repository's
``scenes/`` folder), and the rule by which a command line's scene argument is a file or a name."""

from __future__ import annotations

import importlib.resources
from pathlib import Path

from .scene import SceneError


def scenes_dir() -> Path:
    """Folder of the scenes shipped with the project (``seed_fourbar.toml``, ``hard/``).

    The scenes are the package data of the ``loopcheck.scenes`` package (the repository's
    ``scenes/`` folder), found with importlib.resources, so an installed wheel finds them as well
    as a source checkout.
    """
    root = importlib.resources.files("loopcheck.scenes")
    if not isinstance(root, Path):  # e.g. imported from a zip file
        raise SceneError(f"the shipped scenes are not files on disk ({root}); install loopcheck unzipped")
    return root


def default_scene_path() -> Path:
    """Path of the seed four-bar scene shipped with the project."""
    return scenes_dir() / "seed_fourbar.toml"


def hard_scene_dir() -> Path:
    """Folder of the hard-case catalogue (``loopcheck stress``)."""
    return scenes_dir() / "hard"


def catalogue() -> dict[str, Path]:
    """The shipped scenes by name: each file's path under :func:`scenes_dir` without ``.toml``
    (``seed_fourbar``, ``mechanisms/watt2_sixbar``, ``hard/gravity``), and also its bare file name
    (``watt2_sixbar``) where no other shipped scene has that name. Sorted by the full names."""
    root = scenes_dir()
    full = {p.relative_to(root).with_suffix("").as_posix(): p for p in sorted(root.rglob("*.toml"))}
    stems: dict[str, list[str]] = {}
    for name in full:
        stems.setdefault(name.rpartition("/")[2], []).append(name)
    short = {stem: full[names[0]] for stem, names in stems.items() if len(names) == 1 and stem not in full}
    return {**full, **short}


def resolve_scene(name: str | Path) -> Path:
    """The scene file a command line names: a file that exists (relative to the working folder, or
    absolute) is taken as it is; otherwise a name of the shipped :func:`catalogue`; otherwise, a
    name ending in ``.toml`` or an absolute path is returned as it is (reading it then says the
    file does not exist).

    Raises
    ------
    SceneError
        If it is none of these.
    """
    path = Path(name)
    if path.exists():
        return path
    found = catalogue().get(str(name).removesuffix(".toml"))
    if found is not None:
        return found
    if path.suffix == ".toml" or path.is_absolute():  # a file, surely: reading it says what is wrong
        return path
    raise SceneError(f"'{name}': no such scene file, nor a shipped scene of that name (`loopcheck scenes` lists them)")
