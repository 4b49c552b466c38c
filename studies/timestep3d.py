"""For docs/model_3d.md ("Time steps"): the 3D tapping's time-step convergence.

    python studies/timestep3d.py [--level 1] [--out docs/timestep3d.json] [DESIGN.toml ...]

The 2D model's time steps were chosen by quartering every step (``SimOptions.with_steps_scaled(4)``:
the tapping's loaded steps, its first rest step and the ratio of its geometric rest steps)
and asking every tapping metric to move by at most 0.5 % (docs/validation.md, "Time-step
convergence"). The same test in 3D, on the three corner designs of ``docs/designs/`` by default,
the validity stop off so that every metric exists. The mesh is ``COARSE_MESH_3D.refined(level)``:
the time-stepping error is a property of the materials' relaxation and of the load history,
which the mesh does not change (on the 2D model the change with quartered steps is the same on
the default and the refined mesh within a few percent of itself: docs/validation.md), and a
quartered 3D tapping on the simulations' mesh costs an hour. Prints a table of every tapping
metric (the 3D contact patch included) at both step sizes and writes the figures as JSON.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from sim import SOLVER_VERSION, load_design, simulate  # noqa: E402
from sim.geometry import COARSE_MESH_3D  # noqa: E402
from sim.options import ModelOptions, SimOptions  # noqa: E402
from sim.provenance import git_commit  # noqa: E402

DESIGNS = sorted(Path("docs/designs").glob("*.toml"))
LIMIT = 0.005  # the 2D model's criterion: every tapping metric within 0.5 %


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("designs", nargs="*", type=Path, default=DESIGNS)
    ap.add_argument("--level", type=float, default=1.0)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    base = SimOptions(
        model=ModelOptions("3d"), mesh3d=COARSE_MESH_3D.refined(args.level)
    ).without_validity_stop()
    out: dict = {"solver_version": SOLVER_VERSION, "commit": git_commit(), "level": args.level}
    print("| design | metric | default steps | steps x 4 | change |\n|---|---|---|---|---|")
    for path in args.designs:
        runs = {}
        for factor in (1, 4):
            t0 = time.perf_counter()
            res = simulate(load_design(path), ("tapping",), base.with_steps_scaled(factor))
            tap = res.protocols["tapping"]
            runs[factor] = {
                "metrics": {k: v for k, v in res.metrics.items() if v is not None},
                "settled": tap["settled"],
                "taps": tap["taps"],
                "seconds": time.perf_counter() - t0,
            }
        a, b = runs[1]["metrics"], runs[4]["metrics"]
        for key in a:
            if key in b and b[key] != 0:
                change = abs(a[key] - b[key]) / abs(b[key])
                flag = "" if change <= LIMIT else " (> 0.5 %)"
                print(
                    f"| {path.stem} | `{key}` | {a[key]:.5g} | {b[key]:.5g} | "
                    f"{100 * change:.2f} %{flag} |",
                    flush=True,
                )
        out[path.stem] = runs
        if args.out:  # after every design: a long study keeps what it has done
            args.out.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
