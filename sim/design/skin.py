"""Skin designs: TOML design files <-> frozen dataclasses, with validation.

A design file::

    [geometry]                    # optional: the reference geometry when left out
    half_width_mm = 5.84
    height_mm = 5.48
    exponent = 1.5
    half_length_mm = 11.0         # optional, the 3D pad only (sim.geometry.pad): c
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
(``--model 3d``) sweeps it along the finger (``sim.geometry.pad.PadGeometry``) with
``half_length_mm`` and ``length_exponent``, the pad's defaults when left out (then they are not
written back either, so a 2D design's dict, and the keys of stored 2D results, stay as they
were).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import DesignError, read_toml
from ..geometry import REFERENCE_GEOMETRY, REFERENCE_PAD, Geometry, PadGeometry
from ..materials import Material, material_from_spec

__all__ = [
    "MIN_CORE_MM",
    "MIN_LAYER_MM",
    "Design",
    "Layer",
    "design_from_dict",
    "design_to_toml",
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
    #: the 3D pad's c and m (``sim.geometry.pad.PadGeometry``); None: the pad's default, unstated
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
        """The 3D pad: the section swept along the finger (``sim.geometry.pad``)."""
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
    from ..materials import CATALOGUE

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


# ---------------------------------------------------------------------------------------------
# Writing a design file
# ---------------------------------------------------------------------------------------------

_BARE_KEY = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")
#: the escapes of a TOML basic string (any other control character: \\uXXXX)
_ESCAPES = {
    '"': '\\"',
    "\\": "\\\\",
    "\b": "\\b",
    "\t": "\\t",
    "\n": "\\n",
    "\f": "\\f",
    "\r": "\\r",
}


def design_to_toml(
    data: Design | Mapping[str, Any],
    header: Sequence[str] = (),
    notes: Mapping[str, Sequence[str]] | None = None,
) -> str:
    """The design file of ``data`` (a ``Design`` or its ``to_dict()`` form, the form
    :func:`design_from_dict` reads): TOML text that :func:`load_design` reads back to the same
    design (floats written with ``repr``: bit for bit). ``header``: comment lines on top (without
    their ``#``); ``notes``: comment lines placed under a table's header, by the table's path
    (``"geometry"``, ``"layers[1]"``, ``"layers[1].material"``).

    The values a design file holds: text, numbers, booleans, lists of them, tables of them
    (``[geometry]``, ``[layers.material]``, a material's ``provenance``) and the array of
    ``[[layers]]`` tables."""
    table = data.to_dict() if isinstance(data, Design) else data
    lines = [*(_comment(line) for line in header), *([""] if header else [])]
    _write_table(table, [], "", lines, notes or {}, array=False)
    return "\n".join(lines).strip("\n") + "\n"


def _comment(text: str) -> str:
    """A comment line (a line break or control character, which TOML refuses in a comment,
    written as its escape)."""
    text = " ".join(text.splitlines())
    text = "".join(
        f"\\u{ord(ch):04X}" if (ord(ch) < 0x20 and ch != "\t") or ord(ch) == 0x7F else ch
        for ch in text
    )
    return "# " + text if text else "#"


def _write_table(
    table: Mapping[str, Any],
    keys: list[str],
    path: str,
    lines: list[str],
    notes: Mapping[str, Sequence[str]],
    array: bool,
) -> None:
    """``table`` at ``keys`` (its TOML name) and ``path`` (its ``notes`` key): the header (none
    for the top), its notes, its values, then its tables and its arrays of tables."""
    if keys:
        name = ".".join(_key(k) for k in keys)
        if lines and lines[-1] and not lines[-1].startswith(("[", "#")):  # apart from values
            lines.append("")
        lines.append(f"[[{name}]]" if array else f"[{name}]")
    lines += [_comment(n) for n in notes.get(path, ())]
    tables = []
    for key, value in table.items():
        if isinstance(value, Mapping) or _is_table_array(value):
            tables.append((key, value))
        else:
            lines.append(f"{_key(key)} = {_value(value, f'{path}.{key}'.lstrip('.'))}")
    for key, value in tables:
        sub = f"{path}.{key}".lstrip(".")
        if isinstance(value, Mapping):
            _write_table(value, [*keys, key], sub, lines, notes, array=False)
        else:
            for k, item in enumerate(value):
                _write_table(item, [*keys, key], f"{sub}[{k}]", lines, notes, array=True)


def _is_table_array(value: Any) -> bool:
    return (
        isinstance(value, list | tuple)
        and bool(value)
        and all(isinstance(v, Mapping) for v in value)
    )


def _key(key: str) -> str:
    return key if key and set(key) <= _BARE_KEY else _string(key)


def _string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = []
    for ch in text:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _value(value: Any, field: str) -> str:
    """One TOML value: text, a boolean, an integer, a finite float (``repr``: read back bit for
    bit) or an inline array of them."""
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise DesignError(field, f"must be a finite number, got {value!r}")
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v, f"{field}[{k}]") for k, v in enumerate(value)) + "]"
    raise DesignError(field, f"cannot be written to a design file: {value!r}")
