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

from paired import in_pairs, largest_change, simulate_design

PRECISIONS = ("single", "double")


def run_wedge(design_index: int, precision: str) -> dict:
    """One design's wedge in ``precision``: its figures, metrics and seconds."""
    simulate_module = importlib.import_module("sim.simulate")
    others = tuple(p for p in simulate_module.SINGLE_PRECISION_PROTOCOLS if p != "wedge")
    wedge = ("wedge",) if precision == "single" else ()
    simulate_module.SINGLE_PRECISION_PROTOCOLS = others + wedge
    return simulate_design(design_index, "wedge")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, nargs="+", default=[0, 2, 3, 4])
    args = ap.parse_args()
    totals = dict.fromkeys(PRECISIONS, 0.0)
    for d, runs in in_pairs(run_wedge, args.designs, PRECISIONS):
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
        change = largest_change(runs["single"]["metrics"], runs["double"]["metrics"])
        print(f"design {d}: largest relative change of a wedge metric {change:.1e}")
    print("seconds in all: " + ", ".join(f"{p} {s:.1f}" for p, s in totals.items()))


if __name__ == "__main__":
    main()
