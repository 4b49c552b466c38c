"""Parsing and validation of design-file values; every failure is a ``DesignError``."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from numbers import Real
from typing import Any

from sim.errors import DesignError

NU_MIN = -1.0
NU_MAX = 0.5


def number(value: Any, field: str) -> float:
    """Return ``value`` as a finite float; booleans and strings are rejected."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise DesignError(field, f"must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise DesignError(field, f"must be a finite number, got {out}")
    return out


def number_list(value: Any, field: str, min_len: int, max_len: int) -> tuple[float, ...]:
    """Return a list/tuple of ``min_len``..``max_len`` finite numbers as a tuple of floats."""
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, Iterable):
        raise DesignError(field, f"must be a list of {min_len} to {max_len} numbers, got {value!r}")
    items = tuple(value)
    if not min_len <= len(items) <= max_len:
        raise DesignError(
            field, f"must be a list of {min_len} to {max_len} numbers, got {len(items)}"
        )
    return tuple(number(v, f"{field}[{i}]") for i, v in enumerate(items))


def positive(value: float, field: str) -> float:
    """Check ``value > 0``."""
    if not value > 0.0:
        raise DesignError(field, f"must be > 0, got {value:g}")
    return value


#: The initial (small-strain) shear modulus a material may have, MPa: [1e-4, 1e3], from a gel
#: that still holds the shape of a fingertip to far beyond any elastomer. Not what is realistic
#: for a skin (the design spaces' 2.5 kPa-0.35 MPa are, docs/design_space.md), what is physical:
#:
#: - Low, 1e-4 MPa = 0.1 kPa: 29 times below the softest material in the catalogue (Dragon
#:   Skin FX-Pro + Slacker, 2.89 kPa, fitted to Marechal et al., Soft Robotics 8(3) (2021)
#:   284-297) and below the softest soft tissue, brain (shear moduli of about 1 kPa, Budday et
#:   al., Acta Biomaterialia 48 (2017) 319-340). Below it a fingertip cannot hold its own shape:
#:   its own weight strains a 6 mm tall pad by rho g h / E = 1000 kg/m^3 x 9.81 m/s^2 x 6 mm /
#:   (3 x 100 Pa) = 20 % at 0.1 kPa (E = 3 mu, nearly incompressible), before any touch.
#: - High, 1e3 MPa = 1 GPa: the shear modulus of a glassy polymer (Young's moduli of 1-3 GPa
#:   below the glass transition, e.g. Ward & Sweeney, Mechanical Properties of Solid Polymers,
#:   3rd ed. (2013), ch. 2), not of a rubber: an elastomer's entropic modulus, G = rho R T /
#:   M_c, stays within a few MPa, and the stiffest polyurethane elastomers reach tens of MPa;
#:   the catalogue's stiffest is 0.31 MPa (RTV615). A hyperelastic law beyond it describes no
#:   material it was made for (issue 31: mu_MPa = 1e12 gave a plate force of 9.97e13 N).
MU0_MIN_MPA = 1e-4
MU0_MAX_MPA = 1e3


def moduli_in_range(mu0: float, terms: Mapping[str, float | tuple[float, ...]], field: str) -> None:
    """A law's moduli against the physical range (``MU0_MIN_MPA``, ``MU0_MAX_MPA``): its initial
    shear modulus ``mu0`` within it (the error names the first of ``terms``), and every term of
    its moduli ``terms`` (field -> value or values, MPa; a term may be small, or negative where
    the law allows it) no larger than ``MU0_MAX_MPA`` in magnitude: a term stiffer than any
    elastomer is no elastomer either (or a fit whose terms cancel, which the data cannot pin
    down)."""
    allowed = f"[{MU0_MIN_MPA:g}, {MU0_MAX_MPA:g}] MPa (a gel that holds its shape to a stiff "
    allowed += "elastomer)"
    first = next(iter(terms))
    if not MU0_MIN_MPA <= mu0 <= MU0_MAX_MPA:
        raise DesignError(
            f"{field}.{first}", f"initial shear modulus {mu0:g} MPa is outside {allowed}"
        )
    for name, value in terms.items():
        values = value if isinstance(value, tuple) else (value,)
        for i, x in enumerate(values):
            if abs(x) > MU0_MAX_MPA:
                which = f"{name}[{i}]" if isinstance(value, tuple) else name
                raise DesignError(
                    f"{field}.{name}",
                    f"{which} = {x:g} MPa is beyond +-{MU0_MAX_MPA:g} MPa (stiffer than any "
                    "elastomer)",
                )


def poisson(value: float, field: str) -> float:
    """Check Poisson's ratio: compressible only, ``-1 < nu < 0.5``."""
    if not NU_MIN < value < NU_MAX:
        hint = (
            "; incompressible materials are not supported, use nu <= 0.499"
            if value >= NU_MAX
            else ""
        )
        raise DesignError(field, f"must be in (-1, 0.5), got {value:g}{hint}")
    return value


def known_keys(params: Mapping[str, Any], allowed: Iterable[str], field: str) -> None:
    """Reject keys not in ``allowed`` (typos must not pass silently)."""
    allowed = tuple(allowed)
    for key in params:
        if key not in allowed:
            raise DesignError(
                f"{field}.{key}", f"unknown key; allowed keys: {', '.join(sorted(allowed))}"
            )
