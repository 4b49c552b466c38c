"""Heavy functions imported on first use, so that ``import sim`` stays light.

``import sim`` (the CLI's parser, the surrogate reading metric names and design spaces) should
not pay for scipy.special; the FE code calls these thousands of times, where the import
statement is a dictionary look-up (~0.3 us against ~1 ms per evaluation).
"""

from __future__ import annotations

from typing import Any


def exprel(x: Any) -> Any:
    """``(e^x - 1) / x``, 1 at ``x = 0`` (``scipy.special.exprel``, elementwise)."""
    from scipy.special import exprel as _exprel

    return _exprel(x)
