"""Mesh and time-step convergence of every metric, for the catalogue materials.

    python scripts/convergence.py --kind mesh --factors 0.7 1 1.41 2 2.83 --out runs/convergence
    python scripts/convergence.py --kind time --factors 0.5 1 2 4 --out runs/convergence

For each refinement factor the mesh sizes (``MeshOptions.refined``) or all step counts are scaled,
every protocol is run, and the metrics are written to ``<out>/<kind>_<material>.json``. The report
gives each metric's relative difference to the finest run and the observed order of convergence
(fitted with ``np.polyfit`` on log(error) vs log(h)).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sim import SimOptions, homogeneous_design, simulate
from sim.provenance import json_text


def scaled_options(kind: str, factor: float) -> SimOptions:
    base = SimOptions()
    return base.with_mesh_refined(factor) if kind == "mesh" else base.with_steps_scaled(factor)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", choices=["mesh", "time"], default="mesh")
    ap.add_argument("--factors", type=float, nargs="+", default=[0.7, 1.0, 1.41, 2.0, 2.83])
    ap.add_argument("--materials", nargs="+", default=["silicone_gls40", "polyurethane_74_45"])
    ap.add_argument("--out", type=Path, default=Path("runs/convergence"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for material in args.materials:
        rows = []
        for f in sorted(args.factors):
            res = simulate(homogeneous_design(material), options=scaled_options(args.kind, f))
            rows.append(
                {
                    "factor": f,
                    "n_dofs": res.n_dofs,
                    "wall_time_s": res.wall_time_s,
                    "ok": res.ok,
                    "metrics": res.metrics,
                    "newton_iterations": {
                        k: v["newton_iterations"] for k, v in res.protocols.items()
                    },
                }
            )
            print(material, f, res.n_dofs, round(res.wall_time_s, 2), res.metrics, flush=True)
        path = args.out / f"{args.kind}_{material}.json"
        path.write_text(json_text(rows, indent=1))
        finest = rows[-1]["metrics"]
        print(f"\n{material}: relative difference to the finest run (factor {rows[-1]['factor']})")
        for name, ref in finest.items():
            errs = [abs(r["metrics"][name] - ref) / abs(ref) for r in rows[:-1]]
            h = [1.0 / r["factor"] for r in rows[:-1]]
            ok = [e > 0 for e in errs]
            order = (
                np.polyfit(np.log(np.array(h)[ok]), np.log(np.array(errs)[ok]), 1)[0]
                if sum(ok) >= 2
                else float("nan")
            )
            print(f"  {name:28s} " + " ".join(f"{e:8.2e}" for e in errs) + f"  order {order:.2f}")


if __name__ == "__main__":
    main()
