"""Where the FE time of default-space designs goes: protocols, taps and phases, in counts.

    python scripts/fe_time_study.py --n 12 --seed 1

Simulates ``n`` designs of the default space (a scrambled Sobol sample,
``sim.sweep.sample_points``) with every protocol and prints, summed over the designs, the
steps, LDL^T factorisations and residual evaluations of the plate, the wedge and the tapping,
the tapping split by tap (the first, the second, the later ones) and phase (plate in contact,
rest) from its ``cost`` log, and the factorisations per step of each. Counts, not seconds:
they do not depend on the machine's load (one factorisation with its tangent and residual
costs about 8 ms on this 2-core machine). The wall time per design is printed too, as a
rough guide only when the machine is not quiet.
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

from sim import simulate
from sim.space import load_space, point_to_design
from sim.sweep import sample_points

COUNTS = ("steps", "factorizations", "evaluations")


def tap_group(tap: int) -> str:
    """The first tap has no earlier tap to start Newton from; the second starts from the
    first (before the periodic-state jump); the later ones from a tap near their own."""
    return {1: "tap 1", 2: "tap 2"}.get(tap, "taps 3+")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    space = load_space()
    rows: dict[str, dict[str, int]] = defaultdict(lambda: dict.fromkeys(COUNTS, 0))
    wall = 0.0
    taps = []
    for i, point in enumerate(sample_points(space, args.n, args.seed)):
        t0 = time.perf_counter()
        res = simulate(point_to_design(point))
        wall += time.perf_counter() - t0
        for name, fig in res.protocols.items():
            if name == "tapping":
                continue
            for c in COUNTS:
                rows[name][c] += fig.get(c, 0) or 0
        tapping = res.protocols.get("tapping", {})
        taps.append(tapping.get("taps", 0))
        for entry in tapping.get("cost", []):
            key = f"tapping, {tap_group(entry['tap'])}, {entry['phase']}"
            for c in COUNTS:
                rows[key][c] += entry[c]
        print(
            f"design {i}: {time.perf_counter() - t0:.1f} s, {tapping.get('taps')} taps", flush=True
        )
    total = sum(r["factorizations"] for r in rows.values())
    print(f"\n{args.n} designs (seed {args.seed}), {sum(taps)} taps in all")
    print("| part | steps | factorisations | share | per step | evaluations |")
    print("|---|---|---|---|---|---|")
    for key in sorted(rows):
        r = rows[key]
        per = r["factorizations"] / r["steps"] if r["steps"] else float("nan")
        print(
            f"| {key} | {r['steps']} | {r['factorizations']} | "
            f"{100 * r['factorizations'] / max(total, 1):.0f} % | {per:.2f} | {r['evaluations']} |"
        )
    print(f"| all | | {total} | 100 % | | {sum(r['evaluations'] for r in rows.values())} |")
    print(f"\nwall time {wall / args.n:.1f} s per design (load-dependent)")


if __name__ == "__main__":
    main()
