"""The GPU ports talk, and only in loopcheck's words (issue 39, "Long engine runs talk" and
"Output"): `loopcheck check --engines reduced,mjx,mjwarp` run as the command, from a folder of its
own, with empty compilation caches of its own (JAX_COMPILATION_CACHE_DIR, WARP_CACHE_PATH).

The first time each port says "compiling (first compile: no time recorded)" between its start and
end lines; the second time "compiling (about N s)", N the first run's compile time (which `-v`
printed, "compiled in X s", and the record beside the cache holds); a corrupt record is ignored
("first compile" again, no traceback); `-q` silences it all. No line of JAX's, XLA's or Warp's own
reaches stdout or stderr (Warp's "Warp CUDA warning: Could not find or load the NVIDIA CUDA
driver" on a machine without one, MJX's root logging that printed every later line twice), and
the working folder holds nothing afterwards.

Planted, each failing here: Warp's init outside the filter (the CUDA warning on stderr); no record
written (the second run says "first compile"); the record written in the working folder.
Measured (2026-11-28, 2 shared cores, load about 5): the first run 161 s (MJX's compile 59 s, MJWarp's
75 s), the second 36 s (compiles from the caches: 11 s and 1.1 s).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

pytest.importorskip("jax", reason="the mjx engine's extra is not installed (docs/engines.md)")
pytest.importorskip("mujoco.mjx", reason="MJX is not installed (pip install --no-deps mujoco-mjx: docs/engines.md)")
pytest.importorskip("warp", reason="the mjwarp engine's extra is not installed (docs/engines.md)")
pytest.importorskip("mujoco_warp", reason="MJWarp is not installed (pip install --no-deps mujoco-warp: docs/engines.md)")

from loopcheck.mujoco_model.compile_record import about  # noqa: E402

from helpers import SEED_SCENE  # noqa: E402

pytestmark = pytest.mark.slow  # two cold compiles (MJX's scan, MJWarp's kernels): a minute or more on a CPU

FOREIGN = re.compile(r"\b(Warp|warp|jax|jaxlib|JAX|XLA|CUDA|cuda|absl)\b|^(WARNING|INFO|[IWEF]\d{4} )")
SCENE = "seed_fourbar"


def _run(tmp_path, *flags, engines="reduced,mjx,mjwarp"):
    work = tmp_path / "work"
    work.mkdir(exist_ok=True)
    env = {**os.environ, "JAX_COMPILATION_CACHE_DIR": str(tmp_path / "jax-cache"),
           "WARP_CACHE_PATH": str(tmp_path / "warp-cache"), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    argv = [sys.executable, "-m", "loopcheck.compare.cli", *flags, "check", str(SEED_SCENE), "--engines", engines,
            "--horizon", "0.1"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=900, cwd=work, env=env)
    assert done.returncode in (0, 1), done.stderr  # 1: MJX's known defect fails its gate
    assert "Traceback" not in done.stderr
    # nothing of the libraries' own: every stderr line is loopcheck's, no stdout line names them
    assert all(line.startswith("loopcheck: ") for line in done.stderr.splitlines()), done.stderr
    assert not [line for line in done.stdout.splitlines() if FOREIGN.search(line)], done.stdout
    assert list(work.iterdir()) == []  # nothing written in the working folder
    return done.stderr.splitlines()


def _talk(err, engine):
    """The engine's lines from its start to its end."""
    start = err.index(f"loopcheck: {SCENE}: {engine} started")
    end = next(k for k, line in enumerate(err) if line.startswith(f"loopcheck: {SCENE}: {engine} ended in "))
    return err[start:end + 1]


def _record(tmp_path, engine):
    found = list(tmp_path.glob(f"*-cache/**/loopcheck-compile-{engine}-*.json"))
    assert len(found) == 1, found
    return found[0]


def test_the_ports_say_they_compile_and_how_long_it_took_last_time(tmp_path):
    first = _run(tmp_path, "-v")
    measured = {}
    for engine in ("mjx", "mjwarp"):
        talk = _talk(first, engine)
        assert f"loopcheck: {SCENE}: {engine} compiling (first compile: no time recorded)" in talk, talk
        compiled = [line for line in talk if line.startswith(f"loopcheck: {SCENE}: {engine} compiled in ")]
        assert len(compiled) == 1, talk
        seconds = json.loads(_record(tmp_path, engine).read_text())["seconds"]
        assert compiled[0] == f"loopcheck: {SCENE}: {engine} compiled in {seconds:.3g} s"
        measured[engine] = seconds
    # the record sits beside its engine's compilation cache
    assert _record(tmp_path, "mjx").parent == tmp_path / "jax-cache"
    assert _record(tmp_path, "mjwarp").parent.parent == tmp_path / "warp-cache"

    second = _run(tmp_path)
    for engine in ("mjx", "mjwarp"):
        assert _talk(second, engine)[1] == f"loopcheck: {SCENE}: {engine} compiling (about {about(measured[engine])} s)"

    # a corrupt record is ignored, never trusted (MJWarp alone: its warm run is short)
    _record(tmp_path, "mjwarp").write_text('{"format": "loopcheck compile record 1", "seconds": 1')
    third = _run(tmp_path, engines="reduced,mjwarp")
    assert _talk(third, "mjwarp")[1] == f"loopcheck: {SCENE}: mjwarp compiling (first compile: no time recorded)"

    quiet = _run(tmp_path, "-q", engines="reduced,mjwarp")
    assert quiet == []
