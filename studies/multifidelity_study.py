"""For docs/multifidelity.md: each multi-fidelity method against 3D-only training, by the number of
3D designs, on a fixed held-out set of settled, valid 3D designs.

    python studies/multifidelity_study.py runs/sweep3d --low-fidelity surrogate/pretrained/default
    python studies/multifidelity_study.py runs/sweep3d --sizes 32 64 128 256 --repeats 3 \\
        --out runs/multifidelity_study.json
    python studies/multifidelity_study.py runs/sweep3d --sizes 30 60 --folds 5

SWEEP3D is a sweep of the 3D model (``fingertip sweep --model 3d``). 15 % of its settled, valid
designs (drawn with ``--seed``) are held out; for each size n of ``--sizes`` and repeat r every
method is trained on the same first n designs of the others in the order drawn with seed + r
(nested subsets: 85 % training, 15 % validation), and scored on the held-out designs
(``surrogate.multifidelity_curve``). It prints, per size and method, the median relative error of
each displacement reading, the hysteresis and the contact area at 1 N and 4 N, with the share of
FE values inside the predicted 90 % interval, and how many of the targets (median error 2 % on
each displacement, 5 % on the hysteresis and the contact area, 85-95 % inside the interval)
are met; ``--out`` keeps every training's scores of every metric as JSON.

``--folds K`` scores by cross-validation instead: the settled, valid designs split into K
folds, every method trained once per fold on the first n of the other designs, and scored on
every settled, valid design, each predicted by the training that did not see it. With a few
dozen 3D designs the fixed 15 % is a handful of designs; K folds score all of them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.provenance import json_safe, json_text
from surrogate import MULTIFIDELITY_METHODS, multifidelity_curve
from surrogate._multifidelity_run import MF_TARGETS, format_curve

SHIPPED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep3d", type=Path, help="a sweep of the 3D model")
    ap.add_argument(
        "--low-fidelity", type=Path, default=SHIPPED,
        help="the 2D surrogate (default: the shipped surrogate/pretrained/default)",
    )  # fmt: skip
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128, 256])
    ap.add_argument(
        "--methods", nargs="+", default=list(MULTIFIDELITY_METHODS),
        choices=list(MULTIFIDELITY_METHODS), help="default: every method",
    )  # fmt: skip
    ap.add_argument("--repeats", type=int, default=1, help="subsets per size, averaged")
    ap.add_argument("--seed", type=int, default=0, help="the held-out set; repeat r: seed + r")
    ap.add_argument("--folds", type=int, help="cross-validation over this many folds")
    ap.add_argument("--members", type=int, default=5, help="ensemble members")
    ap.add_argument("--max-epochs", type=int, help="cap on epochs (early stopping decides)")
    ap.add_argument("--out", type=Path, help="JSON of every training's scores")
    args = ap.parse_args()

    def progress(run: dict) -> None:
        shown = [
            f"{m} {100 * run['scores'][m]['median_rel_error']:.1f} %"
            for m in MF_TARGETS
            if m in run["scores"] and run["scores"][m]["median_rel_error"] is not None
        ]
        fold = f", fold {run['fold']}" if "fold" in run else ""
        print(
            f"n {run['n']}, repeat {run['repeat']}{fold}, {run['method']}: "
            f"{run['seconds']:.0f} s, "
            f"{run['epochs']} epochs; " + ", ".join(shown),
            flush=True,
        )

    result = multifidelity_curve(
        args.sweep3d,
        args.sizes,
        low_fidelity=args.low_fidelity,
        methods=args.methods,
        seed=args.seed,
        repeats=args.repeats,
        folds=args.folds,
        members=args.members,
        max_epochs=args.max_epochs,
        on_run=progress,
    )
    print()
    print(format_curve(result), end="")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json_text(json_safe(result), indent=1) + "\n")
        print(f"written: {args.out}")


if __name__ == "__main__":
    main()
