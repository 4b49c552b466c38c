"""Parametric fingertip cross-section: a superellipse pulp on a flat rigid base, in layers.

The outer surface is the superellipse |x/a|^n + |y/b|^n = 1, y >= 0, with half-width ``a`` and
height ``b`` (mm). The straight bottom edge y = 0, |x| <= a, is bonded to the rigid bone and fully
fixed (paper §3.1). Layers follow the outer surface, outermost first: the interface below the
outer layers of cumulative thickness T is the superellipse with semi-axes (a - T, b - T) and the
same exponent, so each layer has exactly its thickness at the apex and at the base, and close to
it in between (exactly for n = 2 and a = b). The last layer fills the rest.

Only the half x >= 0 is meshed: every protocol is symmetric about x = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DesignError

__all__ = ["REFERENCE_GEOMETRY", "Geometry", "superellipse_points"]


def check_in_range(field_name: str, value: object, lo: float, hi: float) -> None:
    """``DesignError`` naming ``field_name`` unless ``value`` is a number (not a bool) in
    [lo, hi] (NaN fails the comparison too)."""
    is_number = isinstance(value, int | float) and not isinstance(value, bool)
    if not (is_number and lo <= value <= hi):
        raise DesignError(field_name, f"must be in [{lo}, {hi}], got {value!r}")


@dataclass(frozen=True)
class Geometry:
    """Cross-section of the pulp.

    Attributes:
        half_width_mm: a, half the width of the pulp at the base (mm).
        height_mm: b, height of the apex above the base (mm).
        exponent: n of the superellipse; 2 is the semi-ellipse, smaller is pointier.
    """

    half_width_mm: float = 5.84
    height_mm: float = 5.48
    exponent: float = 1.5

    def __post_init__(self) -> None:
        for name, lo, hi in (
            ("half_width_mm", 1.0, 50.0),
            ("height_mm", 1.0, 50.0),
            ("exponent", 1.2, 8.0),
        ):
            check_in_range(f"geometry.{name}", getattr(self, name), lo, hi)

    def to_dict(self) -> dict[str, float]:
        return {
            "half_width_mm": float(self.half_width_mm),
            "height_mm": float(self.height_mm),
            "exponent": float(self.exponent),
        }

    def inset(self, depth_mm: float) -> Geometry:
        """The interface curve ``depth_mm`` below the outer surface (same exponent)."""
        return Geometry(self.half_width_mm - depth_mm, self.height_mm - depth_mm, self.exponent)


REFERENCE_GEOMETRY = Geometry()


def superellipse_points(a: float, b: float, n: float, theta: np.ndarray) -> np.ndarray:
    """Points of the first-quadrant superellipse at parameters ``theta`` in [0, pi/2].

    theta = 0 is the base corner (a, 0), theta = pi/2 the apex (0, b). Returns shape (len, 2).
    """
    c = np.clip(np.cos(theta), 0.0, None)
    s = np.clip(np.sin(theta), 0.0, None)
    return np.column_stack([a * c ** (2.0 / n), b * s ** (2.0 / n)])


def sample_curve(a: float, b: float, n: float, size_fn, n_fine: int = 4000) -> np.ndarray:
    """Sample the quarter superellipse from the apex (0, b) to the corner (a, 0).

    The spacing follows the target element size ``size_fn(points) -> h_mm`` (integrating
    ds / h along the arc length), so the boundary is resolved where the mesh is fine.
    """
    theta = np.linspace(np.pi / 2, 0.0, n_fine)
    pts = superellipse_points(a, b, n, theta)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    mid = 0.5 * (pts[1:] + pts[:-1])
    count = np.concatenate([[0.0], np.cumsum(seg / size_fn(mid))])
    n_seg = max(2, int(np.ceil(count[-1])))
    targets = np.linspace(0.0, count[-1], n_seg + 1)
    arclen = np.concatenate([[0.0], np.cumsum(seg)])
    s_new = np.interp(targets, count, arclen)
    x = np.interp(s_new, arclen, pts[:, 0])
    y = np.interp(s_new, arclen, pts[:, 1])
    out = np.column_stack([x, y])
    out[0] = (0.0, b)
    out[-1] = (a, 0.0)
    return out
