"""Scene builders shared by the tests (real scenes, built from the seed file)."""

from __future__ import annotations

import tomllib
from pathlib import Path

from reduced import Scene, scene_from_dict

ROOT = Path(__file__).resolve().parent.parent
SEED_SCENE = ROOT / "scenes" / "seed_fourbar.toml"


def seed_dict() -> dict:
    with open(SEED_SCENE, "rb") as f:
        return tomllib.load(f)


def variant(*, drop: tuple[str, ...] = (), **changes) -> Scene:
    """The seed scene with top-level tables removed or replaced."""
    data = seed_dict()
    for key in drop:
        data.pop(key, None)
    data.update(changes)
    return scene_from_dict(data)


def conservative(qdot0: float = 10.0, horizon: float = 2.0) -> Scene:
    """Seed linkage, no damper, no torque, no gravity, started with speed qdot0 (rad/s)."""
    return variant(drop=("torque", "dampers", "tolerances"), initial={"q": 0.2, "qdot": qdot0},
                   simulation={"horizon": horizon})
