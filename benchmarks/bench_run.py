"""Time the main job, ``fingertip run`` on the embedded defaults, from a fresh run folder.

    python benchmarks/bench_run.py [--keep runs/bench_run] [--model 3d]

Prints the wall time of the whole command (search -> FE confirmation -> retraining -> report)
and its split as recorded in summary.json; the target (the FE speed issue) is at most 3
minutes on the 2-core machine. The machine's load average is printed too (other jobs slow
every part). ``--model 3d`` times ``fingertip run --model 3d``: the same search, then every
answer simulated with the 3D pad (``explore._check3d``), whose simulations' own seconds are
printed too.
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
    ap.add_argument("--model", choices=["2d", "3d"], default="2d")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp) / "run"
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "explore.cli", "run", "--out", str(out), "--no-progress",
             "--model", args.model],
            check=True,
        )  # fmt: skip
        total = time.perf_counter() - t0
        summary = json.loads((out / "summary.json").read_text())
        three = out / "answers_3d.json"
        answers_3d = json.loads(three.read_text()) if three.exists() else None
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
    if answers_3d is not None:
        done = [a for a in answers_3d["answers"].values() if a]
        print(
            f"  of which the answers in 3D: {len(done)} answer(s), their simulations "
            f"{answers_3d['fe_wall_time_s']:.0f} s of one core in all"
        )


if __name__ == "__main__":
    main()
