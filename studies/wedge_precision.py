"""Whether the 3D wedge gains from single-precision PARDISO: default-space designs' wedges
with the wedge in ``SINGLE_PRECISION_PROTOCOLS`` and without it.

    python studies/wedge_precision.py [--designs 0 2 3 4]

Runs each design's wedge twice at once, in two processes, in single and in double precision,
so that both runs share whatever else the machine is doing, and prints for each whether it
completed, the linear solver that made the last factorisation, the steps tried again in double
precision (``precision_fallbacks``: a failed step is retried in double, and the body goes back
to single at the next step that converges, ``sim.fe.Body.advance``), the factorisations, the
Newton iterations, the seconds, and the largest relative change of a wedge metric."""

from __future__ import annotations

import argparse
import importlib
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from same_metrics import sweep_options

from sim.design import point_to_design
from sim.sweep import read_config, sample_points
from sim.sweep.run import load_space_config

FOLDER = Path(__file__).resolve().parents[1] / "datasets" / "default3d" / "seg_0-31"
PRECISIONS = ("single", "double")


def run_wedge(design_index: int, precision: str) -> dict:
    """One design's wedge in ``precision``: its figures, metrics and seconds."""
    simulate_module = importlib.import_module("sim.simulate")
    config, space = read_config(FOLDER), load_space_config(FOLDER)
    points = sample_points(space, design_index + 1, config["seed"], config["sampler"])
    others = tuple(p for p in simulate_module.SINGLE_PRECISION_PROTOCOLS if p != "wedge")
    wedge = ("wedge",) if precision == "single" else ()
    simulate_module.SINGLE_PRECISION_PROTOCOLS = others + wedge
    t0 = time.perf_counter()
    res = simulate_module.simulate(
        point_to_design(points[design_index]), ("wedge",), sweep_options(FOLDER)
    )
    return {
        "ok": res.ok,
        "figures": res.protocols.get("wedge", {}),
        "metrics": res.metrics,
        "seconds": time.perf_counter() - t0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, nargs="+", default=[0, 2, 3, 4])
    args = ap.parse_args()
    totals = dict.fromkeys(PRECISIONS, 0.0)
    with ProcessPoolExecutor(len(PRECISIONS)) as pool:
        for d in args.designs:
            runs = dict(zip(PRECISIONS, pool.map(run_wedge, [d] * 2, PRECISIONS), strict=True))
            for precision, run in runs.items():
                fig = run["figures"]
                totals[precision] += run["seconds"]
                print(
                    f"design {d}, {precision}: ok {run['ok']}, solver {fig.get('linear_solver')}, "
                    f"fallbacks {fig.get('precision_fallbacks')}, factorisations "
                    f"{fig.get('factorizations')}, Newton iterations "
                    f"{fig.get('newton_iterations')}, {run['seconds']:.1f} s",
                    flush=True,
                )
            single, double = runs["single"]["metrics"], runs["double"]["metrics"]
            change = max(
                (abs(single[m] - v) / max(abs(v), 1e-12) for m, v in double.items() if m in single),
                default=float("nan"),
            )
            print(f"design {d}: largest relative change of a wedge metric {change:.1e}")
    print("seconds in all: " + ", ".join(f"{p} {s:.1f}" for p, s in totals.items()))


if __name__ == "__main__":
    main()
