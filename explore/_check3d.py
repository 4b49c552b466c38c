"""The answers of a search run simulated with the 3D pad: ``fingertip run --model 3d``.

The search and its confirmations are the 2D model's (the shipped surrogate is a 2D one). With
``--model 3d`` every answer the run found (best, gel, foam, buildable) is then simulated with
every protocol by the 3D model: its section and layers as in the answer, the pad's length and
profile at their defaults (``sim.geometry.pad``), the run's other FE options, and every
protocol run to its end, beyond the validity limits too (:func:`options_3d`). Each record is
written to ``fe3d/records/<key>.json`` as it finishes (the key of
``sim.sweep.run.record_key``: a killed run recomputes nothing it has), and each answer's 3D
result is set against the targets as its 2D result is (``explore._summary``): its relative
error on each tapping target and their root mean square, its FE score as the 2D one's with the
wedge's effort taken against the 3D model's own reference (``WEDGE_REFERENCE_3D_N``: the
paper's silicone as the default pad, where the 2D score's reference is its section's force per
10 mm of finger), whether it is credible (settled, within
the validity limits, within the sag limit), the contact patch at 1 N and 4 N, and how far each
tapping metric moved from the 2D result. The file is ``answers_3d.json``
(``explore._run_folder``); ``report.md`` shows it.

An answer is chosen in 2D: its 3D result says how that choice fares as a fingertip, not which
design is best in 3D: a search with a multi-fidelity surrogate chooses in 3D (``Setup.model``,
`docs/search.md`, "The search in 3D"), and then this check is not made.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from sim.design import Targets, with_every_layer
from sim.materials import Material
from sim.options import ModelOptions, SimOptions
from sim.provenance import json_safe
from sim.sweep import record_key

from ._confirm import compare, run_fe
from ._objective import TAPPING, WEDGE_REFERENCE_3D_N, closeness
from ._run_folder import read_summary, write_answers_3d
from ._summary import credible, target_errors
from ._types import Candidate

__all__ = ["RECORDS_3D", "check_in_3d", "not_credible", "options_3d"]

#: where a run folder keeps its answers' 3D records
RECORDS_3D = Path("fe3d") / "records"


def options_3d(options: SimOptions) -> SimOptions:
    """The run's FE options with the 3D model (its mesh ``mesh3d``) and every protocol run to
    its end (``without_validity_stop``): an answer beyond the validity limits in 3D keeps its
    metrics, flagged not credible with the limit it broke, where a sweep would stop it."""
    return dataclasses.replace(options, model=ModelOptions("3d")).without_validity_stop()


def _point(answer: Mapping[str, Any]) -> dict[str, Any]:
    """The answer's design point as the searches hold it (inactive: NaN), every layer entry
    present (``with_every_layer``: as ``explore._confirm`` keys and simulates a point)."""
    return with_every_layer({k: (math.nan if v is None else v) for k, v in answer["point"].items()})


def _candidate(answer: Mapping[str, Any]) -> Candidate:
    """The answer as a candidate with no prediction (the surrogate predicts 2D metrics)."""
    return Candidate(
        point=_point(answer),
        reason=str(answer.get("reason", "")),
        round=int(answer.get("round") or 0),
        trial=-1,
        search=str(answer.get("search", "")),
        score=math.nan,
        predicted={},
        in_domain=True,
        disagreement=math.nan,
    )


def check_in_3d(
    out: str | Path,
    targets: Targets,
    options: SimOptions,
    *,
    tolerance: float,
    workers: int = 1,
    progress: bool = True,
    materials: dict[str, dict[str, Any]] | None = None,
    catalogue: Mapping[str, Material] | None = None,
) -> dict[str, Any]:
    """Simulate every answer of the run folder ``out`` (its summary.json) with the 3D model
    (``options``: 3D options, :func:`options_3d`), write ``answers_3d.json`` and return it:
    ``{"model": "3d", "options": ..., "fe_wall_time_s": ..., "answers": {kind: result | None}}``
    (``fe_wall_time_s``: the 3D simulations' own seconds, summed).
    ``materials`` / ``catalogue``: the user catalogue, as for the 2D confirmations
    (``explore._confirm.confirm``)."""
    if options.dimension != "3d":
        raise ValueError("check_in_3d needs the 3D model's options (options_3d)")
    out = Path(out)
    answers = {k: a for k, a in (read_summary(out).get("answers") or {}).items()}
    paths: dict[str, Path] = {}
    jobs: dict[Path, dict[str, Any]] = {}
    for kind, answer in answers.items():
        if not isinstance(answer, dict) or not isinstance(answer.get("point"), dict):
            continue
        point = _point(answer)
        key = record_key(point, options, catalogue)
        paths[kind] = out / RECORDS_3D / f"{key}.json"
        jobs.setdefault(paths[kind], point)  # one simulation for answers that are one design
    records = run_fe(
        list(jobs.items()),
        options,
        workers=workers,
        progress=progress,
        desc="FE 3D answers",
        materials=materials,
    )
    results: dict[str, Any] = {}
    for kind, answer in answers.items():
        if kind not in paths:
            results[kind] = None
            continue
        results[kind] = _result(answer, paths[kind], records[paths[kind]], targets, tolerance)
    data = {
        "model": "3d",
        "options": options.as_dict(),
        # the simulations' own time (each record's), so that a re-run that finds every record
        # writes the same file
        "fe_wall_time_s": sum(float(r.get("wall_time_s") or 0.0) for r in records.values()),
        "answers": json_safe(results),
    }
    write_answers_3d(out, data)
    return data


def _result(
    answer: Mapping[str, Any], path: Path, record: dict, targets: Targets, tolerance: float
) -> dict[str, Any]:
    """One answer's 3D record against the targets, beside its 2D result."""
    conf = compare(_candidate(answer), path.stem, record, targets, "3d")
    fe = record.get("metrics", {}) or {}
    ok = conf.status == "ok" and math.isfinite(conf.fe_score)
    errors = target_errors(conf, targets) if ok else {}
    score = closeness(fe, targets, wedge_reference_N=WEDGE_REFERENCE_3D_N) if ok else None
    fe2d = answer.get("fe_metrics") or {}
    moved = {}
    for m in TAPPING:
        v2, v3 = fe2d.get(m), fe.get(m)
        moved[m] = v3 / v2 - 1.0 if v2 and v3 is not None else None
    return {
        "fe_record": f"{RECORDS_3D.as_posix()}/{path.name}",
        "status": conf.status,
        "reason": conf.reason,
        "n_dofs": record.get("n_dofs"),
        "wall_time_s": record.get("wall_time_s"),
        "fe_metrics": conf.fe_metrics,  # the 3D model's metrics, the contact patch's too
        "tapping_rms_error": math.sqrt(sum(e * e for e in errors.values()) / len(errors))
        if errors
        else None,
        # the FE score with the wedge's effort against the 3D reference (the whole pad's force)
        "wedge_effort": float(score.wedge_effort) if score else None,
        "fe_score": float(score.score) if score else None,
        "errors_vs_targets": errors,
        "within_tolerance": {m: abs(e) <= tolerance for m, e in errors.items()},
        "credible": credible(conf, targets),
        "diagnostics": conf.diagnostics,
        "change_from_2d": moved,
    }


def not_credible(result: Mapping[str, Any], violations: bool = False) -> list[str]:
    """Why a 3D result of :func:`check_in_3d` is not credible, in words ([] when it is):
    unsettled, beyond the validity limits (with ``violations``: which), or its sag."""
    if result.get("credible"):
        return []
    d = result.get("diagnostics") or {}
    limits = "beyond the validity limits" + (f": {d.get('violations')}" if violations else "")
    why = [w for w, bad in (("unsettled", d.get("settled") is False),
                            (limits, d.get("valid") is False)) if bad]  # fmt: skip
    return why or ["sag over the targets' limit"]
