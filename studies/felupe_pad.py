"""Regenerates docs/felupe_pad.json: FElupe's plate force on the elastic quarter pad, the
independent reference of the 3D model (``docs/model_3d.md``).

    python studies/felupe_pad.py --out docs/felupe_pad.json [--refine 1 1.5] [--mu 0.05]
        [--nu 0.49] [--depth 1.0] [--step 0.1] [--also 0.25] [--formulation q1p0]

The method, the formulations and the figures measured are in ``sim/verification/felupe_pad.py``
(``solve_plate``; ``tests/test_fe3d_felupe.py`` runs it on coarse meshes). Needs the ``test``
extra (FElupe). Minutes to tens of minutes per mesh.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import asdict
from pathlib import Path

from sim.geometry import MeshOptions3D, PadGeometry, build_pad_mesh
from sim.verification.felupe_pad import (
    DEFAULT_MU_MPA,
    DEFAULT_NU,
    FORMULATIONS,
    NEWTON_TOL,
    PENALTY_FACTOR,
    bulk_modulus,
    solve_plate,
)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="JSON file to write")
    p.add_argument(
        "--refine",
        type=float,
        nargs="+",
        default=[1.0],
        help="MeshOptions3D().refined(F) for each F (default: 1, the default mesh)",
    )
    p.add_argument("--mu", type=float, default=DEFAULT_MU_MPA, help="shear modulus, MPa")
    p.add_argument("--nu", type=float, default=DEFAULT_NU, help="Poisson's ratio (sets K)")
    p.add_argument("--depth", type=float, default=1.0, help="deepest plate displacement, mm")
    p.add_argument("--step", type=float, default=0.1, help="plate increment (and output), mm")
    p.add_argument(
        "--also",
        type=float,
        nargs="*",
        default=[0.25],
        help="further output depths, mm (default 0.25: the comparison tables' depths are "
        "0.25, 0.5 and 1 mm)",
    )
    p.add_argument("--formulation", choices=FORMULATIONS, default="q1p0")
    p.add_argument("--penalty", type=float, default=PENALTY_FACTOR, help="x E h_apex, N/mm")
    args = p.parse_args(argv)

    import felupe as fem

    geometry = PadGeometry()
    K = bulk_modulus(args.mu, args.nu)
    n_out = max(1, round(args.depth / args.step))
    depths = [round(args.step * k, 12) for k in range(1, n_out + 1)]
    depths[-1] = args.depth
    depths = sorted(set(depths) | {d for d in args.also if 0 < d < args.depth})
    runs = []
    for factor in args.refine:
        options = MeshOptions3D().refined(factor)
        pmesh = build_pad_mesh(geometry, (), options)
        res = solve_plate(
            pmesh,
            args.mu,
            K,
            depths,
            formulation=args.formulation,
            step_mm=args.step,
            penalty_factor=args.penalty,
            h_apex_mm=options.h_apex_mm,
        )
        runs.append({"refine": factor, "mesh_options": asdict(options), **res.to_dict()})
        print(
            f"refine {factor:g}: {res.n_q2_elements} Q2 elements, {res.n_cells} FElupe cells, "
            f"{res.dofs_total} dofs ({res.dofs_free} free), {res.newton_iterations} Newton "
            f"iterations, {res.cutbacks} cutbacks, {res.wall_s:.0f} s wall, {res.cpu_s:.0f} s "
            f"CPU, {res.wall_s / max(1, res.newton_iterations):.2f} s/iteration, "
            f"max penetration {res.max_penetration_mm:.2e} mm, load {res.load_average}",
            flush=True,
        )
    print()
    print(
        "| d (mm) | " + " | ".join(f"F x{r['refine']:g}: quarter, whole (N)" for r in runs) + " |"
    )
    print("|---|" + "---|" * len(runs))
    for k, d in enumerate(depths):
        cells = [f"{r['force_quarter_N'][k]:.5f}, {r['force_N'][k]:.4f}" for r in runs]
        print(f"| {d:.2f} | " + " | ".join(cells) + " |")
    convergence = None
    if len(runs) >= 2:
        f0, f1 = runs[-2]["force_N"][-1], runs[-1]["force_N"][-1]
        convergence = {
            "refine": [runs[-2]["refine"], runs[-1]["refine"]],
            "depth_mm": depths[-1],
            "force_N": [f0, f1],
            "relative_change": f1 / f0 - 1.0,
        }
        print(
            f"\nforce at {depths[-1]:g} mm: {f0:.5f} N (x{runs[-2]['refine']:g}) -> "
            f"{f1:.5f} N (x{runs[-1]['refine']:g}), change {100 * (f1 / f0 - 1):+.2f} %"
        )
    doc = {
        "description": "FElupe reference: rigid frictionless flat plate on the elastic quarter "
        "pad (x >= 0, z >= 0; base bonded, symmetry on x = 0 and z = 0), studies/felupe_pad.py",
        "felupe_version": fem.__version__,
        "command": "python studies/felupe_pad.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "geometry": geometry.to_dict(),
        "layers": 1,
        "material": {
            "model": "neo_hookean",
            "energy": "mu/2 (J^(-2/3) I1 - 3) + K/2 (J - 1)^2",
            "mu_MPa": args.mu,
            "nu": args.nu,
            "K_MPa": K,
            "E_MPa": 2.0 * args.mu * (1.0 + args.nu),
        },
        "formulation": args.formulation,
        "contact": "felupe.MultiPointContact on every outer-surface node, y only "
        "(rigid frictionless plane), multiplier = penalty x E x h_apex",
        "penalty": args.penalty,
        "newton_tol": NEWTON_TOL,
        "force_note": "force_quarter_N: the quarter model (compare sim.fe.solver.Body.force); "
        "force_N: the whole pad (x 4)",
        "runs": runs,
        "convergence": convergence,
        "cpu_count": os.cpu_count(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
