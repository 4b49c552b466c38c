"""Total-Lagrangian 3D discretisation of the fingertip pad: 27-node hexahedra (Q2), the
sibling of the plane-strain ``sim.fe.fe2d.Discretization``.

The mesh is ``sim.geometry.mesh3d.PadMesh`` (the quarter pad x >= 0, z >= 0; base y = 0 bonded,
u_x = 0 on x = 0 and u_z = 0 on z = 0; or, for an inclined plate, the half pad x >= 0 with
u_x = 0 on x = 0 only); the reference element and its 3 x 3 x 3 Gauss rule are
``sim.geometry._q2``. The residual and tangent are the 2D discretisation's
(``sim.fe._assembly.KernelAssembly``: the same laws, Prony update and tangent, with 6-component
``C``, and the same compiled kernels ``sim.fe._kernels``) into the fixed pattern of
``sim.fe._pattern``. The interface a ``sim.fe.solver.Body`` relies on is
the 2D one: ``n_nodes``, ``dim``, ``X``, ``fixed``, ``gmap``, ``n_free``, ``surface_nodes``,
``surface_weights()``, ``evaluate()``, ``initial_states()``, ``pattern_position()``,
``upper_matrix()``, ``upper_data``.

Array conventions: nodal displacements ``u`` have shape (n_nodes, 3); the global dof of node
``i`` and component ``c`` is ``3 i + c``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import _q2
from . import ELEMENTS_3D
from ._assembly import KernelAssembly
from ._constitutive import LayerState, initial_states
from ._pattern import PatternAccess, build_pattern

if TYPE_CHECKING:
    from ..geometry import PadMesh
    from ..materials import Material

__all__ = ["Discretization3D"]


class Discretization3D(KernelAssembly, PatternAccess):
    """Q2 hexahedra on a ``PadMesh`` with one material per layer.

    Elements are reordered so that each layer is a contiguous slice."""

    dim = 3
    #: the obstacles' plane (horizontal, vertical coordinate): every obstacle is a cylinder
    #: along x, across the finger -- the wedge's edge runs across the pad
    obstacle_axes = (2, 1)

    def __init__(
        self,
        pmesh: PadMesh,
        materials: list[Material],
        fixed: Callable[[np.ndarray], np.ndarray] | None = None,
        element: str = "q2",
    ) -> None:
        """``element``: "q2", pure displacement, or "q2p1", the locking-free Q2/P1 element
        (the volume ratio projected on linear polynomials per element, ``sim.fe._mixed``;
        ``sim.fe.ELEMENTS_3D``).

        ``fixed(X) -> mask``: optional function of the node coordinates X (n_nodes, 3)
        returning the (n_nodes, 3) mask of constrained dofs, replacing the default (base fully
        fixed, u_x = 0 on x = 0, u_z = 0 on z = 0). Constrained dofs keep whatever value the
        displacement array holds, so prescribed displacements are set there."""
        n_layers = int(pmesh.layer.max()) + 1
        if len(materials) != n_layers:
            raise ValueError(f"{n_layers} layers in the mesh, {len(materials)} materials given")
        order = np.argsort(pmesh.layer, kind="stable")
        self.pmesh = pmesh
        self.materials = materials
        self.conn = np.ascontiguousarray(pmesh.hexes[order], dtype=np.int64)  # (E, 27)
        self.layer = np.asarray(pmesh.layer)[order]
        counts = np.bincount(self.layer, minlength=n_layers)
        bounds = np.concatenate([[0], np.cumsum(counts)])
        self.slices = [slice(int(bounds[k]), int(bounds[k + 1])) for k in range(n_layers)]
        self.X = np.asarray(pmesh.nodes, dtype=float)  # (n_nodes, 3)
        self.n_nodes = len(self.X)
        self.dN, self.w = reference_gradients(self.X, self.conn)
        self.n_el, self.n_q = self.w.shape
        if element not in ELEMENTS_3D:
            raise ValueError(f"element must be one of {', '.join(ELEMENTS_3D)}, got {element!r}")
        if element == "q2p1":
            from ._mixed import dilatation_basis

            self.dilatation = dilatation_basis(self.quadrature_points(), self.w)

        if fixed is None:
            mask = np.zeros((self.n_nodes, 3), dtype=bool)
            mask[pmesh.base, :] = True
            mask[pmesh.sym_x, 0] = True
            mask[pmesh.sym_z, 2] = True
        else:
            mask = np.asarray(fixed(self.X), dtype=bool)
        self.fixed = mask
        self.free = np.flatnonzero(~mask.ravel())
        self.n_free = len(self.free)
        gmap = -np.ones(3 * self.n_nodes, dtype=np.int64)
        gmap[self.free] = np.arange(self.n_free)
        self.gmap = gmap
        self.surface_nodes = np.asarray(pmesh.surface_nodes)
        #: the half pad x >= 0 (an inclined plate), not the quarter
        self.half = bool(pmesh.half)
        s = self.surface_nodes
        self.apex_node = int(s[np.argmax(self.X[s, 1])])
        self.pattern = build_pattern(self.conn, gmap, 3, extra_nodes=s)
        pat = self.pattern
        self.nnz = pat.nnz
        self.indptr, self.indices = pat.indptr, pat.indices
        self.upper_data = pat.upper_data
        self.upper_indices, self.upper_indptr = pat.upper_indices, pat.upper_indptr

    # ------------------------------------------------------------------ helpers
    @property
    def band_h_mm(self) -> float:
        """The element size of the band along the wedge's edge (mm; 0: no band), the wedge's
        mesh's (``MeshOptions3D.edge_h_mm``)."""
        return self.pmesh.edge_h_mm

    def force_scale(self, length_mm: float) -> float:
        """The whole pad's force (N) per unit of the model's indenter force (N, on the quarter
        x >= 0, z >= 0): 4; on the half x >= 0: 2 (``PadMesh.mirrors``); ``length_mm``, the
        2D model's out-of-plane length, plays no part."""
        return float(self.pmesh.mirrors)

    def section_curves(self) -> list[tuple[np.ndarray, int]]:
        """The outer surface's curves in the symmetry planes, ordered from the apex, each with
        the horizontal coordinate along which it runs: x = 0 (along the finger, z) and z = 0
        (across it, x). Ordered by the angle from the apex in the scaled coordinates (the pad
        is star-shaped from the origin). On the half pad the curve x = 0 is its part z >= 0,
        towards the tip (the quarter's curve; the other part is ``heel_curve``)."""
        return [self._plane_curve(0, 2), self._plane_curve(2, 0)]

    def heel_curve(self) -> np.ndarray | None:
        """On the half pad, the outer surface's curve in x = 0 on the heel's side z <= 0,
        ordered from the apex (its z is -1 x the distance along the finger); None on the
        quarter."""
        return self._plane_curve(0, 2, heel=True)[0] if self.half else None

    def _plane_curve(self, plane: int, axis: int, heel: bool = False) -> tuple[np.ndarray, int]:
        """The surface nodes on the plane ``plane`` = 0, running along ``axis`` from the apex,
        ordered by the angle from the apex; on the half pad's x = 0 the side z >= 0 (``heel``:
        z <= 0)."""
        a, b, c = self.pmesh.geometry.semi_axes_mm()
        scale = (a, b, c)[axis]
        s = self.surface_nodes
        X = self.X[s]
        on = np.flatnonzero(np.abs(X[:, plane]) <= 1e-9 * max(a, b, c))
        if self.half and plane == 0:
            on = on[X[on, 2] <= 0.0] if heel else on[X[on, 2] >= 0.0]
        sign = -1.0 if heel else 1.0
        angle = np.arctan2(sign * X[on, axis] / scale, X[on, 1] / b)
        return s[on[np.argsort(angle, kind="stable")]], axis

    def contact_area_mm2(self, u: np.ndarray, penetration: np.ndarray, samples: int = 8) -> float:
        """The whole pad's contact area (mm^2, 4 x the quarter's): the part of the deformed
        outer surface where the penetration is positive, projected on the plane y = const
        (the plate's; on a flat patch the two are equal).

        ``penetration`` (mm, > 0 inside the obstacle) at the surface nodes, in the order of
        ``surface_nodes``, is interpolated over each 9-node face by its shape functions and
        read at ``samples`` x ``samples`` midpoints of the reference face; each sample counts
        its share of the projected area, |(dx/ds x dx/dt)_y| ds dt. A patch edge is thus
        located to within a fraction 1/samples of an element, not snapped to the nodes."""
        sampled = self._patch_samples(u, penetration, samples)
        if sampled is None:
            return 0.0
        _, tangents, inside, weight = sampled
        normal_y = (
            tangents[:, :, 0, 2] * tangents[:, :, 1, 0]
            - tangents[:, :, 0, 0] * tangents[:, :, 1, 2]
        )  # the y component of dx/ds x dx/dt
        return self.pmesh.mirrors * weight * float(np.sum(np.abs(normal_y) * inside))

    def contact_patch_mm(
        self, u: np.ndarray, penetration: np.ndarray, axis: np.ndarray, samples: int = 8
    ) -> tuple[float, float, float]:
        """The whole pad's contact patch with a plate of outward normal ``axis`` e (3,) (an
        inclined plate, ``sim.fe.contact.Plate``), measured in the plate's plane: its area
        (mm^2), its width across the finger (x) and its length along it (mm).

        - Area: as ``contact_area_mm2`` (the penetration interpolated over each face, read at
          ``samples`` x ``samples`` points), each sample inside counting
          |(dx/ds x dx/dt) . e| ds dt: the patch projected on the plate.
        - Length: on the surface's curve in x = 0 from the heel's end to the tip's (both
          halves on the half pad), at the deformed nodes' coordinate along
          t = (0, -e_z, e_y), the plate's direction along the finger (towards the tip): from
          the edge before the first node in contact to the edge after the last, each edge
          where the penetration interpolated linearly between two nodes is zero (the
          quarter's ``contact_half_width_mm`` reading at both ends).
        - Width: 2 max x (the patch is symmetric about x = 0) over the points where the
          interpolated penetration is positive, read at 8 ``samples`` per side of each face
          (the widest section need not lie on a mesh line): within 1 / (8 samples) of an
          element inside the edge."""
        sampled = self._patch_samples(u, penetration, samples)
        if sampled is None:
            return 0.0, 0.0, 0.0
        _, tangents, inside, weight = sampled
        normal = np.cross(tangents[:, :, 0], tangents[:, :, 1])  # (F, P, 3)
        e = np.asarray(axis, dtype=float)
        area = self.pmesh.mirrors * weight * float(np.sum(np.abs(normal @ e) * inside))
        x, _, inside, _ = self._patch_samples(u, penetration, 8 * samples)
        width = 2.0 * float(x[inside][:, 0].max(initial=0.0))
        nodes, position = self._finger_curve(u)
        p = penetration[np.searchsorted(self.surface_nodes, nodes)]
        length = _extent(position @ np.array([0.0, -e[2], e[1]]), p)
        return area, width, length

    def _finger_curve(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The surface's curve in x = 0 from the heel's end (z = -c) to the tip's: its nodes
        and deformed positions (m, 3); on the quarter its half z <= 0 is the mirror image of
        the half z >= 0 (positions with z negated, the same nodes)."""
        tip = self._plane_curve(0, 2)[0]
        x_tip = self.X[tip] + u[tip]
        if self.half:
            heel = self._plane_curve(0, 2, heel=True)[0]
            x_heel = self.X[heel] + u[heel]
        else:
            heel, x_heel = tip, x_tip * np.array([1.0, 1.0, -1.0])
        return (
            np.concatenate([heel[::-1], tip[1:]]),
            np.concatenate([x_heel[::-1], x_tip[1:]]),
        )

    def _patch_samples(self, u: np.ndarray, penetration: np.ndarray, samples: int):
        """The deformed sample points (F, P, 3), tangents dx/ds, dx/dt (F, P, 2, 3) and
        contact flags (F, P) of the faces with a positive penetration (``contact_area_mm2``),
        and each sample's reference weight; None without contact."""
        faces = np.asarray(self.pmesh.surface_faces)
        on_surface = np.full(self.n_nodes, -np.inf)
        on_surface[self.surface_nodes] = penetration
        p_faces = on_surface[faces]  # (F, 9)
        touching = np.any(p_faces > 0.0, axis=1)
        if not np.any(touching):
            return None
        faces, p_faces = faces[touching], p_faces[touching]
        t = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
        S, T = np.meshgrid(t, t, indexing="ij")
        points = np.column_stack([S.ravel(), T.ravel()])
        N = _q2.face_shape_functions(points)  # (P, 9)
        dN = _q2.face_shape_gradients(points)  # (P, 9, 2)
        x = (self.X + u)[faces]  # (F, 9, 3)
        tangents = np.einsum("fai,pad->fpdi", x, dN)  # (F, P, 2, 3)
        weight = (2.0 / samples) ** 2
        inside = (p_faces @ N.T) > 0.0  # (F, P)
        return np.einsum("pa,fai->fpi", N, x), tangents, inside, weight

    def quadrature_points(self) -> np.ndarray:
        """The Gauss points in the reference configuration (3, n_el, n_q), mm."""
        points, _ = _q2.gauss_rule()
        N = _q2.shape_functions(points)  # (Q, 27)
        return np.einsum("qa,eaI->Ieq", N, self.X[self.conn])

    def surface_weights(self) -> np.ndarray:
        """Each surface node's share of the outer surface's area (mm^2), in the order of
        ``surface_nodes``: the contact penalty's weights
        (``sim.geometry.mesh3d.surface_weights``)."""
        from ..geometry.mesh3d import surface_weights

        w = surface_weights(self.X, np.asarray(self.pmesh.surface_faces))
        return w[self.surface_nodes]

    def initial_states(self) -> list[LayerState]:
        return initial_states(self.materials, self.slices, self.n_q, 6)


def _extent(s: np.ndarray, p: np.ndarray) -> float:
    """The length of the contact along an ordered curve: from the edge before its first node
    in contact (penetration ``p`` > 0) to the edge after its last, at the coordinates ``s``
    (m,); each edge where p interpolated linearly between the two nodes is zero (a curve's end
    node in contact is its own edge). 0 without contact."""
    touching = np.flatnonzero(p > 0.0)
    if touching.size == 0:
        return 0.0

    def edge(k: int, j: int) -> float:  # between the node k in contact and its neighbour j
        if not 0 <= j < len(s):
            return float(s[k])
        w = p[k] / (p[k] - p[j])  # p[k] > 0 >= p[j]
        return float(s[k] + w * (s[j] - s[k]))

    first, last = int(touching[0]), int(touching[-1])
    return abs(edge(last, last + 1) - edge(first, first - 1))


def reference_gradients(X: np.ndarray, conn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients ``dN_a/dX_J`` (E, Q, 27, 3) and the weights ``w = det(dX/dxi)
    w_q`` (E, Q) at the 3 x 3 x 3 Gauss points of each Q2 element of nodes ``X[conn]``.
    Raises ``ValueError`` for an element whose Jacobian is not positive everywhere."""
    points, weights = _q2.gauss_rule()
    G = _q2.shape_gradients(points)  # (Q, 27, 3): dN_a/dxi_d
    Xe = X[conn]  # (E, 27, 3)
    jac = np.einsum("eaI,qad->eqId", Xe, G)  # dX_I/dxi_d
    det = np.linalg.det(jac)
    if not np.all(det > 0.0):
        raise ValueError(f"{int(np.sum(~(det > 0)))} Gauss points with det(dX/dxi) <= 0")
    inv = np.linalg.inv(jac)  # dxi_d/dX_J
    dN = np.einsum("qad,eqdJ->eqaJ", G, inv)
    return np.ascontiguousarray(dN), det * weights[None, :]
