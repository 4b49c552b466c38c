"""Whether the 3D wedge gains from single-precision PARDISO: one default-space design's wedge
with the wedge in ``SINGLE_PRECISION_PROTOCOLS`` and without it.

    python studies/wedge_precision.py [--design 2] [--precision single double]

Prints per run whether it completed, the linear solver that made the last factorisation, the
steps tried again in double precision (``precision_fallbacks``), the factorisations and the
seconds (two runs at once share the machine: compare the counts)."""

from __future__ import annotations

import argparse
import importlib
import time
from pathlib import Path

from same_metrics import sweep_options

from sim.design import point_to_design
from sim.sweep import read_config, sample_points
from sim.sweep.run import load_space_config

FOLDER = Path(__file__).resolve().parents[1] / "datasets" / "default3d" / "seg_0-31"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", type=int, default=2)
    ap.add_argument("--precision", nargs="+", default=["single", "double"])
    args = ap.parse_args()
    simulate_module = importlib.import_module("sim.simulate")
    config, space = read_config(FOLDER), load_space_config(FOLDER)
    points = sample_points(space, args.design + 1, config["seed"], config["sampler"])
    design = point_to_design(points[args.design])
    default = simulate_module.SINGLE_PRECISION_PROTOCOLS
    for precision in args.precision:
        wedge = ("wedge",) if precision == "single" else ()
        simulate_module.SINGLE_PRECISION_PROTOCOLS = (
            tuple(p for p in default if p != "wedge") + wedge
        )
        t0 = time.perf_counter()
        res = simulate_module.simulate(design, ("wedge",), sweep_options(FOLDER))
        fig = res.protocols.get("wedge", {})
        print(
            f"{precision}: ok {res.ok}, solver {fig.get('linear_solver')}, fallbacks "
            f"{fig.get('precision_fallbacks')}, factorisations {fig.get('factorizations')}, "
            f"{time.perf_counter() - t0:.1f} s"
        )
    simulate_module.SINGLE_PRECISION_PROTOCOLS = default


if __name__ == "__main__":
    main()
