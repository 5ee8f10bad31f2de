"""Sweep specifications (loopcheck.compare.sweep_spec): parsing, the grid's order, the seeded Monte Carlo
sample, variants as deep copies, refusals naming the key, and the [sweep] table of a scene file."""

from __future__ import annotations

import copy
import dataclasses
import tomllib

import numpy as np
import pytest

from loopcheck.sweep_spec import (MAX_VARIANTS, Distribution, Engines, Grid, SweepSpec, SweepSpecError,
                                     Variant, count, parse_vary, spec_from_args, spec_from_table, variants)
from loopcheck.compare.sweep_scene import check, load_sweep
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict
from loopcheck.shipped_scenes import default_scene_path

SEED_TEXT = default_scene_path().read_text()
SWEEP_TABLE = """
[sweep]
samples = 100
seed = 1
[sweep.vary]
"dampers.0.coefficient" = "uniform(40, 70)"
"bodies.coupler.mass" = "normal(40, 2)"
"""


@pytest.fixture(scope="module")
def seed_data():
    return tomllib.loads(SEED_TEXT)


# -- parsing -------------------------------------------------------------------------------

@pytest.mark.parametrize("text, values", [
    ("linkage.c2=0.8:1.0:5", (0.8, 0.85, 0.9, 0.95, 1.0)),
    ("linkage.c2 = 0.8 : 1.0 : 3", (0.8, 0.9, 1.0)),
    ("torque.value=-1:1:3", (-1.0, 0.0, 1.0)),
    ("torque.value=7:7:1", (7.0,)),
    ("torque.value=3:9:1", (3.0,)),
    ("dampers.0.coefficient=[40, 55, 70]", (40.0, 55.0, 70.0)),
    ("dampers.0.coefficient=70,40,55", (70.0, 40.0, 55.0)),
    ("dampers.0.coefficient=55", (55.0,)),
    ("initial.qdot=[1e-3]", (1e-3,)),
])
def test_grids_parse(text, values):
    g = parse_vary(text)
    assert isinstance(g, Grid)
    assert g.key == text.split("=")[0].strip()
    np.testing.assert_allclose(g.values, values, rtol=0, atol=1e-15)
    assert all(type(v) is float for v in g.values)


@pytest.mark.parametrize("text, kind, a, b", [
    ("bodies.coupler.mass=normal(40, 2)", "normal", 40.0, 2.0),
    ("bodies.coupler.mass=normal(40,0)", "normal", 40.0, 0.0),
    ("linkage.c1= uniform( 0.45 , 0.55 ) ", "uniform", 0.45, 0.55),
    ("linkage.c1=uniform(0.5, 0.5)", "uniform", 0.5, 0.5),
])
def test_distributions_parse(text, kind, a, b):
    d = parse_vary(text)
    assert d == Distribution(text.split("=")[0].strip(), kind, a, b)


def test_spec_from_table_every_form():
    table = {"samples": 10, "seed": 3,
             "vary": {"bodies.coupler.mass": "normal(40, 2)",
                      "linkage": {"c2": "uniform(0.85, 0.95)"}}}  # a bare dotted key: nested tables
    spec = spec_from_table(table, "s.toml")
    assert spec == SweepSpec((Distribution("bodies.coupler.mass", "normal", 40, 2),
                              Distribution("linkage.c2", "uniform", 0.85, 0.95)), 10, 3)
    grid = spec_from_table({"vary": {"linkage.c2": [0.85, 0.9], "torque.value": "200:300:3"}})
    assert grid.varies == (Grid("linkage.c2", (0.85, 0.9)), Grid("torque.value", (200.0, 250.0, 300.0)))
    assert grid.samples is None and grid.seed == 0


def test_spec_from_args():
    spec = spec_from_args(["linkage.c2=0.8:1:3", "torque.value=[1,2]"])
    assert spec.keys == ("linkage.c2", "torque.value") and count(spec) == 6
    mc = spec_from_args(["torque.value=normal(250, 5)"], samples=7, seed=2)
    assert (mc.samples, mc.seed, count(mc)) == (7, 2, 7)


# -- grid order and count ---------------------------------------------------------------------

def test_grid_is_the_product_with_the_last_key_fastest(seed_data):
    spec = spec_from_args(["dampers.0.coefficient=40:70:3", "bodies.coupler.mass=[38, 42]",
                           "linkage.c2=[0.85, 0.9]"])
    assert count(spec) == 12
    got = [v.values for v in variants(seed_data, spec)]
    want = [{"dampers.0.coefficient": d, "bodies.coupler.mass": m, "linkage.c2": c}
            for d in (40.0, 55.0, 70.0) for m in (38.0, 42.0) for c in (0.85, 0.9)]
    assert got == want
    assert [v.index for v in variants(seed_data, spec)] == list(range(12))


# -- Monte Carlo -------------------------------------------------------------------------------

def _mc(seed: int, samples: int = 50) -> SweepSpec:
    return spec_from_args(["bodies.coupler.mass=normal(40, 2)", "dampers.0.coefficient=uniform(40, 70)"],
                          samples=samples, seed=seed)


def _values(data, spec):
    return [v.values for v in variants(data, spec)]


def test_monte_carlo_is_reproducible_with_its_seed(seed_data):
    first = _values(seed_data, _mc(1))
    assert first == _values(seed_data, _mc(1))
    assert len(first) == 50
    other = _values(seed_data, _mc(2))
    assert all(a[k] != b[k] for a, b in zip(first, other) for k in a)


def test_monte_carlo_draws_the_distributions(seed_data):
    vals = _values(seed_data, _mc(5, 2000))
    mass = np.array([v["bodies.coupler.mass"] for v in vals])
    damper = np.array([v["dampers.0.coefficient"] for v in vals])
    assert abs(mass.mean() - 40.0) < 0.2 and abs(mass.std() - 2.0) < 0.2
    assert 40.0 <= damper.min() and damper.max() <= 70.0 and abs(damper.mean() - 55.0) < 1.0
    # each key drawn in a fixed order from default_rng(seed): key after key, all draws of one key
    rng = np.random.default_rng(5)
    np.testing.assert_array_equal(mass, rng.normal(40.0, 2.0, 2000))
    np.testing.assert_array_equal(damper, rng.uniform(40.0, 70.0, 2000))


# -- variants ------------------------------------------------------------------------------------

def test_variants_are_deep_copies_with_the_values_in_place(seed_data):
    original = copy.deepcopy(seed_data)
    spec = spec_from_args(["dampers.0.coefficient=[41, 69]", "bodies.coupler.mass=[37.5]"])
    out = list(variants(seed_data, spec))
    assert isinstance(out[0], Variant)
    assert seed_data == original  # the scene data is not changed
    for v in out:
        assert v.data["dampers"][0]["coefficient"] == v.values["dampers.0.coefficient"]
        assert v.data["bodies"]["coupler"]["mass"] == 37.5
        assert v.data["bodies"]["coupler"]["inertia"] == original["bodies"]["coupler"]["inertia"]
        scene = scene_from_dict(v.data)
        assert scene.mechanism.dampers[0].coefficient == v.values["dampers.0.coefficient"]
        assert scene.mechanism.linkage.body_map["coupler"].mass == 37.5
    # changing one variant's data changes neither the scene data nor another variant
    out[0].data["dampers"][0]["ground_point"][0] = 99.0
    out[0].data["bodies"]["coupler"]["com"][1] = 99.0
    assert seed_data == original
    assert out[1].data["dampers"][0]["ground_point"][0] == original["dampers"][0]["ground_point"][0]
    assert out[1].data["bodies"]["coupler"]["com"] == original["bodies"]["coupler"]["com"]


def test_a_key_the_file_does_not_give_is_created(seed_data):
    spec = spec_from_args(["mujoco.timestep=[0.0005, 0.001]", "reduced.rtol=[1e-9]"])
    check(seed_data, spec, "seed")
    out = list(variants(seed_data, spec))
    assert "mujoco" not in seed_data and "reduced" not in seed_data
    scene = scene_from_dict(out[0].data)
    assert scene.engine_table("mujoco")["timestep"] == 0.0005 and scene.engine_table("reduced")["rtol"] == 1e-9


def test_integral_values_fit_integer_keys(seed_data):
    spec = spec_from_args(["mujoco.iterations=10:50:5"])
    check(seed_data, spec, "seed")
    v = next(variants(seed_data, spec))
    assert v.data["mujoco"]["iterations"] == 10 and scene_from_dict(v.data).engine_table("mujoco")["iterations"] == 10


def test_variants_do_not_carry_the_sweep_table():
    data = tomllib.loads(SEED_TEXT + SWEEP_TABLE)
    spec = spec_from_table(data["sweep"])
    v = next(variants(data, spec))
    assert "sweep" not in v.data and "sweep" in data


# -- refusals -------------------------------------------------------------------------------

@pytest.mark.parametrize("args, samples, words", [
    (["dampers.0.coefficient=70:40:7"], None, "lo > hi"),
    (["dampers.0.coefficient=40:70:0"], None, "n = 0"),
    (["dampers.0.coefficient=40:70:-2"], None, "n = -2"),
    (["dampers.0.coefficient=[]"], None, "no values"),
    (["bodies.coupler.mass=normal(40, -1)"], 10, "negative sigma"),
    (["bodies.coupler.mass=uniform(42, 38)"], 10, "lo > hi"),
    (["bodies.coupler.mass=40:nan:3"], None, "finite"),
    (["bodies.coupler.mass=[40, inf]"], None, "finite"),
    (["bodies.coupler.mass=normal(inf, 1)"], 10, "finite"),
    (["bodies.coupler.mass=40:70:2.5"], None, "whole number"),
    (["bodies.coupler.mass=gamma(1, 2)"], 10, "unknown distribution"),
    (["bodies.coupler.mass=40:70"], None, "lo:hi:n"),
    (["bodies.coupler.mass=forty"], None, "not a number"),
    (["bodies.coupler.mass=normal(40, 2)"], None, "--samples"),
    (["bodies.coupler.mass=normal(40, 2)"], 0, "--samples"),
    (["bodies.coupler.mass=normal(40, 2)"], MAX_VARIANTS + 1, "--samples"),
    (["bodies.coupler.mass=40:70:3"], 10, "--samples"),
    (["bodies.coupler.mass=40:70:3", "bodies.coupler.mass=[1]"], None, "twice"),
    (["bodies.coupler.mass=40:70:3", "dampers.0.coefficient=normal(55, 1)"], 10, "not both"),
    (["bodies.coupler.mass=40:70:2000", "dampers.0.coefficient=40:70:1000"], None, "2000000 variants"),
    (["bodies.coupler.mass=1:2:1000000000000"], None, "at most"),
])
def test_bad_specs_refused_naming_the_key(args, samples, words):
    with pytest.raises(SweepSpecError) as err:
        spec_from_args(args, samples=samples)
    message = str(err.value)
    assert "\n" not in message and words in message
    assert any(name in message for name in ("'bodies.coupler.mass'", "'dampers.0.coefficient'", "--samples"))


@pytest.mark.parametrize("vary, samples, words", [
    ("linkage.type=1:2:2", None, "not a number"),
    ("name=[1]", None, "not a number"),
    ("bodies.coupler=[1]", None, "not a number"),
    ("bodies.coupler.mas=38:42:3", None, "unknown key"),
    ("bodies.coupler.mass.x=38:42:3", None, "unknown key"),
    ("frobnicate.x=[1]", None, "unknown key"),
    ("dampers.1.coefficient=[50]", None, "unknown key"),
    ("dampers.first.coefficient=[50]", None, "unknown key"),
    ("mujoco.time_step=[0.001]", None, "unknown key"),
    ("bodies.coupler.mass=normal(40, 20)", 10, "mu - 4 sigma"),
    ("bodies.coupler.mass=-1:40:3", None, "smallest"),
    ("dampers.0.coefficient=uniform(0, 70)", 10, "lower bound"),
    ("simulation.horizon=1:1e9:3", None, "largest"),
    ("mujoco.iterations=normal(50, 0.3)", 10, "whole number"),
    ("linkage.branch=[1, 0]", None, "invalid"),
    ("linkage.c1=0.1:5:3", None, "invalid"),
])
def test_bad_specs_refused_against_the_scene(seed_data, vary, samples, words):
    spec = spec_from_args([vary], samples=samples)
    with pytest.raises(SweepSpecError) as err:
        check(seed_data, spec, "seed.toml")
    message = str(err.value)
    key = vary.split("=")[0]
    assert "\n" not in message and words in message and f"'{key}'" in message
    assert message.startswith("seed.toml: ")


def test_check_passes_a_good_sweep_and_does_not_change_the_data(seed_data):
    original = copy.deepcopy(seed_data)
    check(seed_data, _mc(1), "seed")
    check(seed_data, spec_from_args(["linkage.c2=0.85:0.95:3", "torque.value=[200, 300]", "initial.qdot=[0, 1]"]),
          "seed")
    assert seed_data == original


def test_sweep_spec_error_is_a_value_error():
    assert issubclass(SweepSpecError, ValueError)


def test_dataclasses_validate_where_defined():
    with pytest.raises(SweepSpecError, match="'a.b'.*lo > hi"):
        Distribution("a.b", "uniform", 2.0, 1.0)
    with pytest.raises(SweepSpecError, match="'a.b'.*no values"):
        Grid("a.b", ())
    with pytest.raises(SweepSpecError, match="empty part"):
        Grid("a..b", (1.0,))
    with pytest.raises(SweepSpecError, match=r"\[sweep\] table itself"):
        Grid("sweep.samples", (1.0,))
    with pytest.raises(dataclasses.FrozenInstanceError):
        Grid("a", (1.0,)).key = "b"


# -- the [sweep] table of a scene file ------------------------------------------------------

def test_sweep_table_of_a_scene_file(tmp_path):
    path = tmp_path / "seed_fourbar.toml"
    path.write_text(SEED_TEXT + SWEEP_TABLE)
    data, spec = load_sweep(path)
    assert spec == SweepSpec((Distribution("dampers.0.coefficient", "uniform", 40, 70),
                              Distribution("bodies.coupler.mass", "normal", 40, 2)), 100, 1)
    check(data, spec, str(path))
    assert count(spec) == 100
    # the scene loads, and is the scene without the table
    with_sweep = load_scene(path)
    plain = load_scene(default_scene_path())
    assert dataclasses.replace(with_sweep, source=plain.source) == plain


def test_a_bad_sweep_table_makes_the_scene_file_invalid(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SEED_TEXT + SWEEP_TABLE.replace("normal(40, 2)", "normal(40, -2)"))
    with pytest.raises(SceneError, match=r"s\.toml: .*'bodies\.coupler\.mass'.*negative sigma"):
        load_scene(path)
    path.write_text(SEED_TEXT + "\n[sweep]\nsample = 3\n")
    with pytest.raises(SceneError, match=r"unknown key 'sweep\.sample'"):
        load_scene(path)


def test_a_scene_file_without_sweep_table_loads_as_before(tmp_path):
    data, spec = load_sweep(default_scene_path())
    assert spec is None and "sweep" not in data
    assert load_scene(default_scene_path()) == scene_from_dict(data, str(default_scene_path()))
    path = tmp_path / "s.toml"
    path.write_text(SEED_TEXT + "\n[sweeps]\nsamples = 3\n")
    with pytest.raises(SceneError, match=r"unknown key 'sweeps'"):
        load_scene(path)


def test_engines_of_a_spec_and_of_the_sweep_table():
    grid = (Grid("linkage.c2", (0.9,)),)
    assert SweepSpec(grid).engines == Engines.BOTH.runs == ("reduced", "mujoco")
    assert SweepSpec(grid, engines="reduced").engines == ("reduced",)  # a word is converted
    assert Engines.REDUCED.runs == ("reduced",) and Engines.BOTH.runs == ("reduced", "mujoco")
    table = {"engines": "reduced", "vary": {"linkage.c2": [0.9, 1.0]}}
    assert spec_from_table(table).engines == ("reduced",)
    # a list: a comma-separated string or a TOML array, kept in its order (the registry's check is the sweep's)
    assert spec_from_table({**table, "engines": "reduced, mjx,pin"}).engines == ("reduced", "mjx", "pin")
    assert spec_from_table({**table, "engines": ["mjx", "reduced"]}).engines == ("mjx", "reduced")
    assert SweepSpec(grid, engines=["reduced"]).engines == ("reduced",)
    for bad, message in ((3, r"must be both, reduced or a list of engine names .*got 3"),
                         ("reduced,,mjx", r"an empty engine name"), ("reduced,MJX", r"'MJX' is not an engine name"),
                         ("reduced,mjx,mjx", r"an engine is named twice in 'reduced,mjx,mjx'"), ([], "an empty")):
        with pytest.raises(SweepSpecError, match=r"^s\.toml: sweep engines \(--engines or sweep\.engines\)[: ].*"
                                                 + message):
            spec_from_table({**table, "engines": bad}, "s.toml")
