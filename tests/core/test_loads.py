"""Torque profiles: the vectorized sampling (fast path) equals the scalar definition."""

from __future__ import annotations

import numpy as np
import pytest

from loopcheck.loads import ConstantLoad, PiecewiseConstantLoad, PulseLoad, TabulatedForce

PROFILES = [ConstantLoad(3.0), PulseLoad(250.0, 0.5, 1.0),
            PiecewiseConstantLoad((0.0, 1.0, 2.0), (1.0, -2.0, 5.0))]


@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: type(p).__name__)
def test_sample_equals_pointwise_values(profile):
    times = np.concatenate([np.linspace(-1.0, 3.0, 4001), np.array(profile.edges)])
    np.testing.assert_array_equal(profile.sample(times), [profile(t) for t in times])


@pytest.mark.parametrize("profile", PROFILES[1:], ids=lambda p: type(p).__name__)
def test_a_piece_sees_one_side_of_each_edge(profile):
    edges = profile.edges
    for a, b in zip(edges, edges[1:]):
        inside = profile(0.5 * (a + b))
        f = profile.on_piece(a, b)
        assert f(a) == inside and f(b) == inside  # both ends take the value of the open interval


@pytest.mark.parametrize("make, field", [
    (lambda: ConstantLoad(float("nan")), "ConstantLoad.amplitude"),
    (lambda: PulseLoad(1.0, -0.5, 1.0), "PulseLoad.start"),
    (lambda: PulseLoad(1.0, 0.0, -1.0), "PulseLoad.duration"),
    (lambda: PulseLoad(float("inf"), 0.0, 1.0), "PulseLoad.amplitude"),
    (lambda: PiecewiseConstantLoad((0.0, 1.0), (1.0,)), "PiecewiseConstantLoad.times and .values"),
    (lambda: PiecewiseConstantLoad((), ()), "PiecewiseConstantLoad.times and .values"),
    (lambda: PiecewiseConstantLoad((0.0, 0.0), (1.0, 2.0)), "PiecewiseConstantLoad.times must be strictly"),
    (lambda: PiecewiseConstantLoad((0.0, 1.0), (1.0, float("nan"))), "PiecewiseConstantLoad.values[1]"),
], ids=["nan", "neg_start", "neg_duration", "inf", "lengths", "empty", "not_increasing", "nan_value"])
def test_profiles_validate_their_fields(make, field):
    """Built directly (not from a scene), a profile still refuses what it cannot represent."""
    with pytest.raises(ValueError) as info:
        make()
    assert str(info.value).startswith(field)


def _periodic_force_scene(tmp_path, values, period=6.0, q=(0.0, 2.0, 4.0, 6.0)):
    """The planar seed with a periodic point force on the coupler, written as a scene file."""
    import tomllib

    from loopcheck.shipped_scenes import scenes_dir

    text = (scenes_dir() / "mechanisms" / "seed_fourbar.toml").read_text()
    tomllib.loads(text)  # the base parses
    path = tmp_path / "periodic.toml"
    path.write_text(text + f"\n[[point_forces]]\nname = \"push\"\npoint = \"coupler.B\"\ndirection = 0.0\n"
                           f"period = {period!r}\nq = {list(q)!r}\nvalues = {list(values)!r}\n")
    return path


def test_a_periodic_table_whose_ends_disagree_is_refused(tmp_path, capsys):
    """Issue 24: period 6 over q = 0..6 with F(6) = 5000 N: the closing rule dropped the last
    point and F(6) came out 0 (the first value), exit 0. Decision: refused, exit 2, naming the
    key. A table that ends on its first value, or one period short, is accepted, and F at the
    table's points is the table's value (interpolating spline; the period's end is the start)."""
    from loopcheck.compare.cli import main
    from loopcheck.scenefile import load_scene

    path = _periodic_force_scene(tmp_path, [0.0, 1000.0, 3000.0, 5000.0])
    assert main(["reduced", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "point_forces[0]" in err and "ends disagree" in err, err
    for q, values in (((0.0, 2.0, 4.0, 6.0), [5000.0, 1000.0, 3000.0, 5000.0]), ((0.0, 2.0, 4.0), [0.0, 1000.0, 3000.0])):
        scene = load_scene(_periodic_force_scene(tmp_path, values, q=q))
        [pf] = scene.mechanism.point_forces
        force = TabulatedForce(pf.coordinate, pf.values, pf.period)
        assert [force(x) for x in q] == pytest.approx(values, abs=1e-9)  # the points themselves, to rounding
        assert force(6.0) == pytest.approx(values[0], abs=1e-9) and force(12.0) == pytest.approx(values[0], abs=1e-9)
