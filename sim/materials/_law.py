"""Common machinery of the hyperelastic laws.

Conventions (shared by every law, plane strain, total Lagrangian, ``C33 = 1``):

* ``C`` has shape ``(3, *batch)`` = ``[C11, C22, C12]`` (in-plane right Cauchy-Green tensor).
* ``W`` (MPa = N/mm^2) has shape ``batch``.
* ``S`` = ``2 dW/dC`` (MPa) has shape ``(3, *batch)`` = ``[S11, S22, S12]``.
* ``D`` = ``4 d2W/dCdC`` (MPa) has shape ``(3, 3, *batch)``, Voigt form with engineering shear:
  ``dS_i = D_ij dE_j`` with ``dE = [dE11, dE22, 2 dE12]``; it is symmetric.

Many laws are functions of ``t = tr C`` and ``d = det C`` of the 2x2 block only (``I1 = t + 1``,
``I2 = d + t``, ``J = sqrt(d)``).  ``dt/dC = I`` and ``dd/dC = cof C`` (linear in ``C``), so the
stress and tangent follow from the derivatives of ``W(t, d)`` exactly, without eigenvalues:
``S = 2 (W_t I + W_d cof C)`` and ``D = 4 (W_tt I(x)I + W_td (I(x)cof + cof(x)I) + W_dd
cof(x)cof) + 4 W_d dcof/dC``, where in Voigt form with engineering shear ``4 dcof/dC = [[0, 4,
0], [4, 0, 0], [0, 0, -2]]`` (``cof = [C22, C11, -C12]``, ``dC = 2 dE``, ``dC12 = gamma``);
compiled with the laws (``sim.materials._kernels.td_stress``, ``td_tangent``).

The laws' stress and tangent are compiled loops over the points (one ``*_kernels`` module per
law, run by :func:`run_kernel`); their energies, which only the tests and the fitting read, stay
numpy.

A *decoupled* law (``Law.decoupled``; the invariant laws, ``W = W_iso(C) + W_vol(J)``) also gives
its energy, stress and tangent split into the isochoric and the volumetric part, stacked on a
leading axis of length 2 (``[iso, vol]``): ``evaluate_split(C) -> (W, S, D)`` with shapes
``(2, *batch)``, ``(2, 3, *batch)``, ``(2, 3, 3, *batch)``; the parts sum to ``evaluate(C)``.
The Prony series can then relax shear and bulk with different coefficients.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, Self

import numpy as np

from sim.errors import DesignError
from sim.materials import _validate as v

Array = np.ndarray

# Maximum number of terms in a list-valued law parameter (hyperfoam N).
MAX_TERMS = 3


def as_C(C: Any) -> Array:
    """``C`` as a float array of shape ``(3, *batch)``."""
    C = np.asarray(C, dtype=float)
    if C.ndim < 1 or C.shape[0] != 3:
        raise ValueError(f"C must have shape (3, *batch) = [C11, C22, C12], got {C.shape}")
    return C


#: the kernels' placeholder for a tangent not asked for
_NO_TANGENT = np.empty((1, 1, 1, 1))


def run_kernel(
    C: Array, split: bool, tangent: bool, kernel: Callable[[Array, Array, Array], None]
) -> tuple[Array, Array | None]:
    """``(S, D)`` of a compiled law at ``C`` (``(nv, *batch)``; nv = 3 plane strain, 6 in 3D):
    ``kernel(C_flat, S, D)`` fills ``S`` (P, nv, n) and, with ``tangent``, ``D`` (P, nv, nv, n),
    ``P = 2`` with ``split`` (``[iso, vol]``), else 1. Returns shapes ``(2, nv, *batch)``,
    ``(2, nv, nv, *batch)`` with ``split``, else ``(nv, *batch)``, ``(nv, nv, *batch)``; ``D``
    None without ``tangent``."""
    nv, batch = C.shape[0], C.shape[1:]
    flat = C.reshape(nv, -1)
    parts = 2 if split else 1
    S = np.empty((parts, nv, flat.shape[1]))
    D = np.empty((parts, nv, nv, flat.shape[1])) if tangent else _NO_TANGENT
    kernel(flat, S, D)
    S = S.reshape(parts, nv, *batch)
    D = D.reshape(parts, nv, nv, *batch) if tangent else None
    if split:
        return S, D
    return S[0], (D[0] if D is not None else None)


def check_ogden_terms(values: Mapping[str, Any], field: str) -> None:
    """Admissible Ogden-type terms (``mu_MPa``, ``alpha``, as many of each; every
    ``alpha != 0``, every ``mu alpha > 0`` for stability, ``sum mu > 0``), errors naming
    ``f"{field}.key"``; shared by the hyperfoam and the Ogden law."""
    mu, alpha = values["mu_MPa"], values["alpha"]
    if len(alpha) != len(mu):
        raise DesignError(
            f"{field}.alpha",
            f"must have as many terms as mu_MPa ({len(mu)}), got {len(alpha)}",
        )
    for i, (m, a) in enumerate(zip(mu, alpha, strict=True)):
        if a == 0.0:
            raise DesignError(f"{field}.alpha", f"alpha[{i}] must be nonzero, got 0")
        if not m * a > 0.0:
            raise DesignError(
                f"{field}.mu_MPa",
                f"mu_MPa[{i}] * alpha[{i}] must be > 0 (stability), got {m:g} * {a:g}",
            )
    if not sum(mu) > 0.0:
        raise DesignError(
            f"{field}.mu_MPa", f"sum (initial shear modulus) must be > 0, got {sum(mu):g}"
        )


def bulk_modulus(mu0: float, nu: float) -> float:
    """Initial bulk modulus ``K = 2 mu0 (1 + nu) / (3 (1 - 2 nu))`` (MPa)."""
    return 2.0 * mu0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))


def list_field(**kwargs: Any) -> Any:
    """A dataclass field holding a tuple of floats (a list in the design file)."""
    return dataclasses.field(metadata={"list": True}, **kwargs)


class Law:
    """Base of the hyperelastic laws (frozen dataclasses).

    Subclasses define the dataclass fields (the design-file keys; tuple fields marked with
    :func:`list_field` are lists there), ``model`` (registry name), ``moduli_fields`` (the fields
    that scale with the moduli), ``_check`` (physical validation) and the evaluation methods.
    """

    model: ClassVar[str]
    moduli_fields: ClassVar[tuple[str, ...]]
    #: True when ``W = W_iso(C) + W_vol(J)``: the ``*_split`` methods exist and
    #: :meth:`scaled_moduli` can scale shear and bulk apart.
    decoupled: ClassVar[bool] = False
    nu: float

    # --- construction and validation -------------------------------------------------------
    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.metadata.get("list"):
                value = v.number_list(value, f"{self.model}.{f.name}", 1, MAX_TERMS)
            else:
                value = v.number(value, f"{self.model}.{f.name}")
            object.__setattr__(self, f.name, value)
        self._check(self._values(), self.model)

    def _values(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @classmethod
    def _check(cls, values: Mapping[str, Any], field: str) -> None:
        """Raise ``DesignError(f"{field}.{key}", ...)`` for physically invalid parameters."""
        raise NotImplementedError

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """The design-file keys of this law (besides ``model``)."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_params(cls, params: Mapping[str, Any], field: str) -> Self:
        """Build the law from a design-file table; errors name ``f"{field}.{key}"``.

        ``params`` holds the law's keys and optionally ``model`` (which must then be this
        law's name). Beyond what the law admits (``_check``), the moduli of a material given by
        a user must be physical (``_validate.moduli_in_range``); a law made in code (a
        family's, a scaled one) is not held to that range.
        """
        params = dict(params)
        model = params.pop("model", cls.model)
        if model != cls.model:
            raise DesignError(f"{field}.model", f"must be {cls.model!r}, got {model!r}")
        v.known_keys(params, (*cls.keys(), "model"), field)
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            key = f"{field}.{f.name}"
            if f.name not in params:
                if f.default is dataclasses.MISSING:
                    raise DesignError(key, "is required")
                values[f.name] = f.default
            elif f.metadata.get("list"):
                values[f.name] = v.number_list(params[f.name], key, 1, MAX_TERMS)
            else:
                values[f.name] = v.number(params[f.name], key)
        cls._check(values, field)
        law = cls(**values)
        moduli = {name: values[name] for name in cls.moduli_fields}
        v.moduli_in_range(law.initial_shear_modulus_MPa, moduli, field)
        return law

    def to_dict(self) -> dict[str, Any]:
        """The design-file form (``model`` plus the law's keys); round-trips via ``from_params``."""
        out: dict[str, Any] = {"model": self.model}
        for name, value in self._values().items():
            out[name] = list(value) if isinstance(value, tuple) else value
        return out

    def scaled(self, factor: float) -> Self:
        """The same law with every modulus multiplied by ``factor`` (> 0); ``nu`` is kept."""
        if not factor > 0.0:
            raise ValueError(f"factor must be > 0, got {factor}")
        changes: dict[str, Any] = {}
        for name in self.moduli_fields:
            value = getattr(self, name)
            if isinstance(value, tuple):
                changes[name] = tuple(factor * x for x in value)
            else:
                changes[name] = factor * value
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

    def scaled_moduli(self, shear: float, bulk: float) -> Self:
        """The law with its shear moduli times ``shear`` and its bulk modulus times ``bulk`` (> 0).

        Equal factors are :meth:`scaled` (``nu`` kept).  Different factors change ``nu``; only a
        decoupled law (whose bulk modulus enters through ``W_vol`` alone) supports them.
        """
        if shear == bulk:
            return self.scaled(shear)
        if not (shear > 0.0 and bulk > 0.0):
            raise ValueError(f"factors must be > 0, got shear={shear}, bulk={bulk}")
        if not self.decoupled:
            raise ValueError(
                f"{self.model} couples shear and bulk: it can only scale both by one factor"
            )
        mu = shear * self.initial_shear_modulus_MPa
        K = bulk * self.bulk_modulus_MPa
        # nu of (mu, K), the inverse of bulk_modulus(): K = 2 mu (1 + nu) / (3 (1 - 2 nu))
        nu = (3.0 * K - 2.0 * mu) / (2.0 * (3.0 * K + mu))
        return dataclasses.replace(self.scaled(shear), nu=nu)  # type: ignore[type-var]

    # --- moduli ------------------------------------------------------------------------------
    @property
    def initial_shear_modulus_MPa(self) -> float:
        """Initial (small-strain) shear modulus ``mu0`` (MPa)."""
        raise NotImplementedError

    @property
    def bulk_modulus_MPa(self) -> float:
        """Initial (small-strain) bulk modulus ``K0 = 2 mu0 (1 + nu) / (3 (1 - 2 nu))`` (MPa)."""
        return bulk_modulus(self.initial_shear_modulus_MPa, self.nu)

    # --- evaluation (overridden) --------------------------------------------------------------
    def evaluate(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` at ``C`` (shape ``(3, *batch)``); see the module docstring (MPa)."""
        raise NotImplementedError

    def stress(self, C: Any) -> Array:
        """In-plane 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(3, *batch)``; no tangent."""
        raise NotImplementedError

    def stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` as in ``evaluate``; a law overrides it when the energy costs extra."""
        _, S, D = self.evaluate(C)
        return S, D

    def S33(self, C: Any) -> Array:
        """Out-of-plane 2nd Piola-Kirchhoff stress ``S33`` (MPa), shape ``batch``.

        With ``F33 = 1`` the Cauchy stress is ``sigma33 = S33 / J``, ``J = sqrt(det C)``.
        """
        raise NotImplementedError

    # --- isochoric / volumetric split (decoupled laws only) -----------------------------------
    def _not_decoupled(self) -> NotImplementedError:
        return NotImplementedError(
            f"{self.model}'s energy does not split into isochoric and volumetric parts"
        )

    def evaluate_split(self, C: Any) -> tuple[Array, Array, Array]:
        """``(W, S, D)`` split as ``[iso, vol]``: shapes ``(2, *batch)``, ``(2, 3, *batch)``,
        ``(2, 3, 3, *batch)`` (MPa); each part is the derivative of its own energy."""
        raise self._not_decoupled()

    def stress_split(self, C: Any) -> Array:
        """``S`` split as ``[iso, vol]``, shape ``(2, 3, *batch)`` (MPa); no tangent."""
        raise self._not_decoupled()

    def stress_tangent_split(self, C: Any) -> tuple[Array, Array]:
        """``(S, D)`` split as ``[iso, vol]``, as in :meth:`evaluate_split` (no energy)."""
        raise self._not_decoupled()

    def S33_split(self, C: Any) -> Array:
        """``S33`` split as ``[iso, vol]``, shape ``(2, *batch)`` (MPa)."""
        raise self._not_decoupled()

    # --- 3D (sim.materials._law3 conventions; overridden) -------------------------------------
    def evaluate3(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` (MPa) at ``C = [C11, C22, C33, C12, C23, C13]`` (shape
        ``(6, *batch)``); shapes ``batch``, ``(6, *batch)``, ``(6, 6, *batch)``, ``D`` in Voigt
        form with engineering shear (:mod:`sim.materials._law3`)."""
        raise NotImplementedError

    def stress3(self, C: Any) -> Array:
        """3D 2nd Piola-Kirchhoff stress ``S`` (MPa), shape ``(6, *batch)``; no tangent."""
        raise NotImplementedError

    def stress_tangent3(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` as in :meth:`evaluate3` (no energy)."""
        _, S, D = self.evaluate3(C)
        return S, D

    def evaluate3_split(self, C: Any) -> tuple[Array, Array, Array]:
        """3D ``(W, S, D)`` split as ``[iso, vol]``: shapes ``(2, *batch)``, ``(2, 6, *batch)``,
        ``(2, 6, 6, *batch)`` (MPa)."""
        raise self._not_decoupled()

    def stress3_split(self, C: Any) -> Array:
        """3D ``S`` split as ``[iso, vol]``, shape ``(2, 6, *batch)`` (MPa); no tangent."""
        raise self._not_decoupled()

    def stress_tangent3_split(self, C: Any) -> tuple[Array, Array]:
        """3D ``(S, D)`` split as ``[iso, vol]``, as in :meth:`evaluate3_split` (no energy)."""
        raise self._not_decoupled()
