"""Compiled assembly kernels of the total-Lagrangian solid, for any dimension and element.

One set of loops serves the 2D plane-strain triangles and the 3D hexahedra alike: a kernel
sees only the element connectivity, the shape-function gradients at the quadrature points and
the constitutive response there. With ``d`` the dimension, ``A`` nodes per element, ``Q``
quadrature points per element and ``nv = d (d + 1) / 2`` Voigt components:

* ``conn`` (E, A): the element's nodes; ``dN`` (E, Q, A, d): ``dN_a/dX_J`` at each point;
  ``w`` (E, Q): quadrature weight times the reference Jacobian (volume or area measure);
* ``u`` (n_nodes, d): nodal displacements; ``F`` (d, d, E, Q): ``F_iJ = delta_iJ + u_ai dN_aJ``;
* ``S`` (nv, E, Q): second Piola-Kirchhoff stress and ``D`` (nv, nv, E, Q) its tangent
  ``dS_v = D_vw dE_w`` (engineering shear), in the Voigt order ``VOIGT[d]`` (pairs (I, J)):
  ``[11, 22, 12]`` in 2D, ``[11, 22, 33, 12, 23, 13]`` in 3D, as ``sim.materials`` gives them;
* local dof ``a d + i`` (node ``a``, component ``i``); ``scatter_r`` (E A d) maps it to a free
  dof or to the sentinel ``n_free``; ``scatter_K`` (E (A d)^2) maps an element-matrix entry to
  its position in the tangent's data array or to the sentinel ``nnz``. The outputs carry one
  extra slot for the sentinels, dropped by the caller.

The weak form (Bonet & Wood, *Nonlinear Continuum Mechanics for Finite Element Analysis*,
2nd ed., ch. 8): residual ``r_ai = sum_q w P_iJ dN_aJ`` with ``P = F S``; tangent
``K_aibk = sum_q w (B_vai D_vw B_wbk + delta_ik dN_aJ S_JL dN_bL)`` where
``B_vai = F_iI dN_aJ + F_iJ dN_aI`` for a shear pair ``v = (I, J)``, ``I != J``, and
``F_iI dN_aI`` for a normal pair (the variation of the Green-Lagrange strain).

The loops run in a fixed order: the same inputs give the same bits whatever else runs.
Compiled on first use and cached on disk by numba (``cache=True``). Each public kernel hands
the dimension to its loops as the constant 2 or 3, so that they are compiled with fixed trip
counts: unrolled by the compiler, the same arithmetic in the same order (the same bits) in a
fraction of the time of loops over ``d`` read from the arrays' shapes (docs/fe_speed.md,
"Kernels compiled per dimension").
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = [
    "VOIGT",
    "deformation_gradient",
    "internal_forces",
    "right_cauchy_green",
    "stiffness",
]

#: Voigt pairs (I, J) by dimension, in the order of ``sim.materials``.
VOIGT = {
    2: np.array([[0, 0], [1, 1], [0, 1]], dtype=np.int64),
    3: np.array([[0, 0], [1, 1], [2, 2], [0, 1], [1, 2], [0, 2]], dtype=np.int64),
}


@nb.njit(cache=True)
def deformation_gradient(u: np.ndarray, conn: np.ndarray, dN: np.ndarray) -> np.ndarray:
    """``F`` (d, d, E, Q) for nodal displacements ``u`` (n_nodes, d)."""
    if dN.shape[3] == 3:
        return _deformation_gradient(u, conn, dN, 3)
    return _deformation_gradient(u, conn, dN, 2)


@nb.njit(cache=True)
def _deformation_gradient(u: np.ndarray, conn: np.ndarray, dN: np.ndarray, d: int) -> np.ndarray:
    E, Q, A, _ = dN.shape
    F = np.empty((d, d, E, Q))
    ue = np.empty((A, d))  # the element's nodal displacements, gathered once for its points
    for e in range(E):
        for a in range(A):
            for i in range(d):
                ue[a, i] = u[conn[e, a], i]
        for q in range(Q):
            for i in range(d):
                for J in range(d):
                    s = 0.0
                    for a in range(A):
                        s += ue[a, i] * dN[e, q, a, J]
                    F[i, J, e, q] = s + 1.0 if i == J else s
    return F


@nb.njit(cache=True)
def right_cauchy_green(F: np.ndarray, voigt: np.ndarray) -> np.ndarray:
    """``C = F^T F`` (nv, E, Q) in the Voigt order ``voigt``."""
    if F.shape[0] == 3:
        return _right_cauchy_green(F, voigt, 3)
    return _right_cauchy_green(F, voigt, 2)


@nb.njit(cache=True)
def _right_cauchy_green(F: np.ndarray, voigt: np.ndarray, d: int) -> np.ndarray:
    _, _, E, Q = F.shape
    nv = voigt.shape[0]
    C = np.empty((nv, E, Q))
    for e in range(E):
        for q in range(Q):
            for v in range(nv):
                II, JJ = voigt[v, 0], voigt[v, 1]
                s = 0.0
                for i in range(d):
                    s += F[i, II, e, q] * F[i, JJ, e, q]
                C[v, e, q] = s
    return C


@nb.njit(cache=True)
def _full_stress(S: np.ndarray, voigt: np.ndarray, e: int, q: int, out: np.ndarray) -> None:
    """The symmetric d x d tensor of the Voigt stress ``S[:, e, q]`` into ``out``."""
    for v in range(voigt.shape[0]):
        II, JJ = voigt[v, 0], voigt[v, 1]
        out[II, JJ] = S[v, e, q]
        out[JJ, II] = S[v, e, q]


@nb.njit(cache=True)
def internal_forces(
    F: np.ndarray,
    S: np.ndarray,
    dN: np.ndarray,
    w: np.ndarray,
    voigt: np.ndarray,
    scatter_r: np.ndarray,
    n_out: int,
) -> np.ndarray:
    """The assembled internal forces ``r_ai = sum_q w P_iJ dN_aJ`` (``n_out`` slots, the last
    one the sentinel of ``scatter_r``)."""
    if dN.shape[3] == 3:
        return _internal_forces(F, S, dN, w, voigt, scatter_r, n_out, 3)
    return _internal_forces(F, S, dN, w, voigt, scatter_r, n_out, 2)


@nb.njit(cache=True)
def _internal_forces(
    F: np.ndarray,
    S: np.ndarray,
    dN: np.ndarray,
    w: np.ndarray,
    voigt: np.ndarray,
    scatter_r: np.ndarray,
    n_out: int,
    d: int,
) -> np.ndarray:
    E, Q, A, _ = dN.shape
    r = np.zeros(n_out)
    Sf = np.empty((d, d))
    P = np.empty((d, d))
    re = np.empty(A * d)
    for e in range(E):
        re[:] = 0.0
        for q in range(Q):
            _full_stress(S, voigt, e, q, Sf)
            for i in range(d):
                for J in range(d):
                    s = 0.0
                    for K in range(d):
                        s += F[i, K, e, q] * Sf[K, J]
                    P[i, J] = s * w[e, q]
            for a in range(A):
                for i in range(d):
                    s = 0.0
                    for J in range(d):
                        s += P[i, J] * dN[e, q, a, J]
                    re[a * d + i] += s
        base = e * A * d
        for p in range(A * d):
            r[scatter_r[base + p]] += re[p]
    return r


@nb.njit(cache=True)
def _first_elasticity(
    F: np.ndarray,
    S: np.ndarray,
    D: np.ndarray,
    voigt: np.ndarray,
    e: int,
    q: int,
    out: np.ndarray,
    Df: np.ndarray,
    X: np.ndarray,
    Sf: np.ndarray,
    d: int,
) -> None:
    """``A_iJkL = F_iI D_IJKL F_kK + delta_ik S_JL`` (= dP_iJ/dF_kL) at point (e, q) into
    ``out`` (d, d, d, d); ``D_IJKL = D[v(I, J), v(K, L)]`` (engineering shear: dS_IJ =
    sum_KL D_IJKL dE_KL over both orders of a shear pair). ``Df``, ``X`` (d, d, d, d) and
    ``Sf`` (d, d): work arrays."""
    nv = voigt.shape[0]
    for v in range(nv):
        II, JJ = voigt[v, 0], voigt[v, 1]
        for x in range(nv):
            KK, LL = voigt[x, 0], voigt[x, 1]
            val = D[v, x, e, q]
            Df[II, JJ, KK, LL] = val
            Df[JJ, II, KK, LL] = val
            Df[II, JJ, LL, KK] = val
            Df[JJ, II, LL, KK] = val
    # X_iJKL = F_iI D_IJKL
    for i in range(d):
        for J in range(d):
            for K in range(d):
                for L in range(d):
                    s = 0.0
                    for II in range(d):
                        s += F[i, II, e, q] * Df[II, J, K, L]
                    X[i, J, K, L] = s
    _full_stress(S, voigt, e, q, Sf)
    for i in range(d):
        for J in range(d):
            for k in range(d):
                for L in range(d):
                    s = 0.0
                    for K in range(d):
                        s += X[i, J, K, L] * F[k, K, e, q]
                    if i == k:
                        s += Sf[J, L]
                    out[i, J, k, L] = s


@nb.njit(cache=True)
def stiffness(
    F: np.ndarray,
    S: np.ndarray,
    D: np.ndarray,
    dN: np.ndarray,
    w: np.ndarray,
    voigt: np.ndarray,
    scatter_K: np.ndarray,
    n_out: int,
) -> np.ndarray:
    """The tangent's data (material and geometric stiffness) in its sparsity pattern
    (``n_out`` slots, the last one the sentinel of ``scatter_K``).

    ``K_aibk = sum_q w dN_aJ A_iJkL dN_bL`` with the first elasticity tensor ``A`` (which
    holds both parts), computed per element as one matrix product: ``T[(a, i, k), (q, L)] =
    w dN_aJ A_iJkL`` times ``N[(q, L), b] = dN_bL``; the product is BLAS's (``np.dot``).
    (While ``d`` was read from the arrays' shapes, building ``T`` took most of the time, not
    the product: hence the constant ``d`` of each dimension, the module's docstring.)"""
    if dN.shape[3] == 3:
        return _stiffness(F, S, D, dN, w, voigt, scatter_K, n_out, 3)
    return _stiffness(F, S, D, dN, w, voigt, scatter_K, n_out, 2)


@nb.njit(cache=True)
def _stiffness(
    F: np.ndarray,
    S: np.ndarray,
    D: np.ndarray,
    dN: np.ndarray,
    w: np.ndarray,
    voigt: np.ndarray,
    scatter_K: np.ndarray,
    n_out: int,
    d: int,
) -> np.ndarray:
    E, Q, A, _ = dN.shape
    data = np.zeros(n_out)
    T = np.empty((A * d * d, Q * d))
    N = np.empty((Q * d, A))
    Aq = np.empty((d, d, d, d))
    Df = np.empty((d, d, d, d))
    X = np.empty((d, d, d, d))
    Sf = np.empty((d, d))
    for e in range(E):
        for q in range(Q):
            _first_elasticity(F, S, D, voigt, e, q, Aq, Df, X, Sf, d)
            wq = w[e, q]
            for a in range(A):
                for i in range(d):
                    for k in range(d):
                        row = (a * d + i) * d + k
                        for L in range(d):
                            s = 0.0
                            for J in range(d):
                                s += dN[e, q, a, J] * Aq[i, J, k, L]
                            T[row, q * d + L] = wq * s
            for L in range(d):
                for b in range(A):
                    N[q * d + L, b] = dN[e, q, b, L]
        Kt = np.dot(T, N)  # (a, i, k) x b
        _scatter_element(data, scatter_K, e, Kt, A, d)
    return data


@nb.njit(cache=True)
def _scatter_element(
    data: np.ndarray, scatter_K: np.ndarray, e: int, Kt: np.ndarray, A: int, d: int
) -> None:
    """Add element ``e``'s matrix ``Kt`` (rows (a, i, k), columns b: ``K[(a, i), (b, k)]``)
    into the tangent's ``data`` at its pattern positions ``scatter_K``."""
    n = A * d
    base = e * n * n
    for a in range(A):
        for i in range(d):
            p = a * d + i
            for b in range(A):
                for k in range(d):
                    data[scatter_K[base + p * n + b * d + k]] += Kt[p * d + k, b]
