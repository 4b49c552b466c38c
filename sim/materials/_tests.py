"""The strain range each material's law was tested in (``sim/data/material_tests.toml``).

One entry per shipped catalogue material (keyed by its catalogue name) and per material family
(``family.gel``, ``family.foam``): the ``mode`` of the tests its law was fitted to, the largest
compressive and tensile logarithmic strains those tests reached (``|ln stretch|``: compressive
``-ln(lambda_min)``, the quantity of ``sim.protocols.validity.compressive_log_strain``; a nominal
strain ``e`` is ``-ln(1 - e)`` in compression and ``ln(1 + e)`` in tension), a ``source`` and a
``note`` for anything argued rather than read.  A law fitted to tension only has no compression
test: its compressive limit is argued in ``note`` (see ``docs/materials.md``, "The range each
material was tested in").

A material fitted by ``fingertip fit-material`` records the same figures in its ``provenance``
(``PROVENANCE_KEYS``, read by :func:`tested_range_from_provenance`), and an inline material may
state them there.  ``sim.protocols.validity.layer_limit`` holds each FE layer to the compressive
limit of its material's entry.  Nothing here changes a ``Material`` or its dict (which keys
stored results): the entries are looked up by name, family or provenance.  Errors are
``DesignError`` naming ``material_tests.toml:<entry>.<key>`` (or the provenance key).
"""

from __future__ import annotations

import functools
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.errors import DesignError, read_toml

__all__ = [
    "MODES",
    "PROVENANCE_KEYS",
    "TESTS_PATH",
    "TestedRange",
    "load_tested_ranges",
    "tested_range",
    "tested_range_from_provenance",
]

TESTS_PATH = Path(__file__).resolve().parents[1] / "data" / "material_tests.toml"

#: test modes, and the sides of the strain range each one exercises: an equibiaxial test
#: compresses the thickness, a pure-shear (planar) test stretches one direction and shortens
#: another
MODES: dict[str, frozenset[str]] = {
    "uniaxial_compression": frozenset({"compressive"}),
    "uniaxial_tension": frozenset({"tensile"}),
    "biaxial": frozenset({"compressive", "tensile"}),
    "shear": frozenset({"compressive", "tensile"}),
}
_KEYS = ("mode", "max_compressive_log_strain", "max_tensile_log_strain", "source", "note")
#: the keys of a material's ``provenance`` that record its tested range (``fingertip
#: fit-material`` writes them), each with the key of a file entry it stands for; the source is
#: the material's ``source``
PROVENANCE_KEYS = {
    "tested_mode": "mode",
    "max_compressive_log_strain": "max_compressive_log_strain",
    "max_tensile_log_strain": "max_tensile_log_strain",
    "tested_note": "note",
}


@dataclass(frozen=True)
class TestedRange:
    """The tests a material's law was fitted to: their modes, the largest compressive and
    tensile log strains (``None``: no such limit recorded), the ``source`` and a ``note`` on
    what was argued rather than read."""

    mode: tuple[str, ...]
    max_compressive_log_strain: float | None
    max_tensile_log_strain: float | None
    source: str
    note: str = ""

    @property
    def compressive_argued(self) -> bool:
        """Whether the compressive limit is argued rather than read from a test that compressed
        the material: none of the modes compresses (``MODES``), or the note says ``ARGUED``
        (the file's mark, e.g. of a family whose law has no fit of its own)."""
        compresses = any("compressive" in MODES[m] for m in self.mode)
        return not compresses or "ARGUED" in self.note


def _strain(table: Mapping[str, Any], key: str, field: str) -> float | None:
    if key not in table:
        return None
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise DesignError(f"{field}.{key}", f"must be a finite number, got {value!r}")
    if value < 0:
        raise DesignError(f"{field}.{key}", f"must be >= 0 (a log strain's size), got {value!r}")
    return float(value)


def _text(table: Mapping[str, Any], key: str, field: str, required: bool) -> str:
    value = table.get(key, "")
    if not isinstance(value, str):
        raise DesignError(f"{field}.{key}", f"must be a string, got {value!r}")
    if required and not value.strip():
        raise DesignError(f"{field}.{key}", "is required (cite the tests the law was fitted to)")
    return value


def _mode(table: Mapping[str, Any], field: str) -> tuple[str, ...]:
    if "mode" not in table:
        raise DesignError(f"{field}.mode", f"is required: one of {', '.join(MODES)} or a list")
    value = table["mode"]
    modes = [value] if isinstance(value, str) else value
    if not isinstance(modes, list) or not modes:
        raise DesignError(f"{field}.mode", f"must be a mode or a non-empty list, got {value!r}")
    for mode in modes:
        if mode not in MODES:
            raise DesignError(f"{field}.mode", f"unknown mode {mode!r}; known: {', '.join(MODES)}")
    if len(set(modes)) != len(modes):
        raise DesignError(f"{field}.mode", f"lists a mode twice: {value!r}")
    return tuple(modes)


def tested_range_from_table(table: Any, field: str) -> TestedRange:
    """One entry of the file (errors name ``field`` or ``f"{field}.key"``)."""
    if not isinstance(table, Mapping):
        raise DesignError(field, "must be a table")
    unknown = sorted(set(table) - set(_KEYS))
    if unknown:
        raise DesignError(f"{field}.{unknown[0]}", f"unknown key; known: {', '.join(_KEYS)}")
    mode = _mode(table, field)
    limits = {
        side: _strain(table, f"max_{side}_log_strain", field) for side in ("compressive", "tensile")
    }
    if all(v is None for v in limits.values()):
        raise DesignError(field, "needs max_compressive_log_strain and/or max_tensile_log_strain")
    source = _text(table, "source", field, required=True)
    note = _text(table, "note", field, required=False)
    tested = frozenset().union(*(MODES[m] for m in mode))
    for side, value in limits.items():
        if value is not None and side not in tested and not note.strip():
            raise DesignError(
                f"{field}.note",
                f"is required: max_{side}_log_strain is not reached by a {'/'.join(mode)} "
                "test, so say how it was argued",
            )
    return TestedRange(mode, limits["compressive"], limits["tensile"], source.strip(), note.strip())


@functools.cache
def load_tested_ranges(path: Path = TESTS_PATH) -> Mapping[str, TestedRange]:
    """Every entry of a material-tests TOML, validated (read once per path)."""
    path = Path(path)
    data = read_toml(path, path.name)
    entries = {n: tested_range_from_table(t, f"{path.name}:{n}") for n, t in data.items()}
    return types.MappingProxyType(entries)


def tested_range(name: str, path: Path | str = TESTS_PATH) -> TestedRange | None:
    """The tested range of catalogue material ``name`` (or ``"family.gel"``, ...), ``None`` if
    the file has no entry (e.g. a user's material); the file is read once and validated whole,
    so one malformed entry fails every look-up."""
    return load_tested_ranges(Path(path)).get(name)


def tested_range_from_provenance(
    provenance: Mapping[str, Any], source: str | None, field: str
) -> TestedRange | None:
    """The tested range a material's ``provenance`` records (the keys of ``PROVENANCE_KEYS``,
    as ``fingertip fit-material`` writes them), validated like a file entry, with ``source``
    (the material's); None when it records none. Errors name ``f"{field}.<provenance key>"``."""
    entry = {
        PROVENANCE_KEYS[k]: list(v) if isinstance(v, tuple) else v  # a Material keeps tuples
        for k, v in provenance.items()
        if k in PROVENANCE_KEYS
    }
    if not entry:
        return None
    text = source if source and source.strip() else "the material's provenance"
    try:
        return tested_range_from_table({**entry, "source": text}, field)
    except DesignError as exc:
        key = exc.field.removeprefix(f"{field}.")
        named = next((p for p, k in PROVENANCE_KEYS.items() if k == key), None)
        raise DesignError(f"{field}.{named}" if named else exc.field, exc.message) from None
