"""Carry a sweep made under one global strain limit over to each layer's own limit, re-running
only the designs whose course that changes (``fingertip migrate-sweep SOURCE TARGET
--revalidate``).

Solver 2.3 to 2.8 sweeps of the default space (the shipped surrogate's) were made with the
validity option ``max_compressive_log_strain = 0.60``, one limit for every layer; today each
layer is held to the strain its material was tested to (``sim.protocols.validity.layer_limit``:
a gel's 0.53, a foam's 1.05, ...). A design's FE result does not depend on the limits until a
protocol stops at its first step beyond one (``ValidityOptions.stop_at_violation``), so a row of
the source table is what this solver computes under the layers' limits whenever no protocol's
course changes (:func:`rerun_reason`, the rule):

- a protocol that ran to its end, or that another limit (J, ...) stopped, with its largest
  strain ``s`` within the smallest of the layers' limits: no layer's limit stops it earlier;
- a protocol that the global limit ``L0`` stopped (its strain at the stop ``s > L0``) of a
  design whose every layer's limit is at most ``L0``: the layers' limits stop it no later
  (invalid either way, without its metrics either way; its strains and J are those at the old
  stop, bounds as every stopped protocol's are, ``sim.protocols.trust_censoring``);
- a failed design whose every layer's limit is at least ``L0``: its strain stayed within ``L0``
  up to the failure (else it would have stopped), so within every limit, and it fails alike.

Every other row is left out, and the resumed sweep (``resume_command``) computes it: a protocol
stopped by ``L0`` where a layer may go further, a strain within ``L0`` but beyond a layer's
lower limit, and every valid design of more than one layer, because each layer's strain, which
the search holds to the layer's own limit (``sim.metrics.role_strains``), is not in the source
table (a one-layer design's is the design's). The source needs its table only (the shipped
surrogate's folder has no records): a carried row becomes a record with the row's cells, no
curves, and ``migrated`` naming the source. Its design must be the sample's design at its index
(the same space, seed and sampler).

A source made under the layers' own limits already has every row carried: a sweep's table
(with its ``config.json``) kept in git is then enough to rebuild its folder on another machine
and resume it there (``runs/`` is not kept), at the cost of the curves.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..design import point_to_design, space_from_dict
from ..errors import DesignError
from ..metrics import SAME_METRICS_AS, SOLVER_VERSION, diagnostic_names, metric_registry
from ..options import options_from_dict
from ..protocols.validity import layer_limit
from ..provenance import json_safe, provenance
from .folder import SweepStore, open_table, read_config, table_path, write_config, write_meta
from .run import record_key, sample_points, sweep_config, with_todays_defaults

__all__ = ["REVALIDATED_OPTIONS", "layer_limits", "rerun_reason", "revalidate"]

#: the option a revalidation takes away (the global limit), and the one it may differ in
REVALIDATED_OPTIONS = {("validity", "max_compressive_log_strain")}


def layer_limits(
    point: Mapping[str, Any], catalogue: Mapping[str, Any] | None = None
) -> list[float]:
    """The compressive log strain each layer of a design point is held to, outermost first
    (``sim.protocols.validity.layer_limit`` of its material)."""
    design = point_to_design(dict(point), catalogue)
    return [layer_limit(layer.material).log_strain for layer in design.layers]


def rerun_reason(
    row: Mapping[str, str],
    limits: Sequence[float],
    old_limit: float,
    strain_limited: Sequence[str] = ("tapping", "plate"),
) -> str | None:
    """THE rule (module docstring): None when the source ``row`` (a table row's cells) is what
    this solver computes under the layers' own ``limits``, else why it is re-run."""
    if row["status"] != "ok":
        return None if min(limits) >= old_limit else "failed, a layer limited below the old"
    if len(limits) > 1 and row["valid"] == "True":
        return "valid, several layers: each layer's strain is not in the table"
    stopped = {p.strip() for p in row.get("stopped", "").split(",") if p.strip()}
    for p in strain_limited:
        cell = row.get(f"{p}_max_compressive_log_strain", "")
        if cell == "":
            continue  # the protocol has no strain (not run, or failed)
        strain = float(cell)
        if p in stopped and strain > old_limit:  # the old limit stopped it
            if max(limits) > old_limit:
                return f"{p} stopped at the old limit, a layer may go further"
        elif strain > min(limits):
            return f"{p} strain within the old limit, beyond a layer's own"
    return None


def _value(cell: str) -> Any:
    """A table cell as the record value it was written from: None, a bool, an int, a float or
    the text, whichever gives the cell back (``str`` of it)."""
    if cell == "":
        return None
    if cell in ("True", "False"):
        return cell == "True"
    for kind in (int, float):
        try:
            value = kind(cell)
        except ValueError:
            continue
        if str(value) == cell:
            return value
    return cell


def _record(row: Mapping[str, str], point: dict, config: Mapping[str, Any], source: Path) -> dict:
    """The record of a carried row: its cells, the per-layer list of a one-layer design's
    strains (its layer's are the design's), no curves, and where it came from."""
    dimension = "3d" if config["options"].get("model", {}).get("dimension") == "3d" else "2d"
    metrics = {m: _value(row[m]) for m in metric_registry(dimension) if m in row}
    diagnostics = {d: _value(row[d]) for d in diagnostic_names() if d in row}
    if int(point["layers.count"]) == 1:
        for p in ("tapping", "plate", "wedge"):
            strain = diagnostics.get(f"{p}_max_compressive_log_strain")
            if isinstance(strain, int | float) and not isinstance(strain, bool):
                diagnostics[f"{p}_max_compressive_log_strain_by_layer"] = [float(strain)]
    return {
        "params": json_safe(point),
        "status": row["status"],
        "reason": row.get("reason", ""),
        "metrics": {k: v for k, v in metrics.items() if v is not None},
        "diagnostics": diagnostics,
        "curves": {},
        "solver_version": config.get("solver_version"),
        "wall_time_s": float(row.get("wall_time_s") or 0.0),
        "migrated": {
            "from": str(source),
            "key": row["key"],
            "solver_version": config.get("solver_version"),
            "by": "fingertip migrate-sweep --revalidate",
        },
    }


def _same_cell(cell: str, value: Any) -> bool:
    """Whether a table cell holds a sample point's value ("" for an inactive one)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return cell == ""
    return cell == str(value)


def revalidate(
    source: str | Path, target: str | Path
) -> tuple[list[str], list[str], dict, Counter]:
    """Write the sweep folder ``target`` from the table of ``source`` (a sweep of this solver
    or of one it reproduces, ``SAME_METRICS_AS``, made with a global strain limit or under the
    layers' own limits): the carried rows as records, the config of the same sample under the
    layers' own limits. Returns
    (carried keys, the sweep's keys in order, its config, the count of each re-run reason). A
    ``DesignError`` naming SOURCE or TARGET before anything is written."""
    source, target = Path(source), Path(target)
    try:
        old = read_config(source)
        table = table_path(source)
    except (OSError, ValueError) as exc:
        raise DesignError("SOURCE", f"{source} is not a sweep folder ({exc})") from None
    version = old.get("solver_version")
    if version != SOLVER_VERSION and version not in SAME_METRICS_AS:
        raise DesignError(
            "SOURCE", f"{source} is a sweep of solver {version}, which {SOLVER_VERSION} does not "
            "reproduce"
        )  # fmt: skip
    old_limit = (old["options"].get("validity") or {}).get("max_compressive_log_strain")
    if not (old["options"].get("validity") or {}).get("stop_at_violation"):
        raise DesignError(
            "SOURCE", f"{source} ran past the validity limits (no stop_at_violation): carry it "
            "over with migrate-sweep without --revalidate"
        )  # fmt: skip
    if target.exists():
        raise DesignError("TARGET", f"{target} exists; choose a new folder")
    old = with_todays_defaults(old)  # options at a default changed since: today's
    options = options_from_dict(old["options"])
    options = dataclasses.replace(
        options, validity=dataclasses.replace(options.validity, max_compressive_log_strain=None)
    )
    space = space_from_dict(old["space"])
    config = sweep_config(
        space, old["n"], old["seed"], old["sampler"], options, old.get("start", 0)
    )
    if "catalogues" in old:
        config["catalogues"] = old["catalogues"]
    points = sample_points(space, old["n"], old["seed"], old["sampler"])
    keys = [record_key(p, options, space.catalogue) for p in points[old.get("start", 0) :]]
    carried: list[tuple[str, dict]] = []
    reasons: Counter = Counter()
    limited = options.validity.strain_limited
    with open_table(table) as fh:
        for row in csv.DictReader(fh):
            i = int(row["index"])
            point = points[i]
            if not all(_same_cell(row[n], point[n]) for n in space.names):
                raise DesignError("SOURCE", f"{table}: row {i} is not design {i} of the sample")
            why = (
                None  # made under the layers' own limits already: every row is carried
                if old_limit is None
                else rerun_reason(row, layer_limits(point, space.catalogue), old_limit, limited)
            )
            if why is None:
                carried.append((keys[i - old.get("start", 0)], _record(row, point, old, source)))
            else:
                reasons[why] += 1
    target.mkdir(parents=True)
    store = SweepStore(target)
    for key, rec in carried:
        store.write(key, rec)
    write_config(target, config)
    meta = provenance(config, old["seed"], kind="sweep")
    meta["migrated_from"] = {
        "folder": str(source),
        "solver_version": version,
        "revalidated_from_limit": old_limit,
    }
    write_meta(target, meta)
    dimension = options.dimension
    store.consolidate(keys, space.names, old.get("start", 0), dimension)
    return [key for key, _ in carried], keys, config, reasons
