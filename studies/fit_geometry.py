"""For docs/validation.md: reconstruct the paper's fingertip outline, the superellipse (a, b, n)
fitted to Table 2.

    python studies/fit_geometry.py --out runs/fit_geometry [--start 5.84 5.48 1.5] [--evals 60]

For each candidate outline both catalogue materials are tapped to the quasi-steady state
(displacements read from the undeformed top, Table 1 moduli as Abaqus long-term moduli) and
compared with Table 2 (Cabibihan et al.): silicone 0.45 mm, 1.03 mm, 0.17 N mm; polyurethane
0.28 mm, 0.67 mm, 0.29 N mm. Nelder-Mead minimises the largest relative error. Every evaluation
is appended to ``<out>/evaluations.jsonl`` (so an interrupted fit keeps its work and resumes).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from sim import Geometry, homogeneous_design, simulate
from sim.provenance import json_text

TABLE2 = {
    "silicone_gls40": {"disp_at_1N_mm": 0.45, "disp_at_4N_mm": 1.03, "hysteresis_Nmm": 0.17},
    "polyurethane_74_45": {"disp_at_1N_mm": 0.28, "disp_at_4N_mm": 0.67, "hysteresis_Nmm": 0.29},
}


def errors(geometry: Geometry) -> dict[str, float]:
    out = {}
    for mat, ref in TABLE2.items():
        res = simulate(homogeneous_design(mat, geometry), ["tapping"])
        for k, v in ref.items():
            val = res.metrics[k]
            out[f"{mat}:{k}"] = float("nan") if val is None else (val - v) / v
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("runs/fit_geometry"))
    ap.add_argument("--start", type=float, nargs=3, default=[5.84, 5.48, 1.5])
    ap.add_argument("--evals", type=int, default=60)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "evaluations.jsonl"
    cache: dict[tuple, dict] = {}
    if log.exists():
        for line in log.read_text().splitlines():
            rec = json.loads(line)
            cache[tuple(np.round(rec["x"], 6))] = rec["errors"]

    def objective(x: np.ndarray) -> float:
        key = tuple(np.round(x, 6))
        if key not in cache:
            try:
                errs = errors(Geometry(*map(float, x)))
            except ValueError:  # outside the valid geometry range
                return 10.0
            cache[key] = errs
            with log.open("a") as fh:
                fh.write(json_text({"x": list(map(float, x)), "errors": errs}) + "\n")
        errs = cache[key]
        worst = max(abs(e) for e in errs.values())
        print(np.round(x, 3), f"max {worst:.3f}", {k: round(v, 3) for k, v in errs.items()})
        return worst if np.isfinite(worst) else 10.0

    res = minimize(
        objective,
        np.array(args.start),
        method="Nelder-Mead",
        options={"maxfev": args.evals, "initial_simplex": None, "xatol": 0.01, "fatol": 0.002},
    )
    print("best", res.x, res.fun)
    (args.out / "best.json").write_text(
        json_text({"x": list(map(float, res.x)), "max_error": float(res.fun)}, indent=1)
    )


if __name__ == "__main__":
    main()
