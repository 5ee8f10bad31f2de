"""Time limits of the tests (pytest-timeout, of the ``test`` extra): a hang fails, named; and the
runs that several test modules share, computed once per session.

Every test has ``timeout`` seconds (300, pyproject.toml [tool.pytest.ini_options]; ``--timeout``
overrides it), a test marked ``slow`` SLOW_TIMEOUT_S. The method is "thread": a test hung in
compiled code never returns to the interpreter, so a signal handler would never run; the
timer thread names the test, prints every thread's stack and ends the session (exit 1).

Measured with the --durations of the whole suite (a 2-core machine under a load of ~3, 2026-11-26,
issue 26): the slowest test not marked slow took 4.5 s (test_sweep, a row against ``loopcheck run``),
the slowest marked slow 65.5 s (test_packaging, building the wheel). 300 s is 66× the first;
SLOW_TIMEOUT_S is 9× the second.

The session fixtures below hold the runs that several modules read (the seed's reference and
comparisons); a test that needs other settings keeps its own run.
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import pytest

SLOW_TIMEOUT_S = 600
_TIMER = pytest.StashKey[threading.Timer]()


def pytest_sessionstart(session):
    """Stop at once, with the fix, when the compiled core is missing: a checkout that was not
    installed (``pip install -e .`` builds the kernels) would otherwise run every kernel as plain
    Python (``LOOPCHECK_PURE_PYTHON``, the debug path), and the suite for hours."""
    from loopcheck.reduced import kernels

    if not kernels.PURE_PYTHON and not kernels.compiled():
        pytest.exit("the reduced solver's kernels are not compiled: run `pip install -e .` (or "
                    "`python setup.py build_ext --inplace`) in the checkout; LOOPCHECK_PURE_PYTHON=1 runs them "
                    "uncompiled on purpose", returncode=2)


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.get_closest_marker("slow") is not None and item.get_closest_marker("timeout") is None:
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT_S))


# -- shared runs, computed once per session ---------------------------------------------------
# Results are frozen dataclasses holding read-only arrays (tests/test_api.py writes into one and
# expects the error), so sharing them between modules cannot let one test change another's
# input. A test that needs other settings keeps its own run.

SEED_SCENE = Path(__file__).resolve().parent.parent / "scenes" / "seed_fourbar.toml"
SLIDER_DRIVEN_SCENE = SEED_SCENE.parent / "mechanisms" / "slider_crank_driven_slider.toml"


@pytest.fixture(scope="session")
def seed_scene():
    """The seed scene (scenes/seed_fourbar.toml), loaded."""
    from loopcheck.scenefile import load_scene

    return load_scene(SEED_SCENE)


@pytest.fixture(scope="session")
def seed_reference(seed_scene):
    """The seed's reduced reference run: DOP853 at rtol 1e-12, the scene's other settings."""
    from loopcheck.reduced import ReducedSettings, simulate

    return simulate(seed_scene, ReducedSettings(method="dop853", rtol=1e-12))


@pytest.fixture(scope="session")
def seed_mujoco(seed_scene):
    """The seed's MuJoCo run at the default settings (its automatic step)."""
    from loopcheck.reference_models import simulate_mujoco

    return simulate_mujoco(seed_scene)


@pytest.fixture(scope="session")
def seed_comparison(seed_scene):
    """``compare_engines`` on the seed at its defaults (what ``loopcheck run`` compares)."""
    from loopcheck.compare.run import compare_engines

    return compare_engines(seed_scene)


@pytest.fixture(scope="session")
def slider_driven_comparison():
    """``compare_engines`` on the catalogue's slider-driven slider-crank at its defaults."""
    from loopcheck.compare.run import compare_engines
    from loopcheck.scenefile import load_scene

    return compare_engines(load_scene(SLIDER_DRIVEN_SCENE))


@pytest.fixture
def saved_figures(monkeypatch) -> list:
    """The matplotlib figures loopcheck.compare.plots saves from now on (still saved, to their files), in
    order: a test reads what a plot or drawing drew without replacing how it is drawn."""
    import loopcheck.compare.plots

    kept = []
    real = loopcheck.compare.plots._save

    def keep(fig, path):
        real(fig, path)
        kept.append(fig)

    monkeypatch.setattr(loopcheck.compare.plots, "_save", keep)
    return kept


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_timeout_set_timer(item, settings):
    """pytest-timeout's thread timer, with the test's name first (its own dump shows the stacks
    but not which test, with its parameters, ran out of time)."""
    if settings.method != "thread":
        return None
    from pytest_timeout import timeout_timer

    def expire():
        sys.stderr.write(f"\n{item.nodeid}: ran past its time limit of {settings.timeout:g} s\n")
        sys.stderr.flush()
        timeout_timer(item, settings)

    timer = threading.Timer(settings.timeout, expire)
    timer.name = f"{__name__} timeout {item.nodeid}"
    timer.daemon = True
    timer.start()
    item.stash[_TIMER] = timer
    return True


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_timeout_cancel_timer(item):
    timer = item.stash.get(_TIMER, None)
    if timer is None:
        return None
    timer.cancel()
    timer.join()
    del item.stash[_TIMER]
    return True
