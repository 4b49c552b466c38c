"""For docs/fe_speed.md: what a coarser mesh would buy and cost, FE work and the metrics' change
on default-space designs.

    python studies/mesh_speed_study.py --n 8 --seed 1 --factors 1.41 1.0 0.7

Simulates ``n`` designs of the default space (``sim.sweep.run.sample_points``, all three protocols)
on meshes whose element sizes are divided by each factor (``SimOptions.with_mesh_refined``; 1.0
is the default mesh, below 1 coarser) and prints, per factor, the free dofs, the LDL^T
factorisations and residual evaluations summed over the designs (counts: they do not depend on
the machine's load), the summed wall time (seconds: compare factors within one run only), and
per tapping, plate and wedge metric the largest relative change against the first (finest)
factor. Hysteresis below 1e-3 N mm (a nearly elastic design's numerical noise) is left out of
the comparison. The answer for issue 11 item 7 is in ``docs/fe_speed.md``.
"""

from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import time  # noqa: E402

from sim import SimOptions, simulate  # noqa: E402
from sim.design import load_space, point_to_design  # noqa: E402
from sim.sweep import sample_points  # noqa: E402

METRICS = (
    "disp_at_1N_from_touch_mm",
    "disp_at_4N_from_touch_mm",
    "disp_at_1N_mm",
    "hysteresis_Nmm",
    "plate_force_at_1mm_N",
    "wedge_peak_force_N",
)
#: a hysteresis below this is a nearly elastic design's noise, not a value to compare (N mm)
HYSTERESIS_FLOOR_NMM = 1e-3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--factors", type=float, nargs="+", default=[1.41, 1.0, 0.7])
    args = ap.parse_args()
    points = sample_points(load_space(), args.n, args.seed)
    runs: dict[float, list] = {f: [] for f in args.factors}
    for i, point in enumerate(points):
        design = point_to_design(point)
        for f in args.factors:
            t0 = time.perf_counter()
            res = simulate(design, options=SimOptions().with_mesh_refined(f))
            wall = time.perf_counter() - t0
            counts = [
                sum(p.get(k, 0) for p in res.protocols.values())
                for k in ("factorizations", "evaluations")
            ]
            runs[f].append((res.metrics, res.n_dofs, *counts, wall))
            print(f"design {i}, factor {f}: {res.n_dofs} dofs, {counts[0]} factorisations, "
                  f"{counts[1]} evaluations, {wall:.1f} s", flush=True)  # fmt: skip
    finest = args.factors[0]
    print(f"\nsummed over {args.n} designs (seed {args.seed}); changes against factor {finest}")
    for f in args.factors:
        rows = runs[f]
        dofs = sum(r[1] for r in rows) / len(rows)
        fact, evals, wall = (sum(r[k] for r in rows) for k in (2, 3, 4))
        print(f"factor {f}: mean {dofs:.0f} dofs, {fact} factorisations, {evals} evaluations, "
              f"{wall:.1f} s")  # fmt: skip
        if f == finest:
            continue
        for m in METRICS:
            changes = []
            for (ref, *_), (got, *_) in zip(runs[finest], rows, strict=True):
                a, b = ref.get(m), got.get(m)
                if a is None or b is None:
                    continue
                if m == "hysteresis_Nmm" and abs(a) < HYSTERESIS_FLOOR_NMM:
                    continue
                changes.append(100 * abs(b - a) / abs(a))
            worst = f"{max(changes):.2f} %" if changes else "-"
            print(f"  {m}: largest change {worst} ({len(changes)} designs)")


if __name__ == "__main__":
    main()
