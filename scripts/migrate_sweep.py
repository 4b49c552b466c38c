"""Carry a sweep over to this solver version, keeping every record it would reproduce bit for bit.

    python scripts/migrate_sweep.py runs/sweep_v22 runs/sweep_v23 --verify 4

A record is keyed by its design, the simulation options and the solver version
(``sim.sweep.record_key``), so a new solver version starts a sweep from nothing. Solver 2.3
changed one thing only: a protocol stops at its first recorded step beyond the validity limits
(``ValidityOptions.stop_at_violation``). A design whose every protocol completed within the
limits never reaches that stop, and 2.3 computes for it exactly what 2.2 did (the same
operations in the same order; ``tests/test_validity.py`` checks it; records computed before
FE ran BLAS on one thread, commit 2c735c2, agree to round-off: ``VERIFY_RTOL``). So its
record is carried over under its new key, unchanged but for

- ``diagnostics.stopped`` = "" (no protocol stopped: the column 2.3 added), and
- ``migrated``: the source folder, the record's old key and solver version, which the record
  keeps (``solver_version``: the solver that computed it).

Every other record (a failed protocol, or a design beyond the limits, whose 2.3 result stops
early and has no metrics) is left out: resuming the sweep in the new folder with its command
(printed at the end) computes it with this solver. ``--verify K`` re-simulates K carried-over
designs (drawn with ``--seed``) and stops with an error unless their metrics, diagnostics and
curves equal the carried records to ``VERIFY_RTOL``.

Only a source made with options that differ from the new ones in ``stop_at_violation`` alone,
by a solver in ``sim.metrics.SAME_METRICS_AS``, is accepted.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import random
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from sim.metrics import SAME_METRICS_AS, SOLVER_VERSION
from sim.options import options_from_dict
from sim.provenance import json_safe, provenance
from sim.space import space_from_dict
from sim.sweep import evaluate_point, record_key, sample_points, sweep_config
from sim.sweep_folder import SweepStore, read_config, write_config, write_meta

#: how close a re-simulated carried design must come to its record. Records computed before FE
#: ran every BLAS call on one thread (commit 2c735c2; the sweep's worker processes then summed
#: dot products on two threads) can differ from today's bits by round-off
VERIFY_RTOL = 1e-9
#: what may differ between the source's options and the new ones
CHANGED_OPTIONS = {("validity", "stop_at_violation")}


def _comparable(options: dict) -> dict:
    return {
        section: {k: v for k, v in fields.items() if (section, k) not in CHANGED_OPTIONS}
        for section, fields in options.items()
    }


def carried(record: dict) -> bool:
    """Whether this solver reproduces the record bit for bit: every protocol completed, within
    the validity limits (then no protocol ever stops early)."""
    diag = record.get("diagnostics") or {}
    return record.get("status") == "ok" and diag.get("valid") is True


def migrate(source: Path, target: Path) -> tuple[list[str], list[str], dict]:
    """Write ``target``; returns (carried keys, the sweep's keys in order, its config)."""
    old = read_config(source)
    if old.get("solver_version") not in SAME_METRICS_AS:
        sys.exit(f"{source}: solver {old.get('solver_version')} is not in {SAME_METRICS_AS}")
    options = options_from_dict(old["options"])
    if _comparable(dataclasses.asdict(options)) != _comparable(old["options"]):
        sys.exit(f"{source}: its options differ from this solver's in more than the stop")
    if target.exists():
        sys.exit(f"{target} exists; choose a new folder")
    space = space_from_dict(old["space"])
    config = sweep_config(space, old["n"], old["seed"], old["sampler"], options)
    if "catalogues" in old:
        config["catalogues"] = old["catalogues"]
    points = sample_points(space, old["n"], old["seed"], old["sampler"])
    keys = [record_key(p, options, space.catalogue) for p in points]
    wanted = set(keys)
    store = SweepStore(target)
    kept = []
    for old_key, rec in sorted(SweepStore(source).load().items()):
        if not carried(rec):
            continue
        key = record_key(rec["params"], options, space.catalogue)
        if key not in wanted:
            sys.exit(f"{source}: record {old_key} is not a design of the sweep's sample")
        rec = dict(rec)
        rec.pop("key", None)
        rec["diagnostics"] = {**rec["diagnostics"], "stopped": ""}
        rec["migrated"] = {
            "from": str(source),
            "key": old_key,
            "solver_version": rec.get("solver_version"),
            "by": "scripts/migrate_sweep.py",
        }
        store.write(key, rec)
        kept.append(key)
    write_config(target, config)
    meta = provenance(config, old["seed"], kind="sweep")
    meta["migrated_from"] = {"folder": str(source), "solver_version": old["solver_version"]}
    write_meta(target, meta)
    store.consolidate(keys, space.names)
    return kept, keys, config


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


def largest_difference(a: dict, b: dict) -> tuple[float, str]:
    """The largest relative difference between two records' metrics, diagnostics and curves
    (inf where their structure or a non-number differs) and where it is."""
    worst, where = 0.0, ""
    for field in ("status", "metrics", "diagnostics", "curves"):
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


def verify(target: Path, kept: list[str], config: dict, k: int, seed: int) -> None:
    """Re-simulate ``k`` carried designs; exit with an error unless each equals its record to
    ``VERIFY_RTOL`` (bit for bit for records computed since FE runs BLAS on one thread)."""
    records = SweepStore(target).load()
    for key in random.Random(seed).sample(kept, min(k, len(kept))):
        rec = records[key]
        new = json_safe(evaluate_point(rec["params"], config["options"]))
        worst, where = largest_difference(new, rec)
        if worst > VERIFY_RTOL:
            sys.exit(f"verify: {key}: {where} differs from the carried record by {worst:.2g}")
        text = "identical" if worst == 0.0 else f"equal to {worst:.1e} relative (at {where})"
        print(f"verify: {key}: metrics, diagnostics and curves {text}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", type=Path)
    ap.add_argument("target", type=Path)
    ap.add_argument("--verify", type=int, default=0, metavar="K")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    kept, keys, config = migrate(args.source, args.target)
    total = len(set(keys))
    print(
        f"{len(kept)} of {total} designs carried over to {args.target} (solver "
        f"{SOLVER_VERSION}); {total - len(kept)} left for the resumed sweep"
    )
    if args.verify:
        verify(args.target, kept, config, args.verify, args.seed)
    print(
        f"resume: fingertip sweep --n {config['n']} --out {args.target} --seed {config['seed']}"
        + (f" --sampler {config['sampler']}" if config["sampler"] != "sobol" else "")
    )


if __name__ == "__main__":
    main()
