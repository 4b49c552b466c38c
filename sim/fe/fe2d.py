"""Total-Lagrangian P2 plane-strain discretisation with a lean, vectorised assembly.

The P2 basis (shape-function gradients and quadrature weights on the reference configuration)
and the degree-of-freedom map are scikit-fem's, computed by ``sim.geometry._p2`` without importing
it (equal bit for bit; ``skfem_basis`` gives scikit-fem's own). The Newton loop then needs the
residual and the tangent thousands of times per design, so they are assembled here directly from
those arrays: one batched evaluation of the constitutive law per layer, element vectors and matrices
from a few batched ``matmul`` calls, and a scatter into a CSR pattern that is built once
(``np.bincount`` into fixed positions). ``tests/test_fe.py`` checks this assembly against
scikit-fem's own ``BilinearForm``/``LinearForm`` assembly of the same weak form and against finite
differences.

Array conventions: nodal displacements ``u`` have shape (n_nodes, 2); the global dof of node ``i``
and component ``c`` is ``2 * i + c``. Constrained dofs are left out of the free-dof system and
keep the values they hold in ``u``: zero for the fingertip (the bonded base, the symmetry axis),
prescribed values in the patch tests.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import FingertipMesh
from ..geometry._p2 import P2Basis, TriMesh
from ._constitutive import LayerState, initial_states, layer_stresses
from ._pattern import PatternAccess, build_pattern

if TYPE_CHECKING:
    from skfem import Basis

    from ..materials import Material

__all__ = ["Discretization", "LayerState"]

INTORDER = 2  # 3-point rule: exact for the P2 stiffness in small strain, no spurious modes


@dataclass
class Evaluation:
    """Residual (free dofs) at one displacement state, with the tangent assembled on demand.

    ``tangent()`` returns the CSR data of the stiffness in the fixed pattern; it is assembled
    the first time it is asked for (line-search trials that are rejected never pay for it).
    """

    residual: np.ndarray
    _tangent_args: tuple | None
    states: list[LayerState]
    ok: bool = True
    min_J: float = field(default=1.0)
    _assemble: Callable | None = None
    _data: np.ndarray | None = None

    def tangent(self) -> np.ndarray:
        if self._data is None:
            if self._tangent_args is None or self._assemble is None:
                raise ValueError("this evaluation was made without tangent=True")
            self._data = self._assemble(*self._tangent_args)
        return self._data


class Discretization(PatternAccess):
    """P2 triangles on a ``FingertipMesh`` with one material per layer.

    Elements are reordered so that each layer is a contiguous slice.
    """

    dim = 2
    #: the material tangent is computed with the stress, in the same pass (full Newton uses it
    #: at every iteration); ``sim.fe.fe3d`` computes it on demand
    lazy_tangent = False
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
        # shape-function gradients (6, 2, n_el, n_q) and weights (n_el, n_q)
        self.dN = basis.grads
        self._dN0 = np.ascontiguousarray(self.dN[:, 0].transpose(1, 2, 0))  # (e, q, a)
        self._dN1 = np.ascontiguousarray(self.dN[:, 1].transpose(1, 2, 0))
        self._dN01 = np.concatenate([self._dN0, self._dN1], axis=1)  # (e, 2q, a)
        ne, nq = self._dN0.shape[:2]
        # (e, a, J q): F and the residual as batched matmuls (einsum is ~5x slower here)
        self._dNm = np.ascontiguousarray(self.dN.transpose(2, 0, 1, 3).reshape(ne, 6, 2 * nq))
        self._buffers = {
            "B": np.empty((ne, nq, 3, 6, 2)),
            "DB": np.empty((ne, nq, 3, 12)),
            "Ke": np.empty((ne, 12, 12)),
            "left": np.empty((ne, 2 * nq, 6)),
            "G": np.empty((ne, 6, 6)),
        }
        self.w = basis.dx
        self.edofs_scalar = basis.element_dofs.T.copy()  # (n_el, 6)
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

    # ------------------------------------------------------------------ kinematics
    def deformation_gradient(self, u: np.ndarray) -> np.ndarray:
        """F with shape (2, 2, n_el, n_q) for nodal displacements u (n_nodes, 2)."""
        ue = u[self.edofs_scalar]  # (n_el, 6, 2)
        F = np.matmul(ue.transpose(0, 2, 1), self._dNm)  # (e, i, J q)
        F = F.reshape(self.n_el, 2, 2, self.n_q).transpose(1, 2, 0, 3)
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        return F

    # ------------------------------------------------------------------ assembly
    def evaluate(
        self,
        u: np.ndarray,
        states: list[LayerState],
        dt_s: float,
        tangent: bool = True,
        frozen_history: bool = False,
    ) -> Evaluation:
        """Internal-force residual (free dofs), tangent data and trial history at ``u``.

        ``states`` is the history committed at the start of the step and ``dt_s`` the step size.
        With ``frozen_history`` the Prony internal stresses keep their committed values
        (S = g_inf S0(u) + sum g_i H_i, plus the bulk terms when shear and bulk relax apart):
        used to re-equilibrate after a cycle jump.
        """
        with np.errstate(all="ignore"):
            F = self.deformation_gradient(u)
            J = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
        min_J = float(J.min())
        if not min_J > 1e-8:  # also catches NaN from an overflowing trial
            return Evaluation(np.empty(0), None, states, ok=False, min_J=min_J)
        C = np.empty((3, self.n_el, self.n_q))
        C[0] = F[0, 0] ** 2 + F[1, 0] ** 2
        C[1] = F[0, 1] ** 2 + F[1, 1] ** 2
        C[2] = F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1]
        S, D, new_states = layer_stresses(
            self.materials, self.slices, C, states, dt_s, tangent, frozen_history
        )
        if not np.all(np.isfinite(S)) or (tangent and not np.all(np.isfinite(D))):
            return Evaluation(np.empty(0), None, states, ok=False, min_J=min_J)
        w = self.w
        # first Piola-Kirchhoff P = F S  (2x2), residual r_ai = sum_q w P_iL dN_aL
        P00 = F[0, 0] * S[0] + F[0, 1] * S[2]
        P01 = F[0, 0] * S[2] + F[0, 1] * S[1]
        P10 = F[1, 0] * S[0] + F[1, 1] * S[2]
        P11 = F[1, 0] * S[2] + F[1, 1] * S[1]
        Pw = np.empty((self.n_el, 2, self.n_q, 2))  # (e, L, q, i)
        np.multiply(P00, w, out=Pw[:, 0, :, 0])
        np.multiply(P01, w, out=Pw[:, 1, :, 0])
        np.multiply(P10, w, out=Pw[:, 0, :, 1])
        np.multiply(P11, w, out=Pw[:, 1, :, 1])
        re = np.matmul(self._dNm, Pw.reshape(self.n_el, 2 * self.n_q, 2)).reshape(-1)  # (e, a, i)
        residual = np.bincount(self.scatter_r, weights=re, minlength=self.n_free + 1)[:-1]
        args = (F, S, D) if tangent else None
        return Evaluation(residual, args, new_states, ok=True, min_J=min_J, _assemble=self._tangent)

    def _tangent(self, F: np.ndarray, S: np.ndarray, D: np.ndarray) -> np.ndarray:
        """Element stiffness (material + geometric) scattered into the fixed CSR pattern.

        The large temporaries live in buffers allocated once: fresh arrays of this size would
        be new pages from the OS on every call, which costs as much as the arithmetic."""
        w = self.w
        ne, nq = self.n_el, self.n_q
        dN0, dN1 = self._dN0, self._dN1  # (e, q, a), contiguous
        buf = self._buffers
        # B[e, q, v, a, i]: Voigt strain variation of node a, component i
        B = buf["B"]
        F00, F01 = F[0, 0][:, :, None], F[0, 1][:, :, None]
        F10, F11 = F[1, 0][:, :, None], F[1, 1][:, :, None]
        np.multiply(F00, dN0, out=B[:, :, 0, :, 0])
        np.multiply(F10, dN0, out=B[:, :, 0, :, 1])
        np.multiply(F01, dN1, out=B[:, :, 1, :, 0])
        np.multiply(F11, dN1, out=B[:, :, 1, :, 1])
        B[:, :, 2, :, 0] = F00 * dN1 + F01 * dN0
        B[:, :, 2, :, 1] = F10 * dN1 + F11 * dN0
        B4 = B.reshape(ne, nq, 3, 12)
        Dw = (D * w).transpose(2, 3, 0, 1)  # (e, q, 3, 3)
        DB = np.matmul(Dw, B4, out=buf["DB"])
        Ke = np.matmul(
            B.reshape(ne, 3 * nq, 12).transpose(0, 2, 1), DB.reshape(ne, 3 * nq, 12), out=buf["Ke"]
        )
        # geometric stiffness  G_ab = sum_q w dN_aJ S_JL dN_bL, on both components
        Sw = S * w
        left = buf["left"]  # (e, 2q, a)
        np.multiply(Sw[0][:, :, None], dN0, out=left[:, :nq])
        left[:, :nq] += Sw[2][:, :, None] * dN1
        np.multiply(Sw[2][:, :, None], dN0, out=left[:, nq:])
        left[:, nq:] += Sw[1][:, :, None] * dN1
        G = np.matmul(left.transpose(0, 2, 1), self._dN01, out=buf["G"])
        Ke4 = Ke.reshape(ne, 6, 2, 6, 2)
        Ke4[:, :, 0, :, 0] += G
        Ke4[:, :, 1, :, 1] += G
        return np.bincount(self.scatter_K, weights=Ke.reshape(-1), minlength=self.nnz + 1)[:-1]
