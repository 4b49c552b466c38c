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
rule (:mod:`sim.materials._law`). The stress and the tangent are compiled
(:mod:`sim.materials._kernels`); the energy stays numpy.

3D (``evaluate3`` etc.): the same energy in the three eigenvalues of ``C``, the spectral tangent
of :mod:`sim.materials._law3` with the divided differences in closed form
(:meth:`Ogden.evaluate3_split`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from sim.materials import _validate as v
from sim.materials._hyperfoam import _psi
from sim.materials._law import Array, Law, as_C, check_ogden_terms, list_field, run_kernel
from sim.materials._law3 import as_C3, eigh3, flat3, invariants3


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

    def _compiled(self, C: Array, split: bool, tangent: bool) -> tuple[Array, Array | None]:
        """``(S, D)`` from :mod:`sim.materials._kernels` (``run_kernel``), plane strain
        or 3D by the components of ``C``."""
        from sim.materials._kernels import ogden2, ogden3

        k = np.array([kt for kt, _ in self._terms()])
        a = np.array([at for _, at in self._terms()])
        K = self.bulk_modulus_MPa
        if C.shape[0] == 6:

            def kernel(C: Array, S: Array, D: Array) -> None:
                c, N = eigh3(C)
                ogden3(C, c, N, k, a, K, split, tangent, S, D)

        else:

            def kernel(C: Array, S: Array, D: Array) -> None:
                ogden2(C, k, a, K, split, tangent, S, D)

        return run_kernel(C, split, tangent, kernel)

    # -- public -----------------------------------------------------------------------------
    def _flat(self, C: Any) -> tuple[Array, tuple[int, ...]]:
        C = as_C(C)
        return C.reshape(3, -1), C.shape[1:]

    def _energy2(self, C: Any) -> Array:
        """``[U_iso, U_vol]``, shape ``(2, *batch)``."""
        Cf, batch = self._flat(C)
        eig = _eigen(Cf)
        W = np.stack(
            (self._iso(eig[3], eig[4]), 0.5 * self.bulk_modulus_MPa * (np.sqrt(eig[2]) - 1.0) ** 2)
        )
        return W.reshape(2, *batch)

    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``."""
        return self._compiled(as_C(C), split=False, tangent=False)[0]

    def stress_split(self, C: Any) -> Array:
        """``S`` split as ``[iso, vol]``, shape ``(2, 3, *batch)`` (MPa)."""
        return self._compiled(as_C(C), split=True, tangent=False)[0]

    def stress_tangent_split(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` split as ``[iso, vol]`` (MPa), shapes ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        return self._compiled(as_C(C), split=True, tangent=True)

    def evaluate_split(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` split as ``[iso, vol]`` (MPa): ``W_iso = U_iso``,
        ``W_vol = K/2 (J - 1)^2``; shapes ``(2, *batch)``, ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        S, D = self.stress_tangent_split(C)
        return self._energy2(C), S, D

    def stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` (MPa) at ``C`` without the energy (what a Newton iteration needs)."""
        return self._compiled(as_C(C), split=False, tangent=True)

    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` (MPa) at ``C``; shapes ``batch``, ``(3, *batch)``, ``(3, 3, *batch)``."""
        S, D = self.stress_tangent(C)
        return self._energy2(C).sum(axis=0), S, D

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

    # -- 3D (sim.materials._law3 conventions) -----------------------------------------------
    def _energy3(self, C: Array) -> Array:
        """``[U_iso, U_vol]`` (shape ``(2, n)``) at ``C`` (``(6, n)``): ``U_iso = k sum_a x_a^2
        psi(x_a)`` with ``x_a = b (s_a - s_mean)`` (see :meth:`evaluate3_split`)."""
        c, _ = eigh3(C)
        s = np.log(c)
        e = s - s.mean(axis=0)
        W = np.zeros((2, C.shape[1]))
        for k, a6 in self._terms():
            x = 3.0 * a6 * e  # sum_a x_a = 0: k sum (e^x - 1) = k sum (e^x - 1 - x)
            W[0] += k * (x * x * _psi(x)).sum(axis=0)
        I3 = invariants3(C)[2]
        W[1] = 0.5 * self.bulk_modulus_MPa * (np.sqrt(I3) - 1.0) ** 2
        return W

    def evaluate3_split(self, C: Any) -> tuple[Array, Array, Array]:
        r"""3D ``(W, S, D)`` split as ``[iso, vol]`` (MPa); shapes ``(2, *batch)``,
        ``(2, 6, *batch)``, ``(2, 6, 6, *batch)`` (:mod:`sim.materials._law3`).

        Isochoric part, spectral: with the eigenvalues ``c_a = e^(s_a)`` of ``C``,
        ``s_mean = (s_1 + s_2 + s_3) / 3 = (2/3) ln J``, ``b = alpha / 2`` and
        ``x_a = b (s_a - s_mean)`` (so ``lb_a^alpha = e^(x_a)``) one term is
        ``U = k sum_a (e^(x_a) - 1)``, ``k = 2 mu / alpha^2``, and

        .. math::

            \frac{\partial U}{\partial s_a} = k b \left(e^{x_a} - \tfrac{E}{3}\right), \quad
            \frac{\partial^2 U}{\partial s_a \partial s_b} = k b^2 \left(\delta_{ab} e^{x_a}
            - \tfrac{e^{x_a} + e^{x_b}}{3} + \tfrac{E}{9}\right), \quad E = \sum_c e^{x_c},

        ``Phi_a = U_{,s_a} / c_a``, ``Phi_ab = (U_{,s_a s_b} - delta_ab U_{,s_a}) / (c_a c_b)``.
        The divided difference of the spectral tangent (:mod:`sim.materials._law3`), with
        ``sigma = (s_a + s_b)/2``, ``delta = (s_a - s_b)/2``, ``u = b (sigma - s_mean)``, is

        .. math::

            \theta_{ab} = \frac{\Phi_a - \Phi_b}{c_a - c_b}
            = k b\, e^{-2\sigma} \left[ e^{u} \left( \frac{\sinh(b\delta)}{\tanh\delta}
              - 2 \sinh^2\frac{b\delta}{2} \right) - (e^{u} - 1) + \left(\tfrac{E}{3} - 1\right)
              \right]

        (``e^(-b s_mean) (c_a^(b-1) - c_b^(b-1)) / (c_a - c_b) = e^(-2 sigma) e^u
        sinh((b - 1) delta) / sinh(delta)`` and ``sinh((b-1) delta) / sinh(delta) + 1`` is the
        bracket in ``delta``): every term is ``O(b)``, no difference cancels for small ``alpha``
        nor for ``c_a -> c_b``, where ``sinh(b delta) / tanh(delta) -> b`` and ``theta_ab``
        tends to its limit ``Phi_aa - Phi_ab``: the tangent is exact and continuous at equal
        eigenvalues (``C = I``, uniaxial and equibiaxial states).  ``E/3 - 1`` and ``e^u - 1``
        are taken with ``expm1``, and the energy as ``k sum_a x_a^2 psi(x_a)``,
        ``psi(x) = (e^x - 1 - x) / x^2`` (``sum_a x_a = 0``; no cancellation for small
        ``alpha``).  Volumetric part ``K/2 (J - 1)^2`` through ``I3 = det C``
        (``sim.materials._kernels.volumetric3``).
        """
        Cf, batch = flat3(C)
        S, D = self._compiled(as_C3(C), split=True, tangent=True)
        return self._energy3(Cf).reshape(2, *batch), S, D

    def stress3_split(self, C: Any) -> Array:
        """3D ``S`` split as ``[iso, vol]``, shape ``(2, 6, *batch)`` (MPa)."""
        return self._compiled(as_C3(C), split=True, tangent=False)[0]

    def stress_tangent3_split(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` split as ``[iso, vol]`` (MPa)."""
        return self._compiled(as_C3(C), split=True, tangent=True)

    def evaluate3(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` (MPa); shapes ``batch``, ``(6, *batch)``, ``(6, 6, *batch)``."""
        Cf, batch = flat3(C)
        S, D = self.stress_tangent3(C)
        return self._energy3(Cf).sum(axis=0).reshape(batch), S, D

    def stress3(self, C: Any) -> Array:
        """3D 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(6, *batch)``; no tangent."""
        return self._compiled(as_C3(C), split=False, tangent=False)[0]

    def stress_tangent3(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` (MPa) without the energy."""
        return self._compiled(as_C3(C), split=False, tangent=True)
