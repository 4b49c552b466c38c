"""For docs/benchmarks.md: how many epochs the main job's retraining needs (fine-tune on one
round, score the next ones).

    python studies/retrain_study.py runs/main --dataset runs/sweep --epochs 0 25 50 100 150
    python studies/retrain_study.py runs/main --epochs 150 --replay 0 256 512

A run of ``fingertip run`` retrains its surrogate after each round on the training sweep plus
the designs FE-confirmed so far (``explore._retrain.retrain``, ``--retrain-epochs``, every epoch
run: the patience is the epoch count). Here the run's starting surrogate is fine-tuned on the
confirmations of round 0 with each epoch count (0: not retrained), and scored on the trusted
confirmations of the later rounds, designs the retraining never saw, where the search went
next: the median and largest relative error of each tapping metric the targets compare, and
the wall time of the fine-tune (meaningful on a quiet machine only).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from explore._retrain import retrain
from explore._run_folder import read_config, read_confirmations
from surrogate import load_checkpoint

METRICS = (
    "disp_at_1N_from_touch_mm",
    "disp_at_4N_from_touch_mm",
    "hysteresis_Nmm",
    "sag_mm",
)


def errors(surrogate, confirmations) -> dict[str, np.ndarray]:
    """Relative error of the surrogate's median against FE, per metric (one per design)."""
    pred = surrogate.predict([c.candidate.point for c in confirmations])
    names = list(pred.metric_names)
    out = {}
    for m in METRICS:
        fe = np.array([c.fe_metrics[m] for c in confirmations], dtype=float)
        p = pred.median[:, names.index(m)]
        out[m] = np.abs(p - fe) / np.abs(fe)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--dataset", type=Path, help="the training sweep (default: the run's)")
    ap.add_argument("--epochs", type=int, nargs="+", default=[0, 25, 50, 100, 150])
    ap.add_argument(
        "--batch-size", type=int, nargs="+", default=[None], help="default: the model's"
    )
    ap.add_argument(
        "--replay", type=int, nargs="+", default=[0],
        help="sweep designs per epoch besides the new ones (0: all; explore._retrain.retrain)",
    )  # fmt: skip
    args = ap.parse_args()
    config = read_config(args.run)
    dataset = args.dataset or config["dataset"]
    if dataset is None:
        ap.error("the run does not name its training sweep: give --dataset")
    start = load_checkpoint(config["surrogate"], allow_solver_mismatch=True)
    confirmed = read_confirmations(args.run)
    first = [c for c in confirmed if c.candidate.round == 0]
    later = [c for c in confirmed if c.candidate.round > 0 and c.trusted]
    print(
        f"{args.run}: fine-tuned on the {len(first)} confirmations of round 0, scored on the "
        f"{len(later)} trusted confirmations of the later rounds; seed {config['seed']}"
    )
    head = " | ".join(f"{m} median / max" for m in METRICS)
    print(f"| epochs | batch | replay | fine-tune (s) | {head} |")
    print("|---|---|---|---|" + "---|" * len(METRICS))
    for replay in args.replay:
        for batch in args.batch_size:
            for epochs in args.epochs:
                t0 = time.perf_counter()
                model = (
                    start
                    if epochs == 0
                    else retrain(
                        start,
                        Path(dataset),
                        first,
                        epochs,
                        config["seed"],
                        batch_size=batch,
                        replay=replay,
                    )
                )
                wall = time.perf_counter() - t0
                err = errors(model, later)
                cells = [f"{100 * np.median(e):.1f} / {100 * e.max():.1f} %" for e in err.values()]
                size = batch or start.header["training"]["batch_size"]
                print(
                    f"| {epochs} | {size} | {replay or 'all'} | {wall:.1f} | "
                    + " | ".join(cells) + " |",
                    flush=True,
                )  # fmt: skip


if __name__ == "__main__":
    main()
