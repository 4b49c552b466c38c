"""The material catalogue (``sim/data/materials.toml``) and :func:`material_from_spec`."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from sim.errors import DesignError
from sim.materials._material import Material, material_from_table

CATALOGUE_PATH = Path(__file__).resolve().parents[1] / "data" / "materials.toml"


def load_catalogue(path: Path = CATALOGUE_PATH) -> dict[str, Material]:
    """Read a catalogue TOML: one table per material, each with a ``source`` citation."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    out: dict[str, Material] = {}
    for name, table in data.items():
        field = f"{path.name}:{name}"
        if not isinstance(table, Mapping):
            raise DesignError(field, "must be a table")
        if "name" in table:
            raise DesignError(f"{field}.name", "is the table's own name; remove the key")
        if "source" not in table:
            raise DesignError(f"{field}.source", "is required (cite where the numbers come from)")
        out[name] = material_from_table({**table, "name": name}, field)
    return out


#: Catalogue materials by name (from ``sim/data/materials.toml``).
CATALOGUE: dict[str, Material] = load_catalogue()


def catalogue_material(name: str, field: str = "material") -> Material:
    """The catalogue material ``name``; unknown names raise ``DesignError(field, ...)``."""
    try:
        return CATALOGUE[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(CATALOGUE))
        raise DesignError(field, f"unknown material {name!r}; known: {known}") from None


def material_from_spec(
    spec: str | Mapping[str, Any] | Material, field: str = "material"
) -> Material:
    """A material from a design file: a catalogue name or an inline table.

    See :func:`sim.materials._material.material_from_table` for the table keys.  A ``Material``
    is returned unchanged.  Errors are ``DesignError`` naming ``field`` or ``f"{field}.key"``.
    """
    if isinstance(spec, Material):
        return spec
    if isinstance(spec, str):
        return catalogue_material(spec, field)
    return material_from_table(spec, field)
