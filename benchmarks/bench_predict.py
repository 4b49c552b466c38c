"""Benchmark: surrogate inference throughput (designs per second, batched) on this CPU.

    python benchmarks/bench_predict.py [--checkpoint CKPT] [--n 65536] [--repeats 5]

Loads a checkpoint (by default the shipped ``surrogate/pretrained/default``) and times
``Surrogate.predict_features`` (encoded features -> mean and spread in metric units) and
``Surrogate.predict`` (a table of design points -> ``Prediction``, with encoding and the
domain check) on ``n`` designs tiled from the shipped table, best of ``repeats``, with torch's
default threads and with one thread. Target (the surrogate issue): >= 1e5 designs/s.
The load average is printed too: a busy machine gives lower figures.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from surrogate import load_checkpoint, read_points
from surrogate._evaluate import inference_speed

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "surrogate" / "pretrained" / "default"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=DEFAULT / "model.safetensors")
    ap.add_argument("--designs", type=Path, default=DEFAULT / "table.csv.gz")
    ap.add_argument("--n", type=int, default=65536)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    model = load_checkpoint(args.checkpoint, allow_solver_mismatch=True)  # speed only
    points = read_points(args.designs, model.space)
    s = inference_speed(model, points, args.n, args.repeats)
    print(f"{args.checkpoint} on {s.machine}, {s.cpu_count} CPUs, load {s.load_average_1min:.2f}")
    print(f"torch {torch.__version__}, {s.torch_threads} thread(s), {s.n_designs} designs")
    print(
        f"features -> prediction: {s.model_designs_per_s:,.0f} designs/s "
        f"({s.model_designs_per_s_1_thread:,.0f} on 1 thread)"
    )
    print(
        f"design table -> Prediction: {s.end_to_end_designs_per_s:,.0f} designs/s "
        f"({s.end_to_end_designs_per_s_1_thread:,.0f} on 1 thread)  (target >= 100,000)"
    )


if __name__ == "__main__":
    main()
