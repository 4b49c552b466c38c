"""Learning curve of the surrogate: test error vs the number of FE designs it is trained on.

    python scripts/learning_curve.py runs/default_sweep [--sizes 128 256 512 1024 4096]
        [--seed 0] [--out docs/learning_curve.md]

One fixed test set (15 % of the sweep's designs, drawn with the seed) scores ensembles trained
on nested subsets of the other designs (a size above their number means all of them), each
subset split 85/15 into training and early-stopping validation. Per size and metric: R²,
median and 95th-percentile relative error (over designs with |FE| >= 1 % of the median, as in
the surrogate's report). A power law, error ~ n^-b, is
fitted to the largest sizes with ``np.polyfit`` in log-log coordinates and extrapolated to the
design count at which the targets (median relative error <= 3 %, R² >= 0.99) would be met.
Writes a Markdown section, a JSON file and a PNG beside ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from surrogate._evaluate import parity_data, score
from surrogate._io import read_sweep
from surrogate._train import Split, TrainConfig, fit, split_indices

CHECKED = ("disp_at_1N_mm", "disp_at_4N_mm", "hysteresis_Nmm")
TARGET_MEDIAN = 0.03
TARGET_R2 = 0.99


def curve(sweep: Path, sizes: list[int], seed: int) -> dict:
    data = read_sweep(sweep)
    outer = split_indices(len(data.points), seed, (0.85, 0.0, 0.15))
    test = outer.test
    pool = np.random.default_rng(seed).permutation(np.concatenate([outer.train, outer.val]))
    rows = []
    sizes = sorted({min(n, len(pool)) for n in sizes})  # larger than the pool: all of it
    for n in sizes:
        chosen = pool[:n]
        n_val = max(1, round(0.15 * n))
        split = Split(np.sort(chosen[n_val:]), np.sort(chosen[:n_val]), test)
        t0 = time.perf_counter()
        result = fit(data, TrainConfig(seed=seed), progress=False, split=split)
        seconds = time.perf_counter() - t0
        model = result.surrogate
        scores = {}
        for p in parity_data(model, [data.points[i] for i in test], data.targets[test]):
            s = score(p)
            m = p.metric
            scores[m] = {
                "r2": s.r2,
                "median_rel_error": s.median_rel_error,
                "p95_rel_error": s.p95_rel_error,
                "coverage_90": s.coverage_90,
            }
        rows.append({"n_designs": n, "train_seconds": seconds, "epochs": result.epochs, **scores})
        summary = ", ".join(
            f"{m}: R2 {scores[m]['r2']:.3f} med {100 * scores[m]['median_rel_error']:.1f} %"
            for m in CHECKED
        )
        print(f"n = {n:5d} ({seconds:.0f} s): {summary}", flush=True)
    return {
        "sweep": str(sweep),
        "table_sha256": data.table_sha256,
        "n_designs_with_results": len(data.points),
        "n_test": len(test),
        "seed": seed,
        "rows": rows,
    }


def extrapolate(rows: list[dict], metric: str, key: str, target: float) -> dict:
    """Power law through the last (up to) three sizes; n at which ``key`` reaches ``target``.

    ``key`` is "median_rel_error" (error itself) or "r2" (fitted as 1 - R²)."""
    pts = [(r["n_designs"], r[metric][key]) for r in rows if r[metric][key] is not None]
    pts = [(n, (1 - v) if key == "r2" else v) for n, v in pts if math.isfinite(v)]
    goal = (1 - target) if key == "r2" else target
    reached = [n for n, v in pts if v <= goal]
    if reached:
        return {"met_at": min(reached), "slope": None, "needed": min(reached)}
    tail = [(n, v) for n, v in pts if v > 0][-3:]
    if len(tail) < 2:
        return {"met_at": None, "slope": None, "needed": None}
    slope, intercept = np.polyfit(np.log([n for n, _ in tail]), np.log([v for _, v in tail]), 1)
    needed = math.exp((math.log(goal) - intercept) / slope) if slope < 0 else math.inf
    return {"met_at": None, "slope": float(slope), "needed": needed}


def render(result: dict, png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["rows"]
    n = [r["n_designs"] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for m in (*CHECKED, "wedge_peak_force_N"):
        a.loglog(n, [100 * r[m]["median_rel_error"] for r in rows], "o-", label=m)
        b.loglog(n, [max(1 - r[m]["r2"], 1e-5) for r in rows], "o-", label=m)
    a.axhline(100 * TARGET_MEDIAN, color="k", ls="--", lw=1, label="target 3 %")
    b.axhline(1 - TARGET_R2, color="k", ls="--", lw=1, label="target R² 0.99")
    a.set(xlabel="FE designs (train + validation)", ylabel="median relative error (%)")
    b.set(xlabel="FE designs (train + validation)", ylabel="1 - R² (test)")
    for ax in (a, b):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Surrogate learning curve ({result['n_test']} fixed test designs)")
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)


def markdown(result: dict, png: Path, out: Path, command: str) -> str:
    rows = result["rows"]
    lines = [
        "## Learning curve",
        "",
        f"Generated by `{command}` from `{result['sweep']}` "
        f"({result['n_designs_with_results']} designs with FE results, table sha256 "
        f"`{result['table_sha256'][:16]}…`); {result['n_test']} fixed test designs; ensembles "
        "with the default training settings, each size a nested subset.",
        "",
        "| designs | " + " | ".join(f"{m} R² / median err" for m in CHECKED) + " | train time |",
        "|---|" + "---|" * (len(CHECKED) + 1),
    ]
    for r in rows:
        cells = [f"{r[m]['r2']:.4f} / {100 * r[m]['median_rel_error']:.2f} %" for m in CHECKED]
        lines.append(
            f"| {r['n_designs']} | " + " | ".join(cells) + f" | {r['train_seconds']:.0f} s |"
        )
    lines += ["", "Targets (median relative error <= 3 %, R² >= 0.99):", ""]
    for m in CHECKED:
        for key, _target, label in (
            ("median_rel_error", TARGET_MEDIAN, "median error 3 %"),
            ("r2", TARGET_R2, "R² 0.99"),
        ):
            e = result["extrapolation"][m][key]
            if e["met_at"] is not None:
                text = f"met with {e['met_at']} designs"
            elif e["needed"] is None:
                text = "too few sizes to extrapolate"
            elif math.isfinite(e["needed"]):
                text = (
                    f"not met; the power law (slope {e['slope']:.2f}) reaches it at "
                    f"~{e['needed']:,.0f} designs"
                )
            else:
                text = "not met; the error does not fall with more designs"
            lines.append(f"- {m}, {label}: {text}")
    lines += ["", f"![learning curve]({png.relative_to(out.parent).as_posix()})", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep", type=Path)
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512, 1024, 4096])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("docs/learning_curve.md"))
    args = ap.parse_args()
    result = curve(args.sweep, sorted(args.sizes), args.seed)
    result["extrapolation"] = {
        m: {
            "median_rel_error": extrapolate(result["rows"], m, "median_rel_error", TARGET_MEDIAN),
            "r2": extrapolate(result["rows"], m, "r2", TARGET_R2),
        }
        for m in CHECKED
    }
    png = args.out.parent / "figures" / "learning_curve.png"
    render(result, png)
    command = "python scripts/learning_curve.py " + " ".join(
        [str(args.sweep), "--sizes", *map(str, sorted(args.sizes)), "--seed", str(args.seed)]
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    args.out.write_text(markdown(result, png, args.out, command))
    print(f"written {args.out}, {args.out.with_suffix('.json')} and {png}")


if __name__ == "__main__":
    main()
