"""Abaqus hyperfoam (Ogden-type compressible foam), plane strain.

``U = sum_i 2 mu_i / alpha_i^2 [l1^a_i + l2^a_i + l3^a_i - 3 + (J^(-a_i b_i) - 1) / b_i]`` with
full principal stretches, ``l3 = 1``, ``b_i = beta = nu / (1 - 2 nu)``.  (Eq. 2 of Cabibihan et
al. prints ``(J^(-a b) - 1)`` without the ``1/beta`` factor; Abaqus and the moduli below have it.)
Initial moduli ``mu0 = sum mu_i``, ``K0 = sum 2 mu_i (1/3 + beta)``.

Numerics.  With ``s = ln c`` (``c`` an eigenvalue of ``C``), ``u = alpha s / 2`` and
``y = -alpha beta ln J`` the energy is split exactly as ``U = sum_a F(c_a) + G(d)``:

* ``F(c) = 2 mu/alpha^2 (e^u - 1 - u) = mu/2 s^2 psi(u)``, ``psi(x) = (e^x - 1 - x)/x^2``,
* ``G(d) = 2 mu/(alpha^2 beta) (e^y - 1 - y) = 2 mu beta (ln J)^2 psi(y)``,

(the linear terms cancel because ``s_1 + s_2 = ln d = 2 ln J``).  Both parts and all their
derivatives are written with ``exprel(x) = (e^x - 1)/x`` so nothing cancels for small ``alpha``
(silicone: ``alpha_1 = 0.001``) or ``beta`` (``nu = 0``).  ``F`` is a spectral function of ``C``:
``S_F = 2 f(C)``, ``f = F' ``, whose tangent needs the divided difference
``(f(c1) - f(c2))/(c1 - c2)``, taken from a Taylor series about the mean when
``|c1 - c2| <= 5e-3 mean`` (equal eigenvalues: the undeformed state).  ``G`` depends on
``d = det C`` only and goes through the shared ``W(t, d)`` chain rule.

3D (``evaluate3`` etc.): the same split with the three eigenvalues of ``C`` and ``G(det C)``,
the spectral tangent of :mod:`sim.materials._law3` (:meth:`Hyperfoam.evaluate3`).

The stress and the tangent are compiled (:mod:`sim.materials._kernels`, where the
divided difference's series is written out); the energy stays numpy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from sim.materials import _validate as v
from sim.materials._law import Array, Law, as_C, check_ogden_terms, list_field, run_kernel
from sim.materials._law3 import as_C3, eigh3, flat3, invariants3
from sim.materials._special import exprel

# psi(x) = sum_k x^k / (k + 2)!, used for |x| < 0.1 (truncation < 1e-21).
_PSI_SERIES = tuple(1.0 / np.prod(np.arange(1.0, k + 3.0)) for k in range(11))


def _psi(x: Array) -> Array:
    """``(e^x - 1 - x) / x^2`` without cancellation (``1/2`` at ``x = 0``)."""
    small = np.abs(x) < 0.1
    xs = np.where(small, 1.0, x)
    direct = (np.expm1(xs) - xs) / (xs * xs)
    series = _PSI_SERIES[-1]
    for coef in _PSI_SERIES[-2::-1]:
        series = series * x + coef
    return np.where(small, series, direct)


def _spectral(C: Array) -> tuple[Array, ...]:
    """Eigenvalues ``c1 >= c2`` of the 2x2 ``C`` and ``cos 2theta``, ``sin 2theta`` of ``N_1``."""
    C11, C22, C12 = C
    half_diff = 0.5 * (C11 - C22)
    r = np.hypot(half_diff, C12)
    d = C11 * C22 - C12 * C12
    c1 = 0.5 * (C11 + C22) + r
    c2 = d / c1  # no cancellation, and ln c1 + ln c2 = ln d
    split = r > 0.0
    r_safe = np.where(split, r, 1.0)
    cos2 = np.where(split, half_diff / r_safe, 1.0)
    sin2 = np.where(split, C12 / r_safe, 0.0)
    return c1, c2, d, cos2, sin2


@dataclasses.dataclass(frozen=True)
class Hyperfoam(Law):
    """Abaqus hyperfoam with ``N = 1..3`` terms.

    ``mu_MPa``: ``mu_i`` (MPa); ``alpha``: ``alpha_i`` (nonzero, ``mu_i alpha_i > 0``,
    ``sum mu_i > 0``); ``nu``: Poisson's ratio in (-1, 0.5), ``beta = nu / (1 - 2 nu)``.
    """

    mu_MPa: tuple[float, ...] = list_field()
    alpha: tuple[float, ...] = list_field()
    nu: float = dataclasses.field(kw_only=True)

    model: ClassVar[str] = "hyperfoam"
    moduli_fields: ClassVar[tuple[str, ...]] = ("mu_MPa",)

    @classmethod
    def _check(cls, values: Mapping[str, Any], field: str) -> None:
        check_ogden_terms(values, field)
        v.poisson(values["nu"], f"{field}.nu")

    @property
    def beta(self) -> float:
        """``beta = nu / (1 - 2 nu)``."""
        return self.nu / (1.0 - 2.0 * self.nu)

    @property
    def initial_shear_modulus_MPa(self) -> float:
        """``mu0 = sum mu_i`` (MPa)."""
        return float(sum(self.mu_MPa))

    @property
    def bulk_modulus_MPa(self) -> float:
        """``K0 = sum 2 mu_i (1/3 + beta)`` (MPa)."""
        return 2.0 * self.initial_shear_modulus_MPa * (1.0 / 3.0 + self.beta)

    # -- the compiled stress and tangent -------------------------------------------------
    def _compiled(self, C: Array, tangent: bool) -> tuple[Array, Array | None]:
        """``(S, D)`` from :mod:`sim.materials._kernels` (``run_kernel``), plane
        strain or 3D by the components of ``C``."""
        from sim.materials._kernels import hyperfoam2, hyperfoam3

        mu, alpha, beta = np.array(self.mu_MPa), np.array(self.alpha), self.beta
        if C.shape[0] == 6:

            def kernel(C: Array, S: Array, D: Array) -> None:
                c, N = eigh3(C)
                hyperfoam3(C, c, N, mu, alpha, beta, tangent, S, D)

        else:

            def kernel(C: Array, S: Array, D: Array) -> None:
                hyperfoam2(C, mu, alpha, beta, tangent, S, D)

        return run_kernel(C, False, tangent, kernel)

    def _energy(self, s: Array, lnJ: Array) -> Array:
        """``U = sum_a F(c_a) + G`` from the log-eigenvalues ``s`` (``(k, n)``, k = 2 or 3)
        and ``ln J``."""
        W = np.zeros_like(lnJ)
        beta = self.beta
        for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
            W += 0.5 * mu * (s * s * _psi(0.5 * alpha * s)).sum(axis=0)
            W += 2.0 * mu * beta * lnJ * lnJ * _psi(-alpha * beta * lnJ)
        return W

    # -- public -----------------------------------------------------------------------------
    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``."""
        return self._compiled(as_C(C), tangent=False)[0]

    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` (MPa) at ``C``; shapes ``batch``, ``(3, *batch)``, ``(3, 3, *batch)``."""
        C = as_C(C)
        c1, c2, d = _spectral(C.reshape(3, -1))[:3]
        W = self._energy(np.log(np.stack((c1, c2))), 0.5 * np.log(d))
        S, D = self.stress_tangent(C)
        return W.reshape(C.shape[1:]), S, D

    def stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` (MPa) at ``C`` without the energy (what a Newton iteration needs).

        Spectral part: ``4 f'(c1) P1(x)P1 + 4 f'(c2) P2(x)P2 + 2 f[c1, c2] w(x)w`` with
        ``P1 = [u, v, q]``, ``P2 = [v, u, -q]``, ``w = [-sin2, sin2, cos2]`` (Voigt, engineering
        shear), ``f[c1, c2]`` the divided difference; plus ``G(d)`` by the ``W(t, d)`` chain
        rule."""
        return self._compiled(as_C(C), tangent=True)

    def S33(self, C: Any) -> Array:
        """Out-of-plane 2nd Piola-Kirchhoff stress ``S33 = sum 2 mu_i beta ln J exprel(y_i)``.

        (MPa), shape ``batch``; ``y_i = -alpha_i beta ln J``: ``2 G'(d) d``.
        """
        C = as_C(C)
        C11, C22, C12 = C
        d = C11 * C22 - C12 * C12
        lnJ = 0.5 * np.log(d)
        dG = np.zeros_like(d)
        for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
            dG += mu * exprel(-alpha * self.beta * lnJ)
        return 2.0 * self.beta * lnJ * dG

    # -- 3D (sim.materials._law3 conventions) -----------------------------------------------
    def evaluate3(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` (MPa) at ``C = [C11, C22, C33, C12, C23, C13]``; shapes ``batch``,
        ``(6, *batch)``, ``(6, 6, *batch)``.

        ``U = sum_a F(c_a) + G(I3)`` as in the plane-strain law (the linear terms cancel because
        ``s_1 + s_2 + s_3 = ln I3 = 2 ln J``), ``c_a`` the three eigenvalues of ``C``:
        ``S = 2 sum_a f(c_a) M_a + 2 G'(I3) cof C`` and the spectral tangent of
        :mod:`sim.materials._law3` with ``Phi_ab = delta_ab f'(c_a)`` and
        ``theta_ab = (f(c_a) - f(c_b)) / (c_a - c_b)`` from the divided difference of
        ``sim.materials._kernels`` (its
        Taylor series about the mean for relative splits below ``5e-3``, so the tangent is
        continuous at equal eigenvalues), plus ``4 G'' cof (x) cof + 4 G' dcof/dC``.
        """
        Cf, batch = flat3(C)
        c, _ = eigh3(Cf)
        W = self._energy(np.log(c), 0.5 * np.log(invariants3(Cf)[2]))
        S, D = self.stress_tangent3(C)
        return W.reshape(batch), S, D

    def stress3(self, C: Any) -> Array:
        """3D 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(6, *batch)``; no tangent."""
        return self._compiled(as_C3(C), tangent=False)[0]

    def stress_tangent3(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` (MPa) without the energy."""
        return self._compiled(as_C3(C), tangent=True)
