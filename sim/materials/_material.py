"""``Material`` = hyperelastic law + Prony series, and its design-file (TOML table) form."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from functools import cached_property
from typing import Any

from sim.errors import DesignError
from sim.materials import _validate as v
from sim.materials._hyperfoam import Hyperfoam
from sim.materials._invariant import MooneyRivlin, NeoHookean, Yeoh
from sim.materials._law import Law
from sim.materials._prony import Prony

#: Registry of the hyperelastic laws, design-file ``model`` name -> class.
LAWS: dict[str, type[Law]] = {cls.model: cls for cls in (Hyperfoam, NeoHookean, MooneyRivlin, Yeoh)}

#: Allowed values of ``moduli``: which moduli the law's parameters are.
MODULI = ("long_term", "instantaneous")

# Keys of a material table besides the law's own keys.
_MATERIAL_KEYS = ("model", "prony_g", "prony_tau_s", "moduli", "name", "source")


@dataclasses.dataclass(frozen=True)
class Material:
    """A visco-hyperelastic material.

    ``law``: the hyperelastic law as given (MPa moduli); ``prony``: relaxation (empty =
    elastic); ``moduli``: ``"long_term"`` (default, as Abaqus: the law's moduli are the
    ``t -> inf`` moduli, the instantaneous law is the law scaled by ``1 / g_inf``) or
    ``"instantaneous"`` (the law's moduli are the ``t = 0+`` moduli); ``name``: catalogue name;
    ``source``: citation of the numbers.
    """

    law: Law
    prony: Prony = dataclasses.field(default_factory=Prony)
    moduli: str = "long_term"
    name: str | None = None
    source: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.law, Law):
            raise TypeError(f"law must be one of the LAWS classes, got {type(self.law)}")
        if not isinstance(self.prony, Prony):
            raise TypeError(f"prony must be a Prony, got {type(self.prony)}")
        if self.moduli not in MODULI:
            raise DesignError("moduli", f"must be one of {', '.join(MODULI)}, got {self.moduli!r}")

    @property
    def is_elastic(self) -> bool:
        """True when there is no relaxation."""
        return self.prony.is_elastic

    @cached_property
    def instantaneous(self) -> Law:
        """The law with the instantaneous (``t = 0+``) moduli: evaluate this for ``S0``/``D0``."""
        if self.moduli == "long_term" and not self.is_elastic:
            return self.law.scaled(1.0 / self.prony.g_inf)
        return self.law

    @cached_property
    def long_term(self) -> Law:
        """The law with the long-term (``t -> inf``) moduli, ``g_inf`` times the instantaneous."""
        if self.moduli == "instantaneous" and not self.is_elastic:
            return self.law.scaled(self.prony.g_inf)
        return self.law

    def to_dict(self) -> dict[str, Any]:
        """The design-file table; round-trips through :func:`material_from_spec`."""
        out = {**self.law.to_dict(), **self.prony.to_dict(), "moduli": self.moduli}
        if self.name is not None:
            out["name"] = self.name
        if self.source is not None:
            out["source"] = self.source
        return out


def _text(value: Any, field: str) -> str:
    if not isinstance(value, str) or not value:
        raise DesignError(field, f"must be a non-empty string, got {value!r}")
    return value


def material_from_table(table: Mapping[str, Any], field: str = "material") -> Material:
    """Build a ``Material`` from an inline design-file table (errors name ``f"{field}.key"``).

    Keys: ``model`` (one of ``LAWS``), the law's keys, optional ``prony_g``, ``prony_tau_s``
    (lists of equal length, absent = elastic), ``moduli`` (``"long_term"`` default or
    ``"instantaneous"``), ``name``, ``source``.  Unknown keys are rejected.
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
    moduli = table.get("moduli", "long_term")
    if moduli not in MODULI:
        raise DesignError(f"{field}.moduli", f"must be one of {', '.join(MODULI)}, got {moduli!r}")
    name = _text(table["name"], f"{field}.name") if "name" in table else None
    source = _text(table["source"], f"{field}.source") if "source" in table else None
    return Material(law=law, prony=Prony(g, tau), moduli=moduli, name=name, source=source)
