"""The scenes shipped with xval, as package data: ``seed_fourbar.toml`` (the default scene) and
``hard/`` (the hard-case catalogue of ``xval stress``).

Read them through :func:`xval.reduced.scene.scenes_dir`, :func:`xval.reduced.scene.default_scene_path` and
:func:`xval.reduced.scene.hard_scene_dir`; this package holds no code.
"""
