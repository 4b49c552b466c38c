"""Invariant-based laws (Abaqus forms): neo-Hookean, Mooney-Rivlin, Yeoh.

``U = U_iso(I1b, I2b) + K/2 (J - 1)^2`` with ``I1b = J^(-2/3) I1``, ``I2b = J^(-4/3) I2`` and
the 3D invariants of ``C`` with ``C33 = 1``: ``I1 = t + 1``, ``I2 = d + t``, ``J = sqrt(d)``
(``t``, ``d`` = trace, determinant of the in-plane block).  ``K = 2 mu0 (1 + nu)/(3 (1 - 2 nu))``.
Each law supplies only ``U_iso`` and its first and second derivatives; the chain rule to
``W(t, d)`` and then to ``S`` and ``D`` is shared (:mod:`sim.materials._law`).

3D (``evaluate3`` etc., :mod:`sim.materials._law3`): the same ``U`` through the 3D invariants,
``W(I1, I2, I3)`` with ``I1b = I3^(-1/3) I1``, ``I2b = I3^(-2/3) I2``, ``J = I3^(1/2)``; with
``C33 = 1``, ``C13 = C23 = 0`` it is the plane-strain law (``I3 = d``, ``I2 = d + t``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from sim.errors import DesignError
from sim.materials import _validate as v
from sim.materials._law import Array, Law, as_C, td_stress, td_tangent
from sim.materials._law3 import as_C3, inv_stress, inv_tangent, invariants3, mirror

_Derivs = tuple[Any, Any]  # (U_a, U_b); None = identically zero
_Derivs2 = tuple[Any, Any, Any]  # (U_aa, U_ab, U_bb); None = identically zero


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

    def _iso_d1(self, a: Array, b: Array) -> _Derivs:
        """``(dU/dI1b, dU/dI2b)``."""
        raise NotImplementedError

    def _iso_d2(self, a: Array, b: Array) -> _Derivs2:
        """``(d2U/dI1b2, d2U/dI1bdI2b, d2U/dI2b2)``."""
        raise NotImplementedError

    # -- shared chain rule --------------------------------------------------------------------
    def _first(self, C: Array) -> tuple[Any, ...]:
        C11, C22, C12 = C
        t = C11 + C22
        d = C11 * C22 - C12 * C12
        inv_d = 1.0 / d
        J = np.sqrt(d)
        a_t = 1.0 / np.cbrt(d)  # d^(-1/3)
        b_t = a_t * a_t  # d^(-2/3)
        a = (t + 1.0) * a_t
        b = (d + t) * b_t
        K = self.bulk_modulus_MPa
        U_a, U_b = self._iso_d1(a, b)
        U_J = K * (J - 1.0)
        a_d = -a * inv_d / 3.0
        J_d = 0.5 * J * inv_d
        W_t = U_a * a_t
        W_d = U_a * a_d + U_J * J_d
        b_d = None
        if U_b is not None:
            b_d = b_t * (d - 2.0 * t) * inv_d / 3.0
            W_t = W_t + U_b * b_t
            W_d = W_d + U_b * b_d
        return t, d, inv_d, J, a, b, a_t, b_t, a_d, b_d, J_d, U_a, U_b, U_J, W_t, W_d

    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``."""
        C = as_C(C)
        *_, W_t, W_d = self._first(C)
        return td_stress(C, W_t, W_d)

    def _second(self, C: Array, first: tuple[Any, ...], volumetric: bool) -> tuple[Any, ...]:
        """``(W_tt, W_td, W_dd)`` of the isochoric part, plus the volumetric part's ``W_dd``
        when ``volumetric`` (in the order of operations of the whole-law tangent)."""
        (t, d, inv_d, J, a, b, a_t, b_t, a_d, b_d, J_d, U_a, U_b, U_J, _, _) = first
        U_aa, U_ab, U_bb = self._iso_d2(a, b)
        inv_d2 = inv_d * inv_d
        # Second derivatives of a = I1b, b = I2b w.r.t. (t, d) (a_tt = b_tt = 0).
        a_td = -a_t * inv_d / 3.0
        a_dd = (4.0 / 9.0) * a * inv_d2
        W_tt = 0.0
        W_td = U_a * a_td
        if volumetric:
            J_dd = -0.25 * J * inv_d2
            W_dd = U_a * a_dd + self.bulk_modulus_MPa * J_d * J_d + U_J * J_dd
        else:
            W_dd = U_a * a_dd
        if U_aa is not None:
            W_tt = W_tt + U_aa * a_t * a_t
            W_td = W_td + U_aa * a_t * a_d
            W_dd = W_dd + U_aa * a_d * a_d
        if U_b is not None:
            b_td = -(2.0 / 3.0) * b_t * inv_d
            b_dd = b_t * (10.0 * t - 2.0 * d) * inv_d2 / 9.0
            W_td = W_td + U_b * b_td
            W_dd = W_dd + U_b * b_dd
            if U_ab is not None:
                W_tt = W_tt + 2.0 * U_ab * a_t * b_t
                W_td = W_td + U_ab * (a_t * b_d + a_d * b_t)
                W_dd = W_dd + 2.0 * U_ab * a_d * b_d
            if U_bb is not None:
                W_tt = W_tt + U_bb * b_t * b_t
                W_td = W_td + U_bb * b_t * b_d
                W_dd = W_dd + U_bb * b_d * b_d
        return W_tt, W_td, W_dd

    def _vol_W_dd(self, J: Array, J_d: Array, U_J: Array, inv_d2: Array) -> Array:
        """``d2 W_vol / dd2`` of ``W_vol = K/2 (J - 1)^2``, ``J = sqrt(d)``."""
        return self.bulk_modulus_MPa * J_d * J_d + U_J * (-0.25 * J * inv_d2)

    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` (MPa) at ``C``; shapes ``batch``, ``(3, *batch)``, ``(3, 3, *batch)``."""
        C = as_C(C)
        first = self._first(C)
        J, a, b, W_t, W_d = first[3], first[4], first[5], first[14], first[15]
        K = self.bulk_modulus_MPa
        W = self._iso(a, b) + 0.5 * K * (J - 1.0) ** 2
        S = td_stress(C, W_t, W_d)
        W_tt, W_td, W_dd = self._second(C, first, volumetric=True)
        D = np.zeros((3, 3, *C.shape[1:]))
        td_tangent(C, W_d, W_tt, W_td, W_dd, out=D)
        return W, S, D

    # -- isochoric / volumetric split ---------------------------------------------------------
    @staticmethod
    def _split_W_d(first: tuple[Any, ...]) -> tuple[Any, Any]:
        """``dW/dd`` of the isochoric and of the volumetric part."""
        a_d, b_d, J_d, U_a, U_b, U_J = first[8:14]
        W_d_iso = U_a * a_d
        if U_b is not None:
            W_d_iso = W_d_iso + U_b * b_d
        return W_d_iso, U_J * J_d

    def _split_stress(self, C: Array, first: tuple[Any, ...]) -> Array:
        W_d_iso, W_d_vol = self._split_W_d(first)
        S = np.empty((2, *C.shape))
        S[0] = td_stress(C, first[14], W_d_iso)  # W_t comes from the isochoric part only
        S[1] = td_stress(C, None, W_d_vol)
        return S

    def _split_tangent(self, C: Array, first: tuple[Any, ...]) -> Array:
        W_d_iso, W_d_vol = self._split_W_d(first)
        W_tt, W_td, W_dd_iso = self._second(C, first, volumetric=False)
        J, inv_d, J_d, U_J = first[3], first[2], first[10], first[13]
        D = np.zeros((2, 3, 3, *C.shape[1:]))
        td_tangent(C, W_d_iso, W_tt, W_td, W_dd_iso, out=D[0])
        td_tangent(C, W_d_vol, None, None, self._vol_W_dd(J, J_d, U_J, inv_d * inv_d), out=D[1])
        return D

    def evaluate_split(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` split as ``[iso, vol]`` (MPa): ``W_iso = U_iso(I1b, I2b)``,
        ``W_vol = K/2 (J - 1)^2``; shapes ``(2, *batch)``, ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        C = as_C(C)
        first = self._first(C)
        J, a, b = first[3], first[4], first[5]
        W = np.empty((2, *C.shape[1:]))
        W[0] = self._iso(a, b)
        W[1] = 0.5 * self.bulk_modulus_MPa * (J - 1.0) ** 2
        return W, self._split_stress(C, first), self._split_tangent(C, first)

    def stress_split(self, C: Any) -> Array:
        """``S`` split as ``[iso, vol]``, shape ``(2, 3, *batch)`` (MPa)."""
        C = as_C(C)
        return self._split_stress(C, self._first(C))

    def stress_tangent_split(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` split as ``[iso, vol]`` (MPa), shapes ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)``."""
        C = as_C(C)
        first = self._first(C)
        return self._split_stress(C, first), self._split_tangent(C, first)

    def S33_split(self, C: Any) -> Array:
        """``S33`` split as ``[iso, vol]``, shape ``(2, *batch)`` (MPa); see :meth:`S33`."""
        C = as_C(C)
        t, _, _, J, a, b, a_t, b_t, _, _, _, U_a, U_b, U_J, _, _ = self._first(C)
        S33 = np.empty((2, *C.shape[1:]))
        iso = U_a * (a_t - a / 3.0)
        if U_b is not None:
            iso = iso + U_b * (t * b_t - (2.0 / 3.0) * b)
        S33[0] = 2.0 * iso
        S33[1] = U_J * J
        return S33

    def S33(self, C: Any) -> Array:
        """Out-of-plane 2nd Piola-Kirchhoff stress ``S33`` (MPa), shape ``batch``.

        ``S33 = 2 dW/dC33`` at ``C33 = 1``: ``dI1b/dC33 = d^(-1/3) - I1b/3``,
        ``dI2b/dC33 = t d^(-2/3) - 2 I2b/3``, ``dJ/dC33 = J/2``.
        """
        C = as_C(C)
        t, _, _, J, a, b, a_t, b_t, _, _, _, U_a, U_b, U_J, _, _ = self._first(C)
        S33 = U_a * (a_t - a / 3.0) + 0.5 * U_J * J
        if U_b is not None:
            S33 = S33 + U_b * (t * b_t - (2.0 / 3.0) * b)
        return 2.0 * S33

    # -- 3D (sim.materials._law3 conventions) -------------------------------------------------
    def _first3(self, C: Array) -> dict[str, Any]:
        """Invariants and first derivatives of ``W(I1, I2, I3)``, isochoric and volumetric.

        ``a = I1b = I3^(-1/3) I1``, ``b = I2b = I3^(-2/3) I2``, ``J = I3^(1/2)``:
        ``a_1 = I3^(-1/3)``, ``a_3 = -a / (3 I3)``, ``b_2 = I3^(-2/3)``, ``b_3 = -2 b / (3 I3)``,
        ``J_3 = J / (2 I3)``.
        """
        I1, I2, I3, cof = invariants3(C)
        inv3 = 1.0 / I3
        J = np.sqrt(I3)
        a_1 = 1.0 / np.cbrt(I3)
        b_2 = a_1 * a_1
        a = I1 * a_1
        b = I2 * b_2
        U_a, U_b = self._iso_d1(a, b)
        a_3 = -a * inv3 / 3.0
        W1 = U_a * a_1
        W3_iso = U_a * a_3
        W2 = b_3 = None
        if U_b is not None:
            b_3 = -(2.0 / 3.0) * b * inv3
            W2 = U_b * b_2
            W3_iso = W3_iso + U_b * b_3
        U_J = self.bulk_modulus_MPa * (J - 1.0)
        J_3 = 0.5 * J * inv3
        return dict(
            I1=I1, I3=I3, cof=cof, inv3=inv3, J=J, a=a, b=b, a_1=a_1, b_2=b_2, a_3=a_3,
            b_3=b_3, U_a=U_a, U_b=U_b, U_J=U_J, J_3=J_3, W1=W1, W2=W2, W3_iso=W3_iso,
            W3_vol=U_J * J_3,
        )  # fmt: skip

    def _iso_second3(self, f: dict[str, Any]) -> dict[tuple[int, int], Any]:
        """``d2 W_iso / dI_a dI_b`` (``a <= b``; missing or ``None`` = zero).

        ``a_13 = -a_1 / (3 I3)``, ``a_33 = 4 a / (9 I3^2)``, ``b_23 = -2 b_2 / (3 I3)``,
        ``b_33 = 10 b / (9 I3^2)`` (``a_11 = a_12 = b_22 = ... = 0``).
        """
        a, b, a_1, b_2, a_3, b_3 = f["a"], f["b"], f["a_1"], f["b_2"], f["a_3"], f["b_3"]
        inv3, U_a, U_b = f["inv3"], f["U_a"], f["U_b"]
        U_aa, U_ab, U_bb = self._iso_d2(a, b)
        inv3_2 = inv3 * inv3
        W13 = U_a * (-a_1 * inv3 / 3.0)
        W33 = U_a * ((4.0 / 9.0) * a * inv3_2)
        out: dict[tuple[int, int], Any] = {}
        if U_aa is not None:
            out[1, 1] = U_aa * a_1 * a_1
            W13 = W13 + U_aa * a_1 * a_3
            W33 = W33 + U_aa * a_3 * a_3
        if U_b is not None:
            W23 = U_b * (-(2.0 / 3.0) * b_2 * inv3)
            W33 = W33 + U_b * ((10.0 / 9.0) * b * inv3_2)
            if U_ab is not None:
                out[1, 2] = U_ab * a_1 * b_2
                W13 = W13 + U_ab * a_1 * b_3
                W23 = W23 + U_ab * a_3 * b_2
                W33 = W33 + 2.0 * U_ab * a_3 * b_3
            if U_bb is not None:
                out[2, 2] = U_bb * b_2 * b_2
                W23 = W23 + U_bb * b_2 * b_3
                W33 = W33 + U_bb * b_3 * b_3
            out[2, 3] = W23
        out[1, 3] = W13
        out[3, 3] = W33
        return out

    def _vol_W33(self, f: dict[str, Any]) -> Array:
        """``d2 W_vol / dI3^2`` of ``K/2 (J - 1)^2``: ``K J_3^2 + K (J - 1) J_33``,
        ``J_33 = -J / (4 I3^2)``."""
        inv3 = f["inv3"]
        return self.bulk_modulus_MPa * f["J_3"] ** 2 + f["U_J"] * (-0.25 * f["J"] * inv3 * inv3)

    def _stress3_parts(self, C: Array, f: dict[str, Any]) -> Array:
        S = np.empty((2, *C.shape))
        S[0] = inv_stress(C, f["cof"], f["I1"], f["W1"], f["W2"], f["W3_iso"])
        S[1] = inv_stress(C, f["cof"], f["I1"], None, None, f["W3_vol"])
        return S

    def _tangent3_parts(self, C: Array, f: dict[str, Any]) -> Array:
        D = np.zeros((2, 6, 6, *C.shape[1:]))
        cof, I1 = f["cof"], f["I1"]
        inv_tangent(C, cof, I1, f["W2"], f["W3_iso"], self._iso_second3(f), out=D[0])
        inv_tangent(C, cof, I1, None, f["W3_vol"], {(3, 3): self._vol_W33(f)}, out=D[1])
        mirror(D[0])
        mirror(D[1])
        return D

    def _energy3_parts(self, f: dict[str, Any]) -> Array:
        W = np.empty((2, *f["J"].shape))
        W[0] = self._iso(f["a"], f["b"])
        W[1] = 0.5 * self.bulk_modulus_MPa * (f["J"] - 1.0) ** 2
        return W

    def evaluate3_split(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` split as ``[iso, vol]`` (MPa): ``W_iso = U_iso(I1b, I2b)``,
        ``W_vol = K/2 (J - 1)^2``; shapes ``(2, *batch)``, ``(2, 6, *batch)``,
        ``(2, 6, 6, *batch)`` (:mod:`sim.materials._law3`)."""
        C = as_C3(C)
        f = self._first3(C)
        return self._energy3_parts(f), self._stress3_parts(C, f), self._tangent3_parts(C, f)

    def stress3_split(self, C: Any) -> Array:
        """3D ``S`` split as ``[iso, vol]``, shape ``(2, 6, *batch)`` (MPa)."""
        C = as_C3(C)
        return self._stress3_parts(C, self._first3(C))

    def stress_tangent3_split(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` split as ``[iso, vol]`` (MPa)."""
        C = as_C3(C)
        f = self._first3(C)
        return self._stress3_parts(C, f), self._tangent3_parts(C, f)

    def _tangent3(self, C: Array, f: dict[str, Any]) -> Array:
        second = self._iso_second3(f)
        second[3, 3] = second[3, 3] + self._vol_W33(f)
        W3 = f["W3_iso"] + f["W3_vol"]
        D = np.zeros((6, 6, *C.shape[1:]))
        inv_tangent(C, f["cof"], f["I1"], f["W2"], W3, second, out=D)
        return mirror(D)

    def _stress3(self, C: Array, f: dict[str, Any]) -> Array:
        W3 = f["W3_iso"] + f["W3_vol"]
        return inv_stress(C, f["cof"], f["I1"], f["W1"], f["W2"], W3)

    def evaluate3(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` (MPa) at ``C = [C11, C22, C33, C12, C23, C13]``; shapes ``batch``,
        ``(6, *batch)``, ``(6, 6, *batch)`` (:mod:`sim.materials._law3`)."""
        C = as_C3(C)
        f = self._first3(C)
        W = self._iso(f["a"], f["b"]) + 0.5 * self.bulk_modulus_MPa * (f["J"] - 1.0) ** 2
        return W, self._stress3(C, f), self._tangent3(C, f)

    def stress3(self, C: Any) -> Array:
        """3D 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(6, *batch)``; no tangent."""
        C = as_C3(C)
        return self._stress3(C, self._first3(C))

    def stress_tangent3(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` (MPa) without the energy."""
        C = as_C3(C)
        f = self._first3(C)
        return self._stress3(C, f), self._tangent3(C, f)


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

    def _iso_d1(self, a: Array, b: Array) -> _Derivs:
        return 0.5 * self.mu_MPa, None

    def _iso_d2(self, a: Array, b: Array) -> _Derivs2:
        return None, None, None


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

    def _iso_d1(self, a: Array, b: Array) -> _Derivs:
        return self.c10_MPa, self.c01_MPa

    def _iso_d2(self, a: Array, b: Array) -> _Derivs2:
        return None, None, None


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

    def _iso_d1(self, a: Array, b: Array) -> _Derivs:
        x = a - 3.0
        return self.c10_MPa + x * (2.0 * self.c20_MPa + 3.0 * self.c30_MPa * x), None

    def _iso_d2(self, a: Array, b: Array) -> _Derivs2:
        x = a - 3.0
        return 2.0 * self.c20_MPa + 6.0 * self.c30_MPa * x, None, None
