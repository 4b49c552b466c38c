"""``exprel`` for the laws (the Prony update, the hyperfoam) and the fitting, imported from
scipy.special on first use.

``import sim`` stays light (``tests/test_imports.py``): the design schema, the CLI's parser and
the surrogate read designs through ``sim`` without loading scipy. A numpy copy of ``exprel``
(``expm1(x) / x``) differed from scipy's by an ulp on some CPUs, because numpy's vectorised
``expm1`` is chosen by CPU; scipy's scalar implementation is used instead."""

from __future__ import annotations

from typing import Any


def exprel(x: Any) -> Any:
    """``(e^x - 1) / x`` elementwise, 1 at ``x = 0`` (``scipy.special.exprel``)."""
    from scipy.special import exprel as _exprel

    return _exprel(x)
