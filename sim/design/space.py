"""Design spaces: which skins a sweep explores, and how a unit-cube sample becomes a design.

A design-space TOML file gives, for every parameter, bounds (``{low, high}`` and optionally
``log = true``), a fixed value (``{value = ...}``) or a categorical choice (``{choice = [...]}``)::

    [geometry]
    half_width_mm = { low = 5.0, high = 7.0 }
    height_mm = { value = 5.48 }
    exponent = { value = 1.5 }

    [layers]
    count = { choice = [1, 2, 3] }

    [layers.skin]                      # outermost layer (active when count >= 2)
    thickness_mm = { low = 0.2, high = 1.5 }
    material = { choice = ["param", "silicone_gls40"] }
    mu0_MPa = { low = 0.01, high = 0.3, log = true }   # used when material = "param"
    ...
    [layers.middle]                    # between skin and core (active when count = 3)
    [layers.core]                      # innermost layer, fills the rest (always active)

Layers are named by role: a one-layer design is a core, two layers are skin + core, three are
skin + middle + core. A layer's material is either a catalogue entry or ``"param"``, the
continuous family documented in ``param_material``. A catalogue entry is a name of the shipped
catalogue or of a user's catalogue (``catalogue=`` of :func:`load_space`, from ``--catalogue``);
a space keeps the user materials it names (``DesignSpace.materials``) and writes them into its
TOML form as a ``[materials]`` table (name -> material table), so a run folder's space is
complete without the user's file. Parameters that a design does not use are
*inactive*: recorded as NaN (numbers) or "" (choices), never as random values.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DesignError, read_toml
from ..geometry import REFERENCE_PAD, Geometry
from ..materials import (
    CATALOGUE,
    Material,
    catalogue_from_tables,
    catalogue_material,
    material_tables,
)
from .families import (
    FAMILIES,
    FAMILY_KEYS,
    family_material,
    family_uses,
    family_values,
    is_family,
)
from .skin import MIN_CORE_MM, Design, Layer

__all__ = [
    "DEFAULT_SPACE_3D_PATH",
    "DEFAULT_SPACE_PATH",
    "LAYER_ROLES",
    "PARAM_MATERIAL_KEYS",
    "PRONY_TIME_RATIOS",
    "DesignSpace",
    "Parameter",
    "active_roles",
    "inactive_value",
    "is_active",
    "load_space",
    "mask_inactive",
    "param_material",
    "point_from_design",
    "point_to_design",
    "space_from_dict",
    "with_every_layer",
]

DEFAULT_SPACE_PATH = Path(__file__).parents[1] / "data" / "default_space.toml"
#: the default space of the 3D model: the default space and the pad's length and side profile
DEFAULT_SPACE_3D_PATH = DEFAULT_SPACE_PATH.with_name("default_space_3d.toml")
LAYER_ROLES = ("skin", "middle", "core")
#: keys of the continuous material families (``sim.design.families``; which of them a layer uses is
#: ``sim.design.families.family_uses``)
PARAM_MATERIAL_KEYS = FAMILY_KEYS
#: relaxation times of the three Prony terms of the "param" family relative to ``tau_s``
PRONY_TIME_RATIOS = FAMILIES["param"].time_ratios
_GEOMETRY_KEYS = ("half_width_mm", "height_mm", "exponent")
#: the 3D pad's keys (``sim.geometry.pad.PadGeometry``): parameters of a space that states them
#: (the 3D model's ``default_space_3d.toml``); a space without them leaves every design's pad at
#: its default, and the 2D model never reads them
_PAD_KEYS = ("half_length_mm", "length_exponent")
_LAYER_KEYS = ("thickness_mm", "material", *PARAM_MATERIAL_KEYS)


def param_material(
    mu0_MPa: float, alpha: float, nu: float, g_total: float, tau_s: float
) -> Material:
    """The continuous material family of the design spaces.

    A one-term Abaqus hyperfoam, U = 2 mu0 / alpha^2 [sum_a (lambda_a^alpha - 1)
    + (J^(-alpha beta) - 1) / beta], with long-term initial shear modulus ``mu0_MPa``,
    nonlinearity ``alpha`` (alpha = 2 is close to neo-Hookean; larger stiffens faster in
    compression) and Poisson's ratio ``nu``; relaxed by three Prony terms at ``tau_s`` / 3,
    ``tau_s`` and 3 ``tau_s`` (``PRONY_TIME_RATIOS``) sharing the total relaxation ``g_total``
    equally (g(inf) = 1 - g_total; the instantaneous modulus is mu0 / (1 - g_total)).
    Valid for every mu0 > 0, alpha != 0, -1 < nu < 0.5, 0 <= g_total < 1, tau > 0.
    """
    values = {"mu0_MPa": mu0_MPa, "alpha": alpha, "nu": nu, "g_total": g_total, "tau_s": tau_s}
    return family_material("param", values)


@dataclass(frozen=True)
class Parameter:
    """One dimension of a design space.

    ``kind`` is "float" (bounds ``low``..``high``, ``log`` scale), "fixed" (``value``) or
    "choice" (``choices``). ``name`` is dotted: ``geometry.height_mm``, ``layers.count``,
    ``core.mu0_MPa``.
    """

    name: str
    kind: str
    low: float = math.nan
    high: float = math.nan
    log: bool = False
    value: Any = None
    choices: tuple = ()
    weights: tuple = ()  # probabilities of the choices (uniform when empty)

    @property
    def sampled(self) -> bool:
        return self.kind != "fixed" and not (self.kind == "choice" and len(self.choices) == 1)

    def from_unit(self, u: float) -> Any:
        """Map u in [0, 1) to a value."""
        if self.kind == "fixed":
            return self.value
        if self.kind == "choice":
            w = np.asarray(self.weights or [1.0] * len(self.choices), dtype=float)
            k = int(np.searchsorted(np.cumsum(w) / w.sum(), u, side="right"))
            return self.choices[min(k, len(self.choices) - 1)]
        if self.log:
            return float(
                math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
            )
        return float(self.low + u * (self.high - self.low))

    def from_units(self, u: np.ndarray) -> np.ndarray:
        """``from_unit`` of every element of ``u`` (an object array for choices)."""
        u = np.asarray(u, dtype=float)
        if self.kind == "fixed":
            return np.full(len(u), self.value, dtype=object)
        if self.kind == "choice":
            w = np.asarray(self.weights or [1.0] * len(self.choices), dtype=float)
            k = np.searchsorted(np.cumsum(w) / w.sum(), u, side="right")
            return np.asarray(self.choices, dtype=object)[np.minimum(k, len(self.choices) - 1)]
        if self.log:
            lo, hi = math.log(self.low), math.log(self.high)
            return np.exp(lo + u * (hi - lo))
        return self.low + u * (self.high - self.low)

    def to_dict(self) -> dict[str, Any]:
        if self.kind == "fixed":
            return {"value": self.value}
        if self.kind == "choice":
            out_c: dict[str, Any] = {"choice": list(self.choices)}
            if self.weights:
                out_c["weights"] = list(self.weights)
            return out_c
        out: dict[str, Any] = {"low": self.low, "high": self.high}
        if self.log:
            out["log"] = True
        return out


@dataclass(frozen=True)
class DesignSpace:
    """All parameters of a space, in a fixed order (the sampler's dimensions), and the user
    catalogue materials its choices name (``materials``, none for shipped entries)."""

    parameters: tuple[Parameter, ...]
    materials: tuple[Material, ...] = ()

    @property
    def catalogue(self) -> dict[str, Material]:
        """The shipped catalogue plus this space's user materials."""
        return {**CATALOGUE, **{str(m.name): m for m in self.materials}}

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def sampled(self) -> list[Parameter]:
        return [p for p in self.parameters if p.sampled]

    def to_dict(self) -> dict[str, Any]:
        """The TOML form (nested tables), round-trips through ``space_from_dict``."""
        out: dict[str, Any] = {"geometry": {}, "layers": {}}
        if self.materials:
            out["materials"] = material_tables({str(m.name): m for m in self.materials})
        for p in self.parameters:
            head, key = p.name.split(".", 1)
            if head == "geometry":
                out["geometry"][key] = p.to_dict()
            elif head == "layers":
                out["layers"][key] = p.to_dict()
            else:
                out["layers"].setdefault(head, {})[key] = p.to_dict()
        return out

    def point(self, unit: np.ndarray) -> dict[str, Any]:
        """A design point (flat dict name -> value; inactive entries NaN or "") from a unit
        vector with one coordinate per sampled parameter."""
        values: dict[str, Any] = {}
        it = iter(unit)
        for p in self.parameters:
            values[p.name] = p.from_unit(next(it)) if p.sampled else p.from_unit(0.0)
        return mask_inactive(values)

    def points(self, unit: np.ndarray) -> list[dict[str, Any]]:
        """``point`` for every row of ``unit`` (n, number of sampled parameters), vectorised: the
        screen of a search draws 10^5 designs. Which parameters a row uses is decided once per
        combination of layer count and materials, by ``mask_inactive`` itself. Values agree with
        ``point`` to round-off (numpy's exp/log against math's); sweeps keep ``point``, whose
        values key their records."""
        unit = np.asarray(unit, dtype=float).reshape(len(unit), len(self.sampled))
        columns: dict[str, np.ndarray] = {}
        cols = iter(unit.T)
        for p in self.parameters:
            columns[p.name] = p.from_units(next(cols) if p.sampled else np.zeros(len(unit)))
        switches = [n for n in self.names if n == "layers.count" or n.endswith(".material")]
        combos = list(zip(*(columns[n].tolist() for n in switches), strict=True))
        unused: dict[tuple, list[str]] = {}
        for combo in dict.fromkeys(combos):
            probe = mask_inactive(
                {**{n: 0.0 for n in self.names}, **dict(zip(switches, combo, strict=True))}
            )
            unused[combo] = [n for n, v in probe.items() if v == "" or v != v]  # masked
        lists = {n: c.tolist() for n, c in columns.items()}
        out = [dict(zip(lists, row, strict=True)) for row in zip(*lists.values(), strict=True)]
        for point, combo in zip(out, combos, strict=True):
            for name in unused[combo]:
                point[name] = "" if name.endswith(".material") else math.nan
        return out

    def is_active(self, name: str, point: Mapping[str, Any]) -> bool:
        """Whether the design of ``point`` uses parameter ``name`` (the one rule,
        :func:`is_active`); a partial point too (see there)."""
        return is_active(name, point)

    def is_optional(self, name: str) -> bool:
        """Whether some design of the space leaves parameter ``name`` inactive."""
        head = name.split(".", 1)[0]
        if head not in LAYER_ROLES:
            return False
        material = f"{head}.material"
        cases = itertools.product(_options(self["layers.count"]), _options(self[material]))
        return not all(self.is_active(name, {"layers.count": c, material: m}) for c, m in cases)

    def complete(self, point: Mapping[str, Any], *, mask: bool = True) -> dict[str, Any]:
        """``point`` with every parameter of the space it lacks filled: a fixed parameter or a
        single choice takes its value, any other is blank ("" for a choice, NaN for a number);
        then masked (:func:`mask_inactive`) unless ``mask`` is False. The space's parameters
        come first, in its order; other entries of ``point`` are kept after them."""
        values = {
            p.name: point[p.name]
            if p.name in point
            else p.from_unit(0.0)
            if not p.sampled
            else _blank(p)
            for p in self.parameters
        }
        values.update({k: v for k, v in point.items() if k not in values})
        return mask_inactive(values) if mask else values

    def check(self, point: Mapping[str, Any]) -> dict[str, Any]:
        """Validate a hand-written point (active values inside the bounds or choices) and return
        it completed and masked (:meth:`complete`); a DesignError names the first parameter
        outside the space."""
        values = self.complete(point)
        for p in self.parameters:
            v = values[p.name]
            if (isinstance(v, float) and math.isnan(v)) or v == "":
                continue  # inactive
            ok = (
                v == p.value
                if p.kind == "fixed"
                else v in p.choices
                if p.kind == "choice"
                else p.low <= float(v) <= p.high
            )
            if not ok:
                raise DesignError(p.name, f"{v!r} is outside the space ({p.to_dict()})")
        point_to_design(values, self.catalogue)
        return values

    def design(self, point: Mapping[str, Any]) -> Design:
        """The design of a point (validated; a DesignError if the point is impossible)."""
        return point_to_design(point, self.catalogue)


def active_roles(count: int) -> tuple[str, ...]:
    """The layer roles of a design of ``count`` layers, outermost first."""
    return {1: ("core",), 2: ("skin", "core"), 3: ("skin", "middle", "core")}[int(count)]


def _uses(role: str, key: str, roles: tuple[str, ...], material: Any) -> bool:
    """THE rule of which parameters a design uses: a layer's parameter ``key`` is used when the
    layer exists (``role`` among the design's ``roles``) and ``key`` is its material, its
    thickness (not the core's: it fills the rest) or a parameter its material's family uses
    (``sim.design.families.family_uses``)."""
    return role in roles and (
        key == "material"
        or (key == "thickness_mm" and role != "core")
        or family_uses(material, key)
    )


def is_active(name: str, point: Mapping[str, Any]) -> bool:
    """Whether the design of ``point`` uses parameter ``name``: geometry and the layer count
    always; a layer's parameters by :func:`_uses`. ``point`` may be partial, as a define-by-run
    search builds it in space order: without ``layers.count`` every parameter may be used,
    without the layer's material none of its family parameters is."""
    role, _, key = name.partition(".")
    if role not in LAYER_ROLES:
        return True
    count = point.get("layers.count")
    if count is None:
        return True
    return _uses(role, key, active_roles(count), point.get(f"{role}.material"))


def inactive_value(name: str) -> Any:
    """What a point holds for a layer parameter its design does not use: "" for the material,
    NaN for a number."""
    return "" if name.endswith(".material") else math.nan


def mask_inactive(values: Mapping[str, Any]) -> dict[str, Any]:
    """Set the parameters a design does not use to NaN (numbers) or "" (choices)."""
    out = dict(values)
    roles = active_roles(out["layers.count"])
    for role in LAYER_ROLES:
        for key in _LAYER_KEYS:
            name = f"{role}.{key}"
            if name in out and not _uses(role, key, roles, out.get(f"{role}.material")):
                out[name] = inactive_value(name)
    return out


def with_every_layer(point: Mapping[str, Any]) -> dict[str, Any]:
    """``point`` with every layer parameter of every role it lacks set inactive: the form a
    sweep records, for a partial point that names only what its design uses (a reference
    design) and no space to complete it from."""
    out = dict(point)
    for role in LAYER_ROLES:
        for key in _LAYER_KEYS:
            out.setdefault(f"{role}.{key}", inactive_value(f"{role}.{key}"))
    return out


def _blank(p: Parameter) -> Any:
    """A sampled parameter's value before it is chosen: "" for a choice, NaN for a number."""
    return "" if p.kind == "choice" else math.nan


def _options(p: Parameter) -> tuple:
    """The values a fixed or choice parameter can take."""
    return p.choices if p.kind == "choice" else (p.value,)


def point_to_design(
    point: Mapping[str, Any], catalogue: Mapping[str, Material] | None = None
) -> Design:
    """Build the design of a (masked) point; material names from ``catalogue`` (default: the
    shipped one)."""
    geometry = Geometry(*(float(point[f"geometry.{k}"]) for k in _GEOMETRY_KEYS))
    pad = {k: float(point[f"geometry.{k}"]) for k in _PAD_KEYS if f"geometry.{k}" in point}
    layers = []
    for role in active_roles(point["layers.count"]):
        name = point[f"{role}.material"]
        if is_family(name):
            mat = family_material(name, {k: point[f"{role}.{k}"] for k in FAMILIES[name].keys})
        else:
            mat = catalogue_material(name, f"{role}.material", catalogue)
        thickness = None if role == "core" else float(point[f"{role}.thickness_mm"])
        layers.append(Layer(mat, thickness))
    return Design(tuple(layers), geometry, **pad)


def point_from_design(design: Design, space: DesignSpace) -> dict[str, Any]:
    """The point of ``space`` whose design is ``design`` (the inverse of ``point_to_design``):
    each layer's material is a catalogue material the space names or a member of one of its
    families (rebuilt from the family's parameters to round-off); a ``DesignError`` names the
    layer that is neither. The point is checked against the space's bounds by the caller
    (``DesignSpace.check``)."""
    roles = active_roles(len(design.layers))
    point: dict[str, Any] = {
        **{f"geometry.{k}": v for k, v in design.geometry.to_dict().items()},
        **{
            f"geometry.{k}": getattr(design.pad, k)
            for k in _PAD_KEYS
            if f"geometry.{k}" in space.names
        },
        "layers.count": len(design.layers),
    }
    catalogue = space.catalogue
    for k, (role, layer) in enumerate(zip(roles, design.layers, strict=True)):
        name = f"{role}.material"
        if name not in space.names:
            raise DesignError(f"layers[{k}]", f"the space has no {role} layer")
        p = space[name]
        choices = p.choices if p.kind == "choice" else (p.value,)
        mat = layer.material
        named = [c for c in choices if not is_family(c) and catalogue.get(c) == mat]
        if named:
            point[name] = named[0]
        else:
            for fam in (c for c in choices if is_family(c)):
                values = family_values(mat, fam)
                if values is not None:
                    point[name] = fam
                    point.update({f"{role}.{key}": v for key, v in values.items()})
                    break
            else:
                raise DesignError(
                    f"layers[{k}].material",
                    f"not a material of the space's {role}: one of its catalogue choices or a "
                    "member of its families ("
                    + ", ".join(f"{c}: {FAMILIES[c].description}" for c in choices if is_family(c))
                    + ")",
                )
        if role != "core":
            point[f"{role}.thickness_mm"] = layer.thickness_mm
    return point


# ---------------------------------------------------------------------------- parsing
def _parameter(name: str, spec: Any) -> Parameter:
    if not isinstance(spec, Mapping):
        raise DesignError(name, "must be a table: {low, high[, log]}, {value} or {choice}")
    keys = set(spec)
    if keys == {"value"}:
        return Parameter(name, "fixed", value=spec["value"])
    if keys in ({"choice"}, {"choice", "weights"}):
        choices = spec["choice"]
        if not isinstance(choices, list) or not choices:
            raise DesignError(name, "choice must be a non-empty list")
        if len(set(map(str, choices))) != len(choices):
            raise DesignError(name, "choice has duplicates")
        weights = spec.get("weights", [])
        if weights and (
            not isinstance(weights, list)
            or len(weights) != len(choices)
            or not all(
                isinstance(w, int | float) and not isinstance(w, bool) and w > 0 for w in weights
            )
        ):
            raise DesignError(f"{name}.weights", "must be one positive number per choice")
        return Parameter(name, "choice", choices=tuple(choices), weights=tuple(map(float, weights)))
    if keys in ({"low", "high"}, {"low", "high", "log"}):
        low, high, log = spec["low"], spec["high"], bool(spec.get("log", False))
        for k, v in (("low", low), ("high", high)):
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise DesignError(f"{name}.{k}", f"must be a finite number, got {v!r}")
        if not low < high:
            raise DesignError(
                name, f"bounds reversed or empty: low = {low} must be < high = {high}"
            )
        if log and low <= 0:
            raise DesignError(name, f"log scale needs low > 0, got {low}")
        return Parameter(name, "float", float(low), float(high), log)
    raise DesignError(
        name, f"unknown form {sorted(keys)}; use {{low, high[, log]}}, {{value}} or {{choice}}"
    )


def _values(p: Parameter) -> list[Any]:
    """The extreme values a parameter can take (for validation)."""
    if p.kind == "fixed":
        return [p.value]
    if p.kind == "choice":
        return list(p.choices)
    return [p.low, p.high]


def space_from_dict(
    data: Mapping[str, Any], catalogue: Mapping[str, Material] | None = None
) -> DesignSpace:
    """Parse and validate a design space (every sampled design must be valid).

    Material choices are names of ``catalogue`` (default: the shipped one; a merged catalogue
    from ``--catalogue`` files adds the user's) or of the space's own ``[materials]`` table
    (how a run folder stores the user materials it used); a name defined by both must be the
    same material.
    """
    unknown = set(data) - {"geometry", "layers", "description", "materials"}
    if unknown:
        raise DesignError(
            sorted(unknown)[0], "unknown section; allowed: geometry, layers, materials"
        )
    known = dict(CATALOGUE if catalogue is None else catalogue)
    if "materials" in data:
        if not isinstance(data["materials"], Mapping):
            raise DesignError("materials", "must be a table of material tables")
        for name, mat in catalogue_from_tables(data["materials"]).items():
            if name in known and known[name] != mat:
                raise DesignError(
                    f"materials.{name}", "differs from the --catalogue entry of that name"
                )
            known[name] = mat
    params: list[Parameter] = []
    used: dict[str, Material] = {}  # the user materials the choices name
    geo = data.get("geometry", {})
    for key in geo:
        if key not in (*_GEOMETRY_KEYS, *_PAD_KEYS):
            raise DesignError(
                f"geometry.{key}",
                f"unknown key; allowed: {', '.join((*_GEOMETRY_KEYS, *_PAD_KEYS))}",
            )
    ref = Geometry()
    for key in _GEOMETRY_KEYS:
        p = _parameter(f"geometry.{key}", geo.get(key, {"value": getattr(ref, key)}))
        for v in _values(p):
            Geometry(**{**ref.to_dict(), key: v})  # raises DesignError naming geometry.<key>
        params.append(p)
    for key in (k for k in _PAD_KEYS if k in geo):
        p = _parameter(f"geometry.{key}", geo[key])
        for v in _values(p):
            replace(REFERENCE_PAD, **{key: v})  # raises DesignError naming geometry.<key>
        params.append(p)
    layers = data.get("layers")
    if not isinstance(layers, Mapping) or "core" not in layers:
        raise DesignError("layers.core", "missing: every space needs a [layers.core] table")
    for key in layers:
        if key not in ("count", *LAYER_ROLES):
            raise DesignError(f"layers.{key}", "unknown key; allowed: count, skin, middle, core")
    count = _parameter("layers.count", layers.get("count", {"value": 1}))
    for v in _values(count):
        if v not in (1, 2, 3) or isinstance(v, bool):
            raise DesignError("layers.count", f"must be 1, 2 or 3, got {v!r}")
    params.append(count)
    counts = _values(count)
    for role in LAYER_ROLES:
        needed = any(role in active_roles(c) for c in counts)
        table = layers.get(role)
        if table is None:
            if needed:
                raise DesignError(f"layers.{role}", f"missing: layers.count allows a {role} layer")
            continue
        for key in table:
            if key not in _LAYER_KEYS:
                raise DesignError(
                    f"{role}.{key}", f"unknown key; allowed: {', '.join(_LAYER_KEYS)}"
                )
        if "material" not in table:
            raise DesignError(f"{role}.material", "missing")
        mat = _parameter(f"{role}.material", table["material"])
        names = _values(mat)
        for name in names:
            if not is_family(name) and name not in known:
                raise DesignError(
                    f"{role}.material",
                    f"unknown material {name!r}; use a family ({', '.join(FAMILIES)}) or one of "
                    + ", ".join(sorted(known))
                    + (" (or load its catalogue with --catalogue)"),
                )
            if not is_family(name) and CATALOGUE.get(name) != known[name]:
                used.setdefault(name, known[name])
        params.append(mat)
        if role != "core":
            if "thickness_mm" not in table:
                raise DesignError(f"{role}.thickness_mm", "missing")
            p = _parameter(f"{role}.thickness_mm", table["thickness_mm"])
            if min(_values(p)) < 0.1:
                raise DesignError(f"{role}.thickness_mm", "must be >= 0.1 mm")
            params.append(p)
        families = [FAMILIES[n] for n in names if is_family(n)]
        for key in PARAM_MATERIAL_KEYS:
            users = [f for f in families if key in f.keys]
            if not users:
                continue
            if key not in table:
                raise DesignError(
                    f"{role}.{key}", f"missing (the {users[0].name!r} family needs it)"
                )
            p = _parameter(f"{role}.{key}", table[key])
            for fam in users:
                _check_family_bounds(p, key, fam)
            params.append(p)
    space = DesignSpace(tuple(params), tuple(used[n] for n in sorted(used)))
    _check_thickness(space)
    return space


def _check_family_bounds(p: Parameter, key: str, family: Any) -> None:
    """The space's range of ``p`` must lie within what ``family`` admits for ``key``."""
    lo, hi = min(_values(p)), max(_values(p))
    if not (family.admits(key, lo) and family.admits(key, hi)):
        text = family.limits[key][2]
        raise DesignError(p.name, f"must be {text} for the {family.name} family, got [{lo}, {hi}]")


def _check_thickness(space: DesignSpace) -> None:
    """The thickest outer layers must leave a core in the smallest geometry."""
    total = 0.0
    for role in ("skin", "middle"):
        if f"{role}.thickness_mm" in space.names:
            total += max(_values(space[f"{role}.thickness_mm"]))
    smallest = min(
        min(_values(space["geometry.half_width_mm"])), min(_values(space["geometry.height_mm"]))
    )
    if total > smallest - MIN_CORE_MM:
        raise DesignError(
            "layers.thickness_mm",
            f"skin + middle can reach {total:g} mm; must be <= {smallest - MIN_CORE_MM:g} mm "
            f"(smallest half-width/height - {MIN_CORE_MM} mm core)",
        )


def load_space(
    path: str | Path | None = None, catalogue: Mapping[str, Material] | None = None
) -> DesignSpace:
    """Read a design-space TOML file (the shipped default when ``path`` is None); material
    names from ``catalogue`` (default: the shipped one)."""
    path = Path(DEFAULT_SPACE_PATH if path is None else path)
    return space_from_dict(_read_space_toml(path), catalogue)


def _read_space_toml(path: Path, seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A space file's tables; ``extends = "other.toml"`` (beside it) takes the other file's
    tables and replaces or adds what this one states: a whole ``[geometry]`` key or
    ``[layers.<role>]`` table at a time (a space that adds the pad's keys to the default space
    repeats nothing of it)."""
    data = dict(read_toml(path, "SPACE"))
    base_name = data.pop("extends", None)
    if base_name is None:
        return data
    base_path = (path.parent / str(base_name)).resolve()
    if base_path in seen or base_path == path.resolve():
        raise DesignError("extends", f"{path} extends itself through {base_path.name}")
    if not base_path.is_file():
        raise DesignError("extends", f"no such space file beside {path.name}: {base_name}")
    merged = _read_space_toml(base_path, (*seen, path.resolve()))
    for section, table in data.items():
        if section in ("geometry", "layers", "materials") and isinstance(table, Mapping):
            merged[section] = {**merged.get(section, {}), **table}
        else:
            merged[section] = table
    return merged
