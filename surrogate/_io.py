"""Reading design points (TOML, CSV) and sweep folders (config.json + table.csv)."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.design import DesignSpace, space_from_dict
from sim.errors import DesignError, read_toml
from sim.metrics import METRICS, METRICS_3D, PROTOCOLS, diagnostic_names, metric_registry
from sim.protocols import LAYER_STRAIN_OUTPUTS, TRUST_OUTPUTS, trust_censoring, trust_values
from sim.provenance import KINDS, folder_kind, sha256_file
from sim.sweep import (
    CONFIG,
    DAMAGED_GZIP,
    open_table,
    read_config,
    table_path,
    table_sha256,
)

__all__ = ["SweepData", "check_point", "read_points", "read_sweep", "sha256_file"]

#: the columns of a sweep's table.csv that are not design parameters
TABLE_COLUMNS = (
    "index",
    "key",
    "status",
    "wall_time_s",
    "reason",
    *METRICS,
    *METRICS_3D,
    *diagnostic_names(),
)


def _cell(space: DesignSpace, name: str, text: str, where: str) -> Any:
    """A CSV cell as a point value (empty = inactive)."""
    p = space[name]
    text = text.strip()
    if text == "":
        return "" if p.kind == "choice" else math.nan
    if p.kind == "choice" or (p.kind == "fixed" and isinstance(p.value, str)):
        options = p.choices if p.kind == "choice" else (p.value,)
        for c in options:
            if str(c) == text:
                return c
        return text  # an unknown choice: flagged (API) or refused (CLI check)
    try:
        return float(text)
    except ValueError:
        raise DesignError(name, f"{where}: expected a number, got {text!r}") from None


def _read_csv(path: Path, space: DesignSpace) -> list[dict[str, Any]]:
    with open_table(path) as fh:
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        unknown = [c for c in header if c not in space.names and c not in TABLE_COLUMNS]
        if unknown:
            raise DesignError(unknown[0], f"{path.name}: unknown column (not a space parameter)")
        names = [c for c in header if c in space.names]
        rows = []
        for i, row in enumerate(reader):
            if None in row:
                raise DesignError(path.name, f"row {i + 1}: more cells than columns")
            point = {n: _cell(space, n, row[n] or "", f"row {i + 1}") for n in names}
            try:
                rows.append(check_point(space, point))
            except DesignError as exc:
                raise DesignError(f"{path.name} row {i + 1}: {exc.field}", exc.message) from None
    if not rows:
        raise DesignError(path.name, "no design rows")
    return rows


def _flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        name = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(_flatten(v, f"{name}."))
        else:
            out[name] = v
    return out


def read_points(path: str | Path, space: DesignSpace) -> list[dict[str, Any]]:
    """Checked design points (``check_point``) from a TOML file (a design file, as
    ``fingertip simulate`` reads it, whose layers are catalogue materials or family members of
    the space; or one flat table ``name = value``, dotted keys such as ``core.mu0_MPa = 0.05``
    work too) or a CSV file (one point per
    row, columns = point names, empty cell = inactive; a sweep's table.csv works, its
    non-parameter columns are ignored; ``.csv.gz``: gzip-compressed, as the shipped table)."""
    path = Path(path)
    if not path.name.lower().endswith((".csv", ".csv.gz")):
        data = read_toml(path, "DESIGNS")
        if isinstance(data.get("layers"), list):  # a design file, as `fingertip simulate` reads
            return [check_point(space, _design_point(data, space))]
        return [check_point(space, _flatten(data))]
    try:
        return _read_csv(path, space)
    except FileNotFoundError:
        raise DesignError("DESIGNS", f"no such file: {path}") from None
    except IsADirectoryError:
        raise DesignError("DESIGNS", f"{path} is a directory, not a CSV file") from None
    except DAMAGED_GZIP as exc:
        raise DesignError("DESIGNS", f"damaged gzip file {path}: {exc}") from None
    except OSError as exc:
        raise DesignError("DESIGNS", f"cannot read {path}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise DesignError("DESIGNS", f"{path} is not UTF-8 text") from None
    except csv.Error as exc:
        raise DesignError("DESIGNS", f"malformed CSV in {path}: {exc}") from None


def _design_point(data: Mapping[str, Any], space: DesignSpace) -> dict[str, Any]:
    """The point of a design file (``[geometry]``, ``[[layers]]``) in ``space``."""
    from sim.design import design_from_dict, point_from_design

    return point_from_design(design_from_dict(data, space.catalogue), space)


def check_point(space: DesignSpace, point: Mapping[str, Any]) -> dict[str, Any]:
    """A hand-written point checked against ``space`` (names known, active values present and
    inside the bounds or choices, a buildable design); returns it masked. Values of parameters
    the design does not use are dropped (masked), as in a sweep."""
    from sim.design import mask_inactive

    for name in point:
        if name not in space.names:
            raise DesignError(name, "unknown parameter (not in the surrogate's design space)")
    # a blank cell is a missing value: a fixed parameter or a single choice takes its value
    filled = space.complete({k: v for k, v in point.items() if not _blank(v)}, mask=False)
    count = filled["layers.count"]
    if _blank(count):
        raise DesignError("layers.count", "missing")
    if isinstance(count, bool) or count not in (1, 2, 3):
        raise DesignError("layers.count", f"must be 1, 2 or 3, got {count!r}")
    filled["layers.count"] = int(count)
    masked = mask_inactive(filled)
    for p in space.parameters:
        v = masked[p.name]
        if _blank(v):
            if space.is_active(p.name, masked):
                raise DesignError(p.name, "missing (this design uses it)")
        elif p.kind == "float" and (isinstance(v, bool) or not isinstance(v, int | float)):
            raise DesignError(p.name, f"expected a number, got {v!r}")
    return space.check(masked)


def _blank(v: Any) -> bool:
    return v is None or v == "" or (isinstance(v, float) and math.isnan(v))


@dataclass(frozen=True, eq=False)
class SweepData:
    """The usable designs of a sweep folder.

    ``points``: design points; ``targets`` (n, n_metrics): FE metrics in their units (NaN when
    a protocol failed or did not reach the metric), then the trust outputs of
    ``sim.protocols.trust`` when the table has its diagnostic columns (``metric_names`` says which);
    ``index``: the table's design index; ``table_sha256``: hash of table.csv (the training data).
    """

    folder: Path
    space: DesignSpace
    solver_version: str
    points: list[dict[str, Any]]
    targets: np.ndarray
    index: np.ndarray
    metric_names: tuple[str, ...]
    table_sha256: str
    n_rows: int
    #: designs whose FE metrics are left out, by reason ("unsettled", "invalid": they still
    #: teach the trust outputs), and the designs whose table does not say (a sweep made before
    #: the flags were recorded: kept)
    excluded: dict[str, int] = field(default_factory=dict)
    unchecked: int = 0
    #: of the ``excluded`` designs, those whose metrics of the protocols that stayed trusted on
    #: their own were kept (``_trusted_protocols``: e.g. the taps of a design that is invalid
    #: only through the wedge's deformation)
    partial: int = 0
    #: (n,) bool: the designs whose FE result is trusted whole (settled and valid; every design
    #: of a table without the flags); None: all of them
    whole: np.ndarray | None = None

    def scored_targets(self) -> np.ndarray:
        """``targets`` as the accuracy is scored: the FE metrics of the designs trusted whole
        only (the surrogate's accuracy is stated on settled, valid designs), NaN elsewhere;
        the trust outputs of every design."""
        if self.whole is None or self.whole.all():
            return self.targets
        out = self.targets.copy()
        fe = np.array([m in METRICS or m in METRICS_3D for m in self.metric_names])
        out[np.ix_(~self.whole, fe)] = np.nan
        return out

    #: the tapping frequency the sweep was made at (its recorded options; default if absent)
    tapping_frequency_Hz: float = 0.5
    #: (n, n_metrics) int8, like ``targets``: +1 where a value is only a lower bound, -1 an
    #: upper bound (the trust figures of a protocol stopped at its first violation,
    #: ``sim.protocols.trust.trust_censoring``), 0 exact; None: all exact
    censored: np.ndarray | None = None

    def with_rows(self, points: list[dict[str, Any]], targets: np.ndarray) -> SweepData:
        """These designs and, after them, ``points`` with their ``targets`` (one row per
        point, the columns of ``metric_names``; NaN: not learnt): one training set. The added
        designs are in no table: their indices are -1, -2, ... and they count in ``n_rows``;
        everything else (the space, the solver, the tap frequency...) is this sweep's."""
        targets = np.asarray(targets, dtype=np.float64).reshape(-1, len(self.metric_names))
        if len(targets) != len(points):
            raise ValueError(f"{len(points)} points but {len(targets)} rows of targets")
        censored = None
        if self.censored is not None:  # the added designs' values are exact
            censored = np.vstack([self.censored, np.zeros(targets.shape, dtype=np.int8)])
        return replace(
            self,
            points=[*self.points, *points],
            targets=np.vstack([self.targets, targets]),
            censored=censored,
            index=np.concatenate([self.index, -1 - np.arange(len(points))]),
            n_rows=self.n_rows + len(points),
        )


def _number(text: str, field_name: str, *, integer: bool = False) -> float:
    """A numeric table cell (empty = NaN, a metric not reached); anything else is refused."""
    text = text.strip()
    if not text and not integer:
        return math.nan
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if integer and not (math.isfinite(value) and value == int(value) and value >= 0):
        raise DesignError(field_name, f"expected a whole number >= 0, got {text!r}")
    if math.isnan(value) and text.lower() != "nan":
        raise DesignError(field_name, f"expected a number or an empty cell, got {text!r}")
    return value


def _flag(text: str | None) -> bool | None:
    """A table's boolean cell: True/False (also 1/0), None when empty or absent."""
    if text is None or not text.strip():
        return None
    return text.strip().lower() in ("true", "1")


def _untrusted(row: dict[str, str]) -> str | None:
    """Why a design's FE result is not trusted ("unsettled", "invalid"), or None."""
    if _flag(row.get("settled")) is False:
        return "unsettled"
    if _flag(row.get("valid")) is False:
        return "invalid"
    return None


def _trusted_protocols(row: dict[str, str], validity: Any) -> frozenset[str]:
    """The protocols whose FE result of an untrusted design (``_untrusted``) is trusted on its
    own. The protocols run one after another, each from the undeformed design (``sim.simulate``),
    so one that stayed within the validity limits (``sim.protocols.validity.check`` of its own
    figures, with the sweep's ``ValidityOptions``) and, for the taps, reached the periodic state,
    gave a credible result whatever the others did. A protocol without figures (it failed) is not
    trusted. None at all when the figures do not show why the design is untrusted (the table's flags
    and figures disagree). A table has each protocol's largest strain, not each layer's: with
    each layer held to its own tested limit (no ``validity.max_compressive_log_strain``
    override), whether a protocol's layers stayed within theirs is read from the row's
    ``violations`` (``_strain_violated``), the verdict its FE result recorded."""
    from sim.protocols.validity import check

    per_layer = validity.max_compressive_log_strain is None
    kept, blamed = set(), False
    for protocol in PROTOCOLS:
        cells = [row.get(f"{protocol}_{k}") or "" for k in _DIAGNOSED]
        if not all(c.strip() for c in cells):
            continue  # failed (no figures), or not run: nothing of it to keep
        try:
            strain, min_j = float(cells[0]), float(cells[1])
        except ValueError:
            continue
        summary = {
            "max_compressive_log_strain": strain,
            "min_J": min_j,
            "reached_base": bool(_flag(cells[2])),
            "folded": bool(_flag(cells[3])),
        }
        broken = check(summary, validity, protocol)
        if per_layer:
            broken = [v for v in broken if v.option != "max_compressive_log_strain"]
            broken += _strain_violated(row, protocol)
        ok = not broken
        if protocol == "tapping" and _flag(row.get("settled")) is not True:
            ok = False
        blamed |= not ok
        if ok:
            kept.add(protocol)
    return frozenset(kept) if blamed else frozenset()


def _strain_violated(row: dict[str, str], protocol: str) -> list[str]:
    """The compressive strain limits (a layer's tested one, or a Drucker-stable one) that a
    table row's ``violations`` cell records for ``protocol`` (``SimResult.validity``'s
    ``"<violation> (<protocol>)"``, joined by "; ")."""
    cell = row.get("violations") or ""
    return [
        v
        for v in (x.strip() for x in cell.split(";"))
        if v.endswith(f"({protocol})") and "compressive log strain" in v
    ]


#: the per-protocol figures of a table row that ``sim.protocols.validity.check`` judges
_DIAGNOSED = ("max_compressive_log_strain", "min_J", "reached_base", "folded")


def read_sweep(
    folder: str | Path,
    trusted_only: bool = True,
    per_protocol: bool = True,
    *,
    dimension: str = "2d",
) -> SweepData:
    """Designs with at least one finite metric (failed protocols leave NaN, masked in training),
    and, when the table has the trust columns, every design (a failed one teaches ``failed``).

    ``trusted_only``: leave out the designs whose tapping did not reach its periodic state
    (``settled`` false) or whose deformation went beyond the validity limits (``valid`` false);
    they are counted in ``excluded``. With ``per_protocol`` their metrics of a protocol whose own
    result is trusted (``_trusted_protocols``: e.g. the taps of a design invalid only through the
    wedge) are kept, those designs counted in ``partial`` too. On the default space's sweep (675
    designs, 313 untrusted, 286 of which keep some: 57 their taps, 242 their plate, 190 their
    wedge; fixed 15 % test split, 574 training + validation designs, 3 seeds, scored on
    settled, valid designs, ``docs/surrogate_accuracy.md``) the median error of hysteresis_Nmm
    went from 11.5 to 9.7 %, and with the default grouping that of plate_force_at_1mm_N from
    16 to 7 %, wedge_peak_force_N from 5.8 to 3.5 %. A table without these columns (a sweep made
    before they were recorded) is used whole, its designs counted in ``unchecked``.

    ``dimension``: the model the sweep must be of ("2d"; "3d" for the multi-fidelity surrogate,
    ``surrogate._multifidelity``, whose metrics include ``sim.metrics.METRICS_3D``); a sweep of
    the other model is refused."""
    folder = Path(folder)
    config_path, table = folder / CONFIG, table_path(folder)
    if not folder.is_dir():
        raise DesignError("SWEEP", f"no such sweep folder: {folder}")
    kind = folder_kind(folder)
    if kind not in ("sweep", None) and not table.exists():
        raise DesignError("SWEEP", f"{folder} holds a {KINDS[kind]}, not a {KINDS['sweep']}")
    if not config_path.exists() or not table.exists():
        raise DesignError(
            "SWEEP", f"{folder} has no config.json and table.csv; run `fingertip sweep` first"
        )
    try:
        config = read_config(folder)
        space = space_from_dict(config["space"])
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise DesignError("SWEEP", f"unreadable {config_path}: {exc}") from None
    model = ((config.get("options") or {}).get("model") or {}).get("dimension", "2d")
    if model != dimension:  # the search confirms with the 2D FE: a 3D surrogate would mix the two
        learns = (
            "the surrogate learns from 2D sweeps only"
            if dimension == "2d"
            else f"the multi-fidelity surrogate learns from {dimension.upper()} sweeps"
        )
        raise DesignError("SWEEP", f"{folder} is a sweep of the {model} model; {learns}")
    registry = metric_registry(model)
    validity = _validity_options(config)
    points, targets, index, whole = [], [], [], []
    bounds: list[list[int]] = []  # per row, trust_censoring (when the table has trust columns)
    n_rows, unchecked, partial = 0, 0, 0
    excluded: dict[str, int] = {}
    rebuild = "re-run the same `fingertip sweep` command to rebuild it from the records"
    try:
        with open_table(table) as fh:
            reader = csv.DictReader(fh)
            header = reader.fieldnames or []
            # the metrics the table has (a table from before a metric was added lacks it), then
            # the trust outputs (sim.protocols.trust) when it has the diagnostic columns
            metric_names = tuple(m for m in registry if m in header)
            n_fe = len(metric_names)
            learns_trust = "valid" in header
            trust_names: tuple[str, ...] = ()
            if learns_trust:  # each layer's strain too when the table has it (solver >= 2.3)
                layers = tuple(m for m in LAYER_STRAIN_OUTPUTS if m in header)
                trust_names = (*TRUST_OUTPUTS, *layers)
                metric_names += trust_names
            missing = [c for c in ("index", *space.names) if c not in header]
            if missing or not metric_names:
                what = missing[0] if missing else next(iter(registry))
                raise DesignError("SWEEP", f"{table} has no column {what!r}")
            for row in reader:
                n_rows += 1
                where = f"{table} row {n_rows}"
                if None in row or any(v is None for v in row.values()):
                    raise DesignError(
                        "SWEEP",
                        f"{where} does not have the {len(header)} cells of the header "
                        f"(a truncated or damaged table); {rebuild}",
                    )
                y = [_number(row[m], f"{where}: {m}") for m in metric_names[:n_fe]]
                if not (learns_trust or any(math.isfinite(v) for v in y)):
                    continue
                why = _untrusted(row)
                if why is not None and trusted_only:
                    excluded[why] = excluded.get(why, 0) + 1
                    if not learns_trust:
                        continue
                    # its metrics are not learnt (but those of a protocol trusted on its own
                    # are), what made it so is
                    kept = _trusted_protocols(row, validity) if per_protocol else frozenset()
                    partial += any(registry[m][0] in kept for m in metric_names[:n_fe])
                    protocol = [registry[m][0] for m in metric_names[:n_fe]]
                    y = [v if p in kept else math.nan for p, v in zip(protocol, y, strict=True)]
                if learns_trust:
                    trust, censoring = trust_values(row), trust_censoring(row)
                    y += [trust[m] for m in trust_names]
                    bounds.append([0] * n_fe + [censoring[m] for m in trust_names])
                unchecked += not learns_trust
                whole.append(why is None or not trusted_only)
                points.append({n: _cell(space, n, row[n], where) for n in space.names})
                targets.append(y)
                index.append(int(_number(row["index"], f"{where}: index", integer=True)))
    except UnicodeDecodeError:
        raise DesignError("SWEEP", f"{table} is not UTF-8 text; {rebuild}") from None
    except csv.Error as exc:
        raise DesignError("SWEEP", f"malformed CSV in {table}: {exc}; {rebuild}") from None
    except DAMAGED_GZIP as exc:
        raise DesignError("SWEEP", f"damaged gzip file {table}: {exc}") from None
    y_all = np.asarray(targets, dtype=np.float64).reshape(len(points), len(metric_names))
    censored = (
        np.asarray(bounds, dtype=np.int8).reshape(len(points), len(metric_names))
        if learns_trust
        else np.zeros((len(points), len(metric_names)), dtype=np.int8)
    )
    # a layer no design of the sweep has (a middle layer in a space of one or two) is no output
    keep = [
        j for j, m in enumerate(metric_names)
        if m not in LAYER_STRAIN_OUTPUTS or np.isfinite(y_all[:, j]).any()
    ]  # fmt: skip
    metric_names = tuple(metric_names[j] for j in keep)
    y_all = y_all[:, keep]
    censored = censored[:, keep]
    return SweepData(
        folder=folder,
        space=space,
        solver_version=str(config.get("solver_version", "")),
        points=points,
        targets=y_all,
        index=np.asarray(index, dtype=np.int64),
        metric_names=metric_names,
        table_sha256=table_sha256(table),
        n_rows=n_rows,
        excluded=excluded,
        unchecked=unchecked,
        partial=partial,
        whole=np.asarray(whole, dtype=bool),
        tapping_frequency_Hz=_frequency(config),
        censored=censored if learns_trust and censored.any() else None,
    )


def _validity_options(config: Mapping[str, Any]) -> Any:
    """The ``ValidityOptions`` a sweep was made with (its recorded options; defaults if absent:
    the same rule as ``sim.options.options_from_dict``)."""
    import dataclasses

    from sim.protocols import ValidityOptions

    given = (config.get("options") or {}).get("validity") or {}
    known = {f.name for f in dataclasses.fields(ValidityOptions)}
    return ValidityOptions(**{k: v for k, v in given.items() if k in known})


def _frequency(config: Mapping[str, Any]) -> float:
    """The tapping frequency of a sweep's recorded options (the default when it has none)."""
    from sim.protocols import TappingOptions

    tap = (config.get("options") or {}).get("tapping") or {}
    return float(tap.get("frequency_Hz", TappingOptions().frequency_Hz))
