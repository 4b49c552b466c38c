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
