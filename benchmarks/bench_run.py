"""Time the main job, ``fingertip run`` on the embedded defaults, from a fresh run folder.

    python benchmarks/bench_run.py [--keep runs/bench_run]

Prints the wall time of the whole command (search -> FE confirmation -> retraining -> report)
and its split as recorded in summary.json; the target (the FE speed issue) is at most 3
minutes on the 2-core machine. The machine's load average is printed too (other jobs slow
every part).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=Path, help="run folder to keep (default: a temporary one)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp) / "run"
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "explore.cli", "run", "--out", str(out), "--no-progress"],
            check=True,
        )
        total = time.perf_counter() - t0
        summary = json.loads((out / "summary.json").read_text())
    t = summary["timings"]
    print(
        f"fingertip run: {total:.0f} s in all (target <= 180 s), load average {load:.1f} "
        f"at start on {os.cpu_count()} CPUs"
    )
    print(
        f"  search {t['search_s']:.0f} s, FE {t['fe_s']:.0f} s, retraining "
        f"{t['retrain_s']:.0f} s, rest (loading, report) "
        f"{total - t['search_s'] - t['fe_s'] - t['retrain_s']:.0f} s; "
        f"{len(summary['rounds'])} round(s)"
    )


if __name__ == "__main__":
    main()
