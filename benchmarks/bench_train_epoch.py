"""Benchmark: one training epoch of the default ensemble, at the full rate and after a decay.

    python benchmarks/bench_train_epoch.py [--rows 2868] [--repeats 4]

An epoch of ``surrogate._train._train_epoch`` on random data of the shipped surrogate's shape
(57 features, 23 outputs in groups of 6 and 17, 5 members, ``TrainConfig()``), best of
``--repeats``, alternating: every net at the configured rate, and one net's rate cut by a
plateau decay (``_LearningRate``: every step then keeps the weights before it and scales each
net's update). Prints seconds per epoch; the load average says whether the machine was quiet.
"""

from __future__ import annotations

import argparse
import os
import time

import torch

from surrogate._model import EnsembleMLP
from surrogate._train import TrainConfig, _Best, _epoch_order, _LearningRate, _train_epoch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2868, help="training designs")
    ap.add_argument("--repeats", type=int, default=4)
    args = ap.parse_args()
    n, n_in, n_out = args.rows, 57, 23
    model = EnsembleMLP(n_in, n_out, members=5, groups=[0] * 6 + [1] * 17, seed=0)
    gen = torch.Generator().manual_seed(0)
    x, z = torch.rand(n, n_in, generator=gen), torch.randn(n, n_out, generator=gen)
    data = (x, z, torch.ones(n, n_out), torch.zeros(n, n_out))
    config = TrainConfig()
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    threads = torch.get_num_threads()
    print(f"load {os.getloadavg()[0]:.2f}, torch {torch.__version__}, {threads} threads")
    for label in ("full rate", "one net decayed", "full rate", "one net decayed"):
        rate = _LearningRate(model, config)
        if label != "full rate":
            best = _Best.start(model)
            best.epoch[1:] = 10**6  # every net but net 0 improving
            rate.stop_after(config.decay_patience, best)
        times = []
        for _ in range(args.repeats):
            order = _epoch_order(config.members, n, 0, 0, gen)
            t0 = time.perf_counter()
            _train_epoch(model, opt, data, model.net_mask(), order, config, rate)
            times.append(time.perf_counter() - t0)
        print(f"{label}: {min(times):.3f} s per epoch ({n} rows)")


if __name__ == "__main__":
    main()
