"""The best credible score one search study finds on the shipped surrogate, by its budget.

    python studies/search_budget.py [--model 3d] [--seeds 0 1]

For the main job's continuous study (round 0, the default targets and FE options of the
shipped checkpoint of ``--model``, its default rule of credibility: ``explore._config``), runs
the screen + TPE search (``explore._search.run_study``) with a screen of 65 536 designs and 128
trials (the 2D default: ``explore._config.TRIALS``), with 1024 trials (the 3D default) and with a
screen of 524 288 and 128 trials, and prints the
best score among the credible trials (the surrogate's, not FE's), the seconds and the best
design's parameters. One torch thread, in memory. In 3D the search costs seconds and each FE
confirmation minutes, so a budget that finds a better predicted design is cheap.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import torch  # noqa: E402

from explore._config import OptimizeConfig, setup  # noqa: E402
from explore._search import SearchSettings, create_study, run_study  # noqa: E402

#: (screen, trials): the 2D default, eight times the trials (the 3D default), eight times the
#: screen
BUDGETS = ((65536, 128), (65536, 1024), (524288, 128))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", choices=("2d", "3d"), default="3d")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    args = ap.parse_args()
    torch.set_num_threads(1)
    config = OptimizeConfig(model=args.model)
    with tempfile.TemporaryDirectory() as tmp:
        s = setup(config, Path(tmp) / "run")
    bound = s.record["credible_at"] == "bound"  # the model's default rule
    print(f"model {s.model}, credible on the {'bound' if bound else 'median'}")
    print("screen   trials  seed  best credible score  seconds")
    for screen, trials in BUDGETS:
        for seed in args.seeds:
            settings = SearchSettings(trials=trials, seed=seed, trust_bound=bound,
                                      options=s.options, screen=screen)  # fmt: skip
            study = create_study(None, "budget", settings)
            t0 = time.perf_counter()
            run_study(study, s.surrogate, s.space, s.targets, settings, round_=0,
                      search="continuous")  # fmt: skip
            seconds = time.perf_counter() - t0
            done = [t for t in study.trials if t.value is not None and math.isfinite(t.value)]
            best = min(done, key=lambda t: t.value)
            print(f"{screen:>7} {trials:>7} {seed:>5} {best.value:>20.4f} {seconds:>8.1f}")
            print("    " + ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                                     for k, v in best.params.items()))  # fmt: skip


if __name__ == "__main__":
    main()
