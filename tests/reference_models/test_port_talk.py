"""The GPU ports' talk without the ports (issue 39, "Long engine runs talk" and "Output"): the
compile record kept beside a compilation cache (loopcheck.mujoco_model.compile_record) and the
filter that keeps JAX's, XLA's and Warp's own output from the user
(loopcheck.mujoco_model.foreign_output). The messages the filter is tested with are the
libraries' own, copied from their output (JAX 0.10.2, warp 1.19.0): the libraries themselves are
not needed here; tests/compare/test_port_talk_command.py runs the command with them.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import textwrap
import warnings

import pytest

from loopcheck.mujoco_model.compile_record import (CompileRecord, about, compiling, read_record, record_path,
                                                   write_record)
from loopcheck.mujoco_model.foreign_output import foreign_output, in_our_words

JAX_FALLBACK = ("An NVIDIA GPU may be present on this machine, but a CUDA-enabled jaxlib is not installed. "
                "Falling back to cpu.")
WARP_CUDA = "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver. GPU execution will not be available."


# ---- the compile record --------------------------------------------------------------------------

def test_a_record_written_is_read_back_and_a_missing_one_is_none(tmp_path):
    assert read_record(tmp_path, "mjx", "cpu") is None
    write_record(tmp_path, CompileRecord("mjx", "cpu", 16.6))
    assert read_record(tmp_path, "mjx", "cpu") == CompileRecord("mjx", "cpu", 16.6)
    assert read_record(tmp_path, "mjx", "gpu") is None and read_record(tmp_path, "mjwarp", "cpu") is None
    assert [p.name for p in tmp_path.iterdir()] == ["loopcheck-compile-mjx-cpu.json"]  # no temporary file left


@pytest.mark.parametrize("text", [
    "", "{", "not json", "[]", "null", '{"seconds": 3}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu"}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": NaN}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": Infinity}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": -2}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": 0}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": 1e9}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": "16"}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "cpu", "seconds": true}',
    '{"format": "loopcheck compile record 1", "engine": "mjwarp", "device": "cpu", "seconds": 3}',
    '{"format": "loopcheck compile record 1", "engine": "mjx", "device": "gpu", "seconds": 3}',
    '{"format": "other", "engine": "mjx", "device": "cpu", "seconds": 3}',
])
def test_a_corrupt_or_foreign_record_is_ignored_never_trusted(tmp_path, text, caplog):
    """A journal's rows are checked, never trusted: anything but a valid record of this engine on
    this device reads as none, with the reason at DEBUG (planted: trusting "seconds" as found)."""
    record_path(tmp_path, "mjx", "cpu").write_text(text, encoding="utf-8")
    with caplog.at_level(logging.DEBUG, logger="loopcheck.ports"):
        assert read_record(tmp_path, "mjx", "cpu") is None
    assert "ignored" in caplog.text


def test_an_unreadable_record_is_ignored(tmp_path):
    record_path(tmp_path, "mjx", "cpu").write_bytes(b"\xff\xfe\x00 not text")
    assert read_record(tmp_path, "mjx", "cpu") is None
    record_path(tmp_path, "mjwarp", "cpu").mkdir()  # a folder where the file should be
    assert read_record(tmp_path, "mjwarp", "cpu") is None


def test_a_folder_that_cannot_be_written_costs_the_record_only(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    write_record(blocker / "cache", CompileRecord("mjx", "cpu", 3.0))  # its parent is a file: no raise
    assert read_record(blocker / "cache", "mjx", "cpu") is None


def test_the_record_is_replaced_whole(tmp_path):
    """Written to a temporary file, then renamed: an old record is replaced, never appended to or
    left half-written (planted: writing in place with mode "a": the JSON is two objects, ignored)."""
    write_record(tmp_path, CompileRecord("mjwarp", "cuda:0", 40.0))
    write_record(tmp_path, CompileRecord("mjwarp", "cuda:0", 2.5))
    path = record_path(tmp_path, "mjwarp", "cuda:0")
    assert path.name == "loopcheck-compile-mjwarp-cuda_0.json"
    assert json.loads(path.read_text())["seconds"] == 2.5
    assert read_record(tmp_path, "mjwarp", "cuda:0").seconds == 2.5
    assert len(list(tmp_path.iterdir())) == 1


@pytest.mark.parametrize("seconds, text", [(16.6, "17"), (59.4, "59"), (9.96, "10"), (2.34, "2.3"), (0.04, "0.1")])
def test_about_rounds_to_whole_seconds_from_ten(seconds, text):
    assert about(seconds) == text


def test_compiling_says_first_compile_then_the_last_time_and_records_it(tmp_path, caplog):
    """The announcement before the compile: "first compile" without a record, then the time the
    last compile took (planted: no record written: the second says "first compile" again)."""
    with caplog.at_level(logging.DEBUG, logger="loopcheck.ports"):
        with compiling("mjx", "cpu", tmp_path, "seed_fourbar") as timed:
            assert caplog.messages == ["seed_fourbar: mjx compiling (first compile: no time recorded)"]
            os.times()  # the block's work
        first = read_record(tmp_path, "mjx", "cpu").seconds
        assert first == timed.seconds > 0
        caplog.clear()
        with compiling("mjx", "cpu", tmp_path, "seed_fourbar"):
            assert caplog.messages == [f"seed_fourbar: mjx compiling (about {about(first)} s)"]


def test_a_compile_that_fails_records_nothing(tmp_path):
    with pytest.raises(RuntimeError), compiling("mjx", "cpu", tmp_path, "seed_fourbar"):
        raise RuntimeError("XLA ran out of memory")
    assert read_record(tmp_path, "mjx", "cpu") is None


# ---- what the libraries say ----------------------------------------------------------------------

@pytest.mark.parametrize("library, text, level, words", [
    ("JAX", JAX_FALLBACK, logging.INFO,
     "JAX runs on the CPU: an NVIDIA GPU may be present, but the installed jaxlib has no CUDA (pip install "
     "'jax[cuda12]' to use it)"),
    ("Warp", WARP_CUDA, logging.INFO, "Warp found no NVIDIA CUDA driver and runs on the CPU"),
    ("Warp", "Warp 1.19.0 initialized:", logging.DEBUG, "Warp said: Warp 1.19.0 initialized:"),
    ("JAX", "W1128 07:15:21.123456 4242 cpu_client.cc:123] Slow   operation", logging.WARNING,
     "XLA said: Slow operation"),
    ("JAX", "I0000 00:00:1732 4242 service.cc:152] XLA service initialized", logging.DEBUG,
     "XLA said: XLA service initialized"),
    ("Warp", "Module mujoco_warp._src.forward 68fa608 load on device 'cpu' took 3.2 ms", logging.DEBUG,
     "Warp said: Module mujoco_warp._src.forward 68fa608 load on device 'cpu' took 3.2 ms"),
    ("Warp", "Warp UserWarning: something went sideways", logging.WARNING,
     "Warp said: Warp UserWarning: something went sideways"),
])
def test_what_the_libraries_say_in_our_words(library, text, level, words):
    assert in_our_words(library, text) == (level, words)


def test_a_python_warning_stays_a_warning():
    assert in_our_words("JAX", "Explicitly requested dtype float64 is not available", logging.WARNING)[0] == \
        logging.WARNING


def test_foreign_output_keeps_every_channel_and_logs_it_in_our_words(tmp_path):
    """Inside the block: C's and print()'s stdout and stderr, a library logger's record, a root
    logging.info() (which would configure the root logger: MJX's put_model does), and a Python
    warning. Nothing of theirs reaches the process's stdout or stderr; loopcheck's own lines do, and
    the root logger has no handler afterwards (planted: no fd capture: Warp's line on stderr;
    planted: no collector on the root while the block runs and the handler that logging.info()
    adds left: the root has a handler, every later loopcheck line printed twice). Run in a
    process of its own: the descriptors and loggers as a command has them."""
    script = textwrap.dedent(f"""
        import logging, os, sys, warnings
        from loopcheck.mujoco_model.foreign_output import foreign_output
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("loopcheck: %(message)s"))
        logging.getLogger("loopcheck").addHandler(handler)
        logging.getLogger("loopcheck").setLevel(logging.INFO)
        with foreign_output("mjwarp", "Warp", ("jax",)):
            os.write(2, {WARP_CUDA + chr(10)!r}.encode())
            os.write(1, b"C stdout line\\n")
            print("Warp 1.19.0 initialized:")
            print("to stderr via print", file=sys.stderr)
            logging.getLogger("jax._src.xla_bridge").warning({JAX_FALLBACK!r})
            logging.info("Using JAX default device: %s.", "cpu")
            warnings.warn("a library's UserWarning")
        logging.getLogger("loopcheck.compare").info("after the block")
        print("root handlers:", logging.getLogger().handlers)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert done.returncode == 0, done.stderr
    assert done.stdout == "root handlers: []\n"
    assert done.stderr.splitlines() == [
        "loopcheck: warning: mjwarp: Warp said: a library's UserWarning",
        "loopcheck: mjwarp: JAX runs on the CPU: an NVIDIA GPU may be present, but the installed jaxlib has no "
        "CUDA (pip install 'jax[cuda12]' to use it)",
        "loopcheck: mjwarp: Warp found no NVIDIA CUDA driver and runs on the CPU",
        "loopcheck: after the block",
    ]
    assert list(tmp_path.iterdir()) == []


def test_foreign_output_restores_everything_when_the_block_raises(capfd):
    root = logging.getLogger()
    before = (list(root.handlers), logging.getLogger("jax").propagate)
    with pytest.raises(KeyboardInterrupt), warnings.catch_warnings():
        with foreign_output("mjx", "JAX", ("jax",)):
            assert logging.getLogger("jax").propagate is False
            os.write(2, b"Warp CUDA warning: inside\n")
            raise KeyboardInterrupt
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"
    assert (list(root.handlers), logging.getLogger("jax").propagate) == before
