"""Carry a sweep over to this solver version, keeping every record it would reproduce bit for bit
(``fingertip migrate-sweep SOURCE TARGET [--verify K]``).

A record is keyed by its design, the simulation options and the solver version
(``sim.sweep.run.record_key``), so a new solver version starts a sweep from nothing. Solver 2.3
changed one thing only: a protocol stops at its first recorded step beyond the validity limits
(``ValidityOptions.stop_at_violation``). A design whose every protocol completed within the
limits never reaches that stop, and 2.3 computes for it exactly what 2.2 did (the same
operations in the same order; ``tests/test_validity.py`` checks it; records computed before
FE ran BLAS on one thread, commit 2c735c2, agree to round-off: ``VERIFY_RTOL``). So its
record is carried over under its new key, unchanged but for

- ``diagnostics.stopped`` = "" (no protocol stopped: the column 2.3 added), and
- ``migrated``: the source folder, the record's old key and solver version, which the record
  keeps (``solver_version``: the solver that computed it).

A design beyond the limits is carried too when the source's protocols already stopped at the
first step beyond them (``stop_at_violation`` in the source's options, as in ours): its record
is then what this solver computes, within the tolerance ``SAME_METRICS_AS`` stands for (bit
for bit where the versions between compute the same bits, as 2D from 2.4 to 2.6).

Every other record (a failed protocol, or a design beyond the limits of a source that ran
past them, whose result now stops early and has no metrics) is left out: resuming the sweep in
the new folder with its command (:func:`resume_command`) computes it with this solver.
:func:`verify` re-simulates K carried-over designs (drawn with a seed) and gives each one's
largest difference from its record, which must stay within ``VERIFY_RTOL``.

Only a source made with options that differ from the new ones in ``stop_at_violation`` alone,
by a solver in ``sim.metrics.SAME_METRICS_AS``, is accepted.
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..design import space_from_dict
from ..errors import DesignError
from ..metrics import SAME_METRICS_AS, SOLVER_VERSION
from ..options import SimOptions, options_from_dict
from ..provenance import json_safe, provenance
from .folder import SweepStore, read_config, write_config, write_meta
from .run import evaluate_point, record_key, sample_points, sweep_config, with_todays_defaults

__all__ = [
    "MAX_METRICS_RTOL",
    "VERIFY_RTOL",
    "carried",
    "largest_difference",
    "migrate",
    "resume_command",
    "verify",
]

#: how close a re-simulated carried design must come to its record. Records computed before FE
#: ran every BLAS call on one thread (commit 2c735c2; the sweep's worker processes then summed
#: dot products on two threads) can differ from today's bits by round-off
VERIFY_RTOL = 1e-9
#: the largest ``--rtol`` a migration's check may be given: the periodic state's own tolerance
#: (``TappingOptions.settle_tol``, 1e-3), within which two runs of the taps are the same
#: result; a solver that moves a metric further does not reproduce the old one
MAX_METRICS_RTOL = 1e-3
#: what the check with a tolerance compares: the status, the metrics, and these diagnostics
#: exactly (the curves and the counts follow Newton's path, which a solver may change)
METRICS_FIELDS = ("status", "metrics")
JUDGED_DIAGNOSTICS = ("valid", "settled", "stopped")
#: what may differ between the source's options and the new ones
CHANGED_OPTIONS = {("validity", "stop_at_violation")}


def _comparable(options: dict, known: dict | None = None) -> dict:
    """The options that must agree between a source sweep and this solver: all but
    ``CHANGED_OPTIONS`` and, with ``known`` (the source's), the fields the source's solver did
    not have yet (options added since, whose defaults reproduce it: ``SAME_METRICS_AS``)."""
    return {
        section: {
            k: v
            for k, v in fields.items()
            if (section, k) not in CHANGED_OPTIONS
            and (known is None or k in known.get(section, {}))
        }
        for section, fields in options.items()
    }


def carried(record: dict, stopped_alike: bool = False) -> bool:
    """Whether this solver reproduces the record: every protocol completed, within the
    validity limits (then no protocol ever stops early) or, with ``stopped_alike`` (the
    source's protocols stopped at the first step beyond the limits, as ours do), beyond them."""
    diag = record.get("diagnostics") or {}
    return record.get("status") == "ok" and (diag.get("valid") is True or stopped_alike)


def migrate(source: str | Path, target: str | Path) -> tuple[list[str], list[str], dict]:
    """Write the sweep folder ``target`` from ``source``'s carried records; returns (carried
    keys, the sweep's keys in order, its config). A ``DesignError`` naming SOURCE or TARGET when
    the source is no sweep this solver reproduces or the target exists, before anything is
    written."""
    source, target = Path(source), Path(target)
    try:
        old = read_config(source)
    except (OSError, ValueError) as exc:
        raise DesignError("SOURCE", f"{source} is not a sweep folder ({exc})") from None
    if old.get("solver_version") not in SAME_METRICS_AS:
        raise DesignError(
            "SOURCE",
            f"{source} is a sweep of solver {old.get('solver_version')}; only one of "
            f"{', '.join(SAME_METRICS_AS)} is carried over to {SOLVER_VERSION}",
        )
    old = with_todays_defaults(old)  # options at a default changed since: today's
    options = options_from_dict(old["options"])
    # the sections the model reads, in JSON form: those a sweep's config.json records
    ours = json.loads(json.dumps(options.as_dict()))
    if _comparable(ours, old["options"]) != _comparable(old["options"]):
        raise DesignError("SOURCE", f"{source}: its options differ from this solver's in more "
                          "than the validity stop")  # fmt: skip
    if target.exists():
        raise DesignError("TARGET", f"{target} exists; choose a new folder")
    space = space_from_dict(old["space"])
    config = sweep_config(space, old["n"], old["seed"], old["sampler"], options)
    if "catalogues" in old:
        config["catalogues"] = old["catalogues"]
    points = sample_points(space, old["n"], old["seed"], old["sampler"])
    keys = [record_key(p, options, space.catalogue) for p in points]
    wanted = set(keys)
    stop = ("validity", "stop_at_violation")
    stopped_alike = bool(old["options"].get(stop[0], {}).get(stop[1])) and bool(
        ours[stop[0]][stop[1]]
    )
    carry = []
    for old_key, rec in sorted(SweepStore(source).load().items()):
        if not carried(rec, stopped_alike):
            continue
        key = record_key(rec["params"], options, space.catalogue)
        if key not in wanted:
            raise DesignError("SOURCE", f"{source}: record {old_key} is not a design of the "
                              "sweep's sample")  # fmt: skip
        rec = dict(rec)
        rec.pop("key", None)
        rec["diagnostics"] = dict(rec["diagnostics"])
        rec["diagnostics"].setdefault("stopped", "")  # the column 2.3 added: nothing stopped
        rec["migrated"] = {
            "from": str(source),
            "key": old_key,
            "solver_version": rec.get("solver_version"),
            "by": "fingertip migrate-sweep",
        }
        carry.append((key, rec))
    target.mkdir(parents=True)  # also when nothing is carried: the config and meta go there
    store = SweepStore(target)
    for key, rec in carry:
        store.write(key, rec)
    write_config(target, config)
    meta = provenance(config, old["seed"], kind="sweep")
    meta["migrated_from"] = {"folder": str(source), "solver_version": old["solver_version"]}
    write_meta(target, meta)
    store.consolidate(keys, space.names)
    return [key for key, _ in carry], keys, config


def resume_command(target: str | Path, config: dict) -> str:
    """The ``fingertip sweep`` command that computes the designs left out of ``target``: with
    ``--model 3d`` for a 3D sweep, ``--start`` for a segment and a ``--set`` for every option
    the folder keeps at another value than this solver's default (the source's value of an
    option whose default changed since, e.g. ``newton.contact_update_dofs``, which a 2D run does
    not read)."""
    options = options_from_dict(config["options"])
    default = replace(SimOptions(), model=options.model).as_dict()
    sets = [
        f" --set {section}.{name}={value}"
        for section, fields in options.as_dict().items()
        if section != "model"
        for name, value in fields.items()
        if value != default[section][name]
    ]
    sampler = f" --sampler {config['sampler']}" if config["sampler"] != "sobol" else ""
    model = " --model 3d" if options.dimension == "3d" else ""
    start = f" --start {config['start']}" if config.get("start") else ""  # a segment's
    return (
        f"fingertip sweep{model}{start} --n {config['n']} --out {target} --seed {config['seed']}"
        f"{sampler}{''.join(sets)}"
    )


def _numbers(tree: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """(path, leaf) of a JSON tree, lists and dicts (by key) flattened."""
    if isinstance(tree, dict):
        for k, v in sorted(tree.items()):
            yield from _numbers(v, f"{path}.{k}")
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            yield from _numbers(v, f"{path}[{i}]")
    else:
        yield path, tree


def largest_difference(a: dict, b: dict, metrics_only: bool = False) -> tuple[float, str]:
    """The largest relative difference between two records' metrics, diagnostics and curves
    (inf where their structure or a non-number differs) and where it is. ``metrics_only``:
    the status and the metrics, and the validity and settling (``JUDGED_DIAGNOSTICS``, which
    must be equal), not the curves and counts."""
    if metrics_only:
        for name in JUDGED_DIAGNOSTICS:
            if a["diagnostics"].get(name) != b["diagnostics"].get(name):
                return math.inf, f"diagnostics.{name}"
    worst, where = 0.0, ""
    fields = METRICS_FIELDS if metrics_only else ("status", "metrics", "diagnostics", "curves")
    for field in fields:
        x, y = list(_numbers(a[field], field)), list(_numbers(b[field], field))
        if [p for p, _ in x] != [p for p, _ in y]:
            return math.inf, field
        for (p, u), (_, v) in zip(x, y, strict=True):
            if isinstance(u, float) and isinstance(v, float) and not isinstance(u, bool):
                d = abs(u - v) / max(abs(u), abs(v), 1e-300) if u != v else 0.0
            else:
                d = 0.0 if u == v else math.inf
            if d > worst:
                worst, where = d, p
    return worst, where


def verify(
    target: str | Path,
    kept: list[str],
    config: dict,
    k: int,
    seed: int = 0,
    metrics_only: bool = False,
) -> list[tuple[str, float, str]]:
    """Re-simulate ``k`` of the carried designs ``kept`` (drawn with ``seed``); per design
    (key, the largest relative difference from its record, where; ``metrics_only`` as in
    :func:`largest_difference`). Each must stay within ``VERIFY_RTOL`` (round-off, as for
    records computed since FE runs BLAS on one thread), or within the tolerance the caller
    gives for a solver that changed Newton's path (``fingertip migrate-sweep --rtol``)."""
    records = SweepStore(Path(target)).load()
    out = []
    for key in random.Random(seed).sample(kept, min(k, len(kept))):
        rec = records[key]
        new = json_safe(evaluate_point(rec["params"], config["options"]))
        out.append((key, *largest_difference(new, rec, metrics_only)))
    return out
