"""The engines, by name: one line each.

An engine is a package with two names (``docs/engines.md`` has the recipe):

- ``Settings``: a frozen dataclass whose fields are :func:`loopcheck.settings.option` s. They define
  the engine's table of the scene file (``[NAME]``) and its command-line flags. It lives in the
  package's ``settings`` module, which imports nothing of the engine, so that reading a scene
  file or printing the help loads no engine;
- ``simulate(scene, settings) -> EngineResult``.

The registry names packages and imports them only when asked (``importlib``): the scene format
reads each engine's table through it, and the comparison and the command line run engines
through it, without a static import of any engine.

Engines are registered by entry points in the ``loopcheck.engines`` group (:data:`GROUP`): one line
``NAME = "PACKAGE"`` in a distribution's ``pyproject.toml`` (``[project.entry-points."loopcheck.engines"]``).
loopcheck's own five are declared there too; :data:`BUILT_IN` is the same table, so that a
checkout run without installing, or an install older than the group, still has them
(``tests/core/test_engine_entry_points.py`` checks that the two agree). An installed distribution
that declares an engine is found when the registry is first imported (:func:`registered`).
"""

from __future__ import annotations

import functools
import importlib
import inspect
import math
import re
from dataclasses import dataclass
from typing import Any, Sequence

from .results import EngineResult
from .scene import Scene, SceneError


GROUP = "loopcheck.engines"  # the entry-point group an engine is declared in
_NAME = re.compile(r"[a-z][a-z0-9_]*")  # a scene file's table, a word of --engines


@functools.cache
def _takes(function, keyword: str) -> bool:
    """Whether an engine's ``function`` takes the optional ``keyword`` (read once per function: a
    sweep asks at every variant)."""
    return keyword in inspect.signature(function).parameters


@dataclass(frozen=True)
class Rung:
    """One run an engine declares for a study: a point of its accuracy ladder (``loopcheck cost``)
    or one of its stress probes (``loopcheck stress``).

    ``series`` names the curve or the probe's family (e.g. ``"DOP853"``, ``"rk4 (hard)"``),
    ``parameter`` what the series varies (a step in s, or a tolerance; NaN for a single point) and
    ``settings`` the engine's ``Settings`` for that run. ``symbol`` names the parameter in labels
    (``"h"``, a step; ``"rtol"``, a tolerance). ``run_settings``: where the ladder loosens the
    engine's own limits so as to measure what ``loopcheck run`` refuses (a loop gap, an energy
    balance, an error estimate), the same point with run's default limits, which give the point's
    verdict; None: ``settings`` are run's."""

    series: str
    parameter: float
    settings: Any
    symbol: str = "h"
    run_settings: Any = None

    def __post_init__(self):
        if not isinstance(self.series, str) or not self.series:
            raise ValueError(f"Rung.series must be a non-empty string, got {self.series!r}")
        if not isinstance(self.parameter, (int, float)) or isinstance(self.parameter, bool) or (
                not math.isnan(self.parameter) and not (math.isfinite(self.parameter) and self.parameter > 0.0)):
            raise ValueError(f"Rung.parameter must be positive and finite, or NaN, got {self.parameter!r}")
        if not isinstance(self.symbol, str) or not self.symbol:
            raise ValueError(f"Rung.symbol must be a non-empty string, got {self.symbol!r}")

    @property
    def as_run(self) -> Any:
        """The settings ``loopcheck run`` would run this point with (its verdict's)."""
        return self.settings if self.run_settings is None else self.run_settings

    @property
    def label(self) -> str:
        """The point in a table: ``"RKN4 h=1.0e-03"``; the series alone for a single point."""
        return self.series if math.isnan(self.parameter) else f"{self.series} {self.symbol}={self.parameter:.1e}"


@dataclass(frozen=True)
class Engine:
    """One engine: its ``name`` (the scene file's table, the results' label), the ``package``
    that holds it and a one-line ``title`` (for an engine declared by an entry point, the first
    line of its ``settings`` module's docstring, read when asked: :attr:`description`)."""

    name: str
    package: str
    title: str | None = None

    def __post_init__(self):
        if not _NAME.fullmatch(self.name):
            raise ValueError(f"engine name '{self.name}': lower-case letters, digits and _, a letter first")
        if not re.fullmatch(r"[A-Za-z_][\w.]*", self.package):
            raise ValueError(f"engine '{self.name}': '{self.package}' is not a package name (the entry point's "
                             f"value is the engine's package, e.g. my_engine)")

    @property
    def description(self) -> str:
        """The one-line title: ``title``, else the first line of the settings module's docstring."""
        if self.title:
            return self.title
        doc = importlib.import_module(f"{self.package}.settings").__doc__ or ""
        return doc.strip().splitlines()[0] if doc.strip() else self.package

    @property
    def settings(self) -> type:
        """The engine's ``Settings`` type (its ``settings`` module only: no engine is loaded)."""
        return importlib.import_module(f"{self.package}.settings").Settings

    def load(self) -> None:
        """Import the engine (ImportError in one line, the engine's own, when an optional extra
        is missing: checked before any work)."""
        importlib.import_module(self.package).simulate

    def simulate(self, scene: Scene, settings: Any, *, summary: bool = False) -> EngineResult:
        """Run the engine on ``scene`` with ``settings`` (a ``self.settings``). ``summary``: only the
        result's summaries will be read (a sweep's row: the peak, the energy residual, the status),
        passed on to a ``simulate`` that takes a keyword ``summary`` (the reduced engine's cheaper
        run), ignored by one that does not."""
        self.check_dof(scene)
        simulate = importlib.import_module(self.package).simulate
        if summary and _takes(simulate, "summary"):
            return simulate(scene, settings, summary=True)
        return simulate(scene, settings)

    # The optional declarations (docs/engines.md, "What an engine may declare"). Each has a default,
    # so that an engine declaring none of them still reaches every study. The light ones live in the
    # engine's ``settings`` module (read without loading the engine); ``simulate_batch`` in its package.

    @property
    def several_dof(self) -> bool:
        """Whether the engine runs linkages of several degrees of freedom: its settings module's
        ``SEVERAL_DOF`` (default False: one DOF only, and a scene with several inputs is refused
        by :meth:`check_dof`)."""
        return self._declared("SEVERAL_DOF") is True

    def check_dof(self, scene: Scene) -> None:
        """Refuse, in one line (SceneError), a scene of several degrees of freedom that the engine
        cannot run (:attr:`several_dof`)."""
        if getattr(scene, "dof", 1) > 1 and not self.several_dof:  # (a test's fake engine may run on anything)
            raise SceneError(f"scene '{scene.name}' has {scene.dof} degrees of freedom (inputs "
                             f"{', '.join(scene.inputs)}); the {self.label} engine runs one-DOF linkages only")

    def _declared(self, name: str) -> Any:
        return getattr(importlib.import_module(f"{self.package}.settings"), name, None)

    @property
    def label(self) -> str:
        """The engine's name in prose, tables and plots: its settings module's ``LABEL`` (default:
        its name)."""
        label = self._declared("LABEL")
        return label if isinstance(label, str) and label else self.name

    @property
    def colour(self) -> str:
        """The engine's colour in plots (a matplotlib colour): its settings module's ``COLOUR``
        (default: the first colour of :data:`PALETTE` that no registered engine declares, taken
        by the undeclared engines in the registry's order)."""
        colour = self._declared("COLOUR")
        if isinstance(colour, str) and colour:
            return colour
        declared = {e._declared("COLOUR") for e in ENGINES.values()}
        spare = [c for c in PALETTE if c not in declared]
        undeclared = [e.name for e in ENGINES.values() if not e._declared("COLOUR")]
        index = undeclared.index(self.name) if self.name in undeclared else len(undeclared)
        return spare[index % len(spare)] if spare else PALETTE[index % len(PALETTE)]

    @property
    def runs(self) -> tuple[str, ...]:
        """The names of the runs this engine's package produces (``EngineResult.engine``): its own
        name, then its settings module's ``RUNS`` (e.g. a user's own model run as written; default
        none). Each is labelled, coloured and filed as the engine (:func:`engine_of_run`)."""
        runs = self._declared("RUNS") or ()
        return (self.name, *(r for r in runs if isinstance(r, str) and r != self.name))

    @property
    def inherits(self) -> tuple[str, frozenset[str]] | None:
        """Another engine's table whose values are this engine's defaults for some keys: its settings
        module's ``INHERITS = (ENGINE, KEYS)`` (a port taking the scene's table of the engine it
        ports for the options they share; default: nothing inherited)."""
        declared = self._declared("INHERITS")
        if declared is None:
            return None
        engine, keys = declared
        return str(engine), frozenset(keys)

    def settings_text(self, result: EngineResult) -> str | None:
        """A run's settings in a few words, for a table's column head: the settings module's
        ``settings_text(result) -> str`` (default None: the comparison's own words)."""
        declared = self._declared("settings_text")
        return None if declared is None else str(declared(result))

    def check_work(self, scene: Scene, settings: Any) -> None:
        """Refuse, before any work, a run the engine cannot do with ``settings``: the package's
        ``check_work(scene, settings)`` where it has one (ValueError naming what to change), else
        nothing."""
        self.check_dof(scene)
        check = getattr(importlib.import_module(self.package), "check_work", None)
        if check is not None:
            check(scene, settings)

    @property
    def model_files(self) -> tuple[str, ...]:
        """The suffixes of the model files the engine reads as scenes and runs as written (a user's own
        model: ``loopcheck check model.xml``): its settings module's ``MODEL_FILES`` (e.g.
        ``(".xml",)``; default none). Such an engine's package has a ``models`` module
        (:attr:`models`)."""
        files = self._declared("MODEL_FILES") or ()
        return tuple(str(suffix).lower() for suffix in files)

    @property
    def models(self):
        """The module of the engine's package that reads and checks a user's own model (its
        ``models`` module; the commands' interface to it is documented there)."""
        return importlib.import_module(f"{self.package}.models")

    def gate_notes(self, scene: Scene, result: EngineResult, failures: Sequence[str]) -> tuple[str, ...]:
        """What a failed gate adds about the engine's run ``result`` of ``scene`` (``failures``: the
        gate's): the settings module's ``gate_notes(scene, result, failures) -> Sequence[str]``
        (e.g. MuJoCo naming the fixed timestep it ran at), by default nothing."""
        declared = self._declared("gate_notes")
        return () if declared is None else tuple(str(note) for note in declared(scene, result, failures))

    def result_lines(self, scene: Scene, result: EngineResult) -> list[str] | None:
        """What the engine's own command (``loopcheck NAME``) prints of a run beside the common lines:
        the package's ``result_lines(scene, result) -> list[str]`` (default None: the common lines
        alone)."""
        lines = getattr(importlib.import_module(self.package), "result_lines", None)
        return None if lines is None else list(lines(scene, result))

    def ladder(self, scene: Scene, base: Any, quick: bool = False) -> tuple[Rung, ...]:
        """The accuracy ladder ``loopcheck cost`` runs: the settings module's
        ``accuracy_ladder(scene, base, quick) -> Sequence[Rung]`` (``base``: the scene's resolved
        settings; ``quick``: a short ladder), by default one point at ``base``."""
        declared = self._declared("accuracy_ladder")
        rungs = (Rung(self.label, math.nan, base),) if declared is None else tuple(declared(scene, base, quick))
        return self._checked(rungs, "accuracy_ladder")

    def truth(self) -> tuple[Rung, Rung]:
        """The ground truth a study measures every engine against, for the reference engine
        (:data:`REFERENCE`): its settings module's ``truth() -> (Rung, Rung)``, the truth's run and
        a looser one that measures how accurate the truth is.

        Raises
        ------
        ValueError
            In one line, when the engine declares none (or not two Rungs of its Settings).
        """
        declared = self._declared("truth")
        if declared is None:
            raise ValueError(f"engine '{self.name}' declares no ground truth (truth() in {self.package}.settings), "
                             f"which a study's reference needs")
        rungs = tuple(declared())
        if len(rungs) != 2:
            raise ValueError(f"engine '{self.name}': truth() gave {len(rungs)} runs, not two (the truth, its check)")
        return self._checked(rungs, "truth")

    def stress_probes(self, scene: Scene, base: Any) -> tuple[Rung, ...]:
        """The probes ``loopcheck stress`` runs on a case that asks for them (each reported by its
        status): the settings module's ``stress_probes(scene, base) -> Sequence[Rung]``, by default
        none."""
        declared = self._declared("stress_probes")
        return () if declared is None else self._checked(tuple(declared(scene, base)), "stress_probes")

    def peak_accuracy(self, settings: Any) -> float:
        """ε, the relative accuracy of the engine's peak input speed at ``settings`` (sensitivity's
        differences balance their truncation against it): the settings module's
        ``peak_accuracy(settings) -> float``.

        Raises
        ------
        ValueError
            In one line naming what is missing, when the engine declares none.
        """
        declared = self._declared("peak_accuracy")
        if declared is None:
            raise ValueError(f"engine '{self.name}' declares no peak accuracy (peak_accuracy(settings) in "
                             f"{self.package}.settings), which sensitivity needs to choose its steps")
        eps = declared(settings)
        if not (isinstance(eps, (int, float)) and math.isfinite(eps) and 0.0 < eps < 1.0):
            raise ValueError(f"engine '{self.name}': peak_accuracy gave {eps!r}, not a relative accuracy in (0, 1)")
        return float(eps)

    def fixed_step(self, settings: Any) -> float | None:
        """The step (s) of the engine's fixed step grid at ``settings`` as a run used them
        (:attr:`EngineResult.settings`), or None when its steps adapt: the settings module's
        ``fixed_step(settings) -> float | None``, by default None. ``loopcheck stress`` measures the
        error of a load edge off that grid."""
        declared = self._declared("fixed_step")
        if declared is None:
            return None
        h = declared(settings)
        if h is not None and (isinstance(h, bool) or not isinstance(h, (int, float))
                              or not math.isfinite(h) or h <= 0.0):
            raise ValueError(f"engine '{self.name}': fixed_step gave {h!r}, not a positive step in s or None")
        return None if h is None else float(h)

    @property
    def batch_size(self) -> int:
        """How many variants of one structure a sweep hands ``simulate_batch`` at once: the settings
        module's ``BATCH_SIZE`` (default 1: one variant a task, on the sweep's process pool)."""
        size = self._declared("BATCH_SIZE")
        if size is None:
            return 1
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"engine '{self.name}': BATCH_SIZE is {size!r}, not a whole number >= 1")
        return size

    def simulate_batch(self, scenes: Sequence[Scene], settings: Any, *, each: bool = False) -> list:
        """Run variants of one structure: the package's ``simulate_batch(scenes, settings)`` where it
        has one (the ports: one ``vmap``, MJWarp's worlds), else :meth:`simulate` on each in turn.

        With ``each``, one outcome per scene, in order: its ``EngineResult`` or the exception its
        own run raised (a variant's failure sinks no other variant). A package whose
        ``simulate_batch`` takes ``each`` returns those itself (the ports: one batch, the failing
        variants' slots filled by another's run and dropped); one that does not is called plainly,
        and if the batch raises, each scene runs alone (:meth:`simulate`) for its own outcome."""
        for scene in scenes[:1]:  # variants of one structure: one check
            self.check_dof(scene)
        batch = getattr(importlib.import_module(self.package), "simulate_batch", None)
        if not each:
            if batch is None:
                return [self.simulate(scene, settings) for scene in scenes]
            return list(batch(list(scenes), settings))
        if batch is not None:
            try:
                if _takes(batch, "each"):
                    return list(batch(list(scenes), settings, each=True))
                return list(batch(list(scenes), settings))
            except Exception:  # noqa: BLE001 - the batch as a whole: each variant's own run says what failed
                pass
        outcomes: list = []
        for scene in scenes:
            try:
                outcomes.append(self.simulate(scene, settings))
            except Exception as exc:  # noqa: BLE001 - this variant's outcome
                outcomes.append(exc)
        return outcomes

    def batch_limit(self, scene: Scene, settings: Any) -> int | None:
        """The most variants of ``scene``'s structure one batch may hold on the device the engine
        runs on (a sweep splits a larger chunk before any work): the package's
        ``batch_limit(scene, settings) -> int`` (the ports: the device's memory over a variant's
        states, the model's sizes × its steps), by default None (no limit)."""
        declared = getattr(importlib.import_module(self.package), "batch_limit", None)
        if declared is None:
            return None
        limit = declared(scene, settings)
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise ValueError(f"engine '{self.name}': batch_limit gave {limit!r}, not a whole number >= 1")
        return limit

    def _checked(self, rungs: tuple, what: str) -> tuple[Rung, ...]:
        for rung in rungs:
            if not isinstance(rung, Rung) or not isinstance(rung.settings, self.settings) or not (
                    rung.run_settings is None or isinstance(rung.run_settings, self.settings)):
                raise TypeError(f"engine '{self.name}': {what} gave {rung!r}, not a Rung of its Settings")
        return rungs


# The colours an engine that declares none takes (Engine.colour), in this order.
PALETTE = ("tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:grey", "tab:red", "tab:green")

BUILT_IN: tuple[Engine, ...] = (  # pyproject.toml's [project.entry-points."loopcheck.engines"], with titles
    Engine("reduced", "loopcheck.reduced", "Eksergian's equation, solved in one coordinate (the exact reference)"),
    Engine("mujoco", "loopcheck.reference_models", "MuJoCo: the open chain closed by equality constraints"),
    Engine("pin", "loopcheck.pin", "Pinocchio: the tree's constrained dynamics, loops closed by point constraints"),
    Engine("mjx", "loopcheck.mjx", "MJX, MuJoCo's JAX port: the MuJoCo engine's model, stepped by JAX (CPU or GPU)"),
    Engine("mjwarp", "loopcheck.mjwarp", "MJWarp, MuJoCo's Warp port: the MuJoCo engine's model, stepped in float32 (CPU or GPU)"),
)


def registered() -> dict[str, Engine]:
    """The engines by name: the built-ins first, then every other engine declared in the
    :data:`GROUP` entry points of the installed distributions, by name.

    Raises
    ------
    ValueError
        In one line naming the distribution: a declared name that is no engine name, a value
        that is no package, or a built-in's name declared for another package.
    """
    from importlib.metadata import entry_points

    engines = {e.name: e for e in BUILT_IN}
    for point in sorted(entry_points(group=GROUP), key=lambda p: p.name):
        where = f"entry point '{point.name} = {point.value}' of {point.dist.name if point.dist else 'a distribution'} ({GROUP})"
        try:
            engine = Engine(point.name, point.value.strip())
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        known = engines.get(engine.name)
        if known is not None and known.package != engine.package:
            raise ValueError(f"{where}: the engine '{engine.name}' is {known.package}'s")
        engines.setdefault(engine.name, engine)
    return engines


ENGINES: dict[str, Engine] = registered()


REFERENCE = "reduced"  # the exact reference every other engine is judged against (it has no [tolerances.reduced])
DEFAULT_ENGINES = (REFERENCE, "mujoco")  # the default comparison: the design card's pair (others by --engines)


def judged_engines() -> tuple[str, ...]:
    """The engines judged against the reference, by name: every registered engine but it (each may
    have its own tolerances, ``[tolerances.NAME]``)."""
    return tuple(name for name in ENGINES if name != REFERENCE)


def engine_of(settings: Any) -> Engine:
    """The engine whose ``Settings`` ``settings`` are.

    Raises
    ------
    TypeError
        If they are no registered engine's.
    """
    for engine in ENGINES.values():
        if isinstance(settings, engine.settings):
            return engine
    names = ", ".join(e.settings.__name__ for e in ENGINES.values())
    raise TypeError(f"settings of an engine ({names}), not {type(settings).__name__}")


def engine_of_run(name: str) -> Engine | None:
    """The engine whose package produced the run named ``name`` (``EngineResult.engine``: an
    engine's name, or one of its :attr:`Engine.runs`), None for none."""
    if name in ENGINES:
        return ENGINES[name]
    return next((e for e in ENGINES.values() if name in e.runs), None)


def model_reader(path: str) -> Engine | None:
    """The engine that reads the model file ``path`` (by its suffix: :attr:`Engine.model_files`),
    None for a file no engine reads (a scene file)."""
    suffix = "." + str(path).rsplit(".", 1)[-1].lower() if "." in str(path) else ""
    return next((e for e in ENGINES.values() if suffix and suffix in e.model_files), None)


def model_readers() -> tuple[Engine, ...]:
    """The engines that read model files (:attr:`Engine.model_files`), in the registry's order."""
    return tuple(e for e in ENGINES.values() if e.model_files)
