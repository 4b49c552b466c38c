"""Invariant-based laws (Abaqus forms): neo-Hookean, Mooney-Rivlin, Yeoh.

``U = U_iso(I1b, I2b) + K/2 (J - 1)^2`` with ``I1b = J^(-2/3) I1``, ``I2b = J^(-4/3) I2`` and
the 3D invariants of ``C``; in plane strain ``C33 = 1``, so ``I1 = t + 1``, ``I2 = d + t``,
``J = sqrt(d)`` (``t``, ``d`` = trace, determinant of the in-plane block).
``K = 2 mu0 (1 + nu)/(3 (1 - 2 nu))``.

The three isochoric parts are one polynomial, ``U_iso = c10 x + c20 x^2 + c30 x^3 + c01 (I2b -
3)`` with ``x = I1b - 3`` (neo-Hookean ``c10 = mu/2``; Mooney-Rivlin ``c10``, ``c01``; Yeoh
``c10``, ``c20``, ``c30``): each law gives its coefficients (:attr:`InvariantLaw.coefficients`)
and its energy; the stress and the tangent, plane strain and 3D, whole or split into the
isochoric and the volumetric part, are computed by the compiled chain rules of
:mod:`sim.materials._kernels` (the formulas of :mod:`sim.materials._law`, ``W(t, d)``,
and :mod:`sim.materials._law3`, ``W(I1, I2, I3)``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from sim.errors import DesignError
from sim.materials import _validate as v
from sim.materials._law import Array, Law, as_C, run_kernel
from sim.materials._law3 import as_C3


class InvariantLaw(Law):
    """``U(I1b, I2b, J)`` with the isochoric part given by the subclass (MPa).

    Decoupled: ``U_iso(I1b, I2b)`` (isochoric; its Kirchhoff stress is deviatoric) plus
    ``U_vol = K/2 (J - 1)^2`` (volumetric; its stress is the pressure ``-K (J - 1)``), so the
    ``*_split`` methods give the two parts apart.
    """

    decoupled: ClassVar[bool] = True

    def _iso(self, a: Array, b: Array) -> Array:
        """``U_iso(I1b = a, I2b = b)`` (MPa)."""
        raise NotImplementedError

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        """``(c10, c20, c30, c01)`` of ``U_iso`` (MPa; see the module docstring)."""
        raise NotImplementedError

    # -- the compiled stress and tangent ------------------------------------------------------
    def _compiled(self, C: Array, split: bool, tangent: bool) -> tuple[Array, Array | None]:
        """``(S, D)`` from :mod:`sim.materials._kernels` (:func:`run_kernel`)."""
        from sim.materials._kernels import invariant2, invariant3

        kernel = invariant3 if C.shape[0] == 6 else invariant2
        coefficients, K = np.array(self.coefficients), self.bulk_modulus_MPa
        return run_kernel(
            C, split, tangent, lambda C, S, D: kernel(C, coefficients, K, split, tangent, S, D)
        )

    def _volumetric_energy(self, J: Array) -> Array:
        return 0.5 * self.bulk_modulus_MPa * (J - 1.0) ** 2

    def _energy(self, I1: Array, I2: Array, I3: Array) -> Array:
        """``[U_iso, U_vol]`` (shape ``(2, *batch)``) from the 3D invariants of ``C``."""
        a_1 = 1.0 / np.cbrt(I3)
        return np.stack((self._iso(I1 * a_1, I2 * a_1 * a_1), self._volumetric_energy(np.sqrt(I3))))

    def _energy2(self, C: Array) -> Array:
        C11, C22, C12 = C
        t, d = C11 + C22, C11 * C22 - C12 * C12
        return self._energy(t + 1.0, d + t, d)

    def _energy3(self, C: Array) -> Array:
        C11, C22, C33, C12, C23, C13 = C
        cof = (C22 * C33 - C23 * C23, C11 * C33 - C13 * C13, C11 * C22 - C12 * C12)
        I3 = C11 * cof[0] + C12 * (C13 * C23 - C12 * C33) + C13 * (C12 * C23 - C13 * C22)
        return self._energy(C11 + C22 + C33, cof[0] + cof[1] + cof[2], I3)

    # -- plane strain -------------------------------------------------------------------------
    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` (MPa) at ``C``; shapes ``batch``, ``(3, *batch)``, ``(3, 3, *batch)``."""
        C = as_C(C)
        S, D = self._compiled(C, split=False, tangent=True)
        return self._energy2(C).sum(axis=0), S, D

    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``."""
        return self._compiled(as_C(C), split=False, tangent=False)[0]

    def stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` (MPa) without the energy."""
        return self._compiled(as_C(C), split=False, tangent=True)

    def evaluate_split(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` split as ``[iso, vol]`` (MPa): ``W_iso = U_iso(I1b, I2b)``,
        ``W_vol = K/2 (J - 1)^2``; shapes ``(2, *batch)``, ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        C = as_C(C)
        S, D = self._compiled(C, split=True, tangent=True)
        return self._energy2(C), S, D

    def stress_split(self, C: Any) -> Array:
        """``S`` split as ``[iso, vol]``, shape ``(2, 3, *batch)`` (MPa)."""
        return self._compiled(as_C(C), split=True, tangent=False)[0]

    def stress_tangent_split(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` split as ``[iso, vol]`` (MPa), shapes ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        return self._compiled(as_C(C), split=True, tangent=True)

    @staticmethod
    def _out_of_plane(C: Array) -> Array:
        """The 3D ``C`` of the plane-strain ``C`` (``C33 = 1``, ``C23 = C13 = 0``)."""
        C11, C22, C12 = C
        one, zero = np.ones_like(C11), np.zeros_like(C11)
        return np.stack((C11, C22, one, C12, zero, zero))

    def S33_split(self, C: Any) -> Array:
        """``S33`` split as ``[iso, vol]``, shape ``(2, *batch)`` (MPa); see :meth:`S33`."""
        return self.stress3_split(self._out_of_plane(as_C(C)))[:, 2]

    def S33(self, C: Any) -> Array:
        """Out-of-plane 2nd Piola-Kirchhoff stress ``S33`` (MPa), shape ``batch``: the 3D law's
        ``S33`` at ``C33 = 1``, ``C23 = C13 = 0``."""
        return self.stress3(self._out_of_plane(as_C(C)))[2]

    # -- 3D (sim.materials._law3 conventions) -------------------------------------------------
    def evaluate3_split(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` split as ``[iso, vol]`` (MPa): ``W_iso = U_iso(I1b, I2b)``,
        ``W_vol = K/2 (J - 1)^2``; shapes ``(2, *batch)``, ``(2, 6, *batch)``,
        ``(2, 6, 6, *batch)`` (:mod:`sim.materials._law3`)."""
        C = as_C3(C)
        S, D = self._compiled(C, split=True, tangent=True)
        return self._energy3(C), S, D

    def stress3_split(self, C: Any) -> Array:
        """3D ``S`` split as ``[iso, vol]``, shape ``(2, 6, *batch)`` (MPa)."""
        return self._compiled(as_C3(C), split=True, tangent=False)[0]

    def stress_tangent3_split(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` split as ``[iso, vol]`` (MPa)."""
        return self._compiled(as_C3(C), split=True, tangent=True)

    def evaluate3(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` (MPa) at ``C = [C11, C22, C33, C12, C23, C13]``; shapes ``batch``,
        ``(6, *batch)``, ``(6, 6, *batch)`` (:mod:`sim.materials._law3`)."""
        C = as_C3(C)
        S, D = self._compiled(C, split=False, tangent=True)
        return self._energy3(C).sum(axis=0), S, D

    def stress3(self, C: Any) -> Array:
        """3D 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(6, *batch)``; no tangent."""
        return self._compiled(as_C3(C), split=False, tangent=False)[0]

    def stress_tangent3(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` (MPa) without the energy."""
        return self._compiled(as_C3(C), split=False, tangent=True)


@dataclasses.dataclass(frozen=True)
class NeoHookean(InvariantLaw):
    """Compressible neo-Hookean: ``U = mu/2 (I1b - 3) + K/2 (J - 1)^2``.

    ``mu_MPa``: initial shear modulus (MPa); ``nu``: initial Poisson's ratio (sets ``K``).
    """

    mu_MPa: float
    nu: float

    model: ClassVar[str] = "neo_hookean"
    moduli_fields: ClassVar[tuple[str, ...]] = ("mu_MPa",)

    @classmethod
    def _check(cls, values: Mapping[str, Any], field: str) -> None:
        v.positive(values["mu_MPa"], f"{field}.mu_MPa")
        v.poisson(values["nu"], f"{field}.nu")

    @property
    def initial_shear_modulus_MPa(self) -> float:
        """``mu0 = mu`` (MPa)."""
        return self.mu_MPa

    def _iso(self, a: Array, b: Array) -> Array:
        return 0.5 * self.mu_MPa * (a - 3.0)

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        return 0.5 * self.mu_MPa, 0.0, 0.0, 0.0


@dataclasses.dataclass(frozen=True)
class MooneyRivlin(InvariantLaw):
    """Compressible Mooney-Rivlin: ``U = C10 (I1b - 3) + C01 (I2b - 3) + K/2 (J - 1)^2``.

    ``c10_MPa``, ``c01_MPa`` (MPa), ``nu``; ``mu0 = 2 (C10 + C01)`` must be > 0.
    """

    c10_MPa: float
    c01_MPa: float
    nu: float

    model: ClassVar[str] = "mooney_rivlin"
    moduli_fields: ClassVar[tuple[str, ...]] = ("c10_MPa", "c01_MPa")

    @classmethod
    def _check(cls, values: Mapping[str, Any], field: str) -> None:
        mu0 = 2.0 * (values["c10_MPa"] + values["c01_MPa"])
        if not mu0 > 0.0:
            raise DesignError(
                f"{field}.c10_MPa",
                f"initial shear modulus 2 (c10_MPa + c01_MPa) must be > 0, got {mu0:g}",
            )
        v.poisson(values["nu"], f"{field}.nu")

    @property
    def initial_shear_modulus_MPa(self) -> float:
        """``mu0 = 2 (C10 + C01)`` (MPa)."""
        return 2.0 * (self.c10_MPa + self.c01_MPa)

    def _iso(self, a: Array, b: Array) -> Array:
        return self.c10_MPa * (a - 3.0) + self.c01_MPa * (b - 3.0)

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        return self.c10_MPa, 0.0, 0.0, self.c01_MPa


@dataclasses.dataclass(frozen=True)
class Yeoh(InvariantLaw):
    """Compressible Yeoh: ``U = sum_i Ci0 (I1b - 3)^i + K/2 (J - 1)^2``, ``i = 1..3``.

    ``c10_MPa`` (> 0), ``c20_MPa``, ``c30_MPa`` (MPa, default 0), ``nu``; ``mu0 = 2 C10``.
    """

    c10_MPa: float
    c20_MPa: float = 0.0
    c30_MPa: float = 0.0
    nu: float = dataclasses.field(kw_only=True)

    model: ClassVar[str] = "yeoh"
    moduli_fields: ClassVar[tuple[str, ...]] = ("c10_MPa", "c20_MPa", "c30_MPa")

    @classmethod
    def _check(cls, values: Mapping[str, Any], field: str) -> None:
        v.positive(values["c10_MPa"], f"{field}.c10_MPa")
        v.poisson(values["nu"], f"{field}.nu")

    @property
    def initial_shear_modulus_MPa(self) -> float:
        """``mu0 = 2 C10`` (MPa)."""
        return 2.0 * self.c10_MPa

    def _iso(self, a: Array, b: Array) -> Array:
        x = a - 3.0
        return x * (self.c10_MPa + x * (self.c20_MPa + x * self.c30_MPa))

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        return self.c10_MPa, self.c20_MPa, self.c30_MPa, 0.0
