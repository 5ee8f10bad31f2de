"""`loopcheck check model.xml` and `loopcheck run model.xml`: a user's own model, as written, against
the exact answer.

The engine that read the model's file (:func:`loopcheck.registry.model_readers`: MuJoCo reads MJCF)
reads it as a scene, runs it as written, changes each of its settings alone and says which causes
the difference and what to paste into the file (its ``models`` module,
:attr:`loopcheck.registry.Engine.models`: MuJoCo's :mod:`loopcheck.reference_models.model_check`).
What is the comparison's is here: the reduced reference of the model's scene, and the judge that
compares each of the engine's runs with it (:func:`loopcheck.compare.run.judge`).
"""

from __future__ import annotations

from typing import Any

from loopcheck.registry import ENGINES, REFERENCE, Engine, model_readers
from loopcheck.scene import Tolerances

from .run import judge


def reader_of(imported: Any) -> Engine:
    """The engine that read ``imported`` (the engine reading model files whose ``models`` module made
    it: its ``ImportedModel``).

    Raises
    ------
    TypeError
        If no registered engine reads such a model.
    """
    for engine in model_readers():
        if isinstance(imported, engine.models.ImportedModel):
            return engine
    raise TypeError(f"{type(imported).__name__}: no registered engine reads this model")


def check_model(imported: Any, *, tolerances: Tolerances | None = None, reduced: Any = None):
    """The check of the user's model ``imported`` as written (the reading engine's ``check_model``):
    the reduced reference of its scene (``reduced``: the reference's settings, default its
    defaults) handed to the engine with the comparison's judge.

    Raises
    ------
    NumericalFailure
        If the reduced reference fails (the model's own runs record their failures instead).
    VacuousCheck
        The engine's, if the reference does not move: before the model runs.
    """
    reference_engine = ENGINES[REFERENCE]
    reference = reference_engine.simulate(imported.scene, reduced or reference_engine.settings())
    return reader_of(imported).models.check_model(imported, reference, judge, tolerances=tolerances)
