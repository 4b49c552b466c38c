"""Benchmark: sweep throughput (designs per hour) and the speed-up from 1 to 2 workers.

    python benchmarks/bench_sweep.py [--n 16] [--seed 0] [--space SPACE.toml]

Runs the same ``n`` designs of the (default) design space twice, with 1 and with 2 local worker
processes, in fresh temporary folders, and prints wall times, designs per hour, the speed-up
and the mean FE time per design. Target (the sweep issue): speed-up >= 1.8 on this 2-core
machine.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from sim.design import load_space  # noqa: E402
from sim.sweep import run_sweep  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--space", type=Path, default=None)
    args = ap.parse_args()
    space = load_space(args.space)
    walls = {}
    with tempfile.TemporaryDirectory() as tmp:
        for workers in (1, 2):
            s = run_sweep(
                space, args.n, Path(tmp) / f"w{workers}", workers=workers, seed=args.seed,
                progress=False,
            )  # fmt: skip
            walls[workers] = s.wall_time_s
            with (Path(tmp) / f"w{workers}" / "table.csv").open() as fh:
                fe = [float(r["wall_time_s"]) for r in csv.DictReader(fh)]
            print(
                f"{workers} worker(s): {args.n} designs ({s.ok} ok, {s.failed} failed) in "
                f"{s.wall_time_s:.1f} s = {3600 * args.n / s.wall_time_s:.0f} designs/hour; "
                f"FE time per design: mean {sum(fe) / len(fe):.2f} s, max {max(fe):.2f} s"
            )
    print(f"speed-up 1 -> 2 workers: {walls[1] / walls[2]:.2f}x (target >= 1.8)")


if __name__ == "__main__":
    main()
