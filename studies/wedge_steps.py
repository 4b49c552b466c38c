"""Whether the 3D wedge gains from its sub-step rules: default-space designs' wedges with the
rules as they are and with one changed, by default without halving the sub-step after a slow
step (``WEDGE_STEP_GROWTH[3].shrink_above`` None).

    python studies/wedge_steps.py [--designs 0 1 2 3 4 5] [--against 6 | --travel 0]

Runs each design's wedge twice at once, in two processes, so that both runs share whatever
else the machine is doing, and prints for each the step attempts that failed and were cut, the
factorisations in all and in those failed attempts, the Newton iterations, the seconds, and the
largest relative change of a wedge metric. ``--against N`` runs the second variant with
``shrink_above = N`` instead of without the halving; ``--travel F`` with the ramp's sub-steps
bounded by F times the band's element size (``WEDGE_BAND_TRAVEL``; 0: the schedule's steps, as
until solver 2.17) instead."""

from __future__ import annotations

import argparse
import dataclasses
import importlib

from paired import Totals, count_failed, describe, in_pairs, print_pair, simulate_design

VARIANTS = ("halve", "without")


def run_wedge(design_index: int, variant: str) -> dict:
    """One design's wedge with the 3D rules as they are (``halve``), without the halving
    (``without``), with ``shrink_above`` = N (``"N"``) or with ``WEDGE_BAND_TRAVEL`` = F
    (``"travel F"``); its figures, metrics and seconds, and its failed step attempts with
    their factorisations."""
    loading = importlib.import_module("sim.protocols.loading")
    if variant.startswith("travel "):
        loading.WEDGE_BAND_TRAVEL = float(variant.split()[1])
    elif variant != "halve":
        rule = loading.WEDGE_STEP_GROWTH[3]
        shrink_above = None if variant == "without" else int(variant)
        loading.WEDGE_STEP_GROWTH[3] = dataclasses.replace(rule, shrink_above=shrink_above)
    failed = count_failed("advance")
    return {**simulate_design(design_index, "wedge"), "failed": failed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--against", type=int, help="shrink_above of the second variant")
    group.add_argument("--travel", type=float, help="WEDGE_BAND_TRAVEL of the second variant")
    args = ap.parse_args()
    variants = VARIANTS
    if args.against is not None:
        variants = ("halve", str(args.against))
    elif args.travel is not None:
        variants = ("halve", f"travel {args.travel:g}")
    totals = Totals(variants)
    for d, runs in in_pairs(run_wedge, args.designs, variants):
        print_pair(f"design {d}", runs, describe, totals, "wedge metric")
    totals.print()


if __name__ == "__main__":
    main()
