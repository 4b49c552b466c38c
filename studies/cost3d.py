"""For docs/model_3d.md ("Cost"): what a 3D simulation costs, protocol by protocol.

    python studies/cost3d.py docs/designs/stiff_skin_soft_core.toml [--level 1.41]
        [--protocols tapping plate wedge] [--set newton.rtol=1e-7 ...]

Simulates the design with the 3D model on ``COARSE_MESH_3D.refined(level)`` (1.41:
``DEFAULT_MESH_3D``), the validity stop off so that every design runs every step, one BLAS
thread, and prints per protocol the steps, Newton iterations, factorisations and residual
evaluations (counts, which do not depend on the machine's load), the seconds by part of the
solver (which do: a benchmark needs a quiet machine), and for the tapping the taps, whether
they settled, the residual of the periodic state after each tap, how each next tap's start was
made (Anderson, the per-term jump, or plain tapping) and the metrics of the last.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from sim import load_design, simulate  # noqa: E402
from sim.geometry import COARSE_MESH_3D  # noqa: E402
from sim.options import ModelOptions, SimOptions, apply_overrides, parse_override  # noqa: E402

COUNTS = ("steps", "newton_iterations", "factorizations", "evaluations")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("design", type=Path)
    ap.add_argument("--level", type=float, default=1.41, help="COARSE_MESH_3D refined by this")
    ap.add_argument("--protocols", nargs="+", default=["tapping", "plate", "wedge"])
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE")
    args = ap.parse_args()
    options = SimOptions(
        model=ModelOptions("3d"), mesh3d=COARSE_MESH_3D.refined(args.level)
    ).without_validity_stop()
    options = apply_overrides(options, dict(parse_override(s) for s in args.set))
    t0 = time.perf_counter()
    res = simulate(load_design(args.design), args.protocols, options)
    print(
        f"{args.design.stem}, mesh level {args.level} ({res.n_dofs} dofs), {args.set or ''}: "
        f"{time.perf_counter() - t0:.1f} s, failures {list(res.failures)}"
    )
    for name, info in res.protocols.items():
        counts = ", ".join(f"{k} {info.get(k)}" for k in COUNTS)
        split = ", ".join(f"{k} {v:.1f}" for k, v in info["timings_s"].items())
        print(f"  {name}: {info['wall_time_s']:.1f} s; {counts}\n    seconds: {split}")
        if name == "tapping":
            residuals = ", ".join(f"{r:.2g}" for r in info["residual_history"])
            print(f"    taps {info['taps']}, settled {info['settled']}, residuals {residuals}")
            # how each next tap's start was made (sim.protocols.periodic.PeriodicState.used):
            # "plain" counts taps whose accelerated start could not be equilibrated
            print(f"    next taps from: {info['accelerated']}")
            for phase in ("loaded", "rest"):
                part = [c for c in info["cost"] if c["phase"] == phase]
                sums = {
                    k: sum(c[k] for c in part) for k in ("steps", "factorizations", "evaluations")
                }
                print(f"    {phase}: " + ", ".join(f"{k} {v}" for k, v in sums.items()))
        tapping_metrics = ("disp_", "hysteresis", "sag", "contact_")
        mine = {
            k: round(v, 6)
            for k, v in res.metrics.items()
            if v is not None
            and (k.startswith(name) or (name == "tapping" and k.startswith(tapping_metrics)))
        }
        print(f"    {mine}")


if __name__ == "__main__":
    main()
