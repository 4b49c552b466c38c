"""The straight-sided triangle mesh and P2 basis arrays the FE runs on, as scikit-fem computes them.

scikit-fem (``MeshTri``, ``Basis(mesh, ElementTriP2(), intorder=2)``) is the reference for
everything here, but importing it costs ~0.09 s (``skfem.utils`` pulls ``scipy.sparse.linalg``
and ``scipy.sparse.csgraph``), a tenth of a one-protocol ``fingertip simulate`` (issue 15 item
1: the whole process within 1 s), for five arrays. They are computed here with scikit-fem 12's
own operations in its own order — facets from ``Mesh.build_entities``, the affine map of
``MappingAffine``, the P2 shape functions of ``ElementTriP2.lbasis``, its 3-point rule
``get_quadrature_tri(2)``, the dof numbering of ``Dofs`` (vertices, then one dof per facet) and
the dof locations of ``AbstractBasis`` — so that they are *equal* to scikit-fem's, bit for bit:
``tests/test_p2.py`` checks it on fingertip meshes, and the FE's results are unchanged.
scikit-fem stays the reference of the tests (``test_fe.py`` assembles the same weak forms with
its ``BilinearForm``) and of the verification scripts (``Discretization.skfem_basis``).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

__all__ = ["P2Basis", "TriMesh"]

# ElementTriP2.doflocs on the reference triangle (0, 0), (1, 0), (0, 1): vertices, then the
# midpoints of the facets 0-1, 1-2, 0-2 (RefTri.facets)
_REF_DOFLOCS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]])
_REF_FACETS = ((0, 1), (1, 2), (0, 2))
# get_quadrature_tri(2): the 3-point rule, exact for quadratics (points (2, 3), weights (3,))
_QP = np.array(
    [
        [1.666666666666666666666e-01, 6.666666666666666666666e-01, 1.666666666666666666666e-01],
        [1.666666666666666666666e-01, 1.666666666666666666666e-01, 6.666666666666666666666e-01],
    ]
)
_QW = np.array([1.666666666666666666666e-01] * 3)


class TriMesh:
    """Vertices ``p`` (2, n_vertices) and triangles ``t`` (3, n_triangles), with the facet
    numbering of scikit-fem's ``MeshTri`` (``facets``, ``t2f``, ``boundary_facets``). As
    ``MeshTri`` does (``sort_t``), each triangle's vertex indices are sorted ascending: the
    orientation is arbitrary, and the affine map's |det| takes care of it."""

    def __init__(self, p: np.ndarray, t: np.ndarray) -> None:
        self.p = np.ascontiguousarray(np.asarray(p, dtype=np.float64))
        self.t = np.sort(t, axis=0).astype(np.int32)  # a new, contiguous array

    @cached_property
    def _entities(self) -> tuple[np.ndarray, np.ndarray]:
        # Mesh.build_entities: every element's facets, sorted, made unique column-wise
        indexing = np.hstack([self.t[list(ix)] for ix in _REF_FACETS])
        unique, inverse = np.unique(np.sort(indexing, axis=0), axis=1, return_inverse=True)
        return np.ascontiguousarray(unique), inverse.reshape(len(_REF_FACETS), -1)

    @property
    def facets(self) -> np.ndarray:
        """Vertex pairs of the facets (2, n_facets), each sorted, in lexicographic order."""
        return self._entities[0]

    @property
    def t2f(self) -> np.ndarray:
        """The facets of each triangle (3, n_triangles): 0-1, 1-2, 0-2."""
        return self._entities[1]

    @cached_property
    def _boundary_facets(self) -> np.ndarray:
        counts = np.bincount(self.t2f.ravel(), minlength=self.facets.shape[1])
        return np.flatnonzero(counts == 1).astype(np.int32)

    def boundary_facets(self) -> np.ndarray:
        """Indices of the facets that belong to one triangle only, ascending (counted once per
        mesh; a copy, so a caller cannot change the mesh's)."""
        return self._boundary_facets.copy()


class P2Basis:
    """P2 shape-function gradients, quadrature weights, dof map and dof locations on a
    ``TriMesh`` (affine elements, the 3-point rule), equal to scikit-fem's
    ``Basis(mesh, ElementTriP2(), intorder=2)``: ``grads`` (6, 2, n_el, n_q) is
    ``[basis.basis[a][0].grad for a in range(6)]``, ``dx`` (n_el, n_q) ``basis.dx``,
    ``element_dofs`` (6, n_el), ``doflocs`` (2, N) and ``global_coordinates()`` (2, n_el,
    n_q) the same as scikit-fem's."""

    def __init__(self, mesh: TriMesh, intorder: int = 2) -> None:
        if intorder != 2:  # the one rule the FE uses; scikit-fem's Basis has the others
            raise ValueError(f"P2Basis has the 3-point rule (intorder 2) only, not {intorder}")
        p, t = mesh.p, mesh.t
        nv, nt = p.shape[1], t.shape[1]
        # MappingAffine._init_Ab / _init_invA
        A = np.empty((2, 2, nt))
        b = np.empty((2, nt))
        for i in range(2):
            b[i] = p[i, t[0]]
            for j in range(2):
                A[i, j] = p[i, t[j + 1]] - p[i, t[0]]
        detA = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        invA = np.empty((2, 2, nt))
        invA[0, 0] = A[1, 1] / detA
        invA[0, 1] = -A[0, 1] / detA
        invA[1, 0] = -A[1, 0] / detA
        invA[1, 1] = A[0, 0] / detA
        self._A, self._b = A, b
        # ElementH1.gbasis: grad = invDF^T dphi, invDF = invA broadcast over the points
        invDF = np.einsum("ijk,l->ijkl", invA, np.ones(_QP.shape[-1]))
        self.grads = np.stack([np.einsum("ijkl,il->jkl", invDF, g) for g in _lbasis_grads(_QP)])
        # CellBasis.dx: |det DF| times the weights
        self.dx = np.abs(np.tile(detA, (_QP.shape[-1], 1)).T) * np.broadcast_to(
            _QW, (nt, _QW.shape[-1])
        )
        # Dofs: one per vertex (its index), then one per facet (n_vertices + facet index)
        self.element_dofs = np.vstack([t, nv + mesh.t2f]).astype(np.int32)
        self.N = int(self.element_dofs.max()) + 1
        # AbstractBasis: each element's mapped dof locations, later elements overwriting
        locs = self._map(_REF_DOFLOCS.T)  # (2, nt, 6)
        self.doflocs = np.zeros((2, self.N))
        for i in range(2):
            for a in range(6):
                self.doflocs[i, self.element_dofs[a]] = locs[i, :, a]

    def _map(self, X: np.ndarray) -> np.ndarray:
        """MappingAffine.F: reference points X (2, n) to (2, n_el, n) in every element."""
        return (np.einsum("ijk,jl", self._A, X).T + self._b.T).T

    def global_coordinates(self) -> np.ndarray:
        """The quadrature points in the reference configuration (2, n_el, n_q), mm."""
        return self._map(_QP)


def _lbasis_grads(X: np.ndarray) -> list[np.ndarray]:
    """ElementTriP2.lbasis: the reference gradients (2, n) of the six shape functions at X
    (2, n), in its order and with its expressions."""
    x, y = X
    return [
        np.array([-3 + 4.0 * x + 4.0 * y, -3 + 4.0 * x + 4.0 * y]),
        np.array([4.0 * x - 1, 0.0 * x]),
        np.array([0.0 * x, 4.0 * y - 1]),
        np.array([4 - 8.0 * x - 4.0 * y, -4.0 * x]),
        np.array([4.0 * y, 4.0 * x]),
        np.array([-4.0 * y, 4 - 4.0 * x - 8.0 * y]),
    ]
