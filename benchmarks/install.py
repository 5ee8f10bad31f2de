"""Install time and the first run after it: the compiled core's two install-time targets.

On a fresh clone of the repository (``git clone`` of the current commit into a temporary
folder) with a new venv:

1. the install step of the README's test command, ``pip install -q -e '.[test,distributed]'``,
   timed (the compiler's build of the kernels included; pip's downloads come from its cache
   when it has them — say so when quoting);
2. ``loopcheck reduced`` on the seed, run from outside the checkout, twice: the first run right
   after the install and the second. Nothing is compiled or cached at first use, so the first
   should cost what the second does (target: first within 1.2× of the second, both < 1.5 s).

    python benchmarks/install.py [--keep DIR]

Prints the three wall times and the ratio; asserts nothing.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def timed(command: list[str], cwd: Path) -> float:
    start = time.perf_counter()
    done = subprocess.run(command, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {done.returncode}:\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    return wall


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, help="work in this new folder and keep it (default: a temporary one)")
    args = parser.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="loopcheck-install-"))
    try:
        clone = work / "loopcheck"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        subprocess.run([sys.executable, "-m", "venv", ".venv"], cwd=clone, check=True)
        pip = [str(clone / ".venv" / "bin" / "pip"), "install", "-q", "-e", ".[test,distributed]"]
        install = timed(pip, clone)
        outside = work / "elsewhere"
        outside.mkdir()
        loopcheck = [str(clone / ".venv" / "bin" / "loopcheck"), "reduced"]
        first = timed(loopcheck, outside)
        second = timed(loopcheck, outside)
        print(f"fresh clone of {ROOT} at {subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT, capture_output=True, text=True).stdout.strip()}")
        print(f"install step of the README's test command (pip install -e '.[test,distributed]'): {install:.1f} s "
              f"(target < 90 s)")
        print(f"loopcheck reduced, first run after the install: {first:.2f} s; second: {second:.2f} s "
              f"(targets: both < 1.5 s)")
        print(f"ratio first / second: {first / second:.2f} (target ≤ 1.2)")
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
