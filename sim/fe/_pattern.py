"""The sparsity pattern of an element assembly and where each element entry goes in it.

For a mesh of ``E`` elements of ``A`` nodes with ``d`` displacement components per node, the
free dofs numbered by ``gmap`` (global dof ``d node + i`` -> free index, -1 if constrained):
the tangent's pattern (CSR of the free dofs, symmetric), the scatter arrays the compiled
kernels (``sim.fe._kernels``) add into, and the upper triangle (CSC) that an LDL^T factorisation
reads. Plain numpy, built once per mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp

__all__ = ["Pattern", "PatternAccess", "build_pattern"]


@dataclass(frozen=True)
class Pattern:
    """Sparsity of the free-dof tangent and the scatter maps of one mesh.

    Attributes:
        n_free: number of free dofs.
        nnz: stored entries of the (full, symmetric) pattern.
        indptr, indices: CSR structure (int32); for a symmetric pattern also its CSC.
        scatter_r: (E A d,) free dof of each local dof, ``n_free`` where constrained.
        scatter_K: (E (A d)^2,) position of each element-matrix entry in the data array,
            ``nnz`` where its row or column is constrained.
        upper_data: positions (in the data array) of the entries on and above the diagonal,
            in CSC order of the upper triangle; ``upper_indices``, ``upper_indptr``: its
            structure (int32).
        keys: sorted ``row * n_free + col`` of the stored entries (for look-ups).
    """

    n_free: int
    nnz: int
    indptr: np.ndarray
    indices: np.ndarray
    scatter_r: np.ndarray
    scatter_K: np.ndarray
    upper_data: np.ndarray
    upper_indices: np.ndarray
    upper_indptr: np.ndarray
    keys: np.ndarray

    def position(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Where each free-dof pair sits in the data array; -1 where either is constrained
        (numbered -1). The pairs must be in the pattern."""
        rows, cols = np.asarray(rows), np.asarray(cols)
        keys = np.maximum(rows, 0) * self.n_free + np.maximum(cols, 0)
        pos = np.searchsorted(self.keys, keys)
        return np.where((rows >= 0) & (cols >= 0), pos, -1)

    def matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """The free-dof tangent of values ``data`` as a CSC matrix (the pattern is symmetric,
        so its CSR structure is its CSC structure)."""
        import scipy.sparse as sp

        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n_free, self.n_free))

    def upper(self, data: np.ndarray) -> sp.csc_matrix:
        """The upper triangle of the tangent of values ``data`` as a CSC matrix (what an LDL^T
        factorisation reads)."""
        import scipy.sparse as sp

        return sp.csc_matrix(
            (data[self.upper_data], self.upper_indices, self.upper_indptr),
            shape=(self.n_free, self.n_free),
        )


def _sorted_unique(keys: np.ndarray) -> np.ndarray:
    """``np.unique(keys)`` by a sort: numpy 2.4's hash-based unique took 15 s on the 9
    million keys of a 3D mesh, the sort under one."""
    k = np.sort(keys)
    if k.size == 0:
        return k
    keep = np.empty(k.size, dtype=bool)
    keep[0] = True
    np.not_equal(k[1:], k[:-1], out=keep[1:])
    return k[keep]


def build_pattern(
    conn: np.ndarray, gmap: np.ndarray, d: int, extra_nodes: np.ndarray | None = None
) -> Pattern:
    """The pattern of elements ``conn`` (E, A) with free-dof map ``gmap`` (n_nodes d,).

    ``extra_nodes``: nodes whose ``d`` dofs must be coupled among themselves even where no
    element couples them (a contact penalty couples the components of a surface node; inside
    an element they are coupled anyway, so this is only a safeguard)."""
    E, A = conn.shape
    n_free = int(gmap.max()) + 1 if gmap.size else 0
    edofs = (d * conn[:, :, None] + np.arange(d)[None, None, :]).reshape(E, A * d)
    fe = gmap[edofs]
    n = A * d
    rows = np.broadcast_to(fe[:, :, None], (E, n, n)).ravel()
    cols = np.broadcast_to(fe[:, None, :], (E, n, n)).ravel()
    keep = (rows >= 0) & (cols >= 0)
    keys = rows[keep].astype(np.int64) * n_free + cols[keep]
    if extra_nodes is not None and len(extra_nodes):
        nd = gmap[d * np.asarray(extra_nodes)[:, None] + np.arange(d)[None, :]]  # (m, d)
        r = np.broadcast_to(nd[:, :, None], (len(nd), d, d)).ravel()
        c = np.broadcast_to(nd[:, None, :], (len(nd), d, d)).ravel()
        ok = (r >= 0) & (c >= 0)
        keys = np.concatenate([keys, r[ok].astype(np.int64) * n_free + c[ok]])
    ukeys = _sorted_unique(keys)
    nnz = len(ukeys)
    prow, pcol = ukeys // n_free, ukeys % n_free
    scatter_K = np.full(rows.shape, nnz, dtype=np.int64)
    scatter_K[keep] = np.searchsorted(ukeys, rows[keep].astype(np.int64) * n_free + cols[keep])
    scatter_r = np.where(fe >= 0, fe, n_free).ravel().astype(np.int64)
    indptr = np.searchsorted(prow, np.arange(n_free + 1)).astype(np.int32)
    lower = pcol <= prow  # CSR lower triangle read as CSC = the upper triangle (symmetric)
    return Pattern(
        n_free=n_free,
        nnz=nnz,
        indptr=indptr,
        indices=pcol.astype(np.int32),
        scatter_r=scatter_r,
        scatter_K=scatter_K,
        upper_data=np.flatnonzero(lower),
        upper_indices=pcol[lower].astype(np.int32),
        upper_indptr=np.searchsorted(prow[lower], np.arange(n_free + 1)).astype(np.int32),
        keys=ukeys,
    )


class PatternAccess:
    """The tangent's pattern as the solver (``sim.fe.solver.Body``) reads it, for a
    discretisation (2D or 3D) holding its ``Pattern`` as ``self.pattern``."""

    pattern: Pattern

    def pattern_position(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Where each free-dof pair sits in the tangent's data array (``Pattern.position``)."""
        return self.pattern.position(rows, cols)

    def pattern_matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """The free-dof tangent as a CSC matrix (``Pattern.matrix``)."""
        return self.pattern.matrix(data)

    def upper_matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """The upper triangle of the tangent as a CSC matrix, for the LDL^T factorisation."""
        return self.pattern.upper(data)
