"""Total-Lagrangian P2 plane-strain discretisation.

The P2 basis (shape-function gradients and quadrature weights on the reference configuration)
and the degree-of-freedom map are scikit-fem's, computed by ``sim.geometry._p2`` without importing
it (equal bit for bit; ``skfem_basis`` gives scikit-fem's own). The Newton loop needs the
residual and the tangent thousands of times per design; they are assembled by the compiled
kernels the 3D model uses (``sim.fe._assembly``, ``sim.fe._kernels``: one batched evaluation of
the constitutive law per layer, then loops over the elements into a CSR pattern built once).
``tests/test_fe.py`` checks this assembly against scikit-fem's own
``BilinearForm``/``LinearForm`` assembly of the same weak form and against finite differences.

Array conventions: nodal displacements ``u`` have shape (n_nodes, 2); the global dof of node ``i``
and component ``c`` is ``2 * i + c``. Constrained dofs are left out of the free-dof system and
keep the values they hold in ``u``: zero for the fingertip (the bonded base, the symmetry axis),
prescribed values in the patch tests.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import FingertipMesh
from ..geometry._p2 import P2Basis, TriMesh
from ._assembly import Evaluation, KernelAssembly
from ._constitutive import LayerState, initial_states
from ._pattern import PatternAccess, build_pattern

if TYPE_CHECKING:
    from skfem import Basis

    from ..materials import Material

__all__ = ["Discretization", "Evaluation", "LayerState"]

INTORDER = 2  # 3-point rule: exact for the P2 stiffness in small strain, no spurious modes


class Discretization(KernelAssembly, PatternAccess):
    """P2 triangles on a ``FingertipMesh`` with one material per layer.

    Elements are reordered so that each layer is a contiguous slice.
    """

    dim = 2
    #: the obstacles' plane (horizontal, vertical coordinate): every obstacle (plate, wedge,
    #: base) is a cylinder normal to it; here the section itself
    obstacle_axes = (0, 1)

    def __init__(
        self,
        fmesh: FingertipMesh,
        materials: list[Material],
        fixed: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        """``fixed(X) -> mask``: optional function of the P2 node coordinates X (n_nodes, 2)
        returning the (n_nodes, 2) mask of constrained dofs, replacing the default (base fully
        fixed, x fixed on the symmetry axis). Constrained dofs keep whatever value the
        displacement array holds, so prescribed displacements are set there."""
        order = np.argsort(fmesh.layer, kind="stable")
        mesh = TriMesh(fmesh.mesh.p, fmesh.mesh.t[:, order])  # contiguous, as scikit-fem's
        self.fmesh = fmesh
        self.mesh = mesh
        self.materials = materials
        basis = P2Basis(mesh, INTORDER)  # = scikit-fem's Basis(mesh, ElementTriP2(), ...)
        self.basis = basis
        self.n_nodes = basis.N
        self.X = basis.doflocs.T.copy()  # (n_nodes, 2) reference coordinates
        layer = fmesh.layer[order]
        counts = np.bincount(layer, minlength=len(materials))
        bounds = np.concatenate([[0], np.cumsum(counts)])
        self.slices = [slice(int(bounds[k]), int(bounds[k + 1])) for k in range(len(materials))]
        # as the kernels take them: shape-function gradients dN_a/dX_J (n_el, n_q, 6, 2), the
        # weights (n_el, n_q) and the connectivity (n_el, 6)
        self.dN = np.ascontiguousarray(basis.grads.transpose(2, 3, 0, 1))
        self.w = np.ascontiguousarray(basis.dx, dtype=float)
        self.edofs_scalar = basis.element_dofs.T.copy()  # (n_el, 6)
        self.conn = np.ascontiguousarray(self.edofs_scalar, dtype=np.int64)
        self.n_el, self.n_q = self.w.shape

        # boundary nodes (P2 numbering): vertices keep their index; midside nodes are found by
        # position on the straight boundary facets
        if fixed is None:
            mask = np.zeros((self.n_nodes, 2), dtype=bool)
            mask[self._boundary_nodes(fmesh.base), :] = True
            mask[self._boundary_nodes(fmesh.axis), 0] = True
        else:
            mask = np.asarray(fixed(self.X), dtype=bool)
        fixed = mask
        self.fixed = mask
        self.surface_nodes = self._ordered_surface_nodes(fmesh.surface)
        self.apex_node = int(self.surface_nodes[0])
        self.free = np.flatnonzero(~fixed.ravel())
        self.n_free = len(self.free)
        gmap = -np.ones(2 * self.n_nodes, dtype=np.int64)
        gmap[self.free] = np.arange(self.n_free)
        self.gmap = gmap

        # the tangent's pattern and the scatter maps (local dof a*2+i), shared with the 3D model
        pat = build_pattern(self.edofs_scalar, gmap, 2)
        self.pattern = pat
        self.nnz = pat.nnz
        self.indptr, self.indices = pat.indptr, pat.indices
        self.scatter_r, self.scatter_K = pat.scatter_r, pat.scatter_K
        self.upper_data = pat.upper_data
        self.upper_indices, self.upper_indptr = pat.upper_indices, pat.upper_indptr

    def skfem_basis(self, intorder: int = INTORDER) -> Basis:
        """scikit-fem's own P2 basis on this mesh (imports scikit-fem: for verification, and
        for forms assembled with scikit-fem on the FE's dof numbering, which it shares)."""
        from skfem import Basis, ElementTriP2, MeshTri

        return Basis(MeshTri(self.mesh.p, self.mesh.t), ElementTriP2(), intorder=intorder)

    # ------------------------------------------------------------------ helpers
    #: the element size of a band along the wedge's edge (mm): the 2D mesh has none
    band_h_mm = 0.0

    def force_scale(self, length_mm: float) -> float:
        """The whole fingertip's force (N) per unit of the model's indenter force: the half
        section's force per unit thickness (N/mm) times 2 (both halves) times the out-of-plane
        length ``length_mm`` (the paper's plane-strain assumption)."""
        return 2.0 * length_mm

    def section_curves(self) -> list[tuple[np.ndarray, int]]:
        """The outer surface's curves in symmetry planes, ordered from the apex, each with the
        horizontal coordinate along which it runs: here the one surface, along x."""
        return [(self.surface_nodes, 0)]

    def quadrature_points(self) -> np.ndarray:
        """The quadrature points in the reference configuration (2, n_el, n_q), mm."""
        return np.asarray(self.basis.global_coordinates())

    def surface_weights(self) -> np.ndarray:
        """Each surface node's share of the outer surface's length (mm; per unit thickness),
        in the order of ``surface_nodes``: the contact penalty's weights."""
        from .contact import surface_weights

        return surface_weights(self.X[self.surface_nodes])

    def _boundary_nodes(self, vertices: np.ndarray) -> np.ndarray:
        """P2 nodes on the boundary chain through ``vertices`` (vertices + midside nodes)."""
        mesh = self.mesh
        vset = np.zeros(mesh.p.shape[1], dtype=bool)
        vset[vertices] = True
        bf = mesh.boundary_facets()
        f = mesh.facets[:, bf]
        on = vset[f[0]] & vset[f[1]]
        mids = mesh.p.shape[1] + bf[on]  # P2 facet dofs follow the vertex dofs
        return np.concatenate([vertices, mids])

    def _ordered_surface_nodes(self, surface_vertices: np.ndarray) -> np.ndarray:
        mesh = self.mesh
        pos = {int(v): k for k, v in enumerate(surface_vertices)}
        bf = mesh.boundary_facets()
        f = mesh.facets[:, bf]
        nodes = [(2.0 * pos[int(v)], int(v)) for v in surface_vertices]
        for j in range(f.shape[1]):
            a, b = int(f[0, j]), int(f[1, j])
            if a in pos and b in pos and abs(pos[a] - pos[b]) == 1:
                nodes.append((pos[a] + pos[b], mesh.p.shape[1] + int(bf[j])))
        nodes.sort()
        return np.array([n for _, n in nodes], dtype=np.int64)

    def initial_states(self) -> list[LayerState]:
        return initial_states(self.materials, self.slices, self.n_q, 3)
