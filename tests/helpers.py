"""Scene builders shared by the tests (real scenes, built from the seed file)."""

from __future__ import annotations

import re
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


def _locate(data, path: str):
    """(container, key) of a dotted path such as 'dampers[0].body_point[1]' inside parsed TOML."""
    parts = re.findall(r"[^.\[\]]+|\[\d+\]", path)
    node = data
    for part in parts[:-1]:
        node = node[int(part[1:-1])] if part.startswith("[") else node.setdefault(part, {})
    last = parts[-1]
    return node, int(last[1:-1]) if last.startswith("[") else last


DELETE = object()  # a patch value that removes the key


def patched(patch: dict) -> dict:
    """The seed scene's data with each dotted path set to its value (DELETE removes it)."""
    data = seed_dict()
    for path, value in patch.items():
        node, key = _locate(data, path)
        if value is DELETE:
            del node[key]
        else:
            node[key] = value
    return data


def coefficients_along(model, qs) -> list:
    """The model's coefficients at each input q of ``qs`` in turn, evaluated afresh
    (:meth:`MechanismModel.coefficients_at`) at the configuration that a chart of the input
    coordinate, walked from the scene's x0, reaches there: what ``model.coefficients(q)`` gives
    near q0 (MechanismModel.assemble is Newton from x0 and does not converge half a revolution
    away). Not the walked chart's own coefficients: those come from A factored before Newton's
    last step, up to ~1e-10 of V from the ones at the x it returns. The input must be a coordinate."""
    from reduced.partition import Chart

    chart = Chart(model, model.input_coordinate, model.x0)
    return [model.coefficients_at(chart.kinematics(float(q)).x) for q in qs]


def short_seed_file(folder: Path, horizon: str = "0.3") -> Path:
    """The seed scene file with a shorter horizon (s), written into ``folder``: a quick sweep."""
    text = SEED_SCENE.read_text()
    short = re.sub(r"(?m)^horizon = 2\.0.*$", f"horizon = {horizon}", text)
    assert short != text
    path = folder / "short.toml"
    path.write_text(short)
    return path

