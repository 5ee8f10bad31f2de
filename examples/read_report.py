"""Run the main job into a folder, then read what it wrote: ``report.json`` holds every figure
the table prints (README, "Comparison and report.json"); the CSV files the trajectories.

    python examples/read_report.py [OUT_FOLDER]
"""

import csv
import json
import sys
import tempfile
from pathlib import Path

from loopcheck.compare.cli import main

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "seed"
status = main(["run", "seed_fourbar", "--out", str(out)])  # what `loopcheck run` does; 0 when the gate passes
report = json.loads((out / "report.json").read_text())
print(f"loopcheck run exited {status}; report.json has {', '.join(sorted(report))}")
print(f"gate passed: {report['gate']['passed']}; peak difference {report['diff']['peak_omega_rel']:.2e} (relative)")
with open(out / "reduced.csv", newline="") as f:
    rows = list(csv.DictReader(f))
print(f"reduced.csv: {len(rows)} samples, columns {', '.join(list(rows[0])[:4])}, ...")
