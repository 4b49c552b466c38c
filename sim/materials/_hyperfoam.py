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
from sim.materials._law3 import (
    eigh3,
    flat3,
    inv_stress,
    inv_tangent,
    invariants3,
    mirror,
    pair_values,
    spectral_bases,
    spectral_stress,
    spectral_tangent,
)
from sim.materials._special import exprel

# Relative eigenvalue split below which the divided difference uses its Taylor series.
_SPLIT_TOL = 5e-3
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

    # -- pieces ---------------------------------------------------------------------------
    def _f(self, c: Array, s: Array, slope: bool) -> tuple[Array, Array | None]:
        """``f(c) = sum (mu/2) s exprel(alpha s/2) / c`` and, if ``slope``, ``f'(c)``."""
        f = np.zeros_like(c)
        df = np.zeros_like(c) if slope else None
        for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
            a = 0.5 * alpha
            g = 0.5 * s * exprel(a * s)  # expm1(alpha s / 2) / alpha
            f += mu * g
            if df is not None:
                df += mu * ((a - 1.0) * g + 0.5)
        f /= c
        if df is not None:
            df /= c * c
        return f, df

    def _divided_difference(self, c1: Array, c2: Array, f1: Array, f2: Array) -> Array:
        """``(f(c1) - f(c2)) / (c1 - c2)``, ``f'`` in the limit, accurate for any split."""
        mean = 0.5 * (c1 + c2)
        h = 0.5 * (c1 - c2)
        near = np.abs(h) <= 0.5 * _SPLIT_TOL * mean
        out = (f1 - f2) / np.where(near, 1.0, c1 - c2)
        if near.any():
            cm, hm = mean[near], h[near]
            s = np.log(cm)
            d1 = np.zeros_like(cm)
            d3 = np.zeros_like(cm)
            d5 = np.zeros_like(cm)
            for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
                # f^(n)(c) = mu c^(-1-n) [(a-1)_n g + P_n(a)], (k)_n the falling factorial,
                # P_n = ((a-1)_n - (-1)_n) / alpha expanded to avoid cancellation.
                a = 0.5 * alpha
                g = 0.5 * s * exprel(a * s)
                k3 = (a - 1.0) * (a - 2.0) * (a - 3.0)
                k5 = k3 * (a - 4.0) * (a - 5.0)
                p3 = 0.5 * (11.0 + a * (-6.0 + a))
                p5 = 0.5 * (274.0 + a * (-225.0 + a * (85.0 + a * (-15.0 + a))))
                d1 += mu * ((a - 1.0) * g + 0.5)
                d3 += mu * (k3 * g + p3)
                d5 += mu * (k5 * g + p5)
            x2 = (hm / cm) ** 2
            out[near] = (d1 + x2 * (d3 / 6.0 + x2 * d5 / 120.0)) / (cm * cm)
        return out

    def _volumetric(self, d: Array, second: bool) -> tuple[Array, Array, Array | None]:
        """``ln J``, ``G'(d)`` and, if ``second``, ``G''(d)`` of the volumetric part."""
        lnJ = 0.5 * np.log(d)
        beta = self.beta
        dG = np.zeros_like(d)
        ddG = np.zeros_like(d) if second else None
        for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
            y = -alpha * beta * lnJ
            e = exprel(y)
            dG += mu * e
            if ddG is not None:
                ddG += mu * (0.5 * (1.0 + y * e) - lnJ * e)
        dG *= beta * lnJ / d
        if ddG is not None:
            ddG *= beta / (d * d)
        return lnJ, dG, ddG

    @staticmethod
    def _iso_stress(f1: Array, f2: Array, cos2: Array, sin2: Array) -> Array:
        """``2 (f1 N1(x)N1 + f2 N2(x)N2)`` in Voigt form."""
        mean, diff = f1 + f2, f1 - f2
        return np.stack((mean + diff * cos2, mean - diff * cos2, diff * sin2))

    # -- public -----------------------------------------------------------------------------
    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``."""
        C = as_C(C)
        c1, c2, d, cos2, sin2 = _spectral(C)
        f1, _ = self._f(c1, np.log(c1), slope=False)
        f2, _ = self._f(c2, np.log(c2), slope=False)
        _, dG, _ = self._volumetric(d, second=False)
        return self._iso_stress(f1, f2, cos2, sin2) + td_stress(C, None, dG)

    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` (MPa) at ``C``; shapes ``batch``, ``(3, *batch)``, ``(3, 3, *batch)``."""
        C = as_C(C)
        batch = C.shape[1:]
        c1, c2, d = _spectral(C.reshape(3, -1))[:3]
        s1, s2, lnJ = np.log(c1), np.log(c2), 0.5 * np.log(d)
        W = np.zeros_like(d)
        beta = self.beta
        for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
            a = 0.5 * alpha
            W += 0.5 * mu * (s1 * s1 * _psi(a * s1) + s2 * s2 * _psi(a * s2))
            W += 2.0 * mu * beta * lnJ * lnJ * _psi(-alpha * beta * lnJ)
        S, D = self.stress_tangent(C)
        return W.reshape(batch), S, D

    def stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` (MPa) at ``C`` without the energy (what a Newton iteration needs)."""
        C = as_C(C)
        batch = C.shape[1:]
        C = C.reshape(3, -1)
        c1, c2, d, cos2, sin2 = _spectral(C)
        s1, s2 = np.log(c1), np.log(c2)
        f1, df1 = self._f(c1, s1, slope=True)
        f2, df2 = self._f(c2, s2, slope=True)
        _, dG, ddG = self._volumetric(d, second=True)
        S = self._iso_stress(f1, f2, cos2, sin2) + td_stress(C, None, dG)

        # Spectral part: 4 f'(c1) P1(x)P1 + 4 f'(c2) P2(x)P2 + 2 f[c1, c2] w(x)w with
        # P1 = [u, v, q], P2 = [v, u, -q], w = [-sin2, sin2, cos2] (Voigt, engineering shear).
        A, B = 4.0 * df1, 4.0 * df2
        F2 = 2.0 * self._divided_difference(c1, c2, f1, f2)
        u, w_, q = 0.5 * (1.0 + cos2), 0.5 * (1.0 - cos2), 0.5 * sin2
        ss, sc = F2 * sin2 * sin2, F2 * sin2 * cos2
        D = np.empty((3, 3, C.shape[1]))
        D[0, 0] = A * u * u + B * w_ * w_ + ss
        D[1, 1] = A * w_ * w_ + B * u * u + ss
        D[0, 1] = D[1, 0] = (A + B) * u * w_ - ss
        D[0, 2] = D[2, 0] = q * (A * u - B * w_) - sc
        D[1, 2] = D[2, 1] = q * (A * w_ - B * u) + sc
        D[2, 2] = (A + B) * q * q + F2 * cos2 * cos2
        td_tangent(C, dG, None, None, ddG, out=D)
        return S.reshape(3, *batch), D.reshape(3, 3, *batch)

    def S33(self, C: Any) -> Array:
        """Out-of-plane 2nd Piola-Kirchhoff stress ``S33 = sum 2 mu_i beta ln J exprel(y_i)``.

        (MPa), shape ``batch``; ``y_i = -alpha_i beta ln J``.
        """
        C = as_C(C)
        C11, C22, C12 = C
        d = C11 * C22 - C12 * C12
        _, dG, _ = self._volumetric(d, second=False)
        return 2.0 * dG * d

    # -- 3D (sim.materials._law3 conventions) -----------------------------------------------
    def _parts3(self, C: Array, energy: bool, tangent: bool) -> tuple[Any, Array, Any]:
        """``(W, S, D)`` for ``C`` of shape ``(6, n)`` (``W``/``D`` ``None`` unless asked)."""
        c, N = eigh3(C)
        s = np.log(c)
        I1, _, I3, cof = invariants3(C)
        f, df = self._f(c, s, slope=tangent)
        lnJ, dG, ddG = self._volumetric(I3, second=tangent)
        m, w = spectral_bases(N)
        S = spectral_stress(f, m) + inv_stress(C, cof, I1, None, None, dG)
        D = None
        if tangent:
            c_a, c_b = pair_values(c)
            f_a, f_b = pair_values(f)
            theta = self._divided_difference(c_a, c_b, f_a, f_b)
            D = np.zeros((6, 6, C.shape[1]))
            spectral_tangent(df, theta, m, w, out=D)
            mirror(inv_tangent(C, cof, I1, None, dG, {(3, 3): ddG}, out=D))
        W = None
        if energy:
            W = np.zeros_like(I3)
            beta = self.beta
            for mu, alpha in zip(self.mu_MPa, self.alpha, strict=True):
                W += 0.5 * mu * (s * s * _psi(0.5 * alpha * s)).sum(axis=0)
                W += 2.0 * mu * beta * lnJ * lnJ * _psi(-alpha * beta * lnJ)
        return W, S, D

    def evaluate3(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` (MPa) at ``C = [C11, C22, C33, C12, C23, C13]``; shapes ``batch``,
        ``(6, *batch)``, ``(6, 6, *batch)``.

        ``U = sum_a F(c_a) + G(I3)`` as in the plane-strain law (the linear terms cancel because
        ``s_1 + s_2 + s_3 = ln I3 = 2 ln J``), ``c_a`` the three eigenvalues of ``C``:
        ``S = 2 sum_a f(c_a) M_a + 2 G'(I3) cof C`` and the spectral tangent of
        :mod:`sim.materials._law3` with ``Phi_ab = delta_ab f'(c_a)`` and
        ``theta_ab = (f(c_a) - f(c_b)) / (c_a - c_b)`` from :meth:`_divided_difference` (its
        Taylor series about the mean for relative splits below ``5e-3``, so the tangent is
        continuous at equal eigenvalues), plus ``4 G'' cof (x) cof + 4 G' dcof/dC``.
        """
        Cf, batch = flat3(C)
        W, S, D = self._parts3(Cf, energy=True, tangent=True)
        return W.reshape(batch), S.reshape(6, *batch), D.reshape(6, 6, *batch)

    def stress3(self, C: Any) -> Array:
        """3D 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(6, *batch)``; no tangent."""
        Cf, batch = flat3(C)
        return self._parts3(Cf, energy=False, tangent=False)[1].reshape(6, *batch)

    def stress_tangent3(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` (MPa) without the energy."""
        Cf, batch = flat3(C)
        _, S, D = self._parts3(Cf, energy=False, tangent=True)
        return S.reshape(6, *batch), D.reshape(6, 6, *batch)
