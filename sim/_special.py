"""Special functions the FE code needs, in numpy (``import sim`` and ``fingertip simulate``
do not pay ~0.1 s for importing ``scipy.special`` for one function)."""

from __future__ import annotations

from typing import Any

import numpy as np

_EPS = np.finfo(float).eps


def exprel(x: Any) -> Any:
    """``(e^x - 1) / x`` elementwise, 1 at ``x = 0``.

    The same bits as ``scipy.special.exprel`` (``expm1(x) / x``, exactly 1 for
    ``|x| < DBL_EPSILON``, inf beyond overflow); ``tests/test_special.py`` compares them."""
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        y = np.expm1(x) / x
    return np.where(np.abs(x) < _EPS, 1.0, y)[()]
