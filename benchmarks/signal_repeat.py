"""Repeat the signal test of `loopcheck run` (tests/compare/test_cli.py,
test_a_signal_at_any_moment_of_loopcheck_run_ends_it_cleanly) many times, outside the suite: a
crash that comes once in tens of runs (a "Fatal Python error" while the interpreter finalizes
after a signal) shows here. Each round starts `loopcheck run` on the seed scene shortened to
0.3 s and sends SIGINT (or SIGTERM) to its process group at one of the test's delays, as a
fraction of the run's measured length. Python's fault handler is on in the runs, so that a
crash prints every thread's stack.

    PYTHONPATH=. python benchmarks/signal_repeat.py --rounds 100 [--signal TERM]

Prints one line per unexpected outcome and a summary: runs, exit statuses seen, crashes.
Exit 1 if any run crashed (a status other than 0, 130, 143, -2, -15), left a process or a
staging folder, or printed more than one line on stderr when loopcheck's handlers had it.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FRACTIONS = (0.03, 0.1, 0.3, 0.6, 0.8, 0.9, 0.97, 1.1)


def _defaults() -> None:
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_DFL)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=100)
    parser.add_argument("--signal", choices=("INT", "TERM"), default="INT")
    parser.add_argument("--fractions", type=lambda text: tuple(float(f) for f in text.split(",")), default=FRACTIONS,
                        help="the moments, as fractions of the run's length, comma-separated")
    args = parser.parse_args()
    signum = getattr(signal, f"SIG{args.signal}")
    expected = {0, 128 + signum, -signum}
    folder = Path(tempfile.mkdtemp(prefix="signal-repeat-"))
    text = (ROOT / "scenes" / "seed_fourbar.toml").read_text()
    scene = folder / "short.toml"
    scene.write_text(re.sub(r"(?m)^horizon = 2\.0.*$", "horizon = 0.3", text))
    command = [sys.executable, "-m", "loopcheck.compare.cli", "run", str(scene), "--out"]
    env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
    start = time.monotonic()
    subprocess.run(command + [str(folder / "warm")], capture_output=True, timeout=300, env=env, check=True)
    length = time.monotonic() - start
    statuses: collections.Counter = collections.Counter()
    bad = 0
    try:
        for k in range(args.rounds):
            fraction = args.fractions[k % len(args.fractions)]
            out = folder / f"out-{k}"
            shutil.copytree(folder / "warm", out)  # an existing folder, as the test's: staging goes inside
            proc = subprocess.Popen(command + [str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    start_new_session=True, preexec_fn=_defaults, env=env)
            time.sleep(fraction * length)
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signum)
            _, err = proc.communicate(timeout=120)
            left = subprocess.run(["ps", "-o", "pid=,args=", "-g", str(proc.pid)], capture_output=True,
                                  text=True).stdout
            statuses[proc.returncode] += 1
            staging = [p.name for p in out.iterdir() if p.name.startswith(".loopcheck-stage-")] if out.exists() else []
            problem = (proc.returncode not in expected or "Fatal Python error" in err or left or staging
                       or (proc.returncode > 0 and err.count("\n") > 1))
            if problem:
                bad += 1
                print(f"round {k} (signal at {fraction:.2f} of {length:.2f} s): exit {proc.returncode}, "
                      f"processes left {left!r}, staging left {staging}\n{err}", flush=True)
            shutil.rmtree(out, ignore_errors=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print(f"{args.rounds} runs of `loopcheck run` (0.3 s seed, run length {length:.2f} s), SIG{args.signal} at "
          f"{', '.join(f'{f:g}' for f in args.fractions)} of it in turn: exit statuses {dict(sorted(statuses.items()))}; "
          f"{bad} bad")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
