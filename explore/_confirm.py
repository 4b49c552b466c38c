"""FE confirmation of candidates: full simulations, cached per design, compared with the
surrogate's predictions.

Each candidate's FE record is written atomically to ``fe/records/<key>.json`` (the key of
``sim.sweep.run.record_key``: design + options + solver version), so a killed run recomputes
nothing it already has. References (the paper's silicone and polyurethane on the reference
geometry) go to ``fe/references/<name>.json`` for the plots.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from concurrent.futures import as_completed
from pathlib import Path
from typing import Any

from sim.design import Targets, with_every_layer
from sim.geometry import REFERENCE_GEOMETRY
from sim.materials import Material
from sim.metrics import metric_registry
from sim.options import SimOptions
from sim.pool import process_pool
from sim.provenance import write_json
from sim.sweep import PointPart, evaluate_point, point_record, record_key, simulate_part

from ._objective import closeness, wedge_reference_N
from ._types import Candidate, Confirmation

__all__ = ["REFERENCES", "compare", "confirm", "record_path", "reference_point", "run_fe"]

REFERENCES = ("silicone_gls40", "polyurethane_74_45")


def reference_point(material: str) -> dict[str, Any]:
    """A one-layer catalogue design on the reference geometry, as a design point."""
    g = REFERENCE_GEOMETRY
    return {
        "geometry.half_width_mm": g.half_width_mm,
        "geometry.height_mm": g.height_mm,
        "geometry.exponent": g.exponent,
        "layers.count": 1,
        "core.material": material,
    }


def _full_point(point: dict[str, Any]) -> dict[str, Any]:
    """A point with every missing layer entry set inactive (references name only what they
    use): ``sim.design.space.with_every_layer``."""
    return with_every_layer(point)


def run_fe(
    jobs: Sequence[tuple[Path, dict[str, Any]]],
    options: SimOptions,
    *,
    workers: int = 1,
    progress: bool = True,
    desc: str = "FE confirm",
    materials: dict[str, dict[str, Any]] | None = None,
) -> dict[Path, dict]:
    """Simulate each (record path, point) whose record does not exist yet; returns every
    record by path. Records are written as they finish (a kill loses only running designs).
    ``materials``: the user catalogue materials the points may name, as tables, handed to every
    worker process explicitly (``sim.sweep.run.evaluate_point``).

    On several workers each design's protocols run as jobs of their own
    (``sim.sweep.simulate_part``, joined by ``point_record`` into the record the design would
    have run as one): a search confirms a few designs, often fewer than the cores, and one
    design's tapping can take as long as the rest of its FE. The tappings go first, then the
    wedges, then the plates (the longest jobs first, as a rule: ``PART_ORDER``), so that no
    core waits while a long job runs alone at the end. The records are those of one job per
    design: the protocols share nothing (``sim.simulate.merge_results``)."""
    from tqdm import tqdm

    out: dict[Path, dict] = {}
    todo = []
    for path, point in jobs:
        if path.exists():
            out[path] = json.loads(path.read_text())
        else:
            todo.append((path, _full_point(point)))
    options_dict = options.as_dict()
    bar = tqdm(total=len(todo), desc=desc, unit="design", disable=not progress or not todo)
    try:
        if workers <= 1 or not todo:
            for path, point in todo:
                out[path] = _keep(path, evaluate_point(point, options_dict, materials))
                bar.update(1)
        else:
            tasks = [(path, point, p) for p in PART_ORDER for path, point in todo]
            parts: dict[Path, list[PointPart]] = {path: [] for path, _ in todo}
            points = dict(todo)
            with process_pool(min(workers, len(tasks))) as pool:
                futures = {
                    pool.submit(simulate_part, point, options_dict, materials, (p,)): path
                    for path, point, p in tasks
                }
                for fut in as_completed(futures):
                    path = futures[fut]
                    parts[path].append(fut.result())
                    if len(parts[path]) == len(PART_ORDER):
                        out[path] = _keep(path, point_record(points[path], parts[path]))
                        bar.update(1)
    finally:
        bar.close()
    return out


#: the protocols of a design as jobs of their own, in the order they start: the longest first
#: as a rule. In 3D a creeping pad's tapping runs for minutes (default-space design 0: 168 s,
#: docs/fe_speed.md, "One factorisation per tapping step"), the banded wedge for about one
#: (the first six designs' wedges: 300.5 s, "A slow step halves the next"), the plate's press
#: for seconds (docs/model_3d.md, "Cost"); in 2D the same order, seconds each
PART_ORDER = ("tapping", "wedge", "plate")


def _keep(path: Path, record: dict) -> dict:
    record = {"key": path.stem, **record}
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, record, indent=None)
    return record


def confirm(
    candidates: Sequence[Candidate],
    run_dir: Path,
    targets: Targets,
    options: SimOptions | None = None,
    *,
    workers: int = 1,
    progress: bool = True,
    materials: dict[str, dict[str, Any]] | None = None,
    catalogue: Mapping[str, Material] | None = None,
) -> list[Confirmation]:
    """Run (or reuse) the FE of each candidate and compare it with its prediction.
    ``catalogue``: the names the points use (shipped + user materials; default shipped);
    ``materials``: the user ones as tables, for the worker processes (:func:`run_fe`)."""
    options = options or SimOptions()
    paths = [record_path(run_dir, c.point, options, catalogue) for c in candidates]
    records = run_fe(
        [(path, c.point) for c, path in zip(candidates, paths, strict=True)],
        options,
        workers=workers,
        progress=progress,
        materials=materials,
    )
    return [
        compare(c, path.stem, records[path], targets, options.dimension)
        for c, path in zip(candidates, paths, strict=True)
    ]


def record_path(
    run_dir: str | Path,
    point: dict[str, Any],
    options: SimOptions,
    catalogue: Mapping[str, Material] | None = None,
) -> Path:
    """Where a run folder keeps the FE record of ``point``: ``fe/records/<key>.json``."""
    key = record_key(_full_point(point), options, catalogue)
    return Path(run_dir) / "fe" / "records" / f"{key}.json"


def compare(
    candidate: Candidate, key: str, record: dict, targets: Targets, dimension: str = "2d"
) -> Confirmation:
    """Surrogate vs FE for one design: relative error and 90 %-interval hit per metric (the
    FE metrics: every one the model ``dimension`` computes, ``sim.metrics.metric_registry``;
    the predicted trust outputs are judged through the record's diagnostics, not here). The FE
    score takes the wedge's effort against that model's reference (``wedge_reference_N``)."""
    fe = {m: record.get("metrics", {}).get(m) for m in metric_registry(dimension)}
    rel, inside = {}, {}
    for m, p in candidate.predicted.items():
        if m not in fe:
            continue
        v, mean = fe.get(m), p.get("median", p.get("mean"))
        # a value exact by physics (an elastic design's hysteresis, 0) has no meaningful
        # relative error against the FE's round-off (|h| < 1e-3 N mm)
        if v is None or mean is None or v == 0 or p.get("by_rule"):
            rel[m], inside[m] = None, None
            continue
        rel[m] = (mean - v) / abs(v)
        lo, hi = p.get("lower_90"), p.get("upper_90")
        inside[m] = None if lo is None or hi is None else bool(lo <= v <= hi)
    reference = wedge_reference_N(dimension)
    ok = record.get("status") == "ok"
    score = float(closeness(fe, targets, wedge_reference_N=reference).score) if ok else math.inf
    return Confirmation(
        candidate=candidate,
        key=key,
        status=record.get("status", "failed"),
        reason=record.get("reason", ""),
        fe_metrics=fe,
        fe_score=score,
        rel_error=rel,
        inside_90=inside,
        diagnostics=dict(record.get("diagnostics", {})),
    )
