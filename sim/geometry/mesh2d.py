"""Conforming triangle meshes of the layered half cross-section (Triangle).

The half x >= 0 is meshed with quality triangles (no angle below 30 degrees) that conform to the
layer interfaces. The elements are smallest at the apex (the wedge's tip) and along the top of the
outer surface (where the plate touches) and grow linearly away from them (``MeshOptions``). The
elements are P2 (six-node) triangles in the solver; the boundary is the polygon through the
sampled nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._p2 import TriMesh
from .section import Geometry, sample_curve, superellipse_points

__all__ = ["DEFAULT_MESH", "FingertipMesh", "MeshOptions", "build_mesh"]


def _nearest_distance(points: np.ndarray, curve: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Distance from each of ``points`` (n, 2) to the nearest of ``curve`` (m, 2), exactly.

    Brute force in chunks (a few hundred curve points, a few thousand queries: milliseconds);
    it replaced a KD-tree whose import (``scipy.spatial``, with ``scipy.special``) cost more
    than the whole query, at the same bits: sqrt(dx^2 + dy^2) of the closest point."""
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        d = points[s : s + chunk, None, :] - curve[None, :, :]
        out[s : s + chunk] = np.sqrt(np.min(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1], axis=1))
    return out


@dataclass(frozen=True)
class MeshOptions:
    """Target element sizes (mm).

    ``h = min(h_max, h_apex + grading * d_apex, h_contact + grading * d_contact)`` where
    ``d_apex`` is the distance from the apex (the wedge's tip) and ``d_contact`` the distance from
    the part of the outer surface within ``contact_width_fraction * half_width`` of the axis
    (where the plate touches a soft pulp).
    """

    h_apex_mm: float = 0.05
    h_contact_mm: float = 0.2
    contact_width_fraction: float = 0.7
    grading: float = 0.3
    h_max_mm: float = 0.6

    def sizer(self, geometry: Geometry):
        """The size function ``points (..., 2) -> h (...)`` for ``geometry``."""
        a, b, n = geometry.half_width_mm, geometry.height_mm, geometry.exponent
        theta = np.linspace(0.0, np.pi / 2, 600)
        curve = superellipse_points(a, b, n, theta)
        near = curve[curve[:, 0] <= self.contact_width_fraction * a]

        def size(points: np.ndarray) -> np.ndarray:
            pts = np.asarray(points, dtype=float)
            d_apex = np.hypot(pts[..., 0], pts[..., 1] - b)
            d_contact = _nearest_distance(pts.reshape(-1, 2), near).reshape(pts.shape[:-1])
            h = np.minimum(self.h_apex_mm + self.grading * d_apex, self.h_max_mm)
            return np.minimum(h, self.h_contact_mm + self.grading * d_contact)

        return size

    def refined(self, factor: float) -> MeshOptions:
        """All sizes divided by ``factor`` (for convergence studies)."""
        return MeshOptions(
            self.h_apex_mm / factor,
            self.h_contact_mm / factor,
            self.contact_width_fraction,
            self.grading / factor,
            self.h_max_mm / factor,
        )


DEFAULT_MESH = MeshOptions()


@dataclass(frozen=True)
class FingertipMesh:
    """A linear triangle mesh of the half section with its labelled boundaries.

    Attributes:
        mesh: ``TriMesh`` (vertices ``p`` (2, n), triangles ``t`` (3, m); scikit-fem's
            ``MeshTri`` numbering, ``sim.geometry._p2``).
        layer: (m,) layer index of each triangle, 0 = outermost.
        surface: vertex indices of the free outer surface ordered from the apex to the base
            corner.
        base: vertex indices on the bonded base y = 0 (fully fixed).
        axis: vertex indices on the symmetry axis x = 0 (u_x = 0).
    """

    mesh: TriMesh
    layer: np.ndarray
    surface: np.ndarray
    base: np.ndarray
    axis: np.ndarray


def build_mesh(
    geometry: Geometry, thicknesses_mm: tuple[float, ...] = (), options: MeshOptions = DEFAULT_MESH
) -> FingertipMesh:
    """Mesh the half section with interfaces at the cumulative depths of ``thicknesses_mm``.

    ``thicknesses_mm`` are the thicknesses of all layers but the last (outermost first).
    """
    import triangle

    a, b, n = geometry.half_width_mm, geometry.height_mm, geometry.exponent
    size = options.sizer(geometry)

    depths = np.cumsum(thicknesses_mm) if thicknesses_mm else np.zeros(0)
    curves = [sample_curve(a, b, n, size)]
    curves += [sample_curve(a - d, b - d, n, size) for d in depths]

    vertices: list[np.ndarray] = []
    segments: list[np.ndarray] = []
    offset = 0
    for curve in curves:
        vertices.append(curve)
        idx = np.arange(offset, offset + len(curve))
        segments.append(np.column_stack([idx[:-1], idx[1:]]))
        offset += len(curve)
    origin = offset
    vertices.append(np.array([[0.0, 0.0]]))
    # curve k starts at the apex (0, b_k) on the axis and ends at (a_k, 0) on the base
    starts = [0, *np.cumsum([len(c) for c in curves])[:-1]]
    ends = [s + len(c) - 1 for s, c in zip(starts, curves, strict=True)]
    chain_axis = [*starts, origin]
    chain_base = [*ends, origin]
    for chain in (chain_axis, chain_base):
        segments.append(np.column_stack([chain[:-1], chain[1:]]))
    pts = np.vstack(vertices)
    segs = np.vstack(segments)

    # one region point per layer, just right of the axis, halfway between its bounding curves
    bounds = [0.0, *depths.tolist(), b]
    regions = [
        [1e-3 * options.h_apex_mm, b - 0.5 * (bounds[k] + bounds[k + 1]), k, 0]
        for k in range(len(bounds) - 1)
    ]
    area0 = np.sqrt(3) / 4 * options.h_max_mm**2
    tri = triangle.triangulate(
        {"vertices": pts, "segments": segs, "regions": np.array(regions)}, f"pq30Aa{area0:.8f}"
    )
    for _ in range(8):
        p, t = tri["vertices"], tri["triangles"]
        centroid = p[t].mean(axis=1)
        target = np.sqrt(3) / 4 * size(centroid) ** 2
        area = _areas(p, t)
        if np.all(area <= 1.05 * target):
            break
        tri = triangle.triangulate(
            {
                "vertices": p,
                "segments": tri["segments"],
                "triangles": np.ascontiguousarray(t),
                "triangle_attributes": np.ascontiguousarray(tri["triangle_attributes"]),
                "triangle_max_area": np.ascontiguousarray(target),
            },
            "rpq30Aa",
        )
    p, t = tri["vertices"], tri["triangles"]
    layer = tri["triangle_attributes"][:, 0].astype(int)
    mesh = TriMesh(p.T.copy(), t.T.copy())
    return FingertipMesh(mesh, layer, *_boundaries(mesh, a, b, n))


def _areas(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    e1 = p[t[:, 1]] - p[t[:, 0]]
    e2 = p[t[:, 2]] - p[t[:, 0]]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _boundaries(mesh: TriMesh, a: float, b: float, n: float):
    tol = 1e-9 * max(a, b)
    facets = mesh.facets[:, mesh.boundary_facets()]
    p = mesh.p
    on_base = np.all(np.abs(p[1, facets]) < tol, axis=0)
    on_axis = np.all(np.abs(p[0, facets]) < tol, axis=0)
    base = np.unique(facets[:, on_base])
    axis = np.unique(facets[:, on_axis])
    surf = np.unique(facets[:, ~(on_base | on_axis)])
    # order the outer surface from the apex to the base corner by the superellipse angle
    x, y = p[0, surf], p[1, surf]
    angle = np.arctan2((np.clip(y / b, 0, 1)) ** (n / 2), (np.clip(x / a, 0, 1)) ** (n / 2))
    surf = surf[np.argsort(-angle)]
    return surf, base, axis
