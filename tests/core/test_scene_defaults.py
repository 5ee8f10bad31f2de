"""Every default of a scene file, with its key left out, against the documented value.

The expected defaults are written here from the README ("Scene files", "MuJoCo defaults", "The
reduced solver"), not read from the code's constants: a default taken from the wrong constant
(``q_atol`` given ``omega_atol``'s 0.1 instead of 1e-3, which let a run with |Δq| 1.1e-2 rad
pass the gate) fails here. Each key is left out of a table in which every other key is set to
a value that is not its default, so a default that borrows another key's value shows too.
Scenes without a default for a key (``simulation.horizon``, ``initial.q``, the four-bar's
lengths and branch) are refused naming the key.
"""

from __future__ import annotations

import math
import re

import mujoco
import numpy as np
import pytest

from loopcheck.compare.settings import gate_tolerances, mujoco_settings, reduced_settings
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.loads import PulseLoad
from helpers import DELETE, patched, seed_dict

# [tolerances] (README: "Scene files"): the documented default of each key, and a value that is not.
TOLERANCES = {
    "peak_omega_rtol": (1e-4, 3e-4),
    "peak_omega_atol": (1e-9, 2e-8),  # rad/s
    "q_atol": (1e-3, 5e-3),  # rad
    "omega_atol": (0.1, 0.3),  # rad/s
    "omega_vs_q_atol": (None, 0.05),  # rad/s; absent: not checked
}


def _table_without(table: dict, key: str) -> dict:
    """Every key of ``table`` at its non-default value except ``key``."""
    return {k: other for k, (_, other) in table.items() if k != key and other is not None}


@pytest.mark.parametrize("key", sorted(TOLERANCES))
def test_a_tolerance_left_out_of_its_table_takes_its_documented_default(key):
    data = seed_dict()
    data["tolerances"] = _table_without(TOLERANCES, key)
    scene = scene_from_dict(data)
    expected = {k: (default if k == key else other) for k, (default, other) in TOLERANCES.items()}
    for tolerances in (scene.tolerances, gate_tolerances(scene, "mujoco")):  # the scene, and what the gate uses
        assert {k: getattr(tolerances, k) for k in TOLERANCES} == expected


def test_a_scene_without_a_tolerances_table_takes_every_default():
    data = seed_dict()
    data.pop("tolerances", None)
    tolerances = gate_tolerances(scene_from_dict(data), "mujoco")
    assert {k: getattr(tolerances, k) for k in TOLERANCES} == {k: d for k, (d, _) in TOLERANCES.items()}


# [reduced] (README: "rtol ... default 1e-12 adaptive, 1e-5 rkn4", "RKN4 step (s; default 5e-4)",
# "dop853 (default)").
@pytest.mark.parametrize("table, expected", [
    ({"rtol": 1e-10}, {"method": "dop853", "rtol": 1e-10, "step": None}),
    ({"method": "dop853"}, {"method": "dop853", "rtol": 1e-12, "step": None}),
    ({"method": "radau"}, {"method": "radau", "rtol": 1e-12, "step": None}),
    ({"method": "rkn4", "step": 1e-3}, {"method": "rkn4", "rtol": 1e-5, "step": 1e-3}),
    ({"method": "rkn4", "rtol": 1e-4}, {"method": "rkn4", "rtol": 1e-4, "step": 5e-4}),
    ({}, {"method": "dop853", "rtol": 1e-12, "step": None}),
])
def test_reduced_settings_left_out_take_their_documented_defaults(table, expected):
    data = seed_dict()
    data["reduced"] = table
    settings = reduced_settings(scene_from_dict(data))
    assert {k: getattr(settings, k) for k in expected} == expected
    if settings.method != "rkn4":
        assert settings.sample_interval == 1e-3  # s: the adaptive methods' largest sample spacing


# [mujoco] (README: "MuJoCo defaults"): checked in the model MuJoCo compiles, not in the settings
# object alone. Non-default values: implicit, 2e-4 s, solref (1e-3, 0.9), a softer solimp, 50
# iterations, tolerance 1e-10, refsafe off, diagexact on.
MUJOCO = {
    "integrator": ("rk4", "implicit"),
    "timestep": (None, 2e-4),
    "solref": (None, [1e-3, 0.9]),
    "solimp": ([0.9999, 0.9999, 0.001, 0.5, 2.0], [0.95, 0.99, 0.002, 0.4, 3.0]),
    "iterations": (100, 50),
    "tolerance": (1e-12, 1e-10),
    "refsafe": (True, False),
    "diagexact": (False, True),
}
INTEGRATORS = {"rk4": mujoco.mjtIntegrator.mjINT_RK4, "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT}
SEED_AUTOMATIC_STEP = 1e-3  # s: min(1 ms, horizon/100) with the pulse's edge (1 s) on its grid


def _compiled(model) -> dict:
    opt = model.opt
    return {"integrator": int(opt.integrator), "timestep": opt.timestep,
            "solref": [float(v) for v in model.eq_solref[0]], "solimp": [float(v) for v in model.eq_solimp[0]],
            "iterations": opt.iterations, "tolerance": opt.tolerance,
            "refsafe": not opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_REFSAFE),
            "diagexact": bool(opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT))}


@pytest.mark.parametrize("key", sorted(MUJOCO) + ["(no table)"])
def test_mujoco_settings_left_out_take_their_documented_defaults(key):
    from loopcheck.reference_models.run import build_model

    data = seed_dict()
    if key == "(no table)":
        data.pop("mujoco", None)
        given = {}
    else:
        given = _table_without(MUJOCO, key)
        data["mujoco"] = given
    scene = scene_from_dict(data)
    settings = mujoco_settings(scene)
    value = {k: given.get(k, default) for k, (default, _) in MUJOCO.items()}
    assert settings.automatic == ("timestep" not in given)
    step = value["timestep"] if value["timestep"] is not None else SEED_AUTOMATIC_STEP
    solref = value["solref"] if value["solref"] is not None else [2.0 * step, 1.0]  # (2·timestep, 1)
    expected = {**value, "integrator": int(INTEGRATORS[value["integrator"]]), "timestep": step, "solref": solref}
    assert _compiled(build_model(scene, settings).model) == expected  # float64 in MuJoCo: exact


# The other tables' defaults (README: "Scene files").
def test_the_top_level_and_initial_defaults(tmp_path):
    data = seed_dict()
    for key in ("name", "description", "gravity"):
        data.pop(key, None)
    del data["initial"]["qdot"]
    del data["linkage"]["type"]  # the four-bar shorthand is the default form
    del data["torque"]["start"]
    scene = scene_from_dict(data)
    assert scene.name == "scene" and scene.description == "" and scene.gravity is None
    assert scene.qdot0 == 0.0
    assert scene.four_bar is not None and sorted(scene.mechanism.linkage.moving) == ["coupler", "crank", "rocker"]
    assert isinstance(scene.load, PulseLoad) and scene.load.start == 0.0
    assert scene.mechanism.elements[0].name == "damper0"
    # a scene file's name defaults to its file name
    path = tmp_path / "my_linkage.toml"
    path.write_text(_toml(data))
    assert load_scene(path).name == "my_linkage"


def _toml(data: dict) -> str:
    """A small TOML writer for the seed's tables (numbers, strings, arrays, tables, arrays of tables)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = [f"{k} = {value(v)}" for k, v in data.items() if not isinstance(v, (dict, list))
             or (isinstance(v, list) and not (v and isinstance(v[0], dict)))]
    def table(prefix, t):
        lines.append(f"[{prefix}]")
        lines.extend(f"{k} = {value(v)}" for k, v in t.items() if not isinstance(v, dict))
        for k, v in t.items():
            if isinstance(v, dict):
                table(f"{prefix}.{k}", v)
    for k, v in data.items():
        if isinstance(v, dict):
            table(k, v)
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines.append(f"[[{k}]]")
                lines.extend(f"{kk} = {value(vv)}" for kk, vv in item.items())
    return "\n".join(lines) + "\n"


PLANAR = {
    "linkage": {"type": "planar", "input": "O"},
    "bodies": {"ground": {"points": {"O": [0.0, 0.0], "axis": [0.0, 0.005]}},
               "crank": {"points": {"O": [0.0, 0.0], "A": [0.025, 0.0]}, "pivot_inertia": 0.02, "pivot": "O"},
               "rod": {"points": {"A": [0.0, 0.0], "P": [0.09, 0.0]}, "mass": 0.12, "com": [0.027, 0.0],
                       "inertia": 8e-5},
               "piston": {"points": {"pin": [0.0, 0.0]}, "mass": 0.15, "com": [0.0, 0.0], "inertia": 5e-5}},
    "joints": [{"name": "O", "type": "revolute", "a": "ground.O", "b": "crank.O"},
               {"name": "A", "type": "revolute", "a": "crank.A", "b": "rod.A"},
               {"name": "P", "type": "revolute", "a": "rod.P", "b": "piston.pin"},
               {"name": "slide", "type": "prismatic", "a": "ground.axis", "direction": 0.0, "b": "piston.pin"}],
    "dampers": [{"a": "ground.O", "b": "rod.P", "coefficient": 0.5}],
    "springs": [{"a": "ground.axis", "b": "piston.pin", "stiffness": 100.0, "rest_length": 0.05}],
    "point_forces": [{"point": "piston.pin", "direction": math.pi, "q": [0.0, 1.0, 2.0], "values": [1.0, 2.0, 1.0]}],
    "initial": {"q": 0.5, "guess": {"rod": -0.08, "slide": 0.11}},
    "simulation": {"horizon": 0.1},
}


def test_the_planar_form_defaults():
    """Element names damper<k>, spring<k>, force<k>; no period; q̇0 = 0; a guess not given
    starts every coordinate at 0 (the same assembly as a guess of zeros)."""
    scene = scene_from_dict(PLANAR)
    m = scene.mechanism
    assert [e.name for e in m.dampers] == ["damper0"] and [e.name for e in m.springs] == ["spring0"]
    assert [f.name for f in m.point_forces] == ["force0"] and m.point_forces[0].period is None
    assert scene.qdot0 == 0.0
    unguessed = {**PLANAR, "initial": {"q": 0.5}}
    zeros = {**PLANAR, "initial": {"q": 0.5, "guess": {"rod": 0.0, "slide": 0.0}}}
    assert scene_from_dict(unguessed).x0 == scene_from_dict(zeros).x0


@pytest.mark.parametrize("path, key", [("simulation.horizon", "simulation.horizon"), ("initial.q", "initial.q"),
                                       ("linkage.c1", "linkage.c1"), ("linkage.branch", "linkage.branch"),
                                       ("dampers[0].coefficient", "dampers[0].coefficient")])
def test_keys_without_a_default_are_required(path, key):
    with pytest.raises(SceneError, match=re.escape(f"missing key '{key}'")):
        scene_from_dict(patched({path: DELETE}))
