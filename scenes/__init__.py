"""The scenes shipped with loopcheck, as package data: ``seed_fourbar.toml`` (the default scene) and
``hard/`` (the hard-case catalogue of ``loopcheck stress``).

Read them through :func:`loopcheck.scenefile.scenes_dir`, :func:`loopcheck.scenefile.default_scene_path` and
:func:`loopcheck.scenefile.hard_scene_dir`; this package holds no code.
"""
