"""For docs/multifidelity.md: how far the 3D pad's metrics are from the 2D model's, design by
design, and how much of that the pad's shape explains.

    python studies/ratio3d.py SWEEP3D [--low-fidelity surrogate/pretrained/default]
    python studies/ratio3d.py SWEEP3D --base slice

SWEEP3D is a sweep of the 3D model (``fingertip sweep --model 3d``; its table.csv). For each
design whose metric is trusted (``surrogate.read_sweep``'s rule: a protocol's metrics count
where that protocol stayed settled and within the limits), the 2D surrogate (the low
fidelity) predicts the metric of the design's section and layers (2D, forces per 10 mm of
finger); the script prints,
per metric, the log ratio r = ln(3D FE / 2D prediction): its mean, spread and range, and the
least-squares fit r ~ b0 + b1 ln c + b2 ln m + b3 ln a (c the pad's half-length, m its length
exponent, a the section's half-width) with the spread of its residual. A ratio that the pad's
shape explains is what the multi-fidelity ``delta`` method learns from few 3D designs; the
residual is what it must learn from the materials and the section. The last column is each
design's ratio predicted with it left out, from the others' mean and from their fit: the median
relative error of the 3D metric so predicted (the ``delta-trend`` method's base). The 2D
surrogate's own error (a median of 0.1-0.2 % on the displacements,
``surrogate/pretrained/default/report.md``) is far below these spreads.

``--base slice``: the same against the slice model (``surrogate._slice``: the pad taken as 2D
sections along the finger, fed with the 2D prediction) instead of the 2D prediction itself, for
the metrics it gives (the displacements, the hysteresis, the contact area), the
``delta-slice`` method's base. The column "as is" is the base's median error with no constant
fitted.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from surrogate import load_checkpoint, read_sweep
from surrogate._slice import PAD, SLICE_METRICS, slice_values

SHIPPED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"
METRICS = (
    "disp_at_1N_mm",
    "disp_at_4N_mm",
    "disp_at_1N_from_touch_mm",
    "disp_at_4N_from_touch_mm",
    "hysteresis_Nmm",
    "plate_force_at_1mm_N",
    "wedge_peak_force_N",
)
SLICED = (*METRICS[:5], "contact_area_at_1N_mm2", "contact_area_at_4N_mm2")
SHAPE = ("geometry.half_length_mm", "geometry.length_exponent", "geometry.half_width_mm")


def ratios(sweep3d: Path, low_fidelity: Path = SHIPPED, base: str = "2d") -> dict[str, dict]:
    """Per metric of ``METRICS`` (``base`` "slice": of ``SLICED``): ``n`` designs, the log
    ratios' ``mean``, ``std``, ``min``, ``max``, the base's median error ``as_is``, the fit's
    ``coef`` (b0, b1 ln c, b2 ln m, b3 ln a) and ``residual_std``; ``n`` alone when fewer than 6
    designs have the metric."""
    low = load_checkpoint(low_fidelity)
    data = read_sweep(sweep3d, dimension="3d")  # each protocol's trusted metrics
    pred = low.predict([{k: v for k, v in p.items() if k in low.space.names} for p in data.points])
    shape = np.log([[p[k] for k in SHAPE] for p in data.points])
    names, low_names = list(data.metric_names), list(pred.metric_names)
    two = {m: pred.median[:, j] for j, m in enumerate(low_names)}
    if base == "slice":
        pad = {k: np.array([p[f"geometry.{k}"] for p in data.points]) for k in PAD}
        with np.errstate(all="ignore"):
            bases = slice_values(two, pad, [m for m in SLICED if m in SLICE_METRICS])
    else:
        bases = {m: two[m] for m in METRICS}
    out: dict[str, dict] = {}
    for m in bases:
        y3 = data.targets[:, names.index(m)]
        y2 = bases[m]
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(y3) & (y3 > 0) & (y2 > 0) & pred.in_domain
        if ok.sum() < 6:
            out[m] = {"n": int(ok.sum())}
            continue
        r = np.log(y3[ok] / y2[ok])
        X = np.column_stack([np.ones(ok.sum()), shape[ok]])
        coef = np.linalg.lstsq(X, r, rcond=None)[0]
        # leave one out: each design's ratio predicted from the others' mean, and their fit
        loo_mean, loo_fit = [], []
        for i in range(len(r)):
            others = np.arange(len(r)) != i
            loo_mean.append(r[others].mean() - r[i])
            b = np.linalg.lstsq(X[others], r[others], rcond=None)[0]
            loo_fit.append(X[i] @ b - r[i])
        out[m] = {
            "n": int(ok.sum()),
            "loo_mean": float(np.median(np.expm1(np.abs(loo_mean)))),
            "loo_fit": float(np.median(np.expm1(np.abs(loo_fit)))),
            "as_is": float(np.median(np.abs(np.expm1(-r)))),
            "mean": float(r.mean()),
            "std": float(r.std()),
            "min": float(r.min()),
            "max": float(r.max()),
            "coef": [float(c) for c in coef],
            "residual_std": float((r - X @ coef).std()),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep3d", type=Path, help="a sweep of the 3D model")
    ap.add_argument("--low-fidelity", type=Path, default=SHIPPED, help="the 2D surrogate")
    ap.add_argument(
        "--base", choices=["2d", "slice"], default="2d",
        help="the ratio's base: the 2D prediction, or the slice model fed with it",
    )  # fmt: skip
    args = ap.parse_args()
    rows = ratios(args.sweep3d, args.low_fidelity, args.base)
    name = "2D" if args.base == "2d" else "slice"
    print(f"{args.sweep3d}; 2D surrogate {args.low_fidelity}; base: {args.base}")
    print(
        f"| metric | designs | as is | mean r (3D / {name}) | spread of r | range of r | fit b0, "
        "b1 ln c, b2 ln m, b3 ln a | residual spread | left out: the mean's, the fit's median "
        "error |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for m, row in rows.items():
        if "coef" not in row:
            print(f"| `{m}` | {row['n']} | too few | | | | | | |")
            continue
        print(
            f"| `{m}` | {row['n']} | {100 * row['as_is']:.1f} % | "
            f"{row['mean']:+.3f} (x {math.exp(row['mean']):.2f}) | "
            f"{row['std']:.3f} | {row['min']:+.2f} to {row['max']:+.2f} | "
            + ", ".join(f"{c:+.3f}" for c in row["coef"])
            + f" | {row['residual_std']:.3f} | {100 * row['loo_mean']:.1f} %, "
            f"{100 * row['loo_fit']:.1f} % |"
        )


if __name__ == "__main__":
    main()
