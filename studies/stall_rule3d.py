"""Which stall rule the 3D model's Newton should use (``NewtonOptions.stall_rule_3d``): designs
run with two rules at once, by default "halving" (solver 2.19's, the 2D model's) and
"stagnation" (2.20's).

    python studies/stall_rule3d.py --out DIR [--designs failed | main | 0 1 2 ...]
        [--rules halving stagnation]

``--designs failed`` (the default) takes every design of ``datasets/default3d`` whose row
failed, each with the protocols its reason names; ``main`` the four confirmations of
``fingertip run`` whose tapping failed with solver 2.19 (``studies/designs/stall3d``), their
tapping; numbers take those designs of the default 3D space's sample, all three protocols.
Each job's two runs are saved in ``DIR`` as they end and a rerun skips the jobs already there
(resume). Both rules of a job run at once, in two processes, so that they share whatever else
the machine is doing (``paired.in_pairs``). Prints per design and protocol whether each rule
completed, its failed step attempts (every ``Body._advance`` that did not converge), Newton
iterations, factorisations and seconds, and the largest relative change of a metric where
both completed; then the totals. Counts do not depend on the machine's load; seconds do."""

from __future__ import annotations

import argparse
import csv
import json
import re
from pathlib import Path

from paired import FOLDER, count_failed, describe, in_pairs, largest_change, simulate_design

from sim.fe.solver import STALL_RULES

DATASET = FOLDER.parent
MAIN = Path(__file__).resolve().parent / "designs" / "stall3d"
RULES: tuple[str, str] = ("halving", "stagnation")


def failed_designs(dataset: Path = DATASET) -> list[str]:
    """``"index protocol"`` of every protocol that failed in the dataset's rows."""
    out = []
    for table in sorted(dataset.glob("seg_*/table.csv")):
        with open(table) as f:
            for row in csv.DictReader(f):
                if row["status"] != "ok":
                    for p in sorted(set(re.findall(r"(tapping|plate|wedge) at", row["reason"]))):
                        out.append((int(row["index"]), p))
    return [f"{i} {p}" for i, p in sorted(out)]


def run(job: str, rule: str) -> dict:
    """One ``"design protocol"`` job (a sample index or a design file) with the stall rule
    ``rule``."""
    design, protocol = job.rsplit(" ", 1)
    failed = count_failed("_advance")
    res = simulate_design(design, protocol, {"newton.stall_rule_3d": rule})
    return {**res, "failed": dict(failed)}


def jobs_for(designs: list[str]) -> list[str]:
    if designs == ["failed"]:
        return failed_designs()
    if designs == ["main"]:
        return [f"{path} tapping" for path in sorted(MAIN.glob("*.toml"))]
    return [f"{int(i)} {p}" for i in designs for p in ("tapping", "plate", "wedge")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="folder of the saved runs (resume)")
    ap.add_argument("--designs", nargs="+", default=["failed"])
    ap.add_argument("--rules", nargs=2, default=list(RULES), choices=list(STALL_RULES))
    args = ap.parse_args()
    rules = tuple(args.rules)
    jobs = jobs_for(args.designs)
    args.out.mkdir(parents=True, exist_ok=True)

    def saved(job: str) -> Path:
        name = job.replace(str(MAIN) + "/", "main-").replace(" ", "_")
        return args.out / f"{name}_{'_'.join(rules)}.json"

    todo = [j for j in jobs if not saved(j).exists()]
    for job, runs in in_pairs(run, todo, rules):
        saved(job).write_text(json.dumps(runs, default=str))
        print(f"ran {job}", flush=True)
    totals = {r: dict(completed=0, iterations=0, factorizations=0, seconds=0.0) for r in rules}
    for job in jobs:
        runs = json.loads(saved(job).read_text())
        label = job.replace(str(MAIN) + "/", "")
        for r in rules:
            t, fig = totals[r], runs[r]["figures"]
            t["completed"] += runs[r]["ok"]
            t["iterations"] += fig.get("newton_iterations") or 0
            t["factorizations"] += fig.get("factorizations") or 0
            t["seconds"] += runs[r]["seconds"]
            print(f"design {label}, {r:10s}: {describe(runs[r])}")
        if all(runs[r]["ok"] for r in rules):
            change = largest_change(runs[rules[1]]["metrics"], runs[rules[0]]["metrics"])
            print(f"design {label}: largest relative change of a metric {change:.1e}")
    print(f"\n{len(jobs)} jobs (design, protocol)")
    for r, t in totals.items():
        print(
            f"{r}: {t['completed']} completed, {t['iterations']} Newton iterations, "
            f"{t['factorizations']} factorisations, {t['seconds']:.0f} s in all"
        )


if __name__ == "__main__":
    main()
