"""Join segments of one sweep sample into one sweep folder that ``fingertip train`` reads.

    fingertip sweep --n 4096 --out runs/sweep_a --seed 0
    fingertip sweep --start 4096 --n 6144 --out runs/sweep_b --seed 0
    python scripts/merge_sweeps.py runs/sweep_a runs/sweep_b --out runs/sweep_ab
    fingertip train runs/sweep_ab --out runs/surrogate_ab

The segments must share the space, seed, sampler, options, solver version and catalogues, and
not overlap (``sim.sweep.merge_sweeps``). The merged folder holds config.json (the segments
listed), meta.json and table.csv only: segments are resumed in their own folders, then merged
again. A segment's table.csv is small enough to keep in the repository (about 0.7 MB per
thousand designs) where its records (about 10 kB per design, with the curves) are not.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sim.errors import DesignError
from sim.sweep import merge_sweeps


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweeps", type=Path, nargs="+", help="sweep folders (segments)")
    ap.add_argument("--out", type=Path, required=True, help="the new, merged sweep folder")
    args = ap.parse_args()
    try:
        rows, n = merge_sweeps(args.sweeps, args.out)
    except DesignError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.out}: {rows} designs from {n} sweep folders")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
