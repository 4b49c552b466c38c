"""Continuous material families of the design spaces: a layer's ``material`` is a catalogue name
or one of these family names, and then its properties are the layer's family parameters.

Every family has a long-term small-strain shear modulus ``mu0_MPa``, a nonlinearity ``alpha``
and three Prony terms sharing the total relaxation ``g_total`` equally at times
``tau_s * time_ratios``; some have a Poisson's ratio ``nu`` (``Family.keys`` says which). Which
parameters a layer uses is decided here and only here (:func:`family_uses`).

* ``gel``: a solid silicone gel or elastomer. Decoupled one-term Ogden law, nearly
  incompressible (``GEL_NU``), relaxing in shear only (the bulk response of a rubber or gel
  stays elastic: ``sim.materials.default_prony_k``). Terms at tau/10, tau, 10 tau: a gel's
  relaxation spectrum is broad (two decades here), not one time.
* ``foam``: a soft open-cell foam core. One-term Abaqus hyperfoam with its own Poisson's ratio
  ``nu`` (0 to about 0.3 for flexible foams), relaxing its whole stress: a foam's bulk response
  is the bending of its cell walls and the flow of air through them, so it relaxes as its shear
  does (Abaqus' rule for the hyperfoam). Terms at tau/10, tau, 10 tau.
* ``param``: the earlier compressible family (one-term hyperfoam, any ``nu``, whole-stress
  relaxation, terms at tau/3, tau, 3 tau). Kept so that run folders, sweeps and checkpoints made
  with it still load; the shipped spaces no longer use it (a "gel" with nu = 0.45 whose bulk
  modulus relaxes by 68 % does not exist: see docs/design_space.md).

The bounds of each family's parameters in the shipped spaces, with their sources, are in
``docs/design_space.md``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DesignError
from ..materials import LAWS, Material, Prony
from ..materials._validate import MU0_MAX_MPA, MU0_MIN_MPA

__all__ = [
    "FAMILIES",
    "FAMILY_KEYS",
    "GEL_NU",
    "Family",
    "family_material",
    "family_of",
    "family_uses",
    "family_values",
    "is_family",
]

#: every key a family may use, in the order a layer table lists them
FAMILY_KEYS = ("mu0_MPa", "alpha", "nu", "g_total", "tau_s")

#: Poisson's ratio of the gel family. Silicone gels and elastomers have a bulk modulus of about
#: 1 GPa against shear moduli of kPa to a fraction of a MPa, so their true nu exceeds 0.4999.
#: The displacement-based FE needs nu < 0.5; at 0.499 a soft two-layer gel design's tapping
#: displacements are within 2-3 % of their incompressible limit (+1.9 % from the top, +2.3 %
#: from touch, plate force -2.9 %; linear in 1 - 2 nu between 0.495, 0.499 and 0.4995; mesh
#: refinement x2 moves them by 0.3 %: docs/design_space.md, "Gel compressibility"), while
#: 0.4995 gains about 1 % for about 20 % more Newton work.
GEL_NU = 0.499


def _prony(g_total: float, tau_s: float, ratios: tuple[float, ...]) -> Prony:
    if g_total <= 0:
        return Prony()
    return Prony(
        tuple(float(g_total) / len(ratios) for _ in ratios),
        tuple(float(tau_s) * r for r in ratios),
    )


def _hyperfoam(v: Mapping[str, float], ratios: tuple[float, ...]) -> Material:
    law = LAWS["hyperfoam"](
        mu_MPa=(float(v["mu0_MPa"]),), alpha=(float(v["alpha"]),), nu=float(v["nu"])
    )
    return Material(law, _prony(v["g_total"], v["tau_s"], ratios), "long_term")


def _gel(v: Mapping[str, float], ratios: tuple[float, ...]) -> Material:
    law = LAWS["ogden"](mu_MPa=(float(v["mu0_MPa"]),), alpha=(float(v["alpha"]),), nu=GEL_NU)
    return Material(law, _prony(v["g_total"], v["tau_s"], ratios), "long_term")


@dataclass(frozen=True)
class Family:
    """A continuous material family: the layer parameters it uses (``keys``), the relaxation
    times of its three Prony terms relative to ``tau_s`` (``time_ratios``) and the admissible
    range of each key (``limits``: key -> (low, high, text); low exclusive for times and
    alpha)."""

    name: str
    keys: tuple[str, ...]
    time_ratios: tuple[float, ...]
    build: Callable[[Mapping[str, float], tuple[float, ...]], Material]
    limits: Mapping[str, tuple[float, float, str]]
    description: str

    def material(self, values: Mapping[str, float]) -> Material:
        """The material of a layer with these family parameters (keys of ``self.keys``)."""
        return self.build(values, self.time_ratios)

    def admits(self, key: str, value: float) -> bool:
        """Whether ``value`` of ``key`` is within ``limits`` (low exclusive for ``alpha`` and
        ``tau_s``: they must be > 0; a modulus's low end is a physical bound, inclusive)."""
        low, high, _ = self.limits[key]
        strict_low = key in ("alpha", "tau_s")
        return (value > low if strict_low else value >= low) and value <= high


#: what the laws admit (not what is realistic: the spaces' bounds, argued in
#: docs/design_space.md, are that): a modulus in the physical range of a user's material
#: (``sim.materials._validate.MU0_MIN_MPA`` / ``MU0_MAX_MPA``, argued there); times positive;
#: alpha != 0 for an Ogden-type term, capped at 50 as the space parser did before this module
#: (a guard against typos, far above any fitted value: the catalogue's largest is 15.5,
#: silicone_gls40); g_total < 1 keeps
#: a solid, and 0.95 keeps the instantaneous modulus within 20x the long-term one.
_COMMON_LIMITS = {
    "mu0_MPa": (MU0_MIN_MPA, MU0_MAX_MPA, f"in [{MU0_MIN_MPA:g}, {MU0_MAX_MPA:g}] MPa"),
    "alpha": (0.0, 50.0, "in (0, 50]"),
    "g_total": (0.0, 0.95, "in [0, 0.95]"),
    "tau_s": (0.0, float("inf"), "> 0"),
}

FAMILIES: dict[str, Family] = {
    "gel": Family(
        "gel",
        ("mu0_MPa", "alpha", "g_total", "tau_s"),
        (0.1, 1.0, 10.0),
        _gel,
        _COMMON_LIMITS,
        f"nearly incompressible silicone gel or elastomer (Ogden, nu = {GEL_NU}), shear relaxation",
    ),
    "foam": Family(
        "foam",
        FAMILY_KEYS,
        (0.1, 1.0, 10.0),
        _hyperfoam,
        {**_COMMON_LIMITS, "nu": (0.0, 0.3, "in [0, 0.3] (a flexible foam)")},
        "soft foam (hyperfoam, 0 <= nu <= 0.3), whole-stress relaxation",
    ),
    "param": Family(
        "param",
        FAMILY_KEYS,
        (1.0 / 3.0, 1.0, 3.0),
        _hyperfoam,
        {**_COMMON_LIMITS, "nu": (-0.999, 0.499, "in [-0.999, 0.499]")},
        "earlier compressible family (hyperfoam, any nu), whole-stress relaxation",
    ),
}


def is_family(material: Any) -> bool:
    """Whether a layer's material name is a continuous family (not a catalogue entry)."""
    return isinstance(material, str) and material in FAMILIES


def family_uses(material: Any, key: str) -> bool:
    """Whether a layer of ``material`` uses family parameter ``key`` (the one rule)."""
    return is_family(material) and key in FAMILIES[material].keys


def family_material(material: str, values: Mapping[str, float]) -> Material:
    """The material of family ``material`` with parameters ``values`` (extra keys ignored)."""
    fam = FAMILIES[material]
    return fam.material({k: float(values[k]) for k in fam.keys})


def family_values(mat: Material, family: str) -> dict[str, float] | None:
    """The parameters of ``family`` that rebuild ``mat`` (to round-off), or None when ``mat`` is
    not a member of that family (another law, Prony times or shares, Poisson's ratio...)."""
    law, g, tau = mat.law, mat.prony.g, mat.prony.tau_s
    fam = FAMILIES[family]
    try:
        values = {
            "mu0_MPa": float(law.mu_MPa[0]),
            "alpha": float(law.alpha[0]),
            "nu": float(law.nu),
            "g_total": float(sum(g)),
            "tau_s": float(tau[list(fam.time_ratios).index(1.0)]) if tau else 1.0,
        }
        built = family_material(family, values)
    except (AttributeError, IndexError, TypeError, ValueError, DesignError):
        return None
    same = (
        built.law.model == law.model
        and built.law.to_dict().keys() == law.to_dict().keys()
        and all(
            np.allclose(np.atleast_1d(built.law.to_dict()[k]), np.atleast_1d(v), rtol=1e-9)
            for k, v in law.to_dict().items()
            if k != "model"
        )
        and len(built.prony.g) == len(g)
        and np.allclose(built.prony.g, g, rtol=1e-9)
        and np.allclose(built.prony.tau_s, tau, rtol=1e-9)
        and built.prony_k == mat.prony_k
        and built.moduli == mat.moduli
    )
    return {k: values[k] for k in fam.keys} if same else None


def family_of(mat: Material) -> str | None:
    """The family ``mat`` is a member of (``family_values``, with every parameter within the
    family's ``limits``), first in ``FAMILIES``' order; None for any other material. A family's
    material carries no name, and one written to a design file (an answer) is an inline table:
    this is how either is known as the family's (its tested range, ``sim.protocols.validity``)."""
    for name in FAMILIES:
        values = family_values(mat, name)
        if values is not None and all(FAMILIES[name].admits(k, v) for k, v in values.items()):
            return name
    return None
