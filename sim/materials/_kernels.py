"""Compiled stress and tangent of every hyperelastic law, one loop over the points.

numpy spends most of a law's time in the overhead of some hundred small array operations; a
compiled loop does a few arithmetic operations per point (docs/fe_speed.md, "Compiled material
laws"). The formulas are those of the laws' modules, which keep the energies (numpy: only the
tests and the fitting read them) and the derivations in their docstrings.

Outputs: ``S`` (P, nv, n) and ``D`` (P, nv, nv, n), ``P = 2`` for the ``[iso, vol]`` split of a
decoupled law, ``P = 1`` for the whole law (the parts summed); ``C`` (nv, n), nv = 3
(``[C11, C22, C12]``, ``C33 = 1``) or 6 (``[C11, C22, C33, C12, C23, C13]``). ``D`` in Voigt
form with engineering shear, exactly symmetric. Without ``tangent`` ``D`` is not touched (a
placeholder will do; ``sim.materials._law.run_kernel``).

One module for all the laws: numba's disk cache (``cache=True``) notices a change of the file
that holds a kernel, not of the helpers inlined into it from another file, so the shared
helpers and the kernels that inline them live together. Compiled on first use and cached on
disk; imported lazily so that ``import sim`` does not load numba.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["hyperfoam2", "hyperfoam3", "invariant2", "invariant3", "ogden2", "ogden3"]


# --------------------------------------------------------------------------------------------
# Shared pieces: the chain rules of :mod:`sim.materials._law` (plane strain, ``W(t, d)``) and
# :mod:`sim.materials._law3` (3D: the cofactor, the invariant terms and the spectral tangent),
# one point at a time, inlined into the laws' loops. Each writes into ``S[p, :, q]`` and
# ``D[p, :, :, q]`` (part ``p`` of point ``q``), with ``=`` or, given ``add``, ``+=`` (the whole
# law adds its volumetric part onto its isochoric one; the split law keeps them on p = 0, 1).


#: Voigt order of the 3D tensors (``sim.materials._law3.VOIGT3``) and the spectral pairs
#: (``sim.materials._law3.PAIRS``), as the loops below read them.
_VI = (0, 1, 2, 0, 1, 0)
_VJ = (0, 1, 2, 1, 2, 2)
_PA = (0, 1, 0)
_PB = (1, 2, 2)


@nb.njit(cache=True, inline="always")
def set_or_add(A, index, value, add):
    if add:
        A[index] += value
    else:
        A[index] = value


@nb.njit(cache=True, inline="always")
def td_stress(C11, C22, C12, W_t, W_d, S, p, q, add):
    """``S = 2 (W_t I + W_d cof C)`` (plane strain)."""
    set_or_add(S, (p, 0, q), 2.0 * (W_t + W_d * C22), add)
    set_or_add(S, (p, 1, q), 2.0 * (W_t + W_d * C11), add)
    set_or_add(S, (p, 2, q), -2.0 * W_d * C12, add)


@nb.njit(cache=True, inline="always")
def td_tangent(C11, C22, C12, W_d, W_tt, W_td, W_dd, D, p, q, add):
    """The plane-strain tangent of ``W(t, d)``: ``4 (W_tt I(x)I + W_td (I(x)cof + cof(x)I) +
    W_dd cof(x)cof) + 4 W_d dcof/dC`` (:func:`sim.materials._law.td_tangent`)."""
    d00 = 4.0 * (W_tt + C22 * (2.0 * W_td + W_dd * C22))
    d11 = 4.0 * (W_tt + C11 * (2.0 * W_td + W_dd * C11))
    d01 = 4.0 * (W_tt + W_td * (C11 + C22) + W_dd * C11 * C22 + W_d)
    d02 = -4.0 * C12 * (W_td + W_dd * C22)
    d12 = -4.0 * C12 * (W_td + W_dd * C11)
    d22 = 4.0 * W_dd * C12 * C12 - 2.0 * W_d
    set_or_add(D, (p, 0, 0, q), d00, add)
    set_or_add(D, (p, 1, 1, q), d11, add)
    set_or_add(D, (p, 2, 2, q), d22, add)
    set_or_add(D, (p, 0, 1, q), d01, add)
    set_or_add(D, (p, 1, 0, q), d01, add)
    set_or_add(D, (p, 0, 2, q), d02, add)
    set_or_add(D, (p, 2, 0, q), d02, add)
    set_or_add(D, (p, 1, 2, q), d12, add)
    set_or_add(D, (p, 2, 1, q), d12, add)


@nb.njit(cache=True, inline="always")
def eigen2(C11, C22, C12):
    """The in-plane eigenvalues ``c1 >= c2`` of ``C``, ``det C`` and ``cos 2theta``, ``sin
    2theta`` of the principal direction ``N_1`` (``N_1 = e_1`` when ``c1 = c2``); ``c2 = det /
    c1`` without cancellation, so that ``ln c1 + ln c2 = ln det``."""
    half_diff = 0.5 * (C11 - C22)
    r = math.hypot(half_diff, C12)
    det = C11 * C22 - C12 * C12
    c1 = 0.5 * (C11 + C22) + r
    if r > 0.0:
        return c1, det / c1, det, r, half_diff / r, C12 / r
    return c1, det / c1, det, r, 1.0, 0.0


@nb.njit(cache=True, inline="always")
def spectral_stress2(f1, f2, cos2, sin2, S, q):
    """``S[0, :, q] = 2 (f1 N1 (x) N1 + f2 N2 (x) N2)`` (plane strain, Voigt)."""
    mean, diff = f1 + f2, f1 - f2
    S[0, 0, q] = mean + diff * cos2
    S[0, 1, q] = mean - diff * cos2
    S[0, 2, q] = diff * sin2


@nb.njit(cache=True, inline="always")
def cofactor(C, q, G3):
    """``cof C`` of point ``q`` into ``G3`` (Voigt, 6) and ``(I1, I2, I3)``."""
    C11, C22, C33, C12, C23, C13 = C[0, q], C[1, q], C[2, q], C[3, q], C[4, q], C[5, q]
    G3[0] = C22 * C33 - C23 * C23
    G3[1] = C11 * C33 - C13 * C13
    G3[2] = C11 * C22 - C12 * C12
    G3[3] = C13 * C23 - C12 * C33
    G3[4] = C12 * C13 - C11 * C23
    G3[5] = C12 * C23 - C13 * C22
    I1 = C11 + C22 + C33
    I2 = G3[0] + G3[1] + G3[2]
    I3 = C11 * G3[0] + C12 * G3[3] + C13 * G3[5]
    return I1, I2, I3


@nb.njit(cache=True, inline="always")
def _add_pair(D, p, q, i, j, value):
    D[p, i, j, q] += value
    D[p, j, i, q] += value


@nb.njit(cache=True, inline="always")
def add_dcof(C, q, coef, D, p):
    """Add ``coef * d(cof C)/dE`` (Voigt, engineering shear; ``dC = 2 dE``) to
    ``D[p, :, :, q]`` (:func:`sim.materials._law3._add_dcof`)."""
    C11, C22, C33, C12, C23, C13 = C[0, q], C[1, q], C[2, q], C[3, q], C[4, q], C[5, q]
    two = 2.0 * coef
    _add_pair(D, p, q, 0, 1, two * C33)
    _add_pair(D, p, q, 0, 2, two * C22)
    _add_pair(D, p, q, 1, 2, two * C11)
    _add_pair(D, p, q, 0, 4, -two * C23)
    _add_pair(D, p, q, 1, 5, -two * C13)
    _add_pair(D, p, q, 2, 3, -two * C12)
    _add_pair(D, p, q, 3, 4, coef * C13)
    _add_pair(D, p, q, 3, 5, coef * C23)
    _add_pair(D, p, q, 4, 5, coef * C12)
    D[p, 3, 3, q] -= coef * C33
    D[p, 4, 4, q] -= coef * C11
    D[p, 5, 5, q] -= coef * C22


@nb.njit(cache=True, inline="always")
def volumetric3(C, q, G3, W3, W33, S, D, p, add, tangent):
    """A function of ``I3`` alone: ``S = 2 W3 cof C``, ``D = 4 W33 cof (x) cof + 4 W3
    dcof/dC`` (``W3 = dW/dI3``, ``W33 = d2W/dI3^2``)."""
    for k in range(6):
        set_or_add(S, (p, k, q), 2.0 * W3 * G3[k], add)
    if tangent:
        for i in range(6):
            for j in range(i, 6):
                value = 4.0 * W33 * G3[i] * G3[j]  # the same value on both sides: symmetric
                set_or_add(D, (p, i, j, q), value, add)
                if j != i:
                    set_or_add(D, (p, j, i, q), value, add)
        add_dcof(C, q, 2.0 * W3, D, p)


@nb.njit(cache=True, inline="always")
def spectral3(N, q, phi, phi2, theta, S, D, p, tangent):
    """The spectral part (=): ``S = 2 sum_a Phi_a M_a`` and ``D = 4 sum_ab Phi_ab M_a (x) M_b +
    2 sum_pairs theta W_ab (x) W_ab`` (:mod:`sim.materials._law3`), ``M_a = N_a (x) N_a``,
    ``W_ab = N_a (x) N_b + N_b (x) N_a``; ``N[a, :, q]`` the unit eigenvector of eigenvalue
    ``a``, ``phi`` (3,), ``phi2`` (3, 3), ``theta`` (3,) by the pairs (0, 1), (1, 2), (0, 2)."""
    for k in range(6):
        i, j = _VI[k], _VJ[k]
        S[p, k, q] = 2.0 * (
            phi[0] * N[0, i, q] * N[0, j, q]
            + phi[1] * N[1, i, q] * N[1, j, q]
            + phi[2] * N[2, i, q] * N[2, j, q]
        )
    if not tangent:
        return
    for k in range(6):
        i, j = _VI[k], _VJ[k]
        m0k = N[0, i, q] * N[0, j, q]
        m1k = N[1, i, q] * N[1, j, q]
        m2k = N[2, i, q] * N[2, j, q]
        for l in range(k, 6):
            r, s = _VI[l], _VJ[l]
            m0l = N[0, r, q] * N[0, s, q]
            m1l = N[1, r, q] * N[1, s, q]
            m2l = N[2, r, q] * N[2, s, q]
            value = 4.0 * (
                m0k * (phi2[0, 0] * m0l + phi2[0, 1] * m1l + phi2[0, 2] * m2l)
                + m1k * (phi2[1, 0] * m0l + phi2[1, 1] * m1l + phi2[1, 2] * m2l)
                + m2k * (phi2[2, 0] * m0l + phi2[2, 1] * m1l + phi2[2, 2] * m2l)
            )
            for t in range(3):
                a, b = _PA[t], _PB[t]
                wk = N[a, i, q] * N[b, j, q] + N[b, i, q] * N[a, j, q]
                wl = N[a, r, q] * N[b, s, q] + N[b, r, q] * N[a, s, q]
                value += 2.0 * theta[t] * wk * wl
            D[p, k, l, q] = value
            D[p, l, k, q] = value


# --------------------------------------------------------------------------------------------
# Invariant laws (sim.materials._invariant). Every invariant law here is one energy with four
# coefficients,
#
#     U = c10 x + c20 x^2 + c30 x^3 + c01 (I2b - 3) + K/2 (J - 1)^2,   x = I1b - 3
#
# (neo-Hookean: ``c10 = mu/2``; Mooney-Rivlin: ``c10``, ``c01``; Yeoh: ``c10``, ``c20``, ``c30``),
# so ``U_a = dU/dI1b = c10 + x (2 c20 + 3 c30 x)``, ``U_aa = 2 c20 + 6 c30 x``, ``U_b = c01``
# and ``U_ab = U_bb = 0``. The chain rules are those of the module docstrings of
# :mod:`sim.materials._law` (plane strain, ``W(t, d)``) and :mod:`sim.materials._law3` (3D,
# ``W(I1, I2, I3)``).


@nb.njit(cache=True)
def invariant2(C, coef, K, split, tangent, S, D):
    """Plane strain: ``S`` (and ``D`` with ``tangent``) of the law with ``coef = (c10, c20,
    c30, c01)`` and bulk modulus ``K`` at ``C`` (3, n); see the module docstring.

    With ``t = C11 + C22``, ``d = C11 C22 - C12^2``: ``I1b = (t + 1) d^(-1/3)``, ``I2b =
    (d + t) d^(-2/3)``, ``J = d^(1/2)``, ``S = 2 (W_t I + W_d cof C)``."""
    c10, c20, c30, c01 = coef[0], coef[1], coef[2], coef[3]
    pv = 1 if split else 0
    for q in range(C.shape[1]):
        C11, C22, C12 = C[0, q], C[1, q], C[2, q]
        t = C11 + C22
        d = C11 * C22 - C12 * C12
        inv_d = 1.0 / d
        J = np.sqrt(d)
        a_t = 1.0 / np.cbrt(d)  # d^(-1/3)
        b_t = a_t * a_t
        a = (t + 1.0) * a_t
        x = a - 3.0
        U_a = c10 + x * (2.0 * c20 + 3.0 * c30 * x)
        U_aa = 2.0 * c20 + 6.0 * c30 * x
        U_J = K * (J - 1.0)
        a_d = -a * inv_d / 3.0
        b_d = b_t * (d - 2.0 * t) * inv_d / 3.0
        J_d = 0.5 * J * inv_d
        W_t = U_a * a_t + c01 * b_t
        W_d_iso = U_a * a_d + c01 * b_d
        W_d_vol = U_J * J_d
        td_stress(C11, C22, C12, W_t, W_d_iso, S, 0, q, False)
        td_stress(C11, C22, C12, 0.0, W_d_vol, S, pv, q, not split)
        if tangent:
            inv_d2 = inv_d * inv_d
            # second derivatives of a = I1b, b = I2b by (t, d); a_tt = b_tt = 0
            a_td = -a_t * inv_d / 3.0
            a_dd = (4.0 / 9.0) * a * inv_d2
            b_td = -(2.0 / 3.0) * b_t * inv_d
            b_dd = b_t * (10.0 * t - 2.0 * d) * inv_d2 / 9.0
            W_tt = U_aa * a_t * a_t
            W_td = U_a * a_td + U_aa * a_t * a_d + c01 * b_td
            W_dd = U_a * a_dd + U_aa * a_d * a_d + c01 * b_dd
            td_tangent(C11, C22, C12, W_d_iso, W_tt, W_td, W_dd, D, 0, q, False)
            W_dd_vol = K * J_d * J_d + U_J * (-0.25 * J * inv_d2)
            td_tangent(C11, C22, C12, W_d_vol, 0.0, 0.0, W_dd_vol, D, pv, q, not split)


@nb.njit(cache=True)
def invariant3(C, coef, K, split, tangent, S, D):
    """3D: ``S`` (and ``D`` with ``tangent``) of the law with ``coef = (c10, c20, c30, c01)``
    and bulk modulus ``K`` at ``C`` (6, n); see the module docstring.

    ``I1b = I3^(-1/3) I1``, ``I2b = I3^(-2/3) I2``, ``J = I3^(1/2)``; ``S = 2 sum_a W_a G_a``
    with ``G1 = I``, ``G2 = I1 I - C``, ``G3 = cof C``, and ``D = 4 sum_ab W_ab G_a (x) G_b + 4 W2
    (I (x) I - Isym) + 4 W3 dcof/dC`` (:mod:`sim.materials._law3`)."""
    c10, c20, c30, c01 = coef[0], coef[1], coef[2], coef[3]
    pv = 1 if split else 0
    G1 = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    G2 = np.empty(6)
    G3 = np.empty(6)
    for q in range(C.shape[1]):
        I1, I2, I3 = cofactor(C, q, G3)
        for k in range(6):
            G2[k] = I1 * G1[k] - C[k, q]
        inv3 = 1.0 / I3
        J = np.sqrt(I3)
        a_1 = 1.0 / np.cbrt(I3)
        b_2 = a_1 * a_1
        a = I1 * a_1
        b = I2 * b_2
        x = a - 3.0
        U_a = c10 + x * (2.0 * c20 + 3.0 * c30 * x)
        U_aa = 2.0 * c20 + 6.0 * c30 * x
        a_3 = -a * inv3 / 3.0
        b_3 = -(2.0 / 3.0) * b * inv3
        W1 = U_a * a_1
        W2 = c01 * b_2
        W3_iso = U_a * a_3 + c01 * b_3
        U_J = K * (J - 1.0)
        J_3 = 0.5 * J * inv3
        for k in range(6):
            S[0, k, q] = 2.0 * (W1 * G1[k] + W2 * G2[k] + W3_iso * G3[k])
        if tangent:
            inv3_2 = inv3 * inv3
            W11 = U_aa * a_1 * a_1
            W13 = U_a * (-a_1 * inv3 / 3.0) + U_aa * a_1 * a_3
            W23 = c01 * (-(2.0 / 3.0) * b_2 * inv3)
            W33 = U_a * ((4.0 / 9.0) * a * inv3_2) + U_aa * a_3 * a_3
            W33 += c01 * ((10.0 / 9.0) * b * inv3_2)
            for i in range(6):
                for j in range(i, 6):
                    value = 4.0 * (
                        W11 * G1[i] * G1[j]
                        + W13 * (G1[i] * G3[j] + G3[i] * G1[j])
                        + W23 * (G2[i] * G3[j] + G3[i] * G2[j])
                        + W33 * G3[i] * G3[j]
                    )
                    D[0, i, j, q] = value
                    D[0, j, i, q] = value
            # 4 W2 (I (x) I - Isym)
            four = 4.0 * W2
            for i in range(3):
                for j in range(3):
                    if i != j:
                        D[0, i, j, q] += four
                D[0, i + 3, i + 3, q] -= 0.5 * four
            add_dcof(C, q, 2.0 * W3_iso, D, 0)  # 4 W3 dcof/dC = 2 W3 dcof/dE
        # K/2 (J - 1)^2: W3 = U_J J_3, W33 = K J_3^2 + U_J J_33, J_33 = -J / (4 I3^2)
        W33_vol = K * J_3 * J_3 + U_J * (-0.25 * J * inv3 * inv3)
        volumetric3(C, q, G3, U_J * J_3, W33_vol, S, D, pv, not split, tangent)


# --------------------------------------------------------------------------------------------
# Ogden (sim.materials._ogden): the formulas of :class:`sim.materials._ogden.Ogden`'s
# docstrings (plane strain: the in-plane eigenvalues in closed form, the divided difference with
# ``sinh`` ratios; 3D: the eigenvalues of the compiled Jacobi solver and the spectral tangent of
# :mod:`sim.materials._law3`). ``k`` and ``a`` hold the terms' ``k = 2 mu / alpha^2`` and
# ``a = alpha / 6``; ``K`` is the bulk modulus of ``K/2 (J - 1)^2``.


@nb.njit(cache=True, inline="always")
def _sinh_ratio(n, d):
    """``sinh(n d) / sinh(d)``, ``n`` at ``d = 0``."""
    if d == 0.0:
        return n
    return math.sinh(n * d) / math.sinh(d)


@nb.njit(cache=True)
def ogden2(C, k, a, K, split, tangent, S, D):
    """Plane strain at ``C`` (3, n) (``c3 = 1``): ``c1 >= c2`` the in-plane eigenvalues, ``s =
    ln c``, ``d = (s1 - s2) / 2``; the isochoric stress ``2 (f1 N1 (x) N1 + f2 N2 (x) N2)`` and
    its spectral tangent, the volumetric part by the ``W(t, d)`` chain rule."""
    pv = 1 if split else 0
    for q in range(C.shape[1]):
        C11, C22, C12 = C[0, q], C[1, q], C[2, q]
        c1, c2, det, r, cos2, sin2 = eigen2(C11, C22, C12)
        s1, s2 = math.log(c1), math.log(c2)
        d = 0.5 * math.log1p(2.0 * r / c2)  # (s1 - s2) / 2 without cancellation
        m = 0.5 * (s1 + s2)
        p1 = p2 = f11 = f22 = f12 = dd = 0.0
        for t in range(k.shape[0]):
            kt, at = k[t], a[t]
            A = math.exp(at * (2.0 * s1 - s2))
            B = math.exp(at * (2.0 * s2 - s1))
            Cc = math.exp(-at * (s1 + s2))
            ka = kt * at
            p1 += ka * (2.0 * A - B - Cc)
            p2 += ka * (2.0 * B - A - Cc)
            if tangent:
                ka2 = ka * at
                # d2 Phi / ds_a ds_b, then to c: Phi_11 = (Phi_s1s1 - Phi_s1) / c1^2, ...
                f11 += ka2 * (4.0 * A + B + Cc) - ka * (2.0 * A - B - Cc)
                f22 += ka2 * (4.0 * B + A + Cc) - ka * (2.0 * B - A - Cc)
                f12 += ka2 * (Cc - 2.0 * A - 2.0 * B)
                ratio = 2.0 * _sinh_ratio(3.0 * at - 1.0, d) + _sinh_ratio(3.0 * at + 1.0, d)
                dd += ka * math.exp(-2.0 * m) * (math.exp(at * m) * ratio + math.exp(-2.0 * at * m))
        spectral_stress2(p1 / c1, p2 / c2, cos2, sin2, S, q)
        J = math.sqrt(det)
        J_d = 0.5 / J
        U_J = K * (J - 1.0)
        W_d = U_J * J_d
        td_stress(C11, C22, C12, 0.0, W_d, S, pv, q, not split)
        if not tangent:
            continue
        f11 /= c1 * c1
        f22 /= c2 * c2
        f12 /= c1 * c2
        # 4 Phi_ab P_a (x) P_b + 2 (2 (f1 - f2) / (c1 - c2)) w (x) w, with P1 = [u, v, h],
        # P2 = [v, u, -h], w = [-sin2, sin2, cos2] (Voigt, engineering shear)
        u, v, h = 0.5 * (1.0 + cos2), 0.5 * (1.0 - cos2), 0.5 * sin2
        P1 = (u, v, h)
        P2 = (v, u, -h)
        w = (-sin2, sin2, cos2)
        F2 = 2.0 * dd
        for i in range(3):
            for j in range(i, 3):
                value = (
                    4.0 * (f11 * (P1[i] * P1[j]) + f22 * (P2[i] * P2[j]))
                    + 4.0 * f12 * (P1[i] * P2[j] + P2[i] * P1[j])
                    + F2 * (w[i] * w[j])
                )
                D[0, i, j, q] = value
                D[0, j, i, q] = value
        W_dd = K * J_d * J_d - U_J * 0.25 * J / (det * det)
        td_tangent(C11, C22, C12, W_d, 0.0, 0.0, W_dd, D, pv, q, not split)


@nb.njit(cache=True)
def ogden3(C, c, N, k, a, K, split, tangent, S, D):
    """3D at ``C`` (6, n) with its eigenvalues ``c`` (3, n) and unit eigenvectors ``N`` (3, 3,
    n) (``sim.materials._eigh3``): with ``b = alpha / 2``, ``e_a = s_a - mean(s)`` and ``E =
    sum_c e^(b e_c)``, ``dU/ds_a = k b (e^(b e_a) - E/3)``, the second derivatives and the
    divided differences ``theta_ab`` of :meth:`sim.materials._ogden.Ogden.evaluate3_split`."""
    pv = 1 if split else 0
    G3 = np.empty(6)
    s = np.empty(3)
    em = np.empty(3)
    dW = np.empty(3)
    d2W = np.empty((3, 3))
    theta = np.empty(3)
    phi = np.empty(3)
    for q in range(C.shape[1]):
        for i in range(3):
            s[i] = math.log(c[i, q])
            dW[i] = 0.0
            theta[i] = 0.0
            for j in range(3):
                d2W[i, j] = 0.0
        s_mean = (s[0] + s[1] + s[2]) / 3.0
        for t in range(k.shape[0]):
            b = 3.0 * a[t]
            kb = k[t] * b
            for i in range(3):
                em[i] = math.expm1(b * (s[i] - s_mean))  # lb^alpha - 1
            em_mean = (em[0] + em[1] + em[2]) / 3.0
            for i in range(3):
                dW[i] += kb * (em[i] - em_mean)
            if tangent:
                kb2 = kb * b
                third = (1.0 + em_mean) / 3.0  # E / 9
                for i in range(3):
                    for j in range(3):
                        delta = (1.0 + em[i]) if i == j else 0.0
                        d2W[i, j] += kb2 * (delta - (2.0 + em[i] + em[j]) / 3.0 + third)
                for p in range(3):
                    ia, ib = (0, 1, 0)[p], (1, 2, 2)[p]
                    sig = 0.5 * (s[ia] + s[ib])
                    dl = 0.5 * (s[ia] - s[ib])
                    u = b * (sig - s_mean)
                    ratio = b if dl == 0.0 else math.sinh(b * dl) / math.tanh(dl)
                    r1 = ratio - 2.0 * math.sinh(0.5 * b * dl) ** 2  # sinh((b-1) dl)/sinh(dl) + 1
                    theta[p] += (
                        kb * math.exp(-2.0 * sig) * (math.exp(u) * r1 - math.expm1(u) + em_mean)
                    )
        for i in range(3):
            phi[i] = dW[i] / c[i, q]
        if tangent:
            for i in range(3):
                d2W[i, i] -= dW[i]
            for i in range(3):
                for j in range(3):
                    d2W[i, j] /= c[i, q] * c[j, q]
        spectral3(N, q, phi, d2W, theta, S, D, 0, tangent)
        _, _, I3 = cofactor(C, q, G3)
        J = math.sqrt(I3)
        J_d = 0.5 / J
        U_J = K * (J - 1.0)
        W_dd = K * J_d * J_d - U_J * 0.25 * J / (I3 * I3)
        volumetric3(C, q, G3, U_J * J_d, W_dd, S, D, pv, not split, tangent)


# --------------------------------------------------------------------------------------------
# Hyperfoam (sim.materials._hyperfoam): the formulas of
# :class:`sim.materials._hyperfoam.Hyperfoam` (``U = sum_a F(c_a) + G(det C)``:
# the spectral part ``f = F'`` with its divided difference from a Taylor series about the mean
# for nearly equal eigenvalues, the volumetric part by the chain rule of ``det C``; plane strain
# with the in-plane eigenvalues in closed form, 3D with those of the compiled Jacobi solver).
# ``mu``, ``alpha`` hold the terms, ``beta = nu / (1 - 2 nu)``; ``P = 1`` (the hyperfoam's
# energy does not split).


#: relative eigenvalue split below which the divided difference is its Taylor series (the
#: value of sim.materials._hyperfoam before it was compiled; the tangent is checked against
#: finite differences on both sides of it: tests/test_materials.py,
#: test_hyperfoam_tangent_on_both_sides_of_the_series_branch)
_SPLIT_TOL = 5e-3


@nb.njit(cache=True, inline="always")
def _exprel(x):
    """``(e^x - 1) / x``, 1 at ``x = 0`` (as ``scipy.special.exprel``)."""
    if abs(x) < 1e-16:
        return 1.0
    return math.expm1(x) / x


@nb.njit(cache=True, inline="always")
def _f(c, mu, alpha):
    """``f(c) = sum (mu/2) s exprel(alpha s / 2) / c`` and ``f'(c)``, ``s = ln c``."""
    s = math.log(c)
    f = df = 0.0
    for t in range(mu.shape[0]):
        a = 0.5 * alpha[t]
        g = 0.5 * s * _exprel(a * s)  # expm1(alpha s / 2) / alpha
        f += mu[t] * g
        df += mu[t] * ((a - 1.0) * g + 0.5)
    return f / c, df / (c * c)


@nb.njit(cache=True, inline="always")
def _divided_difference(c1, c2, f1, f2, mu, alpha):
    """``(f(c1) - f(c2)) / (c1 - c2)``, ``f'`` in the limit, accurate for any split: below a
    relative split of ``_SPLIT_TOL`` the series ``f' + h^2 f'''/6 + h^4 f^(5)/120`` about the
    mean (``f^(n)(c) = mu c^(-1-n) [(a-1)_n g + P_n(a)]``, :class:`Hyperfoam`)."""
    mean = 0.5 * (c1 + c2)
    h = 0.5 * (c1 - c2)
    if not abs(h) <= 0.5 * _SPLIT_TOL * mean:
        return (f1 - f2) / (c1 - c2)
    s = math.log(mean)
    d1 = d3 = d5 = 0.0
    for t in range(mu.shape[0]):
        a = 0.5 * alpha[t]
        g = 0.5 * s * _exprel(a * s)
        k3 = (a - 1.0) * (a - 2.0) * (a - 3.0)
        k5 = k3 * (a - 4.0) * (a - 5.0)
        p3 = 0.5 * (11.0 + a * (-6.0 + a))
        p5 = 0.5 * (274.0 + a * (-225.0 + a * (85.0 + a * (-15.0 + a))))
        d1 += mu[t] * ((a - 1.0) * g + 0.5)
        d3 += mu[t] * (k3 * g + p3)
        d5 += mu[t] * (k5 * g + p5)
    x2 = (h / mean) ** 2
    return (d1 + x2 * (d3 / 6.0 + x2 * d5 / 120.0)) / (mean * mean)


@nb.njit(cache=True, inline="always")
def _volumetric(d, mu, alpha, beta):
    """``G'(d)`` and ``G''(d)`` of ``G = sum 2 mu / (alpha^2 beta) (e^y - 1 - y)``, ``y =
    -alpha beta ln J``, ``d = J^2``."""
    lnJ = 0.5 * math.log(d)
    dG = ddG = 0.0
    for t in range(mu.shape[0]):
        y = -alpha[t] * beta * lnJ
        e = _exprel(y)
        dG += mu[t] * e
        ddG += mu[t] * (0.5 * (1.0 + y * e) - lnJ * e)
    return dG * (beta * lnJ / d), ddG * (beta / (d * d))


@nb.njit(cache=True)
def hyperfoam2(C, mu, alpha, beta, tangent, S, D):
    """Plane strain at ``C`` (3, n): ``S = 2 (f(c1) N1 (x) N1 + f(c2) N2 (x) N2) + 2 G' cof C``
    and its tangent (:meth:`sim.materials._hyperfoam.Hyperfoam.stress_tangent`)."""
    for q in range(C.shape[1]):
        C11, C22, C12 = C[0, q], C[1, q], C[2, q]
        c1, c2, d, _, cos2, sin2 = eigen2(C11, C22, C12)
        f1, df1 = _f(c1, mu, alpha)
        f2, df2 = _f(c2, mu, alpha)
        dG, ddG = _volumetric(d, mu, alpha, beta)
        spectral_stress2(f1, f2, cos2, sin2, S, q)
        td_stress(C11, C22, C12, 0.0, dG, S, 0, q, True)
        if not tangent:
            continue
        # 4 f'(c1) P1(x)P1 + 4 f'(c2) P2(x)P2 + 2 f[c1, c2] w(x)w with P1 = [u, v, h],
        # P2 = [v, u, -h], w = [-sin2, sin2, cos2] (Voigt, engineering shear)
        A, B = 4.0 * df1, 4.0 * df2
        F2 = 2.0 * _divided_difference(c1, c2, f1, f2, mu, alpha)
        u, v, h = 0.5 * (1.0 + cos2), 0.5 * (1.0 - cos2), 0.5 * sin2
        ss, sc = F2 * sin2 * sin2, F2 * sin2 * cos2
        D[0, 0, 0, q] = A * u * u + B * v * v + ss
        D[0, 1, 1, q] = A * v * v + B * u * u + ss
        D[0, 0, 1, q] = D[0, 1, 0, q] = (A + B) * u * v - ss
        D[0, 0, 2, q] = D[0, 2, 0, q] = h * (A * u - B * v) - sc
        D[0, 1, 2, q] = D[0, 2, 1, q] = h * (A * v - B * u) + sc
        D[0, 2, 2, q] = (A + B) * h * h + F2 * cos2 * cos2
        td_tangent(C11, C22, C12, dG, 0.0, 0.0, ddG, D, 0, q, True)


@nb.njit(cache=True)
def hyperfoam3(C, c, N, mu, alpha, beta, tangent, S, D):
    """3D at ``C`` (6, n) with its eigenvalues ``c`` (3, n) and unit eigenvectors ``N`` (3, 3,
    n): the spectral part with ``Phi_ab = delta_ab f'(c_a)`` and ``theta_ab = f[c_a, c_b]``,
    plus ``G(det C)`` (:meth:`sim.materials._hyperfoam.Hyperfoam.evaluate3`)."""
    G3 = np.empty(6)
    phi = np.empty(3)
    phi2 = np.zeros((3, 3))
    theta = np.empty(3)
    for q in range(C.shape[1]):
        for i in range(3):
            phi[i], phi2[i, i] = _f(c[i, q], mu, alpha)
        if tangent:
            for p in range(3):
                ia, ib = (0, 1, 0)[p], (1, 2, 2)[p]
                theta[p] = _divided_difference(c[ia, q], c[ib, q], phi[ia], phi[ib], mu, alpha)
        spectral3(N, q, phi, phi2, theta, S, D, 0, tangent)
        _, _, I3 = cofactor(C, q, G3)
        dG, ddG = _volumetric(I3, mu, alpha, beta)
        volumetric3(C, q, G3, dG, ddG, S, D, 0, True, tangent)
