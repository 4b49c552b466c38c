"""Where the 3D contact patch's edge is read: the penetration interpolated over each 9-node face
by its biquadratic shape functions (``Discretization3D.contact_area_mm2``, the metric) against
bilinearly on the face's four sub-quadrilaterals (each between four of its nodes).

    python studies/contact_edge3d.py [--design silicone_gls40] [--levels 1 1.41] [--taps 2]

``--design``: a catalogue material on the reference outline, or a design TOML file. The pad is
tapped on ``COARSE_MESH_3D.refined(f)`` for each level f (1.41 is the simulations' mesh), and at
the tapping's states kept at 1 N and 4 N (the first steps at or beyond them) the contact area is
read both ways, with the same 8 x 8 samples a face and the same area weights. Inside a face
whose nine nodes all touch, both readings count every sample (the biquadratic one has no holes
there: printed as ``holes``); they differ only in the faces the patch's edge crosses, where one
node touches and its neighbour does not. The penalty's penetration inside the patch is small
(about 1e-4 mm) against the gap outside it, so a linear reading puts the edge next to the last
node that touches; the biquadratic one follows the gap's curvature further out. Their difference
is the edge's uncertainty on that mesh (about half an element), which the patch's few elements
across at 1 N make large.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sim import simulate
from sim.design import homogeneous_design, load_design
from sim.geometry import COARSE_MESH_3D, _q2
from sim.options import ModelOptions, SimOptions, apply_overrides
from sim.output._pad_figure import pad_figure_info


def bilinear_inside(p_faces: np.ndarray, samples: int) -> np.ndarray:
    """(F, P) whether the penetration, bilinear on each face's sub-quadrilateral holding the
    sample, is positive at the ``samples`` x ``samples`` points that ``_patch_samples`` reads
    (the same order)."""
    corner = {(int(a), int(b)): k for k, (a, b) in enumerate(_q2.FACE_REFERENCE_POINTS.astype(int))}
    t = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
    S, T = (g.ravel() for g in np.meshgrid(t, t, indexing="ij"))
    s0, t0 = np.where(S < 0, -1, 0), np.where(T < 0, -1, 0)
    ls, lt = S - s0, T - t0  # local coordinates in [0, 1] of the sub-quadrilateral
    out = np.zeros((len(p_faces), len(S)))
    for i in (-1, 0):
        for j in (-1, 0):
            m = (s0 == i) & (t0 == j)
            k00, k10 = corner[(i, j)], corner[(i + 1, j)]
            k01, k11 = corner[(i, j + 1)], corner[(i + 1, j + 1)]
            a, b = ls[m], lt[m]
            out[:, m] = (
                p_faces[:, [k00]] * (1 - a) * (1 - b)
                + p_faces[:, [k10]] * a * (1 - b)
                + p_faces[:, [k01]] * (1 - a) * b
                + p_faces[:, [k11]] * a * b
            )
    return out > 0.0


def readings(design_name: str, level: float, taps: int) -> list[dict]:
    """Both readings at the tapping's kept states of one design on one mesh level."""
    if design_name.endswith(".toml"):
        design = load_design(design_name)
    else:
        design = homogeneous_design(design_name)
    options = SimOptions(model=ModelOptions("3d"), mesh3d=COARSE_MESH_3D.refined(level))
    options = apply_overrides(
        options, {"tapping.max_taps": str(taps), "validity.stop_at_violation": "false"}
    )
    started = time.perf_counter()
    result = simulate(design, ["tapping"], options=options, keep_fields=True)
    disc = result.discretization
    s = disc.surface_nodes
    out = []
    for state in pad_figure_info(result).states:
        u = result.fields[state.name]
        p = (disc.X[s] + u[s])[:, 1] - state.plate_position_mm
        _, tangents, inside, weight = disc._patch_samples(u, p, 8)
        faces = np.asarray(disc.pmesh.surface_faces)
        on = np.full(disc.n_nodes, -np.inf)
        on[s] = p
        p_faces = on[faces]
        p_faces = p_faces[np.any(p_faces > 0.0, axis=1)]
        normal_y = (
            tangents[:, :, 0, 2] * tangents[:, :, 1, 0]
            - tangents[:, :, 0, 0] * tangents[:, :, 1, 2]
        )
        area = disc.pmesh.mirrors * weight * np.abs(normal_y)
        full = np.all(p_faces > 0.0, axis=1)
        out.append(
            {
                "level": level,
                "dofs": result.n_dofs,
                "state": state.name,
                "force_N": state.state_force_N,
                "biquadratic_mm2": float(np.sum(area * inside)),
                "bilinear_mm2": float(np.sum(area * bilinear_inside(p_faces, 8))),
                "holes": int(np.sum(~inside[full])),
                "seconds": time.perf_counter() - started,
            }
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", default="silicone_gls40")
    ap.add_argument("--levels", type=float, nargs="+", default=[1.0, 1.41])
    ap.add_argument("--taps", type=int, default=2)
    args = ap.parse_args()
    print(
        "| f | dofs | state | force (N) | biquadratic (mm²) | bilinear (mm²) | difference | holes |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for level in args.levels:
        for r in readings(args.design, level, args.taps):
            diff = 100.0 * (r["bilinear_mm2"] / r["biquadratic_mm2"] - 1.0)
            print(
                f"| {r['level']:g} | {r['dofs']} | {r['state']} | {r['force_N']:.3f} | "
                f"{r['biquadratic_mm2']:.2f} | {r['bilinear_mm2']:.2f} | {diff:+.1f} % | "
                f"{r['holes']} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
