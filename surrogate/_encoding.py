"""Design points -> network inputs, and the training domain.

Encoding of a design space's parameters, in the space's order:

- float: one feature in [0, 1] over the space's bounds (log scale where the space says log);
  an optional parameter (one a design may not use) adds an "active" flag: an inactive value
  is encoded as (value 0, flag 0), an active one as (u, 1);
- choice: one-hot over the space's choices; an inactive choice is all zeros;
- fixed: no feature (the parameter stays in the header and is checked on input).

Then physical descriptors that put every material, catalogue or family, on the same axes
(``material_descriptors``): per layer the long-term shear modulus, the storage modulus and the
loss tangent of its Prony series around the tap's frequency; and one flag, ``design:elastic``,
set when no active material relaxes (such a design dissipates nothing in a closed cycle).

Points are flat dicts ``name -> value`` (``sim.design.space``); tables are ``name -> column``. Both
are masked like ``sim.design.space.mask_inactive`` before encoding, so values of parameters a design
does not use never reach the network.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.design import (
    FAMILIES,
    LAYER_ROLES,
    PARAM_MATERIAL_KEYS,
    DesignSpace,
    Parameter,
    is_family,
)
from sim.errors import DesignError
from sim.materials import CATALOGUE
from sim.protocols import TappingOptions
from sim.provenance import finite_or_none, nan_if_none

__all__ = [
    "DESCRIPTOR_OMEGA_RAD_S",
    "ELASTIC_FEATURE",
    "Encoded",
    "Encoder",
    "is_optional",
    "material_descriptors",
    "parameter_unit",
    "to_columns",
]

#: angular frequency of the default tap (a half-sine loaded for 1 / (2 f) s): 2 pi f; an encoder
#: of a sweep made at another frequency uses that sweep's (``Encoder.omega_rad_s``)
DESCRIPTOR_OMEGA_RAD_S = 2.0 * math.pi * TappingOptions().frequency_Hz
#: the loss tangent is given at these multiples of ``DESCRIPTOR_OMEGA_RAD_S``
_OMEGA_RATIOS = (1.0 / 3.0, 1.0, 3.0)
#: moduli enter as (log10(G / MPa) + 3) / 3: 1 kPa -> 0, 1 MPa -> 1
_LOG_MODULUS_LOW, _LOG_MODULUS_DECADES = -3.0, 3.0
ELASTIC_FEATURE = "design:elastic"

#: a table of design points: one column (sequence) per parameter name
Columns = dict[str, list[Any]]


def parameter_unit(name: str) -> str:
    """The unit in a parameter's name (``core.mu0_MPa`` -> ``MPa``), "" when dimensionless."""
    for suffix, unit in (("_mm", "mm"), ("_MPa", "MPa"), ("_s", "s"), ("_N", "N")):
        if name.endswith(suffix):
            return unit
    return ""


#: a training range that comes within this fraction of the space's width (on the encoding's
#: unit scale, log for log parameters) of a bound of the space reaches that bound: a sample of
#: the space never lands on a bound exactly, and a design on the bound is no extrapolation. The
#: shipped checkpoint's training ranges stop at most 0.13 % of the width short of a bound
#: (core.mu0_MPa at 0.2977 of 0.3; half-width at 5.00008 mm: 0.004 %); 0.5 % covers that with a
#: margin, while the ranges of a sweep of a few designs, which stop far from the bounds, stay.
BOUND_REACH = 0.005


def _reach_bounds(p: Parameter, lo: float, hi: float) -> tuple[float, float]:
    """The training range [``lo``, ``hi``] of float parameter ``p``, closed up to the space's
    bounds where it comes within ``BOUND_REACH`` of them."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return lo, hi
    if p.log:
        span = math.log(p.high) - math.log(p.low)
        near_low = lo > 0 and (math.log(lo) - math.log(p.low)) <= BOUND_REACH * span
        near_high = hi > 0 and (math.log(p.high) - math.log(hi)) <= BOUND_REACH * span
    else:
        span = p.high - p.low
        near_low = lo - p.low <= BOUND_REACH * span
        near_high = p.high - hi <= BOUND_REACH * span
    return (min(lo, p.low) if near_low else lo), (max(hi, p.high) if near_high else hi)


def is_optional(space: DesignSpace, p: Parameter) -> bool:
    """Whether some design of ``space`` leaves ``p`` inactive (``DesignSpace.is_optional``)."""
    return space.is_optional(p.name)


def _choice_key(v: Any) -> str:
    """Compare choices by text, with 2.0 == 2 (CSV cells and JSON numbers)."""
    if v is None:
        return ""
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        if v.is_integer():
            return str(int(v))
    return str(v)


def _factorize(values: Iterable[Any]) -> tuple[np.ndarray, list[Any]]:
    """``(codes, distinct)`` with ``values[i] == distinct[codes[i]]``: a column of many designs
    holds a few distinct names and choices, so a rule is applied to ``distinct`` only (the hot
    path of encoding). A ``TypeError`` for an unhashable value."""
    values = list(values)
    typed = len(set(map(type, values))) > 1  # 1 == 1.0 == True as dict keys, not as choices
    keys = list(zip(map(type, values), values, strict=True)) if typed else values
    index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    codes = np.fromiter(map(index.__getitem__, keys), dtype=np.intp, count=len(keys))
    return codes, [k[1] for k in index] if typed else list(index)


def _per_value(fn: Callable[[Any], Any], values: Iterable[Any], dtype: Any = None) -> Any:
    """``[fn(v) for v in values]`` (a list, or an array of ``dtype``), ``fn`` called once per
    distinct value (``_factorize``)."""
    values = list(values)
    try:
        codes, distinct = _factorize(values)
    except TypeError:  # an unhashable value
        out = [fn(v) for v in values]
        return out if dtype is None else np.asarray(out, dtype=dtype)
    table = [fn(v) for v in distinct]
    if dtype is not None:
        return np.asarray(table, dtype=dtype)[codes]
    return list(map(table.__getitem__, codes.tolist()))


class _Choices:
    """A column of choice keys held as ``keys[codes]``: the column's few distinct keys and
    each design's index into them, so that a rule is applied once per distinct key and the
    masks are integer comparisons (``Encoder._columns``; ``Encoder.columns`` gives lists)."""

    __slots__ = ("codes", "keys")

    def __init__(self, codes: np.ndarray, keys: list[Any]) -> None:
        self.codes, self.keys = codes, keys

    @classmethod
    def of_values(cls, values: Sequence[Any]) -> _Choices:
        """The choice keys (``_choice_key``) of raw values."""
        try:
            codes, distinct = _factorize(values)
        except TypeError:  # an unhashable value
            return cls.of_keys([_choice_key(v) for v in values])
        keys = [_choice_key(v) for v in distinct]
        # distinct values may share a key (2, 2.0 and "2"): one code per key
        remap, unique = _factorize(keys)
        return cls(remap[codes] if len(unique) < len(keys) else codes, unique)

    @classmethod
    def of_keys(cls, keys: Iterable[Any]) -> _Choices:
        """A column that holds keys already (compared as they are)."""
        codes, distinct = _factorize(keys)
        return cls(codes, distinct)

    def __len__(self) -> int:
        return len(self.codes)

    def tolist(self) -> list[Any]:
        return list(map(self.keys.__getitem__, self.codes.tolist()))

    def per_key(self, fn: Callable[[Any], Any], dtype: Any) -> np.ndarray:
        """``fn`` of each design's key, an array of ``dtype`` (``fn`` once per key)."""
        return np.asarray([fn(k) for k in self.keys], dtype=dtype)[self.codes]

    def rows(self, key: Any) -> np.ndarray:
        """(n,) bool: the designs whose key is ``key``."""
        if key not in self.keys:
            return np.zeros(len(self.codes), dtype=bool)
        return self.codes == self.keys.index(key)

    def where(self, on: np.ndarray, other: Any = "") -> _Choices:
        """This column with ``other`` where ``on`` is False."""
        keys = list(self.keys)
        if other not in keys:
            keys.append(other)
        return _Choices(np.where(on, self.codes, keys.index(other)), keys)


def to_columns(points: Sequence[Mapping[str, Any]] | Mapping[str, Sequence], names: list[str]):
    """``(columns, n)``: a list of points or a table, as one list per known parameter name.

    Unknown names raise a ``DesignError`` (a typo must not be silently ignored); missing names
    give ``None`` entries.
    """
    known = set(names)
    if isinstance(points, Mapping):
        unknown = sorted(set(points) - known)
        lengths = {len(points[k]) for k in points}
        if len(lengths) > 1:
            raise DesignError("table", f"columns of different lengths {sorted(lengths)}")
        n = lengths.pop() if lengths else 0
        cols = {k: list(points[k]) if k in points else [None] * n for k in names}
    else:
        rows = list(points)
        unknown = sorted(set().union(*rows) - known)
        n = len(rows)
        cols = {k: [r.get(k) for r in rows] for k in names}
    if unknown:
        raise DesignError(unknown[0], "unknown parameter (not in the surrogate's design space)")
    return cols, n


def _float_column(name: str, values: list[Any]) -> np.ndarray:
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        pass
    out = np.empty(len(values))
    for i, v in enumerate(values):
        if v is None or v == "":
            out[i] = math.nan
        elif isinstance(v, bool) or not isinstance(v, int | float | str):
            raise DesignError(name, f"design {i}: expected a number, got {v!r}")
        else:
            try:
                out[i] = float(v)
            except ValueError:
                raise DesignError(name, f"design {i}: expected a number, got {v!r}") from None
    return out


@dataclass(frozen=True, eq=False)
class Encoded:
    """Network inputs of ``n`` designs.

    ``features`` (n, n_features) float32; ``in_domain`` (n,) bool: False for a design outside
    the training domain, with the first reason in ``reasons[i]`` ("" when in domain).
    """

    features: np.ndarray
    in_domain: np.ndarray
    reasons: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class Encoder:
    """The encoding of a design space, plus the domain seen in training.

    ``ranges``: for each float parameter, the [min, max] of its active training values (NaN
    when never active); ``seen``: for each choice parameter, the choices seen in training.
    An encoder without a training domain (``fit_domain`` not called) checks the bounds only.
    ``omega_rad_s``: the angular frequency of the taps of the training sweep, 2 pi f, at which
    the material descriptors are taken (``material_descriptors``).
    """

    space: DesignSpace
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    seen: dict[str, tuple[str, ...]] = field(default_factory=dict)
    omega_rad_s: float = DESCRIPTOR_OMEGA_RAD_S
    log_tangents: bool = False

    # ------------------------------------------------------------------ layout
    @property
    def feature_names(self) -> list[str]:
        out = []
        for p in self.space.parameters:
            if p.kind == "float":
                out.append(p.name)
                if is_optional(self.space, p):
                    out.append(f"{p.name}:active")
            elif p.kind == "choice":
                out += [f"{p.name}={_choice_key(c)}" for c in p.choices]
        for role in self.material_roles:
            out += [f"{role}:{d}" for d in descriptor_names(self.log_tangents)]
        out.append(ELASTIC_FEATURE)
        return out

    @property
    def material_roles(self) -> list[str]:
        """The layer roles this space can use, outermost first."""
        return [r for r in LAYER_ROLES if f"{r}.material" in self.space.names]

    @property
    def n_features(self) -> int:
        return len(self.feature_names)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form of the training domain (the space is stored on its own)."""
        return {
            "ranges": {
                k: [finite_or_none(a), finite_or_none(b)] for k, (a, b) in self.ranges.items()
            },
            "seen": {k: list(v) for k, v in self.seen.items()},
            "omega_rad_s": self.omega_rad_s,
            "log_tangents": self.log_tangents,
        }

    @classmethod
    def from_dict(cls, space: DesignSpace, d: Mapping[str, Any]) -> Encoder:
        """The encoder of a checkpoint's ``domain`` entry (one written before ``omega_rad_s``
        was recorded encodes at the default tap's frequency, one written before
        ``log_tangents`` without them, as each was trained)."""
        return cls(
            space,
            {k: (nan_if_none(a), nan_if_none(b)) for k, (a, b) in d["ranges"].items()},
            {k: tuple(v) for k, v in d["seen"].items()},
            float(d.get("omega_rad_s", DESCRIPTOR_OMEGA_RAD_S)),
            bool(d.get("log_tangents", False)),
        )

    # ------------------------------------------------------------------ masking
    def columns(self, points) -> tuple[dict[str, Any], int]:
        """Parsed, masked columns: float parameters as float arrays (NaN inactive), choices
        as lists of choice keys ("" inactive). A ``DesignError`` for a missing active value."""
        cols, n = self._columns(points)
        return {k: c.tolist() if isinstance(c, _Choices) else c for k, c in cols.items()}, n

    def _columns(self, points) -> tuple[dict[str, Any], int]:
        """``columns``, with the choice columns as ``_Choices``."""
        raw, n = to_columns(points, self.space.names)
        cols: dict[str, Any] = {}
        for p in self.space.parameters:
            values = raw[p.name]
            if not p.sampled:  # a fixed parameter or a single choice: may be left out
                default = p.from_unit(0.0)
                values = _per_value(lambda v, d=default: d if _blank(v) else v, values)
                raw[p.name] = values
            numeric = p.kind == "float" or (p.kind == "fixed" and not isinstance(p.value, str))
            if numeric:
                cols[p.name] = _float_column(p.name, values)
            else:
                cols[p.name] = _Choices.of_values(values)
        count = _float_column("layers.count", raw["layers.count"])
        bad = ~np.isin(count, (1.0, 2.0, 3.0))
        if bad.any():
            i = int(np.argmax(bad))
            raise DesignError("layers.count", f"design {i}: must be 1, 2 or 3, got {count[i]!r}")
        for role in LAYER_ROLES:
            mat_name = f"{role}.material"
            if mat_name not in cols:
                continue
            # what decides the rule: the layer count and the material, a few distinct pairs
            material = cols[mat_name]
            pair = material.codes * 4 + count.astype(np.intp)  # few values: no sort
            pairs = np.flatnonzero(np.bincount(pair, minlength=1))
            pair_of = np.searchsorted(pairs, pair)
            mats = material.keys
            for key in ("material", "thickness_mm", *PARAM_MATERIAL_KEYS):
                name = f"{role}.{key}"
                if name not in cols:
                    continue
                rule = [
                    self.space.is_active(name, {"layers.count": int(q % 4), mat_name: mats[q // 4]})
                    for q in pairs
                ]
                on = np.asarray(rule, dtype=bool)[pair_of]
                col = cols[name]
                if isinstance(col, np.ndarray):
                    col = np.where(on, col, np.nan)
                    missing = on & np.isnan(col)
                else:
                    col = col.where(on)
                    missing = on & col.per_key(_is_empty, bool)
                if missing.any():
                    i = int(np.argmax(missing))
                    raise DesignError(name, f"missing for design {i}, which uses it")
                cols[name] = col
        for p in self.space.parameters:
            if p.kind == "float" and not is_optional(self.space, p):
                missing = np.isnan(cols[p.name])
                if missing.any():
                    raise DesignError(p.name, f"missing for design {int(np.argmax(missing))}")
        return cols, n

    # ------------------------------------------------------------------ encoding
    def encode(self, points) -> Encoded:
        """Encode a list of points or a table (``name -> column``)."""
        cols, n = self._columns(points)
        blocks: list[np.ndarray] = []
        in_domain = np.ones(n, dtype=bool)
        reasons = [""] * n

        def flag(mask: np.ndarray, text: str) -> None:
            for i in np.flatnonzero(mask & in_domain):
                reasons[i] = text
            in_domain[mask] = False

        for p in self.space.parameters:
            col = cols[p.name]
            if p.kind == "fixed":
                if isinstance(col, np.ndarray):
                    active = ~np.isnan(col)
                    differs = active & (col != float(p.value))
                else:
                    value = _choice_key(p.value)
                    differs = col.per_key(lambda v, x=value: v not in ("", x), bool)
                flag(differs, f"{p.name} differs from the training value {p.value!r}")
            elif p.kind == "float":
                active = ~np.isnan(col)
                v = np.where(active, col, p.low)
                if p.log:
                    with np.errstate(divide="ignore", invalid="ignore"):
                        u = (np.log(v) - math.log(p.low)) / (math.log(p.high) - math.log(p.low))
                    u = np.where(v > 0, u, -1.0)  # nonpositive on a log scale: far outside
                else:
                    u = (v - p.low) / (p.high - p.low)
                u = np.where(active, u, 0.0)
                flag(active & ((col < p.low) | (col > p.high)), f"{p.name} outside the space")
                lo, hi = _reach_bounds(p, *self.ranges.get(p.name, (p.low, p.high)))
                with np.errstate(invalid="ignore"):
                    outside = ~((col >= lo) & (col <= hi))  # NaN range: never seen active
                flag(active & outside, f"{p.name} outside the training range [{lo:.6g}, {hi:.6g}]")
                blocks.append(u[:, None])
                if is_optional(self.space, p):
                    blocks.append(active[:, None].astype(float))
            else:
                keys = [_choice_key(c) for c in p.choices]
                index = {k: j for j, k in enumerate(keys)}
                # one row of the one-hot block per distinct key (zeros: inactive or unknown)
                table = np.zeros((len(col.keys), len(keys)))
                for r, v in enumerate(col.keys):
                    if v in index:
                        table[r, index[v]] = 1.0
                blocks.append(table[col.codes])
                unknown = col.per_key(lambda v, i=index: v != "" and v not in i, bool)
                flag(unknown, f"{p.name}: unknown choice")
                seen = self.seen.get(p.name)
                if seen is not None:
                    unseen = col.per_key(lambda v, s=seen: v != "" and v not in s, bool)
                    flag(unseen, f"{p.name}: choice never seen in training")
        desc, elastic = material_descriptors(
            cols,
            n,
            self.material_roles,
            self.space.catalogue,
            self.omega_rad_s,
            log_tangents=self.log_tangents,
        )
        blocks += [desc, elastic[:, None].astype(float)]
        # the blocks side by side, as float32: written in place (np.concatenate of many thin
        # blocks, then a cast, takes twice as long)
        features = np.empty((n, sum(b.shape[1] for b in blocks)), dtype=np.float32)
        j = 0
        for b in blocks:
            features[:, j : j + b.shape[1]] = b
            j += b.shape[1]
        return Encoded(features, in_domain, tuple(reasons))

    def fit_domain(self, points) -> Encoder:
        """A copy of this encoder with the training domain of ``points`` (training data)."""
        cols, _ = self.columns(points)
        ranges: dict[str, tuple[float, float]] = {}
        seen: dict[str, tuple[str, ...]] = {}
        for p in self.space.parameters:
            col = cols[p.name]
            if p.kind == "float":
                act = col[~np.isnan(col)]
                ranges[p.name] = (
                    (float(act.min()), float(act.max())) if act.size else (math.nan, math.nan)
                )
            elif p.kind == "choice":
                seen[p.name] = tuple(sorted({v for v in col if v != ""}))
        return Encoder(self.space, ranges, seen, self.omega_rad_s, self.log_tangents)

    # ------------------------------------------------------------------ decoding
    def decode(self, features: np.ndarray) -> list[dict[str, Any]]:
        """Points from features (the inverse of ``encode`` on valid points)."""
        from sim.design import mask_inactive

        features = np.asarray(features, dtype=float)
        points: list[dict[str, Any]] = [{} for _ in range(len(features))]
        j = 0
        for p in self.space.parameters:
            if p.kind == "fixed":
                for pt in points:
                    pt[p.name] = p.value
            elif p.kind == "float":
                optional = is_optional(self.space, p)
                for pt, row in zip(points, features, strict=True):
                    on = row[j + 1] > 0.5 if optional else True
                    pt[p.name] = p.from_unit(float(row[j])) if on else math.nan
                j += 2 if optional else 1
            else:
                k = len(p.choices)
                for pt, row in zip(points, features, strict=True):
                    block = row[j : j + k]
                    pt[p.name] = p.choices[int(np.argmax(block))] if block.max() > 0.5 else ""
                j += k
        return [mask_inactive(pt) for pt in points]


_DESCRIPTOR_NAMES = (
    "log10_mu_MPa",
    "log10_storage_MPa",
    *(f"tan_delta@{r:.3g}w" for r in _OMEGA_RATIOS),
)
#: the log loss tangents enter as (log10(max(tan d, floor)) - log10(floor)) / decades: 1e-5 -> 0,
#: 1 -> 1 (the shipped sweep's largest is 0.82). The floor is below every relaxing layer of
#: the shipped sweep (smallest nonzero tan d 2.5e-5; every design whose hysteresis the
#: evaluation scores has a layer at 4.9e-4 or more: ``python studies/hysteresis_tail.py``); an
#: elastic layer sits on it
_LOG_TAN_FLOOR, _LOG_TAN_DECADES = 1e-5, 5.0


def descriptor_names(log_tangents: bool = False) -> tuple[str, ...]:
    """The names of one layer's material descriptors (``material_descriptors``)."""
    if not log_tangents:
        return _DESCRIPTOR_NAMES
    return (*_DESCRIPTOR_NAMES, *(f"log10_tan_delta@{r:.3g}w" for r in _OMEGA_RATIOS))


def _catalogue_entry(
    name: str, catalogue: Mapping[str, Any] | None = None
) -> tuple[float, np.ndarray, np.ndarray]:
    """Long-term shear modulus (MPa), Prony g and tau_s of a catalogue material (shipped
    entries cached; a user material of the space's ``catalogue`` computed)."""
    m = CATALOGUE.get(name) if catalogue is None else catalogue[name]
    if m is not CATALOGUE.get(name):
        return _entry(m)
    if name not in _CATALOGUE_CACHE:
        _CATALOGUE_CACHE[name] = _entry(m)
    return _CATALOGUE_CACHE[name]


def _entry(m: Any) -> tuple[float, np.ndarray, np.ndarray]:
    return (
        m.long_term.initial_shear_modulus_MPa,
        np.asarray(m.prony.g, dtype=float),
        np.asarray(m.prony.tau_s, dtype=float),
    )


_CATALOGUE_CACHE: dict[str, tuple[float, np.ndarray, np.ndarray]] = {}


def material_descriptors(
    cols: Mapping[str, Any],
    n: int,
    roles: Sequence[str],
    catalogue: Mapping[str, Any] | None = None,
    omega_rad_s: float = DESCRIPTOR_OMEGA_RAD_S,
    *,
    log_tangents: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Linear-viscoelastic descriptors of each layer's material, and the elastic-design flag.

    ``cols``: masked columns (``Encoder.columns``). For each role, five features (zeros when
    the layer is inactive): the long-term small-strain shear modulus mu, the storage modulus
    G'(w) and the loss tangent G''/G' at w/3, w, 3w (w = ``omega_rad_s``, the taps') of the
    Prony series g_i, tau_i in relative (Abaqus) form, with G0 = mu / (1 - sum g):
    G'(w) = G0 [1 - sum g_i / (1 + (w tau_i)^2)], G''(w) = G0 sum g_i w tau_i / (1 + (w tau_i)^2).
    Returns ``(features (n, 5 len(roles)), elastic (n,) bool)``; a design is elastic when no
    active layer relaxes (a material name outside the catalogue gives zero descriptors and is
    never taken as elastic). Names are looked up in ``catalogue`` (the space's: shipped plus
    its user materials; default the shipped catalogue).
    """
    known = CATALOGUE if catalogue is None else catalogue
    blocks = []
    elastic = np.ones(n, dtype=bool)
    k = max(len(f.time_ratios) for f in FAMILIES.values())
    for role in roles:
        names = cols[f"{role}.material"]
        if not isinstance(names, _Choices):  # a list or array of names
            names = _Choices.of_keys(list(names))
        # per distinct name: a layer, of a family, of the catalogue
        is_on = np.asarray([v != "" for v in names.keys], dtype=bool)
        is_param = np.asarray([is_family(v) for v in names.keys], dtype=bool)
        is_known = np.asarray([v in known for v in names.keys], dtype=bool)
        # an unknown name (flagged out of domain by ``encode``): no descriptors, and not elastic
        is_unknown = is_on & ~is_param & ~is_known
        unknown = is_unknown[names.codes]
        on = (is_on & ~is_unknown)[names.codes]
        elastic &= ~unknown
        # the Prony terms of each design, term after term: (terms, n), so that every sum over
        # the terms is a few vectorised additions (bit for bit the row sums of (n, terms) up
        # to 7 terms; the shipped materials have at most 3)
        mu = np.ones(n)
        g = np.zeros((k, n))
        tau = np.ones((k, n))
        for fam in FAMILIES.values():
            rows = names.rows(fam.name)
            if not rows.any():
                continue
            ratios = np.asarray(fam.time_ratios)
            mu[rows] = cols[f"{role}.mu0_MPa"][rows]
            g[:, rows] = 0.0
            g[: ratios.size, rows] = cols[f"{role}.g_total"][rows] / ratios.size
            tau[: ratios.size, rows] = cols[f"{role}.tau_s"][rows] * ratios[:, None]
        for name in itertools.compress(names.keys, is_on & ~is_param & is_known):
            rows = names.rows(name)
            mu_c, g_c, tau_c = _catalogue_entry(name, known)
            if g_c.size > g.shape[0]:
                pad = g_c.size - g.shape[0]
                g = np.pad(g, ((0, pad), (0, 0)))
                tau = np.pad(tau, ((0, pad), (0, 0)), constant_values=1.0)
            mu[rows] = mu_c
            g[:, rows] = 0.0
            g[: g_c.size, rows] = g_c[:, None]
            tau[: tau_c.size, rows] = tau_c[:, None]
        g_sum = g.sum(axis=0)
        elastic &= ~on | (g_sum <= 0)
        g0 = mu / (1.0 - g_sum)
        moduli, tangents = [mu], []
        for r in _OMEGA_RATIOS:
            wt = omega_rad_s * r * tau
            d = 1.0 + wt**2
            storage = g0 * (1.0 - (g / d).sum(axis=0))
            loss = g0 * (g * wt / d).sum(axis=0)
            if r == 1.0:
                moduli.append(storage)
            tangents.append(loss / storage)
        log_moduli = (np.log10(np.stack(moduli)) - _LOG_MODULUS_LOW) / _LOG_MODULUS_DECADES
        log_tangents_ = []
        if log_tangents:
            floor = math.log10(_LOG_TAN_FLOOR)
            log_tangents_ = [
                (np.log10(np.maximum(t, _LOG_TAN_FLOOR)) - floor) / _LOG_TAN_DECADES
                for t in tangents
            ]
        blocks += [np.where(on, b, 0.0) for b in (*log_moduli, *tangents, *log_tangents_)]
    out = np.empty((n, len(blocks)))
    for j, b in enumerate(blocks):
        out[:, j] = b
    return out, elastic


def _is_empty(v: Any) -> bool:
    return v == ""


def _blank(v: Any) -> bool:
    return v is None or v == "" or (isinstance(v, float) and math.isnan(v))
