"""DOF from the rank, not Grübler's count (issue 37): a redundantly closed loop whose loop equations
leave one DOF is accepted, with Grübler's count as a warning; a locked one is refused by its own
message; the reduced engine runs it on an orthonormal basis of its loop rows.

Oracle: scenes/mechanisms/parallelogram_redundant.toml, a parallelogram with a third parallel crank.
Every crank turns by the input's angle and the coupler translates on a circle of the crank length a,
so 𝔍 = Σ_cranks (I_G + m |G − O|²) + m_coupler a² is constant, ζ = 0, and under the constant torque T
without gravity q(t) = q0 + ω0 t + ½ (T/𝔍) t² (closed form, written here from the scene's numbers).
Its motion (q from 0.6 to 2.1 rad) passes q = π/2, where the loop rows chosen once at q0 lose their
rank: a kernel on fixed rows fails there (the plant in the report).
"""

from __future__ import annotations

import copy
import math
import tomllib
import warnings

import numpy as np
import pytest

from loopcheck import kinematics as loops
from loopcheck.mechanism import GrublerCountWarning
from loopcheck.reduced import MechanismModel, ReducedSettings, simulate
from loopcheck.scene import SceneError
from loopcheck.scenefile import load_scene, scene_from_dict

from helpers import ROOT

SCENE = ROOT / "scenes" / "mechanisms" / "parallelogram_redundant.toml"
A = 0.25  # m, the cranks' length


def _data() -> dict:
    with open(SCENE, "rb") as f:
        return tomllib.load(f)


def _quiet(data: dict):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GrublerCountWarning)
        return scene_from_dict(data)


def _inertia(data: dict) -> float:
    """𝔍 of the parallelogram from the scene's numbers (closed form, module docstring)."""
    bodies = data["bodies"]
    total = bodies["coupler"]["mass"] * A ** 2
    for name in ("crank1", "crank2", "crank3"):
        b = bodies[name]
        pivot = np.array(next(iter(b["points"].values())))  # O_k, the crank's first point
        total += b["inertia"] + b["mass"] * float(np.sum((np.array(b["com"]) - pivot) ** 2))
    return total


def test_the_scene_is_accepted_with_grublers_count_as_one_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(SCENE)
    said = [str(w.message) for w in caught if issubclass(w.category, GrublerCountWarning)]
    assert said == [f"{SCENE}: Grübler's count gives 0 degrees of freedom, the rank of the loop equations at the "
                    "start gives 1 (1 of its 4 loop equations are redundant): a redundantly closed loop, run with "
                    "one degree of freedom on its independent equations"]
    linkage = scene.mechanism.linkage
    assert linkage.grubler_dof == 3 * 4 - 2 * 6 == 0
    system = loops.compile_linkage(linkage)
    assert system.redundant and (system.m, system.n) == (4, 4)
    assert loops.rank_dof(loops.all_constraints(system, np.array(scene.x0))[1]) == 1


def test_a_four_bar_that_grubler_accepts_gives_no_warning():
    data = _data()
    del data["bodies"]["crank3"]
    data["joints"] = [j for j in data["joints"] if j["name"] not in ("O3", "A3")]
    del data["initial"]["guess"]["crank3"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", GrublerCountWarning)
        scene = scene_from_dict(data)  # a plain parallelogram: Grübler's count 1
    assert scene.mechanism.linkage.grubler_dof == 1
    assert not loops.compile_linkage(scene.mechanism.linkage).redundant


def test_a_locked_triangle_is_refused_naming_both_counts():
    """Two bars pinned to ground and to each other (a triangle truss): Grübler's count 0 and, assembled
    at the one angle where it closes, the rank of its loop equations leaves 0 DOF: locked."""
    apex = math.atan2(math.sqrt(0.7 ** 2 - 0.5 ** 2), 0.5)  # rad, bar a's angle with the apex closed
    data = {
        "name": "truss", "linkage": {"type": "planar", "input": "Oa"},
        "bodies": {"ground": {"points": {"Oa": [0.0, 0.0], "Ob": [1.0, 0.0]}},
                   "a": {"points": {"O": [0.0, 0.0], "P": [0.7, 0.0]}, "mass": 1.0, "com": [0.35, 0.0], "inertia": 0.04},
                   "b": {"points": {"O": [0.0, 0.0], "P": [0.7, 0.0]}, "mass": 1.0, "com": [0.35, 0.0], "inertia": 0.04}},
        "joints": [{"name": "Oa", "type": "revolute", "a": "ground.Oa", "b": "a.O"},
                   {"name": "Ob", "type": "revolute", "a": "ground.Ob", "b": "b.O"},
                   {"name": "P", "type": "revolute", "a": "a.P", "b": "b.P"}],
        "initial": {"q": apex, "guess": {"b": math.pi - apex}},
        "simulation": {"horizon": 1.0},
    }
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    message = str(info.value)
    assert "\n" not in message
    assert ("the loop equations have rank 2 (2 rows over 2 coordinates) at the assembled configuration: 0 degrees "
            "of freedom by rank (0 by Grübler's count), not 1: the linkage is locked") in message
    data["initial"]["q"] = apex + 0.1  # elsewhere it does not even close
    with pytest.raises(SceneError, match="the loops do not close.*0 degrees of freedom by Grübler's count"):
        scene_from_dict(data)


def test_a_third_crank_that_does_not_fit_is_refused():
    """crank3 1 cm longer: the loop equations no longer agree (no motion at all, but for the flat positions), and
    Newton on a basis of the rows must not pass for an assembly: every row is checked."""
    data = _data()
    data["bodies"]["crank3"]["points"]["A3"] = [0.26, 0.0]
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    message = str(info.value)
    assert "\n" not in message and message.startswith("'initial.q' = 0.6: the loops do not close at q = 0.6 rad")
    assert "0 degrees of freedom by Grübler's count" in message


def test_a_start_where_the_rank_leaves_two_dof_is_refused_naming_both_counts():
    """The redundant parallelogram started flat (q0 = 0: every crank along the ground line, a change point): its
    four loop rows have rank 2 over 4 coordinates there, 2 DOF by rank where Grübler's count says 0."""
    data = _data()
    data["initial"] = {"q": 0.0, "guess": {"crank2": 0.0, "crank3": 0.0, "coupler": 0.0}}
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    assert str(info.value) == ("'initial.q' = 0: the loop equations have rank 2 (4 rows over 4 coordinates) at the "
                               "assembled configuration: 2 degrees of freedom by rank (0 by Grübler's count), not 1 "
                               "(redundant or parallel joints)")


def test_the_reduced_engine_follows_the_closed_form():
    """DOP853 at rtol 1e-12 against q0 + ω0 t + ½ (T/𝔍) t². Measured: |Δq| 5.1e-15 rad, |Δq̇| 6.2e-15 rad/s,
    𝔍 to 1e-16 relative; the bounds (1e-11) leave room for the integrator's error at its rtol, not for a
    wrong 𝔍 (a crank's inertia left out moves q̇(1 s) by 0.1 rad/s) or a lost loop."""
    data = _data()
    scene = _quiet(data)
    inertia = _inertia(data)
    assert inertia == pytest.approx(0.1125025, rel=1e-12)  # the scene's comment
    model = MechanismModel(scene)
    for q in (0.6, 1.2, math.pi / 2, 2.0):
        c = model.coefficients(q)
        assert c.generalized_inertia == pytest.approx(inertia, rel=1e-12)
        assert abs(c.centrifugal) < 1e-12 * inertia
        assert np.allclose(c.kinematics.K, [1.0, 1.0, 1.0, 0.0], rtol=0.0, atol=1e-12)
    result = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12))
    tr = result.trajectory
    T, q0, w0 = data["torque"]["value"], data["initial"]["q"], data["initial"]["qdot"]
    assert tr.t[-1] == pytest.approx(1.0) and tr.q[-1] > math.pi / 2 + 0.4  # well past π/2
    assert np.max(np.abs(tr.q - (q0 + w0 * tr.t + 0.5 * T / inertia * tr.t ** 2))) < 1e-11
    assert np.max(np.abs(tr.qdot - (w0 + T / inertia * tr.t))) < 1e-11
    # every crank turns as the input, the coupler keeps its angle, the dropped loop row stays closed
    x = result.joints.x
    assert np.max(np.abs(x[:, :3] - tr.q[:, None])) < 1e-11 and np.max(np.abs(x[:, 3])) < 1e-11
    system = loops.compile_linkage(scene.mechanism.linkage)
    assert max(np.max(np.abs(loops.all_constraints(system, row)[0])) for row in x) < 1e-12


def test_a_damper_on_the_redundant_crank_decays_as_the_closed_form():
    """A joint damper c on crank3's pivot (its rate is q̇): 𝔍 q̈ = T − c q̇, so
    q̇ = T/c + (ω0 − T/c) e^(−c t/𝔍). Bound 1e-10 rad/s at rtol 1e-12 (measured 1.2e-12)."""
    data = copy.deepcopy(_data())
    c = 0.05  # N·m·s/rad
    data["joint_dampers"] = [{"name": "d3", "joint": "O3", "coefficient": c}]
    scene = _quiet(data)
    inertia = _inertia(data)
    tr = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12)).trajectory
    T, w0 = data["torque"]["value"], data["initial"]["qdot"]
    assert np.max(np.abs(tr.qdot - (T / c + (w0 - T / c) * np.exp(-c * tr.t / inertia)))) < 1e-10


def _seed_with_a_twin_coupler() -> tuple[dict, dict]:
    """The catalogue's seed four-bar with a second coupler, the first's twin, pinned at the same points A and B
    (Grübler's count 3·4 − 2·6 = 0, one DOF by rank), and the same four-bar with the twin merged into the
    coupler (its mass and inertia doubled, the centre of mass where it was): the same mechanism."""
    with open(ROOT / "scenes" / "mechanisms" / "seed_fourbar.toml", "rb") as f:
        plain = tomllib.load(f)
    plain["simulation"]["horizon"] = 0.5
    twin = copy.deepcopy(plain)
    twin["bodies"]["coupler2"] = copy.deepcopy(plain["bodies"]["coupler"])
    twin["joints"] += [{"name": "A2", "type": "revolute", "a": "crank.A", "b": "coupler2.A"},
                       {"name": "B2", "type": "revolute", "a": "coupler2.B", "b": "rocker.B"}]
    twin["initial"]["guess"]["coupler2"] = twin["initial"]["guess"]["coupler"]
    twin["initial"].pop("mode", None)
    merged = copy.deepcopy(plain)
    merged["bodies"]["coupler"]["mass"] *= 2
    merged["bodies"]["coupler"]["inertia"] *= 2
    return twin, merged


def test_a_twin_coupler_moves_as_the_four_bar_it_duplicates():
    """K and L of a redundant four-bar (every L ≠ 0: the rows' γ must be combined as their basis is) against the
    plain four-bar's, over half a turn of the crank; then the reduced run (DOP853, rtol 1e-12) against the merged
    four-bar's. Measured: K 2e-16, L 1.2e-15 (relative), q 9e-16 rad, q̇ 4e-15 rad/s; the bounds, 1e-11, are the
    runs' rtol-level error, far below a wrong combination of γ (L off by O(1))."""
    twin_data, merged_data = _seed_with_a_twin_coupler()
    twin, merged = _quiet(twin_data), scene_from_dict(merged_data)
    assert twin.mechanism.linkage.grubler_dof == 0
    a = loops.compile_linkage(twin.mechanism.linkage)
    b = loops.compile_linkage(merged.mechanism.linkage)
    assert a.redundant and a.coordinate_names[:3] == b.coordinate_names
    xa, xb = np.array(twin.x0), np.array(merged.x0)
    for q in np.linspace(merged.q0, merged.q0 + math.pi, 13):
        xa, xb = loops.assemble(a, q, xa), loops.assemble(b, q, xb)
        (Ka, La), (Kb, Lb) = loops.coefficients(a, xa), loops.coefficients(b, xb)
        assert np.max(np.abs(xa[:3] - xb)) < 1e-12 and abs(xa[3] - xa[1]) < 1e-12  # the twins keep one angle
        assert np.max(np.abs(Ka[:3] - Kb)) < 1e-11 and np.max(np.abs(La[:3] - Lb)) < 1e-11 * np.max(np.abs(Lb))
        assert Ka[3] == pytest.approx(Ka[1], abs=1e-12) and La[3] == pytest.approx(La[1], abs=1e-11)
    settings = ReducedSettings(method="dop853", rtol=1e-12)
    ta, tb = simulate(twin, settings).trajectory, simulate(merged, settings).trajectory
    q, qdot, _ = tb.interpolate(ta.t)
    assert np.max(np.abs(ta.q - q)) < 1e-11 and np.max(np.abs(ta.qdot - qdot)) < 1e-11 * np.max(np.abs(qdot))
