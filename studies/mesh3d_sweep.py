"""The 3D mesh's error across the default 3D space: one sample swept on two meshes, compared
design by design (``docs/model_3d.md``, "Mesh convergence").

    fingertip sweep --model 3d --n 64 --seed 0 --out COARSE --workers 2 \\
        --set mesh3d.h_apex_mm=1.0 --set mesh3d.h_contact_mm=1.5 --set mesh3d.grading=0.6 \\
        --set mesh3d.h_max_mm=3.0 --set mesh3d.layer_divisions=2 --set mesh3d.around_divisions=2
    python studies/mesh3d_sweep.py --coarse COARSE \\
        --fine datasets/default3d_plain/seg_0-31 datasets/default3d_plain/part_32-63

The two elastic pads of ``studies/mesh3d_convergence.py`` tell how the metrics converge; this
tells how far apart two meshes are on the designs a dataset is made of (layers, soft and
compressible cores, viscoelastic taps, the validity limits). ``--fine`` and ``--coarse`` are
sweep folders (or kept segments) of the same sample, model and options but the mesh; rows are
matched by their index in the sample. Printed per metric, over the designs where both meshes
give it: the median, 90th percentile and largest relative difference (coarse - fine) / fine,
and its median (the bias); the designs whose validity, settling or status differ, with the
limit that decided; the largest compressive strain's ratio (the validity limits are read from
it); and the FE CPU time of each mesh (the workers' seconds the records hold).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
from pathlib import Path

from sim.metrics import METRICS, METRICS_3D
from sim.sweep import open_table, read_config, table_path

STRAINS = ("tapping_max_compressive_log_strain", "plate_max_compressive_log_strain")


def rows(folders: list[Path]) -> dict[int, dict[str, str]]:
    """The table rows of ``folders`` by sample index (a later folder's row wins)."""
    out: dict[int, dict[str, str]] = {}
    for folder in folders:
        with open_table(table_path(folder)) as f:
            for row in csv.DictReader(f):
                out[int(row["index"])] = row
    return out


def cpu_seconds(folders: list[Path]) -> dict[str, float]:
    """Each record's worker CPU seconds by key (the records' ``cpu_time_s``; none for a kept
    segment, which holds its table only)."""
    out = {}
    for folder in folders:
        for path in (folder / "records").glob("*.json"):
            record = json.loads(path.read_text())
            if "cpu_time_s" in record:
                out[record["key"]] = float(record["cpu_time_s"])
    return out


def number(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * (len(ordered) - 1) + 0.5))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fine", type=Path, nargs="+", required=True)
    ap.add_argument("--coarse", type=Path, nargs="+", required=True)
    args = ap.parse_args()
    configs = [read_config(f) for f in (*args.fine, *args.coarse)]
    for key in ("space", "seed", "sampler"):
        if any(c.get(key) != configs[0].get(key) for c in configs):
            raise SystemExit(f"the folders differ in {key}: not one sample")
    fine, coarse = rows(args.fine), rows(args.coarse)
    both = sorted(set(fine) & set(coarse))
    print(f"{len(both)} designs in both (fine {len(fine)}, coarse {len(coarse)})")
    print(f"mesh, fine: {configs[0]['options'].get('mesh3d', 'default')}")
    print(f"mesh, coarse: {configs[-1]['options'].get('mesh3d', 'default')}\n")

    print("| metric | designs | median abs | 90th pct abs | largest abs | median (bias) |")
    print("|---|---|---|---|---|---|")
    for m in (*METRICS, *METRICS_3D):
        diffs = []
        for i in both:
            a, b = number(fine[i].get(m)), number(coarse[i].get(m))
            floor = 1e-3 if m == "hysteresis_Nmm" else 1e-9  # N mm: noise of nearly elastic pads
            if math.isfinite(a) and math.isfinite(b) and abs(a) > floor:
                diffs.append((b - a) / abs(a))
        if diffs:
            absd = [abs(d) for d in diffs]
            print(
                f"| {m} | {len(diffs)} | {100 * statistics.median(absd):.2f} % "
                f"| {100 * quantile(absd, 0.9):.2f} % | {100 * max(absd):.2f} % "
                f"| {100 * statistics.median(diffs):+.2f} % |"
            )

    print("\n| strain | designs | median coarse / fine | range |")
    print("|---|---|---|---|")
    for s in STRAINS:
        ratios = []
        for i in both:
            a, b = number(fine[i].get(s)), number(coarse[i].get(s))
            # a stopped protocol's strain is censored at its stop: compare completed ones only
            stopped = s.split("_")[0] in (fine[i].get("stopped", "") + coarse[i].get("stopped", ""))
            if math.isfinite(a) and math.isfinite(b) and a > 0 and not stopped:
                ratios.append(b / a)
        if ratios:
            print(
                f"| {s} | {len(ratios)} | {statistics.median(ratios):.3f} "
                f"| {min(ratios):.3f}-{max(ratios):.3f} |"
            )

    print("\nstatus, validity or settling differ:")
    changed = 0
    for i in both:
        for key in ("status", "valid", "settled"):
            if fine[i].get(key, "") != coarse[i].get(key, ""):
                changed += 1
                print(
                    f"  design {i}: {key} {fine[i].get(key)!r} -> {coarse[i].get(key)!r} "
                    f"(violations {fine[i].get('violations')!r} -> {coarse[i].get('violations')!r})"
                )
    print(f"  {changed} in all")

    for name, table, folders in (("fine", fine, args.fine), ("coarse", coarse, args.coarse)):
        cpu = cpu_seconds(folders)
        seconds = [cpu.get(table[i]["key"], math.nan) for i in both]
        seconds = [s for s in seconds if math.isfinite(s)]
        if seconds:
            mean, median = statistics.fmean(seconds), statistics.median(seconds)
            print(
                f"FE CPU time, {name} ({len(seconds)} designs): mean {mean:.1f} s, "
                f"median {median:.1f} s, max {max(seconds):.1f} s"
            )
    for i in both:
        for name, table in (("fine", fine), ("coarse", coarse)):
            if table[i].get("status") == "failed":
                print(f"design {i} failed on the {name} mesh: {table[i].get('reason')}")


if __name__ == "__main__":
    main()
