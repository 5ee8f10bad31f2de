"""Local sensitivities d(peak |ω|)/dp (loopcheck.compare.sensitivity, ``loopcheck sweep --sensitivity``).

Oracle: the same derivative by central differences at a step ten times the module's and more
(1e-3 of the nominal value), Richardson-extrapolated, whose own truncation is estimated from its
two steps. The two must agree within the sum of their error estimates (measured on the seed over
1.3 s: damper 1.6e-9 apart with estimates 2.9e-8 and 3.9e-7 at 1 %; coupler mass 3.7e-4 apart at
1 % with its estimate 1.2e-3 — at 0.1 % below). Each run is the reduced solver's continuous peak.
Seen failing: D(2h) divided by 2h instead of 4h; a step of ε^(2/3) instead of ε^(1/3) (the
noise term swamps the estimate). Not detectable here, and said so: the sign of the Richardson
correction (it moves D by 1.6e-6 of the coupler mass's derivative, inside the estimates):
tests/compare/test_sensitivity_closed_form.py catches it against a closed-form derivative.
"""

from __future__ import annotations

import json

import pytest

from loopcheck.compare.cli import main
from loopcheck.compare.sensitivity import Sensitivity, _peaks, sensitivities
from loopcheck.sweep_spec import spec_from_args
from loopcheck.compare.sweep_scene import load_sweep
from loopcheck.shipped_scenes import default_scene_path

from helpers import plots_left_out

KEYS = ["dampers.0.coefficient=40:70:2", "bodies.coupler.mass=35:45:2"]


@pytest.fixture(scope="module")
def seed():
    path = str(default_scene_path())
    data, _ = load_sweep(path)
    data["simulation"]["horizon"] = 1.3  # the peak is at 1.154 s
    return data, path


def _richardson(data, path, key, p0, delta):
    peaks = {k: _peaks(data, {key: p0 + k * delta}, key, path)[0] for k in (-2, -1, 1, 2)}
    d_h = (peaks[1] - peaks[-1]) / (2 * delta)
    d_2h = (peaks[2] - peaks[-2]) / (4 * delta)
    return d_h + (d_h - d_2h) / 3, abs(d_h - d_2h) / 3


def test_sensitivities_agree_with_a_coarser_richardson_estimate(seed):
    data, path = seed
    items = sensitivities(data, spec_from_args(KEYS), path)
    assert [s.key for s in items] == ["dampers.0.coefficient", "bodies.coupler.mass"]
    for s in items:
        assert s.step < 1e-3 * abs(s.nominal)  # the module's own step is the finer one
        coarse, coarse_error = _richardson(data, path, s.key, s.nominal, 1e-3 * abs(s.nominal))
        assert abs(s.derivative - coarse) <= s.error + coarse_error, (s, coarse, coarse_error)
        assert s.error < 1e-4 * abs(s.derivative)  # a smooth peak: the estimate is small
    damper, mass = items
    assert damper.derivative < 0 and mass.derivative < 0  # more damping, more mass: a lower peak


def test_the_sweep_command_prints_and_records_the_sensitivities(tmp_path, capsys):
    scene = tmp_path / "short.toml"
    text = default_scene_path().read_text().replace("horizon = 2.0", "horizon = 1.3")
    scene.write_text(text)
    out = tmp_path / "out"
    with plots_left_out():  # what it prints and sweep.json are read
        status = main(["sweep", str(scene), "--vary", "dampers.0.coefficient=50,60", "--sensitivity",
                       "--out", str(out), "--workers", "1"])
    assert status == 0
    printed = capsys.readouterr().out
    assert "d(peak |omega|)/dp" in printed and "dampers.0.coefficient" in printed
    [recorded] = json.loads((out / "sweep.json").read_text())["sensitivity"]
    assert recorded["key"] == "dampers.0.coefficient" and recorded["nominal"] == 55.0
    data, _ = load_sweep(scene)
    coarse, coarse_error = _richardson(data, str(scene), recorded["key"], 55.0, 0.055)
    assert abs(recorded["derivative"] - coarse) <= recorded["error"] + coarse_error


def test_a_sensitivity_needs_a_positive_step():
    with pytest.raises(ValueError, match="step"):
        Sensitivity("k", 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0)


def test_a_failed_run_near_the_nominal_value_is_a_numerical_failure_naming_the_key(seed):
    """A run that fails (here RKN4 at a step far too large for its own error estimate) is a
    numerical failure (exit 1), not bad input, and names the key and value that needed it."""
    from loopcheck.errors import NumericalFailure

    data, path = seed
    coarse = {**data, "reduced": {"method": "rkn4", "step": 0.05}}
    with pytest.raises(NumericalFailure, match="sensitivity to 'dampers.0.coefficient'") as failure:
        sensitivities(coarse, spec_from_args(KEYS[:1]), path)
    assert failure.value.reason == "inaccurate"
