"""Benchmark: writing finished trials to an Optuna SQLite database against a journal file.

    python benchmarks/bench_storage.py [--trials 600]

What the search does each round (``study.add_trials`` of ~600 finished trials with ~12
parameters and a few user attributes), into a fresh storage of each kind in a temporary folder.
The figures behind ``explore/_storage.py``'s choice of a journal by default. The load average
is printed too: a busy machine gives slower figures.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

import optuna

from explore._storage import open_storage


def _trials(n: int) -> list:
    dist = {f"p{j}": optuna.distributions.FloatDistribution(0.0, 10.0) for j in range(12)}
    return [
        optuna.trial.create_trial(
            params={f"p{j}": 0.01 * j + 1e-4 * i for j in range(12)},
            distributions=dist,
            value=float(i),
            user_attrs={f"a{k}": float(k) for k in range(6)},
        )
        for i in range(n)
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=600)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    trials = _trials(args.trials)
    print(f"load average {os.getloadavg()[0]:.2f}, {args.trials} trials")
    with tempfile.TemporaryDirectory() as tmp:
        for kind, spec in (
            ("sqlite", f"sqlite:///{tmp}/study.db"),
            ("journal", f"{tmp}/study.log"),
        ):
            study = optuna.create_study(storage=open_storage(spec), study_name="bench")
            t0 = time.perf_counter()
            study.add_trials(trials)
            wall = time.perf_counter() - t0
            size = Path(spec.removeprefix("sqlite:///")).stat().st_size
            print(
                f"{kind:8s} {wall:6.2f} s = {1e3 * wall / args.trials:5.1f} ms a trial, "
                f"{size:,} bytes"
            )


if __name__ == "__main__":
    main()
