"""Whether this solver still gives the metrics of a shipped sweep: re-simulates its first designs.

    python studies/same_metrics.py [--table surrogate/pretrained/default] [--n 64] [--start 0]
    python studies/same_metrics.py --n 64 --save before.json          # at one commit
    python studies/same_metrics.py --n 64 --reference before.json     # at the next
    python studies/same_metrics.py --tables OLD NEW --n 6              # two sweeps' tables

A change to the FE that moves the metrics by less than their discretisation error keeps a
trained surrogate's data valid: the new ``SOLVER_VERSION`` then lists the old one in
``sim.metrics.SAME_METRICS_AS`` (no re-sweep). This study is the evidence: designs ``start`` to
``start + n - 1`` of the sweep in ``--table`` (its space, seed and sampler, from its
``config.json``), re-run with this solver and the default options (a 3D sweep's: its own
options, ``datasets/default3d/seg_*``), against the stored table or,
with ``--reference``, against the run another commit saved with ``--save`` (the table's rows
can come from an earlier solver that ``SAME_METRICS_AS`` carried over, and from another CPU:
two runs on one machine tell the change alone). Prints, per metric, the largest and the median
change relative to the larger of the reference value and ``--floor`` of its unit (a hysteresis
of 1e-4 N mm of a nearly elastic design is numerical noise), the designs whose validity or
settling changed, and the factorisations and residual evaluations of both runs (counts, which
do not depend on the machine's load). Run it with the repository's ``sim`` on the path
(``PYTHONPATH=.`` in a second checkout: an editable install points at the first).
``--tables OLD NEW`` re-runs nothing: it compares two sweep folders' tables of the same designs
(for example the folders two commits' ``benchmarks/bench_sweep.py --keep`` left).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
import time
from pathlib import Path

import sim
from sim import SOLVER_VERSION, SimOptions, simulate
from sim.design import point_to_design
from sim.metrics import metric_registry
from sim.options import options_from_dict
from sim.sweep import open_table, read_config, sample_points, table_path
from sim.sweep.run import load_space_config, with_todays_defaults

#: summed over every design and protocol; ``precision_fallbacks`` and ``fresh_retries``: failed
#: steps tried again in double precision and in the same precision from a fresh factorisation
#: (``sim.fe.Body.advance``), 0 in runs made before they were counted
COUNTS = ("factorizations", "evaluations", "precision_fallbacks", "fresh_retries")


def sweep_options(folder: Path) -> SimOptions:
    """The options the designs are re-run with: a 3D sweep's own (its mesh and model, today's
    defaults where ``DEFAULTS_BEFORE`` says so), else the default options."""
    options = with_todays_defaults(read_config(folder)).get("options") or {}
    if options.get("model", {}).get("dimension") == "3d":
        return options_from_dict(options)
    return SimOptions()


def table_rows(folder: Path, indices: range) -> dict[int, dict]:
    """The table's rows of the designs ``indices`` (by the sample index), numbers parsed."""
    wanted, rows = set(indices), {}
    metrics = metric_registry(sweep_options(folder).dimension)
    with open_table(table_path(folder)) as f:
        for row in csv.DictReader(f):
            if int(row["index"]) in wanted:
                rows[int(row["index"])] = {
                    **{m: as_float(row.get(m)) for m in metrics if m in row},
                    "valid": row.get("valid", "").lower() == "true" if row.get("valid") else None,
                    "settled": row.get("settled", "").lower() == "true"
                    if row.get("settled")
                    else None,
                }
    return rows


def as_float(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def run(folder: Path, indices: range) -> dict:
    """This solver on the designs ``indices``: per design its metrics, validity and settling,
    and the counts summed over every design and protocol."""
    config = read_config(folder)
    space = load_space_config(folder)
    points = sample_points(space, indices.stop, config["seed"], config.get("sampler", "sobol"))
    options = sweep_options(folder)
    designs, counts, t0 = {}, dict.fromkeys(COUNTS, 0), time.perf_counter()
    for i in indices:
        res = simulate(point_to_design(points[i]), options=options)
        for fig in res.protocols.values():
            for key in COUNTS:
                counts[key] += fig.get(key, 0)
        diag = res.diagnostics()
        metrics = {m: v for m, v in res.metrics.items() if v is not None and math.isfinite(v)}
        designs[i] = {**metrics, "valid": diag["valid"], "settled": diag.get("settled")}
        print(f"design {i} done", flush=True)
    return {
        "solver_version": SOLVER_VERSION,
        "sim": str(Path(sim.__file__).parent),
        "seconds": time.perf_counter() - t0,
        "counts": counts,
        "designs": designs,
    }


def compare(
    reference: dict[int, dict], new: dict[int, dict], floor: float, dimension: str = "2d"
) -> None:
    metrics = metric_registry(dimension)
    changes: dict[str, list[float]] = {m: [] for m in metrics}
    worst: dict[str, str] = {}
    flipped, missing = [], []
    for i, now in new.items():
        if i not in reference:  # a sweep still running has not reached every design
            missing.append(i)
            continue
        ref = reference[i]
        for m in metrics:
            old, value = ref.get(m, math.nan), now.get(m, math.nan)
            if math.isfinite(old) and math.isfinite(value):
                change = abs(value - old) / max(abs(old), floor)
                if change > max(changes[m], default=-1.0):
                    worst[m] = f"design {i}: {old:.6g} -> {value:.6g}"
                changes[m].append(change)
        for key in ("valid", "settled"):
            if ref.get(key) is not None and now.get(key) is not None and ref[key] != now[key]:
                flipped.append(f"design {i}: {key} {ref[key]} -> {now[key]}")
    print(f"{'metric':34s} {'n':>4s} {'largest':>9s} {'median':>9s}  largest at")
    for m in metrics:
        c = changes[m]
        if c:
            print(f"{m:34s} {len(c):4d} {max(c):9.2e} {statistics.median(c):9.2e}  {worst[m]}")
    if missing:
        print(f"not in the reference (not compared): designs {', '.join(map(str, missing))}")
    print(f"validity or settling changed: {len(flipped)}")
    for line in flipped:
        print("  " + line)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", type=Path, default=Path("surrogate/pretrained/default"))
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--floor", type=float, default=1e-3)
    ap.add_argument("--save", type=Path, help="write this run (metrics and counts) as JSON")
    ap.add_argument("--reference", type=Path, help="compare with a run saved by --save")
    ap.add_argument(
        "--tables", type=Path, nargs=2, metavar=("OLD", "NEW"), help="compare two sweep tables"
    )
    args = ap.parse_args()
    indices = range(args.start, args.start + args.n)
    if args.tables:
        old, new = args.tables
        print(
            f"{new} (solver {read_config(new)['solver_version']}) against {old} (solver "
            f"{read_config(old)['solver_version']}), designs {indices.start}-{indices.stop - 1}"
        )
        rows = table_rows(new, indices)
        compare(table_rows(old, indices), rows, args.floor, sweep_options(new).dimension)
        return
    result = run(args.table, indices)
    if args.save:
        args.save.write_text(json.dumps(result, indent=1))
    if args.reference:
        saved = json.loads(args.reference.read_text())
        reference = {int(i): d for i, d in saved["designs"].items()}
        label = f"the run of solver {saved['solver_version']} in {args.reference}"
    else:
        reference = table_rows(args.table, indices)
        label = f"{args.table} (solver {read_config(args.table)['solver_version']})"
    print(
        f"\nsolver {SOLVER_VERSION} ({result['sim']}) against {label}, designs "
        f"{indices.start}-{indices.stop - 1}, {result['seconds']:.0f} s"
    )
    compare(reference, result["designs"], args.floor, sweep_options(args.table).dimension)
    print("this run: " + ", ".join(f"{k} {v}" for k, v in result["counts"].items()))
    if args.reference:
        print("reference: " + ", ".join(f"{k} {v}" for k, v in saved["counts"].items()))


if __name__ == "__main__":
    main()
