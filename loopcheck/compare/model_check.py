"""`loopcheck check model.xml` and `loopcheck run model.xml`: a user's own model, as written, against
the exact answer.

The engine that reads the model's file (:func:`loopcheck.registry.model_reader`: MuJoCo reads MJCF)
reads it as a scene, runs it as written, changes each of its settings alone and says which causes
the difference and what to paste into the file (its ``models`` module,
:attr:`loopcheck.registry.Engine.models`: MuJoCo's :mod:`loopcheck.reference_models.model_check`).
What is the comparison's is here: the reduced reference of the model's scene, and the judge that
compares each of the engine's runs with it (:func:`loopcheck.compare.run.judge`).
"""

from __future__ import annotations

from typing import Any

from loopcheck.registry import ENGINES, REFERENCE, Engine, model_reader
from loopcheck.scene import Tolerances

from .run import judge


def reader_of(imported: Any) -> Engine:
    """The engine that read ``imported`` (the model its scene was read from, by the file's suffix).

    Raises
    ------
    ValueError
        If no registered engine reads that file.
    """
    source = imported.scene.source or ""
    engine = model_reader(source)
    if engine is None:
        raise ValueError(f"{source}: no engine reads this file as a model")
    return engine


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
