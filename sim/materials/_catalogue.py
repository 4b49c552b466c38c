"""The material catalogue (``sim/data/materials.toml``), user catalogues and
:func:`material_from_spec`.

A catalogue is a TOML file with one table per material (the table's name is the material's
name), each with a ``source`` citing where its numbers come from and optionally a flat
``provenance`` table (how they were obtained, e.g. by ``fingertip fit-material``).  A user's
catalogues (``--catalogue FILE.toml``, :func:`read_user_catalogue`) are merged with the shipped
one by :func:`merge_catalogues`; a name defined twice is refused.  The merged catalogue is passed
explicitly (``catalogue=`` arguments, and as tables to worker processes): the module's
``CATALOGUE`` stays the shipped catalogue in every process.
"""

from __future__ import annotations

import hashlib
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.errors import DesignError, read_bytes
from sim.materials._material import Material, material_from_table

CATALOGUE_PATH = Path(__file__).resolve().parents[1] / "data" / "materials.toml"


def _entries(data: Mapping[str, Any], label: str) -> dict[str, Material]:
    """The materials of a parsed catalogue (errors name ``f"{label}:{name}.key"``)."""
    out: dict[str, Material] = {}
    for name, table in data.items():
        field = f"{label}:{name}"
        if not isinstance(table, Mapping):
            raise DesignError(field, "must be a table")
        if "name" in table:
            raise DesignError(f"{field}.name", "is the table's own name; remove the key")
        if "source" not in table:
            raise DesignError(f"{field}.source", "is required (cite where the numbers come from)")
        out[name] = material_from_table({**table, "name": name}, field)
    return out


def load_catalogue(path: Path = CATALOGUE_PATH) -> dict[str, Material]:
    """Read a catalogue TOML: one table per material, each with a ``source`` citation."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    return _entries(data, path.name)


def load_catalogue_text(text: str, label: str) -> dict[str, Material]:
    """The materials of catalogue TOML ``text`` (``label`` names it in errors)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(label, f"malformed TOML: {exc}") from None
    return _entries(data, label)


#: Catalogue materials by name (from ``sim/data/materials.toml``).
CATALOGUE: dict[str, Material] = load_catalogue()


@dataclass(frozen=True)
class UserCatalogue:
    """A user's catalogue file as read: ``path``, the ``sha256`` of its bytes (a run records
    both, so it can be reproduced and a resume with another file refused) and its
    ``materials``."""

    path: str
    sha256: str
    materials: tuple[Material, ...]

    @property
    def names(self) -> list[str]:
        return [str(m.name) for m in self.materials]

    def record(self) -> dict[str, Any]:
        """What a run folder records of this file."""
        return {"path": self.path, "sha256": self.sha256, "materials": self.names}


def read_user_catalogue(path: str | Path, option: str = "--catalogue") -> UserCatalogue:
    """Read a user catalogue; every problem is one ``DesignError`` (naming ``option`` for the
    file, ``file:name.key`` for an entry)."""
    path = Path(path)
    raw = read_bytes(path, option, "TOML file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise DesignError(option, f"{path} is not UTF-8 text (TOML files must be)") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(option, f"malformed TOML in {path}: {exc}") from None
    if not data:
        raise DesignError(option, f"{path} defines no material")
    from sim.design import FAMILIES  # here: sim.design.families builds on this package

    for name in data:
        if name in FAMILIES:
            raise DesignError(
                f"{path.name}:{name}",
                f"the name of a material family ({', '.join(FAMILIES)}); rename the material",
            )
    materials = _entries(data, path.name)
    return UserCatalogue(str(path), hashlib.sha256(raw).hexdigest(), tuple(materials.values()))


def merge_catalogues(
    user: Sequence[UserCatalogue], base: Mapping[str, Material] | None = None
) -> dict[str, Material]:
    """The shipped catalogue (or ``base``) plus the user's materials; a name defined twice is
    refused in one line (``DesignError`` naming ``--catalogue``)."""
    out = dict(CATALOGUE if base is None else base)
    origin = dict.fromkeys(out, f"the shipped catalogue ({CATALOGUE_PATH.name})")
    for cat in user:
        for mat in cat.materials:
            name = str(mat.name)
            if name in out:
                raise DesignError(
                    "--catalogue",
                    f"material {name!r} of {cat.path} is already defined in {origin[name]}; "
                    "rename it",
                )
            out[name] = mat
            origin[name] = cat.path
    return out


def load_user_catalogues(
    paths: Sequence[str | Path],
) -> tuple[tuple[UserCatalogue, ...], dict[str, Material]]:
    """Read the ``--catalogue`` files; returns them and the merged catalogue."""
    user = tuple(read_user_catalogue(p) for p in paths)
    return user, merge_catalogues(user)


def user_materials(catalogue: Mapping[str, Material] | None) -> dict[str, Material]:
    """The materials of ``catalogue`` that are not the shipped entries of their name."""
    if catalogue is None:
        return {}
    return {n: m for n, m in catalogue.items() if CATALOGUE.get(n) != m}


def material_tables(materials: Mapping[str, Material]) -> dict[str, dict[str, Any]]:
    """Materials as design-file tables (JSON-able, picklable): how user materials are passed
    to worker processes and stored in run folders; :func:`catalogue_from_tables` inverts it."""
    out = {}
    for name, mat in materials.items():
        table = mat.to_dict()
        table.pop("name", None)
        out[name] = table
    return out


def catalogue_from_tables(
    tables: Mapping[str, Mapping[str, Any]] | None, field: str = "materials"
) -> dict[str, Material]:
    """The shipped catalogue plus the materials of ``tables`` (:func:`material_tables`); a
    table may repeat a shipped entry exactly, a different one under a shipped name is refused."""
    out = dict(CATALOGUE)
    for name, table in (tables or {}).items():
        mat = material_from_table({**table, "name": name}, f"{field}.{name}")
        if name in CATALOGUE and CATALOGUE[name] != mat:
            raise DesignError(
                f"{field}.{name}", "differs from the shipped catalogue entry of that name"
            )
        out[name] = mat
    return out


def catalogue_material(
    name: str, field: str = "material", catalogue: Mapping[str, Material] | None = None
) -> Material:
    """The material ``name`` of ``catalogue`` (default: the shipped one); unknown names raise
    ``DesignError(field, ...)``."""
    cat = CATALOGUE if catalogue is None else catalogue
    try:
        return cat[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(cat))
        hint = "" if catalogue is not None else " (a user material needs --catalogue FILE.toml)"
        raise DesignError(field, f"unknown material {name!r}; known: {known}{hint}") from None


def material_from_spec(
    spec: str | Mapping[str, Any] | Material,
    field: str = "material",
    catalogue: Mapping[str, Material] | None = None,
) -> Material:
    """A material from a design file: a name of ``catalogue`` (default: the shipped one) or an
    inline table.

    See :func:`sim.materials._material.material_from_table` for the table keys.  A ``Material``
    is returned unchanged.  Errors are ``DesignError`` naming ``field`` or ``f"{field}.key"``.
    """
    if isinstance(spec, Material):
        return spec
    if isinstance(spec, str):
        return catalogue_material(spec, field, catalogue)
    return material_from_table(spec, field)
