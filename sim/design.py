"""Skin designs: TOML design files <-> frozen dataclasses, with validation.

A design file::

    [geometry]                    # optional: the reference geometry when left out
    half_width_mm = 5.84
    height_mm = 5.48
    exponent = 1.5
    half_length_mm = 11.0         # optional, the 3D pad only (sim.geometry3d): c
    length_exponent = 2.0         # optional, the 3D pad only: m
    [[layers]]                    # outermost first; the last layer fills the rest
    thickness_mm = 1.0
    material = "silicone_gls40"   # a catalogue name, or an inline table
    [[layers]]
    [layers.material]
    model = "hyperfoam"
    mu_MPa = [0.100, 0.063]
    alpha = [5.5, 8.25]
    nu = 0.47

Every validation failure raises ``DesignError`` naming the offending field.

The section (half-width, height, exponent) is the 2D model's whole geometry; the 3D model
(``--model 3d``) sweeps it along the finger (``sim.geometry3d.PadGeometry``) with
``half_length_mm`` and ``length_exponent``, the pad's defaults when left out (then they are not
written back either, so a 2D design's dict, and the keys of stored 2D results, stay as they
were).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import DesignError, read_toml
from .geometry import REFERENCE_GEOMETRY, Geometry
from .geometry3d import REFERENCE_PAD, PadGeometry
from .materials import Material, material_from_spec

__all__ = [
    "MIN_CORE_MM",
    "MIN_LAYER_MM",
    "Design",
    "Layer",
    "design_from_dict",
    "homogeneous_design",
    "load_design",
]

MIN_LAYER_MM = 0.1  # thinnest layer the mesh resolves
MIN_CORE_MM = 0.5  # the last layer keeps at least this much at the apex and at the base


@dataclass(frozen=True)
class Layer:
    """One layer: its material and thickness in mm (None for the last, which fills the rest)."""

    material: Material
    thickness_mm: float | None = None


@dataclass(frozen=True)
class Design:
    """A fingertip skin design: geometry and 1 to 3 layers, outermost first."""

    layers: tuple[Layer, ...]
    geometry: Geometry = REFERENCE_GEOMETRY
    #: the 3D pad's c and m (``sim.geometry3d.PadGeometry``); None: the pad's default, unstated
    half_length_mm: float | None = None
    length_exponent: float | None = None

    def __post_init__(self) -> None:
        self.pad  # noqa: B018 -- checks the 3D keys' ranges (DesignError naming the key)
        if not 1 <= len(self.layers) <= 3:
            raise DesignError("layers", f"must have 1 to 3 layers, got {len(self.layers)}")
        total = 0.0
        for k, layer in enumerate(self.layers[:-1]):
            t = layer.thickness_mm
            if not _is_number(t) or not t >= MIN_LAYER_MM:
                raise DesignError(
                    f"layers[{k}].thickness_mm", f"must be a number >= {MIN_LAYER_MM}, got {t!r}"
                )
            total += float(t)
        if self.layers[-1].thickness_mm is not None:
            raise DesignError(
                f"layers[{len(self.layers) - 1}].thickness_mm",
                "the last layer fills the rest of the body: leave its thickness out",
            )
        limit = min(self.geometry.half_width_mm, self.geometry.height_mm) - MIN_CORE_MM
        if total > limit:
            raise DesignError(
                "layers.thickness_mm",
                f"outer layers total {total:g} mm; must be <= {limit:g} mm "
                f"(min(half_width, height) - {MIN_CORE_MM} mm) to leave a core",
            )

    @property
    def pad(self) -> PadGeometry:
        """The 3D pad: the section swept along the finger (``sim.geometry3d``)."""
        return PadGeometry(
            self.geometry,
            REFERENCE_PAD.half_length_mm if self.half_length_mm is None else self.half_length_mm,
            REFERENCE_PAD.length_exponent if self.length_exponent is None else self.length_exponent,
        )

    @property
    def thicknesses_mm(self) -> tuple[float, ...]:
        """Thicknesses of all layers but the last."""
        return tuple(float(layer.thickness_mm) for layer in self.layers[:-1])

    @property
    def materials(self) -> list[Material]:
        return [layer.material for layer in self.layers]

    def to_dict(self) -> dict[str, Any]:
        """The design-file form (inline material tables; catalogue names kept by ``name``)."""
        layers = []
        for layer in self.layers:
            mat = layer.material
            entry: dict[str, Any] = {}
            if layer.thickness_mm is not None:
                entry["thickness_mm"] = float(layer.thickness_mm)
            entry["material"] = mat.name if _is_catalogue(mat) else mat.to_dict()
            layers.append(entry)
        geometry: dict[str, float] = self.geometry.to_dict()
        for key in _PAD_KEYS:  # only when stated: a 2D design's dict is unchanged
            if getattr(self, key) is not None:
                geometry[key] = float(getattr(self, key))
        return {"geometry": geometry, "layers": layers}


_SECTION_KEYS = ("half_width_mm", "height_mm", "exponent")
_PAD_KEYS = ("half_length_mm", "length_exponent")


def _is_catalogue(mat: Material) -> bool:
    """True if ``mat`` is exactly the catalogue entry of its name (so the name stands for it)."""
    from .materials import CATALOGUE

    return mat.name is not None and CATALOGUE.get(mat.name) == mat


def _is_number(value: Any) -> bool:
    """A finite int or float, not a bool (TOML booleans must not pass as 0/1 mm)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def design_from_dict(
    data: Mapping[str, Any], catalogue: Mapping[str, Material] | None = None
) -> Design:
    """Build and validate a design from the parsed TOML table; material names from
    ``catalogue`` (default: the shipped one; ``--catalogue`` files merged into it)."""
    unknown = set(data) - {"geometry", "layers", "name", "description"}
    if unknown:
        raise DesignError(sorted(unknown)[0], "unknown key; allowed: geometry, layers")
    geo = data.get("geometry", {})
    if not isinstance(geo, Mapping):
        raise DesignError("geometry", "must be a table")
    extra = set(geo) - {*_SECTION_KEYS, *_PAD_KEYS}
    if extra:
        raise DesignError(
            f"geometry.{sorted(extra)[0]}",
            f"unknown key; allowed: {', '.join((*_SECTION_KEYS, *_PAD_KEYS))}",
        )
    section = {k: v for k, v in geo.items() if k in _SECTION_KEYS}
    geometry = Geometry(**{**REFERENCE_GEOMETRY.to_dict(), **section})
    pad = {k: geo[k] for k in _PAD_KEYS if k in geo}
    raw_layers = data.get("layers")
    if not isinstance(raw_layers, list) or not raw_layers:
        raise DesignError("layers", "must be an array of 1 to 3 [[layers]] tables")
    layers = []
    for k, raw in enumerate(raw_layers):
        if not isinstance(raw, Mapping):
            raise DesignError(f"layers[{k}]", "must be a table")
        extra = set(raw) - {"thickness_mm", "material"}
        if extra:
            raise DesignError(
                f"layers[{k}].{sorted(extra)[0]}", "unknown key; allowed: thickness_mm, material"
            )
        if "material" not in raw:
            raise DesignError(f"layers[{k}].material", "missing: a catalogue name or a table")
        mat = material_from_spec(raw["material"], f"layers[{k}].material", catalogue)
        layers.append(Layer(mat, raw.get("thickness_mm")))
    return Design(tuple(layers), geometry, **pad)


def load_design(path: str | Path, catalogue: Mapping[str, Material] | None = None) -> Design:
    """Read and validate a design TOML file (material names from ``catalogue``)."""
    data = read_toml(path, "DESIGN")
    return design_from_dict(data, catalogue)


def homogeneous_design(
    material: str | Material,
    geometry: Geometry = REFERENCE_GEOMETRY,
    catalogue: Mapping[str, Material] | None = None,
) -> Design:
    """A one-layer design of ``material`` (a name of ``catalogue`` or a Material) on
    ``geometry``."""
    return Design((Layer(material_from_spec(material, "material", catalogue)),), geometry)
