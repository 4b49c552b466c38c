"""For docs/model_3d.md ("A plane-strain slab against the 2D model"): the 3D discretisation in
plane strain against the 2D model, on the same section, under mesh refinement.

    python studies/plane_strain_slab.py [--levels2d 1 2 2.83] [--levels3d 1 1.41 2 2.83 4]

The 2D section of the tests' pad (a = 5.84, b = 5.48 mm, n = 1.5; neo-Hookean mu = 0.05 MPa,
nu = 0.49) is meshed by the 2D model (P2 triangles, ``MeshOptions().refined(f)``) and, as the
face z = 0 of the 3D quarter pad on ``COARSE_MESH_3D.refined(f)``, extruded into a slab of Q2
hexahedra 0.5 mm thick (``sim.geometry.extruded_section_mesh``) with u_z = 0 at every node:
plane strain, the middle of a long extrusion. A flat plate is pressed to 1 mm in steps of
0.05 mm (halved where Newton fails); printed: the free dofs and the plate force per mm of
each model (the slab's force divided by its thickness) at 0.25, 0.5 and 1 mm, and each slab's
relative difference from the finest 2D mesh. The 2D and 3D elements differ (triangles,
hexahedra), so the two models agree only as both converge.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402

from sim.fe import Body, Discretization, Discretization3D, Plate  # noqa: E402
from sim.geometry import (  # noqa: E402
    COARSE_MESH_3D,
    Geometry,
    MeshOptions,
    PadGeometry,
    build_mesh,
    build_pad_mesh,
    extruded_section_mesh,
)
from sim.materials._material import material_from_table  # noqa: E402
from sim.verification import press_plate  # noqa: E402

PAD = PadGeometry(Geometry(5.84, 5.48, 1.5), half_length_mm=8.0, length_exponent=2.0)
DEPTHS = (0.25, 0.5, 1.0)
THICKNESS_MM = 0.5
STEP_MM = 0.05


def plane_strain(X: np.ndarray) -> np.ndarray:
    """The slab's constraints: the base fixed, u_x = 0 on x = 0, u_z = 0 everywhere."""
    mask = np.zeros(X.shape, dtype=bool)
    mask[X[:, 1] == 0.0] = True
    mask[X[:, 0] == 0.0, 0] = True
    mask[:, 2] = True
    return mask


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels2d", type=float, nargs="+", default=[1.0, 2.0, 2.83])
    ap.add_argument("--levels3d", type=float, nargs="+", default=[1.0, 1.41, 2.0, 2.83, 4.0])
    args = ap.parse_args()
    mat = material_from_table({"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49})
    print("| model | level | free dofs | " + " | ".join(f"N/mm at {d} mm" for d in DEPTHS) + " |")
    print("|---|---|---|" + "---|" * len(DEPTHS))
    finest = None
    for level in args.levels2d:
        disc = Discretization(build_mesh(PAD.section, (), MeshOptions().refined(level)), [mat])
        finest = press_plate(Body(disc, Plate()), DEPTHS, STEP_MM, min_step_mm=1e-4)
        cells = " | ".join(f"{f:.6f}" for f in finest)
        print(f"| 2D, P2 triangles | {level:g} | {disc.n_free} | {cells} |", flush=True)
    for level in args.levels3d:
        pmesh = build_pad_mesh(PAD, (), COARSE_MESH_3D.refined(level))
        disc = Discretization3D(
            extruded_section_mesh(pmesh, THICKNESS_MM), [mat], fixed=plane_strain
        )
        per_mm = press_plate(Body(disc, Plate()), DEPTHS, STEP_MM, min_step_mm=1e-4) / THICKNESS_MM
        cells = " | ".join(
            f"{f:.6f} ({100 * (f / g - 1):+.2f} %)" for f, g in zip(per_mm, finest, strict=True)
        )
        print(f"| slab, Q2 hexahedra | {level:g} | {disc.n_free} | {cells} |", flush=True)
    print(f"(percentages: against the 2D model at level {args.levels2d[-1]:g})")


if __name__ == "__main__":
    main()
