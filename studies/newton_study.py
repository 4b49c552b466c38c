"""For docs/fe_speed.md ("Newton"): what Newton's stall rule saves, and that it leaves the
metrics where they were.

    python studies/newton_study.py --n 12 --seed 1 [--variants 6,8 5,7 8,10]

Runs ``n`` designs of the default space (a scrambled Sobol sample, ``sim.sweep.run.sample_points``)
once with the stall rule switched off (``NewtonOptions.stall_from`` beyond ``max_iterations``:
a step is pursued to the iteration limit, as solver 2.1 did) and once per variant
``window,from`` of ``NewtonOptions.stall_window`` / ``stall_from``. Prints per variant the
factorisations and residual evaluations summed over every protocol (counts, which do not
depend on the machine's load), the failed designs, and the largest relative change of any
metric against the run without the rule. Metrics whose reference is below ``--floor`` in their
unit (an elastic design's hysteresis of 1e-4 N mm is numerical noise) are compared absolutely.
"""

from __future__ import annotations

import argparse
import dataclasses
import math

from sim import SimOptions, simulate
from sim.design import load_space, point_to_design
from sim.fe import NewtonOptions
from sim.sweep import sample_points


def run(designs, newton: NewtonOptions) -> dict:
    opts = dataclasses.replace(SimOptions(), newton=newton)
    out = {"factorizations": 0, "evaluations": 0, "failed": 0, "metrics": []}
    for design in designs:
        res = simulate(design, options=opts)
        for fig in res.protocols.values():
            out["factorizations"] += fig.get("factorizations", 0)
            out["evaluations"] += fig.get("evaluations", 0)
        out["failed"] += not res.ok
        out["metrics"].append(res.metrics)
    return out


def largest_change(ref: list[dict], new: list[dict], floor: float) -> tuple[float, str]:
    worst, where = 0.0, ""
    for i, (a, b) in enumerate(zip(ref, new, strict=True)):
        for name, va in a.items():
            vb = b.get(name)
            if va is None or vb is None or not (math.isfinite(va) and math.isfinite(vb)):
                continue
            change = abs(vb - va) / max(abs(va), floor)
            if change > worst:
                worst, where = change, f"design {i}, {name}: {va:.6g} -> {vb:.6g}"
    return worst, where


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--variants", nargs="+", default=["6,8", "5,7", "8,10"])
    ap.add_argument("--floor", type=float, default=1e-3)
    args = ap.parse_args()
    space = load_space()
    designs = [point_to_design(p) for p in sample_points(space, args.n, args.seed)]
    base = NewtonOptions()
    off = run(designs, dataclasses.replace(base, stall_from=base.max_iterations + 1))
    print(f"{args.n} default-space designs (Sobol, seed {args.seed}), all three protocols\n")
    print("| stall rule (window, from) | factorisations | evaluations | failed | largest change |")
    print("|---|---|---|---|---|")
    print(f"| off | {off['factorizations']} | {off['evaluations']} | {off['failed']} | - |")
    for v in args.variants:
        window, start = (int(x) for x in v.split(","))
        new = run(designs, dataclasses.replace(base, stall_window=window, stall_from=start))
        worst, where = largest_change(off["metrics"], new["metrics"], args.floor)
        f = new["factorizations"] / off["factorizations"] - 1
        e = new["evaluations"] / off["evaluations"] - 1
        print(
            f"| ({window}, {start}) | {new['factorizations']} ({100 * f:+.0f} %) | "
            f"{new['evaluations']} ({100 * e:+.0f} %) | {new['failed']} | "
            f"{100 * worst:.3f} % ({where}) |"
        )


if __name__ == "__main__":
    main()
