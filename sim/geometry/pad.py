"""Parametric 3D fingertip pad: the 2D superellipse section swept along the finger, in layers.

Coordinates (mm): x across the finger, y up from the rigid base, z along the finger. The cross
section at z is the 2D section (``sim.geometry.section.Geometry``: semi-axes a, b, exponent n),
scaled by

    s(z) = (1 - |z/c|^m)^(1/m),      |z| <= c,

with c = ``half_length_mm`` and m = ``length_exponent``. The body is therefore

    B(a, b, c) = { y >= 0 :  G(x, y, z) <= 1 },   G = (|x/a|^n + |y/b|^n)^(m/n) + |z/c|^m,

(|x/a|^n + |y/b|^n <= s(z)^n is G <= 1), so its x = 0 section is (y/b)^m + (z/c)^m <= 1 and its
footprint on the base y = 0 is |x/a|^m + |z/c|^m <= 1. G is positively homogeneous of degree m
in (x/a, y/b, z/c): the boundary point along any direction v of the octant is

    sigma(v) diag(a, b, c) v,    sigma(v) = G_1(v)^(-1/m),

with G_1 the level function of the unit body (a = b = c = 1) -- in closed form, no root finding.
Layers follow the outer surface, outermost first: the interface at cumulative depth T is the
boundary of B(a - T, b - T, c - T) (same exponents), so each layer has exactly its thickness at
the apex (0, b, 0), at the ends (+-a, 0, 0) of the base and at the tip end (0, 0, +-c), as in 2D.
B(a', b', c') grows with each semi-axis, so the interfaces are nested.

Volume (Euler's Beta integral  int_0^1 (1 - u^p)^q du = G(1 + 1/p) G(1 + q) / G(1 + q + 1/p),
G = Gamma): the section x >= 0 of B at z is the quarter superellipse of semi-axes
(a s(z), b s(z)), of area A(z) = s(z)^2 A_half with

    A_half = a b Gamma(1 + 1/n)^2 / Gamma(1 + 2/n)            (pi a b / 4 for n = 2),

and  int_0^c s(z)^2 dz = c Gamma(1 + 1/m) Gamma(1 + 2/m) / Gamma(1 + 3/m)  (2c/3 for m = 2), so
the quarter x >= 0, z >= 0 has the volume

    V_quarter = a b c Gamma(1+1/n)^2 / Gamma(1+2/n) * Gamma(1+1/m) Gamma(1+2/m) / Gamma(1+3/m)

(pi a b c / 6 for n = m = 2, an eighth of an ellipsoid), the whole pad 4 V_quarter; a layer's
volume is the difference of two such bodies' volumes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DesignError
from .section import REFERENCE_GEOMETRY, Geometry, check_in_range

__all__ = [
    "HALF_LENGTH_RANGE_MM",
    "LENGTH_EXPONENT_RANGE",
    "REFERENCE_PAD",
    "PadGeometry",
    "half_section_area_mm2",
    "level",
    "unit_radius",
]

# What a design file may ask for: the same bounds as the section's half-width (1-50 mm,
# sim.geometry.section.Geometry), a shape, not an anatomy check. The anatomical default (11 mm)
# and the design space's range (8-14 mm) are argued in docs/fingertip_3d.md, "Pad geometry".
HALF_LENGTH_RANGE_MM = (1.0, 50.0)
# The section's exponent bounds (sim.geometry.section.Geometry); the design space's 2-8 and the
# default 2 (an ellipsoidal side profile): docs/fingertip_3d.md, "Pad geometry".
LENGTH_EXPONENT_RANGE = (1.2, 8.0)


@dataclass(frozen=True)
class PadGeometry:
    """The pad: the 2D ``section`` (a, b, n) swept along z by s(z) = (1 - |z/c|^m)^(1/m).

    Attributes:
        section: the cross-section across the finger at z = 0 (``sim.geometry.section.Geometry``).
        half_length_mm: c, half the length of the pad along the finger (mm).
        length_exponent: m, the exponent of the x = 0 section (y/b)^m + (z/c)^m <= 1; 2 is a
            semi-ellipse, smaller is pointier, larger is blunter.
    """

    section: Geometry = REFERENCE_GEOMETRY
    half_length_mm: float = 11.0  # a 22 mm pad: docs/fingertip_3d.md, "Pad geometry"
    length_exponent: float = 2.0  # ellipsoidal side profile: docs/fingertip_3d.md

    def __post_init__(self) -> None:
        if not isinstance(self.section, Geometry):
            raise DesignError("geometry.section", f"must be a Geometry, got {self.section!r}")
        for name, (lo, hi) in (
            ("half_length_mm", HALF_LENGTH_RANGE_MM),
            ("length_exponent", LENGTH_EXPONENT_RANGE),
        ):
            check_in_range(f"geometry.{name}", getattr(self, name), lo, hi)

    def to_dict(self) -> dict[str, float]:
        """The section's keys plus ``half_length_mm`` and ``length_exponent``."""
        return {
            **self.section.to_dict(),
            "half_length_mm": float(self.half_length_mm),
            "length_exponent": float(self.length_exponent),
        }

    @property
    def exponents(self) -> tuple[float, float]:
        """(n, m): the section's exponent and the length exponent."""
        return float(self.section.exponent), float(self.length_exponent)

    def semi_axes_mm(self, depth_mm: float = 0.0) -> tuple[float, float, float]:
        """(a - T, b - T, c - T): the semi-axes of the body ``depth_mm`` = T below the surface."""
        return (
            float(self.section.half_width_mm) - depth_mm,
            float(self.section.height_mm) - depth_mm,
            float(self.half_length_mm) - depth_mm,
        )

    def level(self, points: np.ndarray, depth_mm: float = 0.0) -> np.ndarray:
        """G(points) (...,) of the body ``depth_mm`` below the surface: < 1 inside, 1 on its
        boundary surface (not counting the base y = 0), > 1 outside."""
        return level(points, self.semi_axes_mm(depth_mm), *self.exponents)

    def surface_points(self, directions: np.ndarray, depth_mm: float = 0.0) -> np.ndarray:
        """Boundary points (..., 3) of the body ``depth_mm`` below the surface along the scaled
        directions ``directions`` (..., 3) (components >= 0, not all 0):
        sigma(v) diag(a - T, b - T, c - T) v."""
        v = np.asarray(directions, dtype=float)
        return (
            unit_radius(v, *self.exponents)[..., None] * v * np.array(self.semi_axes_mm(depth_mm))
        )

    def volume_mm3(self, depth_mm: float = 0.0, quarter: bool = False) -> float:
        """Volume of the body ``depth_mm`` below the surface (closed form, module docstring);
        ``quarter``: of its part x >= 0, z >= 0 (the meshed quarter)."""
        a, b, c = self.semi_axes_mm(depth_mm)
        n, m = self.exponents
        v = half_section_area_mm2(a, b, n) * c * _beta_integral(m, 2.0 / m)
        return v if quarter else 4.0 * v

    def layer_volumes_mm3(
        self, thicknesses_mm: tuple[float, ...] = (), quarter: bool = False
    ) -> tuple[float, ...]:
        """Volumes of the layers, outermost first, for the thicknesses of all layers but the
        last (which fills the rest); ``quarter``: of their parts x >= 0, z >= 0."""
        depths = [0.0, *np.cumsum(thicknesses_mm).tolist()]
        bodies = [self.volume_mm3(d, quarter) for d in depths] + [0.0]
        return tuple(bodies[k] - bodies[k + 1] for k in range(len(depths)))

    def check_layers(self, thicknesses_mm: tuple[float, ...]) -> None:
        """``DesignError`` unless each thickness is >= ``MIN_LAYER_MM`` and the layers leave a
        core of ``MIN_CORE_MM`` along every semi-axis (``sim.design.skin``'s limits, with c)."""
        from ..design import MIN_CORE_MM, MIN_LAYER_MM

        for k, t in enumerate(thicknesses_mm):
            ok = isinstance(t, int | float) and not isinstance(t, bool) and t >= MIN_LAYER_MM
            if not ok:
                raise DesignError(
                    f"layers[{k}].thickness_mm", f"must be a number >= {MIN_LAYER_MM}, got {t!r}"
                )
        total = float(sum(thicknesses_mm))
        limit = min(self.semi_axes_mm()) - MIN_CORE_MM
        if total > limit:
            raise DesignError(
                "layers.thickness_mm",
                f"outer layers total {total:g} mm; must be <= {limit:g} mm "
                f"(min(half_width, height, half_length) - {MIN_CORE_MM} mm) to leave a core",
            )


REFERENCE_PAD = PadGeometry()


def level(
    points: np.ndarray, semi_axes_mm: tuple[float, float, float], n: float, m: float
) -> np.ndarray:
    """G = (|x/a|^n + |y/b|^n)^(m/n) + |z/c|^m at ``points`` (..., 3): the body is G <= 1."""
    p = np.abs(np.asarray(points, dtype=float)) / np.asarray(semi_axes_mm, dtype=float)
    return (p[..., 0] ** n + p[..., 1] ** n) ** (m / n) + p[..., 2] ** m


def unit_radius(directions: np.ndarray, n: float, m: float) -> np.ndarray:
    """sigma(v) = G_1(v)^(-1/m) (...,): sigma(v) v is on the boundary of the unit body
    (a = b = c = 1) for any v (..., 3) with components >= 0, not all 0 (G_1 is homogeneous of
    degree m)."""
    return level(directions, (1.0, 1.0, 1.0), n, m) ** (-1.0 / m)


def half_section_area_mm2(a: float, b: float, n: float) -> float:
    """Area of the section's half x >= 0, y >= 0 (the 2D mesh's domain):
    a b Gamma(1 + 1/n)^2 / Gamma(1 + 2/n)."""
    return a * b * _beta_integral(n, 1.0 / n)


def _beta_integral(p: float, q: float) -> float:
    """int_0^1 (1 - u^p)^q du = Gamma(1 + 1/p) Gamma(1 + q) / Gamma(1 + q + 1/p)."""
    return math.gamma(1.0 + 1.0 / p) * math.gamma(1.0 + q) / math.gamma(1.0 + q + 1.0 / p)
