"""``Material`` = hyperelastic law + Prony series, and its design-file (TOML table) form."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from functools import cached_property
from typing import Any

import numpy as np

from sim.errors import DesignError
from sim.materials import _validate as v
from sim.materials._drucker import stable_log_strain, stable_ranges
from sim.materials._hyperfoam import Hyperfoam
from sim.materials._invariant import MooneyRivlin, NeoHookean, Yeoh
from sim.materials._law import Law
from sim.materials._ogden import Ogden
from sim.materials._prony import Prony, prony_stress, prony_stress_split, prony_update_split

Array = np.ndarray

#: Registry of the hyperelastic laws, design-file ``model`` name -> class.
LAWS: dict[str, type[Law]] = {
    cls.model: cls for cls in (Hyperfoam, NeoHookean, MooneyRivlin, Yeoh, Ogden)
}

#: Allowed values of ``moduli``: which moduli the law's parameters are.
MODULI = ("long_term", "instantaneous")

# Keys of a material table besides the law's own keys.
_MATERIAL_KEYS = (
    "model", "prony_g", "prony_tau_s", "prony_k", "moduli", "name", "source", "provenance",
)  # fmt: skip

#: A ``provenance`` value: text, a number, a boolean or a flat list of them (a list is kept as a
#: tuple, so that materials stay hashable).
ProvenanceValue = str | int | float | bool | tuple[str | int | float | bool, ...]

# Abaqus, "Time domain viscoelasticity" (Abaqus 2017 Materials Guide,
# abaqus-docs.mit.edu/2017/English/SIMACAEMATRefMap/simamat-c-timevisco.htm): "if the
# instantaneous behavior is defined by the hyperfoam model, the deviatoric and volumetric
# constitutive behavior are coupled and it is mandatory to use the same relaxation data for both
# behaviors" (Theory Guide, "Finite-strain viscoelasticity", simathe-c-finitestrvisco.htm, says
# the same).  So a hyperfoam relaxes its whole stress (k_i = g_i), the paper's convention.
_COUPLED_PRONY_K = (
    "must equal prony_g (or be left out) for {model}: shear and bulk are coupled in its energy, "
    "so it relaxes its whole stress (as Abaqus requires)"
)


def default_prony_k(law: Law, g: tuple[float, ...]) -> tuple[float, ...]:
    """The bulk coefficients ``k_i`` a material gets when ``prony_k`` is left out.

    * Decoupled (invariant) laws: ``k_i = 0``, shear-only relaxation, the bulk response stays
      elastic.  Elastomers and gels are nearly incompressible because their bulk modulus comes
      from the liquid-like packing of the chains (and the solvent), which barely relaxes, while
      the shear modulus is the entropic network that does; the usual modelling assumption
      (e.g. COMSOL, "Linear Viscoelasticity": "the viscous part of the deformation is
      incompressible so that the volumetric deformation is purely elastic").  With ``k = g``
      a ``nu = 0.45`` material relaxing by 68 % would also lose 68 % of its bulk modulus.
    * Hyperfoam (not decoupled): ``k_i = g_i``, the whole stress relaxes (Abaqus' rule, see
      ``_COUPLED_PRONY_K``; the paper's Table 2 convention).
    """
    return tuple(0.0 for _ in g) if law.decoupled else g


def _check_prony_k(law: Law, prony: Prony, prefix: str) -> None:
    """Refuse bulk coefficients a law cannot have (``DesignError`` naming ``prony_k``)."""
    if prony.k is not None and not law.decoupled and prony.k != prony.g:
        raise DesignError(f"{prefix}prony_k", _COUPLED_PRONY_K.format(model=law.model))


@dataclasses.dataclass(frozen=True)
class Material:
    """A visco-hyperelastic material.

    ``law``: the hyperelastic law as given (MPa moduli); ``prony``: relaxation (empty =
    elastic), shear coefficients ``g_i`` and optional bulk coefficients ``k_i``
    (``prony.k = None``: the law's default, :func:`default_prony_k`; a ``k`` equal to the
    default is stored as ``None``, so equal materials compare equal); ``moduli``:
    ``"long_term"`` (default, as Abaqus: the law's moduli are the ``t -> inf`` moduli, the
    instantaneous law has its shear moduli divided by ``g_inf`` and its bulk modulus by
    ``k_inf``) or ``"instantaneous"`` (the law's moduli are the ``t = 0+`` moduli); ``name``:
    catalogue name; ``source``: citation of the numbers; ``provenance``: how the numbers were
    obtained (e.g. by ``fingertip fit-material``: tests, strain ranges, rate, fit errors), as
    ``(key, value)`` pairs in the order given (:attr:`provenance_dict`); it does not enter the
    mechanics, but its Drucker-stable ranges (:attr:`drucker_limit_log_strain`) and its tested
    range (``sim.materials._tests.PROVENANCE_KEYS``, read by
    ``sim.protocols.validity.layer_limit``) bound the strains at which a result is trusted.

    When ``k != g`` (:attr:`split_relaxation`) the isochoric and volumetric stresses relax
    apart and the state keeps them apart: ``S0`` has shape ``(2, 3, ...)`` (``[iso, vol]``) and
    ``H`` ``(N_G, 2, 3, ...)``; otherwise ``(3, ...)`` and ``(N_G, 3, ...)``.  The methods
    :meth:`initial_state`, :meth:`instantaneous_stress_tangent`, :meth:`relax`,
    :meth:`history_stress` and :meth:`tangent` hide the difference from the assembly.
    """

    law: Law
    prony: Prony = dataclasses.field(default_factory=Prony)
    moduli: str = "long_term"
    name: str | None = None
    source: str | None = None
    provenance: tuple[tuple[str, ProvenanceValue], ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.law, Law):
            raise TypeError(f"law must be one of the LAWS classes, got {type(self.law)}")
        if not isinstance(self.prony, Prony):
            raise TypeError(f"prony must be a Prony, got {type(self.prony)}")
        if self.moduli not in MODULI:
            raise DesignError("moduli", f"must be one of {', '.join(MODULI)}, got {self.moduli!r}")
        _check_prony_k(self.law, self.prony, "")
        if self.prony.k is not None and self.prony.k == default_prony_k(self.law, self.prony.g):
            object.__setattr__(self, "prony", dataclasses.replace(self.prony, k=None))

    @property
    def provenance_dict(self) -> dict[str, Any]:
        """``provenance`` as the design-file table (lists for tuples)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.provenance}

    @cached_property
    def drucker_limit_log_strain(self) -> float | None:
        """The largest compressive log strain within which the law stays Drucker-stable, from
        the stable ranges ``fingertip fit-material`` recorded in ``provenance``
        (``sim.materials._drucker``); None when none was cut short by an instability. One of
        the two parts of ``provenance`` that the FE reads (with the tested range): its results
        flag a layer strained beyond it (``sim.protocols.validity.check``)."""
        return stable_log_strain(self.law, stable_ranges(dict(self.provenance), "provenance"))

    # --- relaxation coefficients ------------------------------------------------------------
    @cached_property
    def prony_k(self) -> tuple[float, ...]:
        """The bulk coefficients ``k_i`` in force (``prony.k`` or the law's default)."""
        return default_prony_k(self.law, self.prony.g) if self.prony.k is None else self.prony.k

    @property
    def k_inf(self) -> float:
        """Long-term relative bulk modulus ``k_inf = 1 - sum k_i``."""
        return 1.0 - float(sum(self.prony_k))

    @cached_property
    def split_relaxation(self) -> bool:
        """True when shear and bulk relax differently (``k != g``): the split state is used."""
        return self.prony_k != self.prony.g

    @property
    def is_elastic(self) -> bool:
        """True when there is no relaxation (all ``g_i`` and ``k_i`` zero)."""
        return not any(self.prony.g) and not any(self.prony_k)

    def bulk_relaxation(self, t_s: Any) -> Array:
        """``k(t) = 1 - sum k_i (1 - exp(-t / tau_i))`` for ``t_s`` (s, any shape)."""
        return self.prony.relaxation(t_s, self.prony_k)

    # --- the two elastic limits ---------------------------------------------------------------
    @cached_property
    def instantaneous(self) -> Law:
        """The law with the instantaneous (``t = 0+``) moduli: evaluate this for ``S0``/``D0``."""
        if self.moduli == "long_term" and not self.is_elastic:
            if not self.split_relaxation:
                return self.law.scaled(1.0 / self.prony.g_inf)
            return self.law.scaled_moduli(shear=1.0 / self.prony.g_inf, bulk=1.0 / self.k_inf)
        return self.law

    @cached_property
    def long_term(self) -> Law:
        """The law with the long-term (``t -> inf``) moduli: shear moduli ``g_inf`` times, bulk
        modulus ``k_inf`` times the instantaneous ones."""
        if self.moduli == "instantaneous" and not self.is_elastic:
            if not self.split_relaxation:
                return self.law.scaled(self.prony.g_inf)
            return self.law.scaled_moduli(shear=self.prony.g_inf, bulk=self.k_inf)
        return self.law

    # --- the viscoelastic update (what the assembly calls) ------------------------------------
    def initial_state(self, batch: tuple[int, ...], n_voigt: int = 3) -> tuple[Array, Array]:
        """Zero ``(S0, H)`` (undeformed, at rest) for a batch of points; shapes in the class
        docstring (MPa), with ``n_voigt`` stress components: 3 in plane strain, 6 in 3D."""
        parts = (2,) if self.split_relaxation else ()
        shape = (*parts, n_voigt, *batch)
        return np.zeros(shape), np.zeros((self.prony.n_terms, *shape))

    def instantaneous_stress(self, C: Any) -> Array:
        """``S0`` of the instantaneous law at ``C`` (MPa), split when :attr:`split_relaxation`.

        ``C`` of 3 components is plane strain (``[C11, C22, C12]``), of 6 components 3D
        (``[C11, C22, C33, C12, C23, C13]``, :mod:`sim.materials._law3`); the stress has the
        same components. The Prony update and the tangent below act on either alike."""
        law = self.instantaneous
        if np.shape(C)[0] == 6:
            return law.stress3_split(C) if self.split_relaxation else law.stress3(C)
        return law.stress_split(C) if self.split_relaxation else law.stress(C)

    def instantaneous_stress_tangent(self, C: Any) -> tuple[Array, Array]:
        """``(S0, D0)`` of the instantaneous law (MPa), split when :attr:`split_relaxation`;
        plane strain or 3D by the components of ``C`` (:meth:`instantaneous_stress`)."""
        law = self.instantaneous
        if np.shape(C)[0] == 6:
            if self.split_relaxation:
                return law.stress_tangent3_split(C)
            return law.stress_tangent3(C)
        return law.stress_tangent_split(C) if self.split_relaxation else law.stress_tangent(C)

    def relax(
        self, S0_new: Array, S0_old: Array, H_old: Array, dt_s: float
    ) -> tuple[Array, Array, Any]:
        """One recursive step: ``(S, H_new, factor)``, ``S`` (MPa) shape ``(3, ...)``; ``factor``
        goes to :meth:`tangent` (:func:`prony_update`, :func:`prony_update_split`)."""
        if not self.split_relaxation:
            return self.prony.update(S0_new, S0_old, H_old, dt_s)
        prony = self.prony
        return prony_update_split(S0_new, S0_old, H_old, dt_s, prony.g, self.prony_k, prony.tau_s)

    def history_stress(self, S0: Array, H: Array) -> tuple[Array, Any]:
        """``(S, factor)`` with the history ``H`` held as it is (no time passes):
        ``S = g_inf S0 + sum g_i H_i`` (split: plus the bulk terms with ``k``)."""
        if not self.split_relaxation:
            return prony_stress(S0, H, self.prony.g)
        return prony_stress_split(S0, H, self.prony.g, self.prony_k)

    def tangent(self, D0: Array, factor: Any) -> Array:
        """The viscoelastic tangent (MPa), shape ``(3, 3, ...)`` (3D: ``(6, 6, ...)``), from the
        instantaneous ``D0`` and the ``factor`` of :meth:`relax` or :meth:`history_stress`."""
        if not self.split_relaxation:
            return factor * D0
        return factor[0] * D0[0] + factor[1] * D0[1]

    def to_dict(self) -> dict[str, Any]:
        """The design-file table; round-trips through :func:`material_from_spec`."""
        out = {**self.law.to_dict(), **self.prony.to_dict(), "moduli": self.moduli}
        if self.name is not None:
            out["name"] = self.name
        if self.source is not None:
            out["source"] = self.source
        if self.provenance:
            out["provenance"] = self.provenance_dict
        return out


def _text(value: Any, field: str) -> str:
    if not isinstance(value, str) or not value:
        raise DesignError(field, f"must be a non-empty string, got {value!r}")
    return value


def _provenance(value: Any, field: str) -> tuple[tuple[str, ProvenanceValue], ...]:
    """Validate a ``provenance`` table: flat, values text, numbers, booleans or lists of them."""
    if not isinstance(value, Mapping):
        raise DesignError(field, f"must be a table of key = value, got {value!r}")
    scalar = (str, int, float, bool)
    out = []
    for key, item in value.items():
        if isinstance(item, list | tuple) and all(isinstance(x, scalar) for x in item):
            item = tuple(item)
        elif not isinstance(item, scalar):
            raise DesignError(
                f"{field}.{key}",
                f"must be text, a number, a boolean or a list of them, got {item!r}",
            )
        out.append((str(key), item))
    return tuple(out)


def _check_tested_range(provenance: dict[str, Any], source: str | None, field: str) -> None:
    """The tested range a provenance records (``sim.materials._tests.PROVENANCE_KEYS``), which
    the FE's validity check reads: valid, and with a compressive limit (measured, or argued in
    ``tested_note`` for tests in tension only: never none)."""
    from sim.materials._tests import tested_range_from_provenance

    tested = tested_range_from_provenance(provenance, source, field)
    if tested is not None and tested.max_compressive_log_strain is None:
        raise DesignError(
            f"{field}.max_compressive_log_strain",
            "is required with a tested range: the compressive log strain the tests reached, or "
            "one argued in tested_note when no test compressed the material",
        )


def material_from_table(table: Mapping[str, Any], field: str = "material") -> Material:
    """Build a ``Material`` from an inline design-file table (errors name ``f"{field}.key"``).

    Keys: ``model`` (one of ``LAWS``), the law's keys, optional ``prony_g``, ``prony_tau_s``
    (lists of equal length, absent = elastic), optional ``prony_k`` (bulk coefficients, as long
    as ``prony_g``; default :func:`default_prony_k`), ``moduli`` (``"long_term"`` default or
    ``"instantaneous"``), ``name``, ``source``, ``provenance`` (a flat table, kept as it is).
    Unknown keys are rejected.
    """
    if not isinstance(table, Mapping):
        raise DesignError(field, f"must be a catalogue name or a table, got {table!r}")
    known = ", ".join(LAWS)
    if "model" not in table:
        raise DesignError(f"{field}.model", f"is required, one of: {known}")
    model = table["model"]
    if not isinstance(model, str) or model not in LAWS:
        raise DesignError(f"{field}.model", f"unknown model {model!r}; known models: {known}")
    law_cls = LAWS[model]
    v.known_keys(table, (*law_cls.keys(), *_MATERIAL_KEYS), field)
    law = law_cls.from_params({k: table[k] for k in law_cls.keys() if k in table}, field)
    g, tau = Prony.check(table.get("prony_g", ()), table.get("prony_tau_s", ()), f"{field}.")
    k = Prony.check_k(table["prony_k"], g, f"{field}.") if "prony_k" in table else None
    prony = Prony(g, tau, k)
    _check_prony_k(law, prony, f"{field}.")
    moduli = table.get("moduli", "long_term")
    if moduli not in MODULI:
        raise DesignError(f"{field}.moduli", f"must be one of {', '.join(MODULI)}, got {moduli!r}")
    name = _text(table["name"], f"{field}.name") if "name" in table else None
    source = _text(table["source"], f"{field}.source") if "source" in table else None
    provenance = (
        _provenance(table["provenance"], f"{field}.provenance") if "provenance" in table else ()
    )
    stable_ranges(dict(provenance), f"{field}.provenance")  # the FE reads them: checked here
    _check_tested_range(dict(provenance), source, f"{field}.provenance")
    return Material(
        law=law, prony=prony, moduli=moduli, name=name, source=source, provenance=provenance
    )
