"""The locking-free 3D element: Q2 displacements with the volume ratio projected on linear
polynomials per element (Q2/P1), in its displacement-only, energy-consistent form.

Nearly incompressible rubbers (Poisson's ratio 0.49-0.4999) lock in pure-displacement
elements: every quadrature point must keep its own ``J = det F`` near 1, too many constraints
for the displacements, and the element is too stiff. The classic cure for the 27-node
hexahedron is the Q2/P1 pair: the pressure discontinuous and linear in each element, which
satisfies the inf-sup condition (Boffi, Brezzi & Fortin, *Mixed Finite Element Methods and
Applications*, 2013, on the Stokes pairs). Its displacement-only equivalent, for any hyperelastic or
viscoelastic law written in ``C`` (Simo, Taylor & Pister 1985, CMAME 51, 177; the projected
F-bar of Elguedj, Bazilevs, Calo & Hughes 2008, CMAME 197, 2732, in its variational form):

    J̄ = Π J,                     the L2 projection of J on span{1, X, Y, Z} per element,
    F̄ = (J̄ / J)^(1/3) F,         so det F̄ = J̄ and F̄ has F's isochoric part,
    Π_h(u) = Σ_e Σ_q w_q W(C̄_q), C̄ = F̄ᵀ F̄ = θ C,  θ = (J̄ / J)^(2/3).

The constraint on the volume is then enforced at four points' worth per element instead of
27; the pressure modes are the inf-sup stable P1 (unmapped: polynomials in the reference
configuration's coordinates, centred and scaled per element, which keep the optimal rate on
distorted meshes where the mapped ones lose it, Boffi et al.). Because ``Π_h`` is a
potential, the residual is its gradient and the tangent its Hessian: symmetric, as the
solver's LDLᵀ and PARDISO need.

With ``S̄``, ``D̄`` the law's stress and tangent at ``C̄`` (Voigt, engineering shear) and
``P̄ = F̄ S̄``, ``β = P̄ : F̄ / 3`` (``= θ S̄ : C / 3``), ``g = F⁻ᵀ``, and per point

    η_q = Σ_p w_p (β_p / J̄_p) Π_pq,   Π_pq = N(X_p)ᵀ M⁻¹ N(X_q),  M = Σ_q w_q N(X_q) N(X_q)ᵀ,

the residual is the usual ``Σ_q w_q dN_aJ (F S)_iJ`` with the symmetric effective stress

    S = θ S̄ + (J η − β) C⁻¹,

and the tangent, the Hessian of ``Π_h`` through ``F_q`` and the four projection modes, is
``Σ_q w_q Bᵀ A_q B`` (per point, as the pure-displacement kernel, with the 9 x 9 matrix)

    A = Lᵀ Ā L − (φ/3)(P̄ ⊗ g + g ⊗ P̄) + (β/3 + J η) g ⊗ g + (β − J η) G,
    L = φ (I − F ⊗ g / 3),  φ = θ^(1/2),  G_iJkL = g_iL g_kJ,  Ā = ∂P̄/∂F̄,

plus the element's rank-4 coupling of its points through the projection,

    K_J̄ = H M⁻¹ Gᵀ + G M⁻¹ Hᵀ + G M⁻¹ Z M⁻¹ Gᵀ,
    G[:, k] = Σ_q w_q N_k(X_q) Bᵀ (J g)_q,     H[:, k] = Σ_q w_q N_k(X_q) Bᵀ W_FJ̄,q,
    Z = Σ_q w_q W_J̄J̄,q N(X_q) N(X_q)ᵀ,
    W_FJ̄ = Lᵀ Ā c + ((φ/3) P̄ − (β/3) g) / J̄,  W_J̄J̄ = cᵀ Ā c − (2/3) β / J̄²,  c = φ F / (3 J̄).

The kernels are checked against finite differences of the residual, the residual against
finite differences of the energy, and a homogeneous state (``J`` linear, so ``J̄ = J``)
against the pure-displacement element (``tests/test_mixed3d.py``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._kernels import _first_elasticity, _scatter_element

__all__ = ["dilatation_basis", "effective_stress", "project", "stiffness"]


def dilatation_basis(points: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The P1 modes ``N`` (E, Q, 4) = [1, (X - X_c) / h, (Y - Y_c) / h, (Z - Z_c) / h] at the
    quadrature points ``points`` (3, E, Q) of weights ``w`` (E, Q), with ``X_c`` each element's
    centroid and ``h`` the cube root of its volume (so that ``M`` is well conditioned whatever
    the element's size), and the inverse Gram matrices ``M⁻¹`` (E, 4, 4),
    ``M = Σ_q w_q N N^T``."""
    vol = w.sum(axis=1)  # (E,)
    centroid = np.einsum("ieq,eq->ie", points, w) / vol  # (3, E)
    h = np.cbrt(vol)
    N = np.empty((*w.shape, 4))
    N[..., 0] = 1.0
    N[..., 1:] = np.moveaxis((points - centroid[:, :, None]) / h[None, :, None], 0, -1)
    M = np.einsum("eqk,eq,eql->ekl", N, w, N)
    return np.ascontiguousarray(N), np.ascontiguousarray(np.linalg.inv(M))


@nb.njit(cache=True)
def _project_element(
    f: np.ndarray, e: int, w: np.ndarray, N: np.ndarray, Minv: np.ndarray, out: np.ndarray
) -> None:
    """The L2 projection of element ``e``'s point values ``f`` (E, Q) on its modes, into
    ``out[e]``: ``N(X_q)ᵀ M⁻¹ Σ_r w_r N(X_r) f_r``."""
    Q = f.shape[1]
    b = np.zeros(4)
    for q in range(Q):
        for k in range(4):
            b[k] += w[e, q] * N[e, q, k] * f[e, q]
    alpha = np.empty(4)
    for k in range(4):
        s = 0.0
        for m in range(4):
            s += Minv[e, k, m] * b[m]
        alpha[k] = s
    for q in range(Q):
        s = 0.0
        for k in range(4):
            s += N[e, q, k] * alpha[k]
        out[e, q] = s


@nb.njit(cache=True)
def project(J: np.ndarray, w: np.ndarray, N: np.ndarray, Minv: np.ndarray) -> np.ndarray:
    """``J̄`` (E, Q): the L2 projection of ``J`` (E, Q) on the modes ``N`` per element."""
    out = np.empty(J.shape)
    for e in range(J.shape[0]):
        _project_element(J, e, w, N, Minv, out)
    return out


@nb.njit(cache=True)
def effective_stress(
    C: np.ndarray,
    J: np.ndarray,
    Jbar: np.ndarray,
    theta: np.ndarray,
    Sbar: np.ndarray,
    w: np.ndarray,
    N: np.ndarray,
    Minv: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(S, β, η)``: the effective stress (6, E, Q) whose usual assembly is the residual, and
    the point scalars the tangent needs (module docstring), from ``C`` (6, E, Q) in the 3D
    Voigt order, ``J``, ``J̄``, ``θ = (J̄ / J)^(2/3)`` (E, Q) and the law's stress ``S̄``
    (6, E, Q) at ``C̄ = θ C``."""
    _, E, Q = C.shape
    S = np.empty((6, E, Q))
    beta = np.empty((E, Q))
    load = np.empty((E, Q))  # β / J̄, whose projection is η
    eta = np.empty((E, Q))
    for e in range(E):
        for q in range(Q):
            sc = 0.0  # S̄ : C, the shear pairs twice
            for v in range(6):
                sc += Sbar[v, e, q] * C[v, e, q] * (1.0 if v < 3 else 2.0)
            beta[e, q] = theta[e, q] * sc / 3.0
            load[e, q] = beta[e, q] / Jbar[e, q]
        _project_element(load, e, w, N, Minv, eta)
        for q in range(Q):
            coef = J[e, q] * eta[e, q] - beta[e, q]
            c11, c22, c33 = C[0, e, q], C[1, e, q], C[2, e, q]
            c12, c23, c13 = C[3, e, q], C[4, e, q], C[5, e, q]
            detC = J[e, q] * J[e, q]
            # C⁻¹ = adj(C) / det C, in the order [11, 22, 33, 12, 23, 13]
            inv = (
                (c22 * c33 - c23 * c23) / detC,
                (c11 * c33 - c13 * c13) / detC,
                (c11 * c22 - c12 * c12) / detC,
                (c13 * c23 - c12 * c33) / detC,
                (c12 * c13 - c11 * c23) / detC,
                (c12 * c23 - c13 * c22) / detC,
            )
            for v in range(6):
                S[v, e, q] = theta[e, q] * Sbar[v, e, q] + coef * inv[v]
    return S, beta, eta


@nb.njit(cache=True)
def stiffness(
    F: np.ndarray,
    J: np.ndarray,
    Jbar: np.ndarray,
    Sbar: np.ndarray,
    Dbar: np.ndarray,
    beta: np.ndarray,
    eta: np.ndarray,
    dN: np.ndarray,
    w: np.ndarray,
    N: np.ndarray,
    Minv: np.ndarray,
    voigt: np.ndarray,
    scatter_K: np.ndarray,
    n_out: int,
) -> np.ndarray:
    """The tangent's data (``n_out`` slots, the last one the sentinel of ``scatter_K``): the
    Hessian of the projected energy (module docstring), from the true ``F`` (3, 3, E, Q),
    ``J``, ``J̄``, the law's ``S̄``, ``D̄`` at ``C̄`` and ``β``, ``η`` of ``effective_stress``."""
    d = 3
    E, Q, A, _ = dN.shape
    n = A * d
    data = np.zeros(n_out)
    T = np.empty((A * d * d, Q * d))
    Nb = np.empty((Q * d, A))
    Aq = np.empty((d, d, d, d))
    Df = np.empty((d, d, d, d))
    Xw = np.empty((d, d, d, d))
    Sf = np.empty((d, d))
    Fbar = np.empty((d, d, 1, 1))
    Sq = np.empty((6, 1, 1))
    Dq = np.empty((6, 6, 1, 1))
    Abar = np.empty((9, 9))
    Am = np.empty((9, 9))
    v9 = np.empty(9)
    g = np.empty(9)
    Fv = np.empty(9)
    Pb = np.empty(9)
    WFJ = np.empty(9)
    G = np.empty((n, 4))
    H = np.empty((n, 4))
    Z = np.empty((4, 4))
    Mi = np.empty((4, 4))
    for e in range(E):
        G[:] = 0.0
        H[:] = 0.0
        Z[:] = 0.0
        for q in range(Q):
            Jq, Jb, bq, eq = J[e, q], Jbar[e, q], beta[e, q], eta[e, q]
            phi = (Jb / Jq) ** (1.0 / 3.0)
            for i in range(d):
                for K in range(d):
                    Fv[i * 3 + K] = F[i, K, e, q]
                    Fbar[i, K, 0, 0] = phi * F[i, K, e, q]
            for v in range(6):
                Sq[v, 0, 0] = Sbar[v, e, q]
                for x in range(6):
                    Dq[v, x, 0, 0] = Dbar[v, x, e, q]
            _first_elasticity(Fbar, Sq, Dq, voigt, 0, 0, Aq, Df, Xw, Sf, d)
            for i in range(d):
                for K in range(d):
                    for k in range(d):
                        for M in range(d):
                            Abar[i * 3 + K, k * 3 + M] = Aq[i, K, k, M]
            # g = F^-T by cofactors: g_iJ = cof(F)_iJ / J
            f = Fv
            g[0] = (f[4] * f[8] - f[5] * f[7]) / Jq
            g[1] = (f[5] * f[6] - f[3] * f[8]) / Jq
            g[2] = (f[3] * f[7] - f[4] * f[6]) / Jq
            g[3] = (f[2] * f[7] - f[1] * f[8]) / Jq
            g[4] = (f[0] * f[8] - f[2] * f[6]) / Jq
            g[5] = (f[1] * f[6] - f[0] * f[7]) / Jq
            g[6] = (f[1] * f[5] - f[2] * f[4]) / Jq
            g[7] = (f[2] * f[3] - f[0] * f[5]) / Jq
            g[8] = (f[0] * f[4] - f[1] * f[3]) / Jq
            for i in range(d):  # P̄ = F̄ S̄ (Sf holds S̄ in full after _first_elasticity)
                for K in range(d):
                    s = 0.0
                    for M in range(d):
                        s += Fbar[i, M, 0, 0] * Sf[M, K]
                    Pb[i * 3 + K] = s
            # L = phi (I - F (x) g / 3) is the identity plus a rank one: with v = Abar F
            # (Abar is symmetric), L^T Abar L = phi^2 (Abar - (v g + g v) / 3 + (F.v) g g / 9)
            # and Abar c = phi v / (3 Jbar), in O(81) instead of two 9 x 9 products
            fv = 0.0
            for m in range(9):
                s = 0.0
                for p in range(9):
                    s += Abar[m, p] * Fv[p]
                v9[m] = s
                fv += Fv[m] * s
            p2 = phi * phi
            for m in range(9):
                for p in range(9):
                    Am[m, p] = p2 * (
                        Abar[m, p] - (v9[m] * g[p] + g[m] * v9[p]) / 3.0 + fv * g[m] * g[p] / 9.0
                    )
            kc = phi / (3.0 * Jb)  # c = kc F
            fac = kc * fv  # F . Abar c
            wjj = kc * kc * fv - 2.0 / 3.0 * bq / (Jb * Jb)
            for m in range(9):
                # L^T Abar c = phi (Abar c - g (F . Abar c) / 3)
                WFJ[m] = (
                    phi * (kc * v9[m] - g[m] * fac / 3.0)
                    + (phi / 3.0 * Pb[m] - bq / 3.0 * g[m]) / Jb
                )
            je = Jq * eq
            for i in range(d):
                for K in range(d):
                    m = i * 3 + K
                    for k in range(d):
                        for M in range(d):
                            p = k * 3 + M
                            Am[m, p] += (
                                -phi / 3.0 * (Pb[m] * g[p] + g[m] * Pb[p])
                                + (bq / 3.0 + je) * g[m] * g[p]
                                + (bq - je) * g[i * 3 + M] * g[k * 3 + K]
                            )
            wq = w[e, q]
            for a in range(A):
                for i in range(d):
                    for k in range(d):
                        row = (a * d + i) * d + k
                        for M in range(d):
                            s = 0.0
                            for K in range(d):
                                s += dN[e, q, a, K] * Am[i * 3 + K, k * 3 + M]
                            T[row, q * d + M] = wq * s
                    sg = 0.0
                    sh = 0.0
                    for K in range(d):
                        sg += dN[e, q, a, K] * g[i * 3 + K]
                        sh += dN[e, q, a, K] * WFJ[i * 3 + K]
                    for k in range(4):
                        G[a * d + i, k] += wq * N[e, q, k] * Jq * sg
                        H[a * d + i, k] += wq * N[e, q, k] * sh
            for M in range(d):
                for b in range(A):
                    Nb[q * d + M, b] = dN[e, q, b, M]
            for k in range(4):
                for m in range(4):
                    Z[k, m] += wq * wjj * N[e, q, k] * N[e, q, m]
        Kt = np.dot(T, Nb)  # (a, i, k) x b
        Mi[:, :] = Minv[e]
        GM = np.dot(G, Mi)
        HG = np.dot(H, GM.T)
        Klr = HG + HG.T + np.dot(np.dot(GM, Z), GM.T)  # (a, i) x (b, k)
        for a in range(A):  # into the kernel's layout (a, i, k) x b
            for i in range(d):
                for b in range(A):
                    for k in range(d):
                        Kt[(a * d + i) * d + k, b] += Klr[a * d + i, b * d + k]
        _scatter_element(data, scatter_K, e, Kt, A, d)
    return data
