"""Ogden law in its decoupled (Abaqus) form, plane strain.

``U = sum_p 2 mu_p / alpha_p^2 (lb1^a_p + lb2^a_p + lb3^a_p - 3) + K/2 (J - 1)^2`` with the
isochoric principal stretches ``lb_a = J^(-1/3) l_a`` (``l3 = 1``), ``mu0 = sum mu_p`` and
``K = 2 mu0 (1 + nu) / (3 (1 - 2 nu))`` (Abaqus, "Hyperelastic behavior of rubberlike
materials", Ogden form with ``D1 = 2 / K``).

Why a law of its own rather than the hyperfoam with a given ``nu``: the hyperfoam (Ogden-
Storakers) couples shear and bulk in one energy, so it can only relax its whole stress (Abaqus'
rule, :mod:`sim.materials._material`), while an elastomer or gel relaxes its shear and keeps its
bulk modulus (the default of the decoupled laws, ``prony_k`` = 0).  A fitted Ogden material must
relax like the other silicones, so it is decoupled like the invariant laws.

Numerics.  With ``s_a = ln c_a`` (``c_a`` the eigenvalues of the in-plane ``C``, ``c3 = 1``) and
``a = alpha / 6`` one term of the isochoric energy is

    Phi = k [e^(a (2 s1 - s2)) + e^(a (2 s2 - s1)) + e^(-a (s1 + s2)) - 3],  k = 2 mu / alpha^2,

a symmetric function of ``(c1, c2)``.  ``S_iso = 2 sum_a Phi_a N_a (x) N_a`` and the tangent is
the spectral form with the cross term ``Phi_12`` and the divided difference
``(Phi_1 - Phi_2) / (c1 - c2)``, written with ``m = s`` the mean and ``d = (s1 - s2) / 2`` as

    k a e^(-2 m) [e^(a m) (2 sinh((3a - 1) d) + sinh((3a + 1) d)) / sinh(d) + e^(-2 a m)]

so nothing cancels when the eigenvalues meet (the undeformed state): ``sinh(n d)/sinh(d) -> n``.
The volumetric part depends on ``d = det C`` only and goes through the shared ``W(t, d)`` chain
rule (:func:`sim.materials._law.td_tangent`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from sim.materials import _validate as v
from sim.materials._law import (
    Array,
    Law,
    as_C,
    check_ogden_terms,
    list_field,
    td_stress,
    td_tangent,
)


def _sinh_ratio(n: float, d: Array) -> Array:
    """``sinh(n d) / sinh(d)``, ``n`` at ``d = 0`` (``np.sinh`` is accurate for small ``d``)."""
    zero = d == 0.0
    safe = np.where(zero, 1.0, d)
    return np.where(zero, n, np.sinh(n * safe) / np.sinh(safe))


def _eigen(C: Array) -> tuple[Array, ...]:
    """``c1 >= c2``, ``ln c1``, ``ln c2``, ``d = (ln c1 - ln c2) / 2`` and ``cos 2theta``,
    ``sin 2theta`` of the principal direction ``N_1`` (``N_1 = e_1`` when ``c1 = c2``)."""
    C11, C22, C12 = C
    half_diff = 0.5 * (C11 - C22)
    r = np.hypot(half_diff, C12)
    det = C11 * C22 - C12 * C12
    c1 = 0.5 * (C11 + C22) + r
    c2 = det / c1
    split = r > 0.0
    r_safe = np.where(split, r, 1.0)
    cos2 = np.where(split, half_diff / r_safe, 1.0)
    sin2 = np.where(split, C12 / r_safe, 0.0)
    s1, s2 = np.log(c1), np.log(c2)
    d = 0.5 * np.log1p(2.0 * r / c2)  # (s1 - s2) / 2 without cancellation
    return c1, c2, det, s1, s2, d, cos2, sin2


@dataclasses.dataclass(frozen=True)
class Ogden(Law):
    """Decoupled Ogden law with ``N = 1..3`` terms (Abaqus form).

    ``mu_MPa``: ``mu_p`` (MPa); ``alpha``: ``alpha_p`` (nonzero, ``mu_p alpha_p > 0`` for every
    term: Ogden's sufficient condition for a stable, convex response in every deformation);
    ``nu``: initial Poisson's ratio in (-1, 0.5), sets ``K``.  ``mu0 = sum mu_p``.
    """

    mu_MPa: tuple[float, ...] = list_field()
    alpha: tuple[float, ...] = list_field()
    nu: float = dataclasses.field(kw_only=True)

    model: ClassVar[str] = "ogden"
    moduli_fields: ClassVar[tuple[str, ...]] = ("mu_MPa",)
    decoupled: ClassVar[bool] = True

    @classmethod
    def _check(cls, values: Mapping[str, Any], field: str) -> None:
        check_ogden_terms(values, field)
        v.poisson(values["nu"], f"{field}.nu")

    @property
    def initial_shear_modulus_MPa(self) -> float:
        """``mu0 = sum mu_p`` (MPa)."""
        return float(sum(self.mu_MPa))

    # -- isochoric part --------------------------------------------------------------------
    def _terms(self):
        for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
            yield 2.0 * mu / (alpha * alpha), alpha / 6.0

    def _iso(self, s1: Array, s2: Array) -> Array:
        """``U_iso`` (MPa) from the log-eigenvalues."""
        W = np.zeros_like(s1)
        for k, a in self._terms():
            W += k * (
                np.expm1(a * (2.0 * s1 - s2))
                + np.expm1(a * (2.0 * s2 - s1))
                + np.expm1(-a * (s1 + s2))
            )
        return W

    def _iso_first(self, c1: Array, c2: Array, s1: Array, s2: Array) -> tuple[Array, Array]:
        """``(dU/dc1, dU/dc2)`` of the isochoric part."""
        p1 = np.zeros_like(c1)
        p2 = np.zeros_like(c1)
        for k, a in self._terms():
            A = np.exp(a * (2.0 * s1 - s2))
            B = np.exp(a * (2.0 * s2 - s1))
            Cc = np.exp(-a * (s1 + s2))
            p1 += k * a * (2.0 * A - B - Cc)
            p2 += k * a * (2.0 * B - A - Cc)
        return p1 / c1, p2 / c2

    def _iso_stress(self, C: Array, eig: tuple[Array, ...]) -> Array:
        c1, c2, _, s1, s2, _, cos2, sin2 = eig
        f1, f2 = self._iso_first(c1, c2, s1, s2)
        mean, diff = f1 + f2, f1 - f2
        return np.stack((mean + diff * cos2, mean - diff * cos2, diff * sin2))

    def _iso_tangent(self, C: Array, eig: tuple[Array, ...], out: Array) -> Array:
        """Add the isochoric Voigt tangent to ``out`` (shape ``(3, 3, n)``)."""
        c1, c2, _, s1, s2, d, cos2, sin2 = eig
        f11 = np.zeros_like(c1)
        f22 = np.zeros_like(c1)
        f12 = np.zeros_like(c1)
        dd = np.zeros_like(c1)  # (f1 - f2) / (c1 - c2)
        m = 0.5 * (s1 + s2)
        for k, a in self._terms():
            A = np.exp(a * (2.0 * s1 - s2))
            B = np.exp(a * (2.0 * s2 - s1))
            Cc = np.exp(-a * (s1 + s2))
            ka2 = k * a * a
            # d2 Phi / ds_a ds_b, then to c: Phi_11 = (Phi_s1s1 - Phi_s1) / c1^2, ...
            f11 += ka2 * (4.0 * A + B + Cc) - k * a * (2.0 * A - B - Cc)
            f22 += ka2 * (4.0 * B + A + Cc) - k * a * (2.0 * B - A - Cc)
            f12 += ka2 * (Cc - 2.0 * A - 2.0 * B)
            ratio = 2.0 * _sinh_ratio(3.0 * a - 1.0, d) + _sinh_ratio(3.0 * a + 1.0, d)
            dd += k * a * np.exp(-2.0 * m) * (np.exp(a * m) * ratio + np.exp(-2.0 * a * m))
        f11 /= c1 * c1
        f22 /= c2 * c2
        f12 /= c1 * c2
        # 4 Phi_ab P_a (x) P_b + 2 (2 (f1 - f2) / (c1 - c2)) w (x) w, with P1 = [u, w_, q],
        # P2 = [w_, u, -q], w = [-sin2, sin2, cos2] (Voigt, engineering shear)
        u, w_, q = 0.5 * (1.0 + cos2), 0.5 * (1.0 - cos2), 0.5 * sin2
        P1 = (u, w_, q)
        P2 = (w_, u, -q)
        F2 = 2.0 * dd
        w = (-sin2, sin2, cos2)
        for i in range(3):
            for j in range(i, 3):
                part = (
                    4.0 * (f11 * (P1[i] * P1[j]) + f22 * (P2[i] * P2[j]))
                    + 4.0 * f12 * (P1[i] * P2[j] + P2[i] * P1[j])
                    + F2 * (w[i] * w[j])
                )
                out[i, j] += part
                if j != i:
                    out[j, i] += part
        return out

    # -- volumetric part -------------------------------------------------------------------
    def _vol(self, det: Array) -> tuple[Array, Array, Array]:
        """``J``, ``dW_vol/dd`` and ``d2W_vol/dd2`` of ``K/2 (J - 1)^2``, ``J = sqrt(d)``."""
        K = self.bulk_modulus_MPa
        J = np.sqrt(det)
        J_d = 0.5 / J
        U_J = K * (J - 1.0)
        return J, U_J * J_d, K * J_d * J_d - U_J * 0.25 * J / (det * det)

    # -- public -----------------------------------------------------------------------------
    def _flat(self, C: Any) -> tuple[Array, tuple[int, ...]]:
        C = as_C(C)
        return C.reshape(3, -1), C.shape[1:]

    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``."""
        S = self.stress_split(C)
        return S[0] + S[1]

    def stress_split(self, C: Any) -> Array:
        """``S`` split as ``[iso, vol]``, shape ``(2, 3, *batch)`` (MPa)."""
        Cf, batch = self._flat(C)
        eig = _eigen(Cf)
        _, W_d, _ = self._vol(eig[2])
        S = np.stack((self._iso_stress(Cf, eig), td_stress(Cf, None, W_d)))
        return S.reshape(2, 3, *batch)

    def stress_tangent_split(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` split as ``[iso, vol]`` (MPa), shapes ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        Cf, batch = self._flat(C)
        eig = _eigen(Cf)
        _, W_d, W_dd = self._vol(eig[2])
        S = np.stack((self._iso_stress(Cf, eig), td_stress(Cf, None, W_d)))
        D = np.zeros((2, 3, 3, Cf.shape[1]))
        self._iso_tangent(Cf, eig, D[0])
        td_tangent(Cf, W_d, None, None, W_dd, out=D[1])
        return S.reshape(2, 3, *batch), D.reshape(2, 3, 3, *batch)

    def evaluate_split(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` split as ``[iso, vol]`` (MPa): ``W_iso = U_iso``,
        ``W_vol = K/2 (J - 1)^2``; shapes ``(2, *batch)``, ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        Cf, batch = self._flat(C)
        eig = _eigen(Cf)
        W = np.stack(
            (self._iso(eig[3], eig[4]), 0.5 * self.bulk_modulus_MPa * (np.sqrt(eig[2]) - 1.0) ** 2)
        )
        S, D = self.stress_tangent_split(C)
        return W.reshape(2, *batch), S, D

    def stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` (MPa) at ``C`` without the energy (what a Newton iteration needs)."""
        S, D = self.stress_tangent_split(C)
        return S[0] + S[1], D[0] + D[1]

    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` (MPa) at ``C``; shapes ``batch``, ``(3, *batch)``, ``(3, 3, *batch)``."""
        W, S, D = self.evaluate_split(C)
        return W[0] + W[1], S[0] + S[1], D[0] + D[1]

    def S33_split(self, C: Any) -> Array:
        """``S33`` split as ``[iso, vol]``, shape ``(2, *batch)`` (MPa).

        ``S33_iso = 2 dU_iso/dc3`` at ``c3 = 1`` = ``sum_p 2 k_p a_p (2 e^(-a (s1 + s2)) -
        e^(a (2 s1 - s2)) - e^(a (2 s2 - s1)))``; ``S33_vol = K (J - 1) J``.
        """
        Cf, batch = self._flat(C)
        _, _, det, s1, s2, _, _, _ = _eigen(Cf)
        iso = np.zeros_like(det)
        for k, a in self._terms():
            A = np.exp(a * (2.0 * s1 - s2))
            B = np.exp(a * (2.0 * s2 - s1))
            Cc = np.exp(-a * (s1 + s2))
            iso += 2.0 * k * a * (2.0 * Cc - A - B)
        J = np.sqrt(det)
        out = np.stack((iso, self.bulk_modulus_MPa * (J - 1.0) * J))
        return out.reshape(2, *batch)

    def S33(self, C: Any) -> Array:
        """Out-of-plane 2nd Piola-Kirchhoff stress ``S33`` (MPa), shape ``batch``."""
        S = self.S33_split(C)
        return S[0] + S[1]
