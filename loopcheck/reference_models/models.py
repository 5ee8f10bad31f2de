"""A user's own MuJoCo model (MJCF), as the commands reach it: the MuJoCo engine reads ``.xml`` files
(its settings' ``MODEL_FILES``; :attr:`loopcheck.registry.Engine.models` is this module), so that
the comparison and the command line name no engine.

The interface: ``Control`` (an actuator's control, ``--ctrl``), ``import_model`` (the file read as a
scene at a keyframe or qpos0, an ``ImportedModel``), ``import_loop`` (one loop cut out, ``--loop``), ``import_assembled``
(the loops closed by Newton, ``--assemble``), ``input_coordinate`` (the input as the file names it),
``model_text`` (a scene's model written in the format, ``export-mjcf``), ``run_model`` (the model
as written, run: ``check model.xml --engines``), and the check of the model
as written against the reduced reference (:mod:`loopcheck.reference_models.model_check`:
``check_model``, ``check_lines``, ``diagnosis_lines``, ``reference_failure_lines``, ``VacuousCheck``,
``refuse_vacuous_model``).
Each name loads its module on first use.
"""

from __future__ import annotations

from loopcheck._lazy import lazy_names

FORMAT = "MuJoCo model (MJCF)"  # how messages name the files read here

_HOMES = {
    **dict.fromkeys(("Control", "ImportedModel"), ".mjcf_import"),
    "import_model": (".mjcf_import", "import_mjcf"),
    **dict.fromkeys(("import_loop", "import_assembled"), ".extract"),
    **dict.fromkeys(("input_coordinate", "run_model"), ".user_model"),
    "model_text": (".run", "mjcf_text"),
    **dict.fromkeys(("VacuousCheck", "check_lines", "check_model", "diagnosis_lines", "reference_failure_lines",
                     "refuse_vacuous_model"),
                    ".model_check"),
}
__getattr__, __dir__, _names = lazy_names("loopcheck.reference_models", _HOMES, globals())
__all__ = ["FORMAT", *_names]
