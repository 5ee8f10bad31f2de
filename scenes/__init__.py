"""The scenes shipped with xval, as package data: ``seed_fourbar.toml`` (the default scene) and
``hard/`` (the hard-case catalogue of ``xval stress``).

Read them through :func:`xval.scenefile.scenes_dir`, :func:`xval.scenefile.default_scene_path` and
:func:`xval.scenefile.hard_scene_dir`; this package holds no code.
"""
