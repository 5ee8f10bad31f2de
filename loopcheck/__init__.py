"""loopcheck: the dynamics of one-DOF planar linkages solved independent ways, and how far apart they are.

The API (each name loads its module on first use, so ``import loopcheck`` is light):

- scenes: :func:`load_scene` (a file, or a shipped scene by name), :func:`scene_from_string`,
  :func:`scene_from_dict`, :func:`catalogue` (the shipped scenes by name), :class:`Scene`;
- engines: :func:`simulate` (the engine is the one whose settings are given),
  :class:`ReducedSettings` (Eksergian's equation, the exact reference), :class:`MujocoSettings`,
  and the scene's own settings of each, :func:`reduced_settings`, :func:`mujoco_settings`; every
  registered engine (``reduced``, ``mujoco``, ``pin``, ``mjx``, ``mjwarp``: ``loopcheck.registry.ENGINES``,
  its ``Settings`` as ``ENGINES[name].settings``) runs through :func:`simulate` and :func:`check`;
- comparison: :func:`compare_results` (two results of one scene, a :class:`Comparison` of a
  ``reference`` and an ``other`` run; the name `compare` is the subpackage), :func:`check` (engines
  against the reduced reference, as ``loopcheck check --engines``: an :class:`EnginesCheck` with
  ``.passed``, ``.verdicts`` (:class:`EngineVerdict`), ``.outlier`` and ``.comparison(name)``;
  by default the reduced reference against MuJoCo, as ``loopcheck check``), :class:`Tolerances`.
  Every engine at once::

      check = loopcheck.check(scene, engines=["reduced", "mujoco", "pin", "mjx", "mjwarp"])
      print(check.passed, check.outlier, [(v.engine, v.passed) for v in check.verdicts])
      print(check.comparison("pin").diff.peak_omega_rel)

- results: :class:`EngineResult` (the input's trajectory, every joint's coordinate and rate,
  peak, energy audit, the loops' opening, cost, the settings as run; every array of a result is
  read-only), :class:`Trajectory`, :class:`Peak`; errors: :class:`SceneError` (bad input), :class:`NumericalFailure` (a run that
  cannot meet its accuracy, with the reason).

Subpackages: :mod:`loopcheck.reduced` (the Eksergian engine and its compiled core),
:mod:`loopcheck.reference_models` (the same mechanism in MuJoCo), :mod:`loopcheck.compare` (comparison,
gate, studies, plots and the command line ``loopcheck``); the shipped scenes are package data of
:mod:`loopcheck.scenes`.
"""

from __future__ import annotations

from ._lazy import lazy_names

_HOMES = {
    **{name: "loopcheck.api" for name in ("Comparison", "EngineResult", "EngineVerdict", "EnginesCheck", "MujocoSettings", "ReducedSettings", "Scene",
                                     "SceneError", "Tolerances", "check", "compare_results", "load_scene", "mujoco_settings",
                                     "reduced_settings", "scene_from_dict", "scene_from_string", "catalogue",
                                     "simulate")},
    "NumericalFailure": "loopcheck.errors",
    "Trajectory": "loopcheck.trajectory",
    "Peak": "loopcheck.trajectory",
}

_lazy_getattr, __dir__, __all__ = lazy_names(__name__, _HOMES, globals())


def __getattr__(name: str):
    if name == "__version__":  # looked up on first use: importlib.metadata costs the command's start-up ~30 ms
        from importlib.metadata import PackageNotFoundError, version

        try:
            found = version("loopcheck")
        except PackageNotFoundError:  # a checkout that was never installed
            found = "0+unknown"
        globals()["__version__"] = found
        return found
    return _lazy_getattr(name)
