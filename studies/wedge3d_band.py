"""The 3D wedge's band refined at a fixed outer mesh: regenerates ``docs/wedge3d_band.json``
(``docs/model_3d.md``, "Mesh convergence").

    python studies/wedge3d_band.py                       # every band size, resumes
    python studies/wedge3d_band.py --edge-h 0.4 0.2      # a quick look

The wedge's metrics move by 6-12 % at every refinement of the whole 3D mesh family
(``studies/mesh3d_convergence.py --wedge``): its flanks' contact, about 1 mm wide, spans one or
two elements. Here the outer mesh stays ``DEFAULT_MESH_3D`` and only the band along the edge
is refined (``MeshOptions3D.edge_h_mm`` = H, halved from level to level, ``edge_grading``
0.5 per mm): the two elastic pads of the mesh study, the wedge protocol alone (its edge
pressed 1 mm in 1 s and held). Per metric the script fits err(H) = C H^p to the differences
between successive band sizes (``np.polyfit`` on the logs) and extrapolates (Richardson), as
the mesh study does; the smallest band within 1 % of the extrapolation is the one to simulate
with. Results are written after each run."""

from __future__ import annotations

import argparse
import dataclasses
from functools import partial
from pathlib import Path

import numpy as np
from mesh3d_convergence import DESIGNS, WEDGE_METRICS, measured, richardson, run_cases

from sim.design import design_from_dict
from sim.geometry import DEFAULT_MESH_3D
from sim.options import ModelOptions, SimOptions

OUT = Path(__file__).resolve().parents[1] / "docs" / "wedge3d_band.json"
SIZES = (0.4, 0.2, 0.1, 0.05)
#: the band's growth per mm away from the edge and the surface: 0.5 keeps the band narrow
#: (2.5 mm wide at 1 mm elements), where the flanks wrap the edge
GRADING = 0.5


def run(sizes: tuple[float, ...]) -> dict:
    def case(name: str, h: float) -> dict:
        mesh = dataclasses.replace(DEFAULT_MESH_3D, edge_h_mm=h, edge_grading=GRADING)
        options = SimOptions(model=ModelOptions("3d"), mesh3d=mesh).without_validity_stop()
        figures = measured(design_from_dict(DESIGNS[name]), ("wedge",), options, WEDGE_METRICS)
        return {"design": name, "edge_h_mm": h, **figures}

    return run_cases(OUT, ((f"{n}@{h:g}", partial(case, n, h)) for n in DESIGNS for h in sizes))


def report(done: dict) -> None:
    for name in DESIGNS:
        rows = sorted(
            (v for v in done.values() if v["design"] == name), key=lambda v: -v["edge_h_mm"]
        )
        if len(rows) < 3:
            continue
        print(
            f"\n{name}: band {[r['edge_h_mm'] for r in rows]} mm, dofs {[r['dofs'] for r in rows]}"
        )
        h = np.array([r["edge_h_mm"] for r in rows])
        for m in WEDGE_METRICS:
            y = np.array([r["metrics"][m] or np.nan for r in rows])
            p, best = richardson(h, y)
            values = ", ".join(f"{v:.4g}" for v in y)
            errs = ", ".join(f"{100 * (v / best - 1):+.2f}%" for v in y) if best == best else "-"
            print(f"  {m:26s} {values}  rate {p:4.2f}  extrapolated {best:.4g}  errors {errs}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--edge-h", type=float, nargs="+", default=list(SIZES))
    args = ap.parse_args()
    report(run(tuple(args.edge_h)))
