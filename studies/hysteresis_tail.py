"""For docs/surrogate_accuracy.md: where a checkpoint's hysteresis errors are, and how small
the loss tangents get.

    python studies/hysteresis_tail.py [CKPT] [SWEEP]

(default: the shipped checkpoint and its table). Prints, on the checkpoint's own held-out test
designs that are settled and valid, the median and 95th-percentile relative error of the
hysteresis by its size (bands of FE hysteresis / median FE hysteresis, the report's point
prediction and floor: ``surrogate._evaluate.parity_data``, ``REL_FLOOR``), the worst designs,
and over the sweep's designs the loss tangents (``Encoder`` descriptors) against the floor of
their log encoding (``surrogate._encoding._LOG_TAN_FLOOR``): the smallest nonzero one of any
layer, and the smallest largest-of-the-layers among the designs whose hysteresis is scored.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from surrogate import load_checkpoint
from surrogate._encoding import _LOG_TAN_FLOOR, Encoder
from surrogate._evaluate import REL_FLOOR, parity_data
from surrogate._io import read_sweep

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "surrogate" / "pretrained" / "default"
METRIC = "hysteresis_Nmm"
BANDS = ((0.0, 0.05), (0.05, 0.2), (0.2, 1.0), (1.0, 10.0), (10.0, np.inf))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoint", type=Path, nargs="?", default=SHIPPED / "model.safetensors")
    ap.add_argument("sweep", type=Path, nargs="?", default=SHIPPED)
    args = ap.parse_args()
    model = load_checkpoint(args.checkpoint)
    data = read_sweep(args.sweep)
    row_of = {int(i): r for r, i in enumerate(data.index)}
    test = model.header["training_data"]["split_table_index"]["test"]
    rows = np.array([row_of[i] for i in test if i in row_of])
    j = list(data.metric_names).index(METRIC)
    points = [data.points[r] for r in rows]
    parity = parity_data(model, points, data.scored_targets()[rows])
    p = next(q for q in parity if q.metric == METRIC)
    # the designs and errors of ``surrogate._evaluate.score`` (the report's table)
    ok = np.isfinite(p.fe) & np.isfinite(p.mean)
    fe, pred = p.fe[ok], p.mean[ok]
    median = np.median(np.abs(fe))
    big = (np.abs(fe) >= REL_FLOOR * median) & (fe != 0)
    rel = np.abs(pred[big] - fe[big]) / np.abs(fe[big])
    size = fe[big] / median
    print(f"{args.checkpoint}: {big.sum()} scored test designs, median |FE| {median:.4g} N mm")
    print(f"all: median {100 * np.median(rel):.2f} %, p95 {100 * np.quantile(rel, 0.95):.1f} %")
    for lo, hi in BANDS:
        s = (size >= lo) & (size < hi)
        if s.any():
            print(
                f"  FE / median in [{lo:g}, {hi:g}): n = {s.sum():3d}, median "
                f"{100 * np.median(rel[s]):.2f} %, p95 {100 * np.quantile(rel[s], 0.95):.1f} %"
            )
    worst = np.argsort(-rel)[:10]
    where = np.flatnonzero(ok)[big][worst]
    print("worst: FE, predicted, error, design")
    for k, w in zip(worst, where, strict=True):
        pt = {n: v for n, v in points[w].items() if v is not None and v == v}
        layers = ", ".join(f"{r}: {pt.get(f'{r}.material')}" for r in ("skin", "core"))
        print(f"  {fe[big][k]:.4g}  {pred[big][k]:.4g}  {100 * rel[k]:.0f} %  {layers}")
    # the loss tangents against the log encoding's floor, over the whole sweep
    enc = Encoder(data.space)
    x = enc.encode(data.points).features.astype(float)
    cols = [i for i, n in enumerate(enc.feature_names) if ":tan_delta@" in n]
    tan = x[:, cols]
    y = data.scored_targets()[:, j]
    scored = np.isfinite(y) & (y >= REL_FLOOR * np.nanmedian(np.where(y > 0, y, np.nan)))
    print(
        f"loss tangents (log floor {_LOG_TAN_FLOOR:g}): smallest nonzero of any layer "
        f"{tan[tan > 0].min():.3g}; smallest largest-of-the-layers among the "
        f"{scored.sum()} designs whose hysteresis is scored {tan[scored].max(axis=1).min():.3g}"
    )


if __name__ == "__main__":
    main()
