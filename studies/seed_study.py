"""For docs/benchmarks.md: the main job over several seeds and retraining rehearsals, how much
of an answer is the seed's.

    python studies/seed_study.py --seeds 0 1 2 --replay 0 256 --out runs/replay_study

Runs ``explore.run`` (the main job's defaults, the Python API: no figures) once per (replay,
seed) into ``OUT/r<replay>_s<seed>`` (a finished folder is read, not re-run) and prints one JSON
line per run: its wall time and phases, the best FE closeness score of each round and the best
credible design's errors against the targets. ``--replay`` is
``OptimizeConfig.retrain_replay`` (0: every retraining epoch over the whole training sweep).
Timings are meaningful on a quiet machine only.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from explore import OptimizeConfig, run
from sim.provenance import json_text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--replay", type=int, nargs="+", default=[256])
    ap.add_argument("--surrogate", help="checkpoint (default: the shipped one)")
    ap.add_argument("--out", type=Path, default=Path("runs/seed_study"))
    args = ap.parse_args()
    extra = {"surrogate": args.surrogate} if args.surrogate else {}
    for replay in args.replay:
        for seed in args.seeds:
            out = args.out / f"r{replay}_s{seed}"
            t0 = time.perf_counter()
            config = OptimizeConfig(seed=seed, retrain_replay=replay, **extra)
            run(config, out, progress=False)
            wall = time.perf_counter() - t0
            d = json.loads((out / "summary.json").read_text())
            best = d["answers"].get("best") or {}
            line = {
                "replay": replay,
                "seed": seed,
                "wall_s": round(wall, 1),
                "timings": {k: round(v, 1) for k, v in d["timings"].items()},
                # None: no credible design that round
                "round_best": [
                    None if r["best_fe_score"] is None else round(r["best_fe_score"], 3)
                    for r in d["rounds"]
                ],
                "best_errors": best.get("errors_vs_targets"),
            }
            print(json_text(line), flush=True)


if __name__ == "__main__":
    main()
