"""Benchmark: the best score a search finds per second, today's sampler alone vs screen + sampler.

    python benchmarks/bench_search.py [--trials 1000] [--screen 65536] [--after 128]

On the shipped surrogate and the default space, for the default human targets and for a hard
case (targets far from them: half the human displacements and twice the hysteresis), runs

- ``tpe``: the sampler alone (multivariate TPE, batches of 16), ``--trials`` trials: the search
  before the screen;
- ``screen+tpe``: a scrambled Sobol screen of ``--screen`` designs scored by the surrogate, its
  64 best as the study's first trials, then ``--after`` TPE trials (the main job's default).

and prints, from the trials' completion times, the best score found after 5, 10, 20 and 30 s
and at the end, with the wall time and the number of designs scored. One torch thread, in
memory (no database), the same seed. Run it on a quiet machine.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import torch  # noqa: E402

from explore._config import DEFAULT_CHECKPOINT  # noqa: E402
from explore._search import SearchSettings, create_study, run_study  # noqa: E402
from sim.design import load_space, load_targets  # noqa: E402
from surrogate import load_checkpoint  # noqa: E402

MARKS_S = (5.0, 10.0, 20.0, 30.0)


def hard_targets(targets):
    """Half the human displacements, twice the hysteresis: far from every default."""
    scale = {"disp": 0.5, "hysteresis": 2.0}
    values = {k: v * scale.get(k.split("_")[0], 1.0) for k, v in targets.values.items()}
    return dataclasses.replace(targets, values=values)


def best_by_time(study, t0: float) -> tuple[list[float], float]:
    """The running best score at each of MARKS_S seconds after ``t0``, and at the end."""
    done = sorted(
        (t.datetime_complete.timestamp() - t0, t.value)
        for t in study.trials
        if t.value is not None and math.isfinite(t.value)
    )
    marks, best, k = [], math.inf, 0
    for mark in MARKS_S:
        while k < len(done) and done[k][0] <= mark:
            best = min(best, done[k][1])
            k += 1
        marks.append(best)
    return marks, min((v for _, v in done), default=math.inf)


def run(surrogate, space, targets, settings: SearchSettings) -> tuple[list[float], float, float]:
    study = create_study(None, "bench", settings)
    t0 = time.time()
    run_study(study, surrogate, space, targets, settings, round_=0, search="continuous")
    wall = time.time() - t0
    marks, final = best_by_time(study, t0)
    return marks, final, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--screen", type=int, default=65536)
    ap.add_argument("--after", type=int, default=128)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    torch.set_num_threads(1)
    warnings.simplefilter("ignore")
    surrogate = load_checkpoint(DEFAULT_CHECKPOINT, allow_solver_mismatch=True)
    space = load_space()
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    head = " | ".join(f"best by {m:g} s" for m in MARKS_S)
    print(f"| targets | search | designs scored | wall s | {head} | best at end |")
    print("|---|---|---|---|" + "---|" * len(MARKS_S) + "---|")
    for label, targets in (("human", load_targets()), ("hard", hard_targets(load_targets()))):
        plans = (
            ("tpe", SearchSettings(trials=args.trials, seed=args.seed), args.trials),
            (
                "screen+tpe",
                SearchSettings(trials=args.after, seed=args.seed, screen=args.screen),
                args.screen + args.after,
            ),
        )
        for name, settings, scored in plans:
            marks, final, wall = run(surrogate, space, targets, settings)
            cells = " | ".join("-" if math.isinf(m) else f"{m:.4f}" for m in marks)
            print(f"| {label} | {name} | {scored} | {wall:.1f} | {cells} | {final:.4f} |")


if __name__ == "__main__":
    main()
