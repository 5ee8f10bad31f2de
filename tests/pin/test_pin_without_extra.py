"""Where Pinocchio is not installed (the extra ``loopcheck[pin]`` left out): the scene format and the
flags still know the ``[pin]`` table (its settings import nothing of Pinocchio), and ``loopcheck pin``
says in one line how to install it (exit 2), no traceback. Runs everywhere: Pinocchio is hidden
from the import system here, installed or not. (Planted: a bare ``import pinocchio`` at the top
of loopcheck/pin/run.py, before the model's message, makes the command print Python's own words
instead: the first test fails.)"""

from __future__ import annotations

import sys

import pytest

import loopcheck.pin
from loopcheck.compare.cli import main
from loopcheck.scenefile import scene_from_dict

from helpers import seed_dict


@pytest.fixture
def no_pinocchio(monkeypatch):
    monkeypatch.setitem(sys.modules, "pinocchio", None)  # `import pinocchio` raises ModuleNotFoundError
    for name in ("loopcheck.pin.model", "loopcheck.pin.run"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    for name in ("simulate", "simulate_pin", "build", "PinModel", "PinDetails"):
        monkeypatch.delitem(loopcheck.pin.__dict__, name, raising=False)


def test_the_command_says_how_to_install_it(no_pinocchio, capsys):
    assert main(["pin", "seed_fourbar", "--rtol", "1e-8"]) == 2
    err = capsys.readouterr().err
    assert err == "loopcheck: error: the pin engine needs Pinocchio: pip install -e '.[pin]' in loopcheck's checkout (the PyPI package pin)\n"


def test_the_scene_table_is_read_without_it(no_pinocchio):
    data = seed_dict()
    data["pin"] = {"rtol": 1e-9, "baumgarte_kp": 50.0}
    settings = loopcheck.pin.Settings(**scene_from_dict(data).engine_table("pin"))
    assert (settings.rtol, settings.kd) == (1e-9, pytest.approx(2 * 50.0 ** 0.5))
    assert "pinocchio" not in [m for m in sys.modules if sys.modules[m] is not None]
