"""For docs/surrogate_accuracy.md: the surrogate accuracy experiments on one sweep.

    python studies/accuracy_study.py SWEEP [--n 10000] [--repeats 0 1 2] [--groups NAME]
        [--old-trust] [--config '{"hidden": [128, 128, 128]}'] [--cv K] [--json OUT]
    python studies/accuracy_study.py SWEEP --rebuild-table

Fixed-split mode (default): the fixed test split of ``fingertip learning-curve`` (15 % of the
sweep's designs, drawn with seed 0) scores ensembles trained on the first ``--n`` designs of each
repeat's order of the others (repeat r: order and training seed r; 15 % of them for early stopping),
exactly as ``surrogate._learning_curve.train_one`` does, with the ``TrainConfig`` overrides of
``--groups`` and ``--config``. ``--cv K``: K-fold cross-validation over all designs instead
(out-of-fold predictions of every design; fold f trained with seed 10 f). Either way the scores
(median and 95th-percentile relative error, coverage of the 90 % interval) are taken on the designs
trusted whole (settled and valid: ``SweepData.scored_targets``), and the credibility prediction's
``TrustScore`` is printed. ``--old-trust``: train on the FE metrics of the designs trusted whole
only (``read_sweep(per_protocol=False)``, the rule before the per-protocol trust).

``--rebuild-table``: write ``table.csv`` of an interrupted sweep folder from its records (a
sweep writes it at the end of an invocation), matching the records to the folder's Sobol sample
by their design points: the record keys hash the options of the solver version the sweep was
made with, which the current options need not reproduce.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from surrogate._learning_curve import CHECKED, SCORE_KEYS, held_out_and_pool


def rebuild_table(folder: Path) -> None:
    """table.csv of ``folder`` from its records, in the order of its Sobol sample."""
    from sim.design import space_from_dict
    from sim.provenance import json_safe
    from sim.sweep import SweepStore, read_config, sample_points

    config = read_config(folder)
    space = space_from_dict(config["space"])
    points = sample_points(space, config["n"], config["seed"], config["sampler"])
    store = SweepStore(folder)
    records = store.load()
    by_point = {json.dumps(r["params"], sort_keys=True): k for k, r in records.items()}
    keys = [
        by_point.get(json.dumps(json_safe(p), sort_keys=True), f"not-computed-{i}")
        for i, p in enumerate(points)
    ]
    found = sum(k in records for k in keys)
    store.consolidate(keys, space.names)
    print(f"{folder / 'table.csv'}: {found} of {len(records)} records, {len(points)} designs")


def _config(args):
    from surrogate._train import TrainConfig

    over = json.loads(args.config)
    over = {k: tuple(v) if isinstance(v, list) else v for k, v in over.items()}
    if args.groups:
        over["groups"] = args.groups
    return lambda seed: TrainConfig(seed=seed, **over)


def _scores(surrogate, points, targets) -> tuple[dict, object]:
    from surrogate._evaluate import parity_data, score, trust_score

    parity = parity_data(surrogate, points, targets)
    scores = {p.metric: {k: getattr(score(p), k) for k in SCORE_KEYS} for p in parity}
    return scores, trust_score(parity)


def fixed_split(args, data, config) -> list[dict]:
    from surrogate._train import Split, fit

    test, pool = held_out_and_pool(data, 0)
    scored = data.scored_targets()
    runs = []
    for r in args.repeats:
        chosen = np.random.default_rng(r).permutation(pool)[: args.n]
        n_val = max(1, round(0.15 * len(chosen)))
        split = Split(np.sort(chosen[n_val:]), np.sort(chosen[:n_val]), test)
        result = fit(data, config(r), progress=False, split=split)
        scores, trust = _scores(result.surrogate, [data.points[i] for i in test], scored[test])
        run = {"repeat": r, "n": len(chosen), "epochs": result.epochs, "scores": scores}
        runs.append({**run, "trust": trust.__dict__})
        _print(f"n = {len(chosen)}, repeat {r}, {result.epochs} epochs", scores, trust)
    return runs


def cross_validation(args, data, config) -> list[dict]:
    from surrogate._evaluate import ParityData, score
    from surrogate._train import Split, fit

    n, k = len(data.points), args.cv
    folds = np.array_split(np.random.default_rng(1000).permutation(n), k)
    pred = {key: np.full((n, len(data.metric_names)), np.nan) for key in ("med", "lo", "hi")}
    for f in range(k):
        rest = np.random.default_rng(f).permutation(np.concatenate(folds[:f] + folds[f + 1 :]))
        n_val = round(0.15 * len(rest))
        split = Split(np.sort(rest[n_val:]), np.sort(rest[:n_val]), np.sort(folds[f]))
        result = fit(data, config(10 * f), progress=False, split=split)
        p = result.surrogate.predict([data.points[i] for i in split.test])
        for key, value in (("med", p.median), ("lo", p.lower_90), ("hi", p.upper_90)):
            pred[key][split.test] = value
    scored = data.scored_targets()
    scores = {}
    for j, m in enumerate(data.metric_names):
        rule = (pred["lo"][:, j] == 0) & (pred["hi"][:, j] == 0)  # exact by physics
        parity = ParityData(m, "", scored[:, j], pred["med"][:, j], pred["lo"][:, j],
                            pred["hi"][:, j], np.ones(n, dtype=bool), rule)  # fmt: skip
        scores[m] = {key: getattr(score(parity), key) for key in SCORE_KEYS}
    _print(f"{k}-fold cross-validation over {n} designs", scores, None)
    return [{"cv": k, "scores": scores}]


def _print(title: str, scores: dict, trust) -> None:
    cells = [
        f"{m}: {100 * scores[m]['median_rel_error']:.2f} % / "
        f"{100 * scores[m]['p95_rel_error']:.0f} % / {100 * scores[m]['coverage_90']:.0f} %"
        for m in CHECKED
    ]
    line = f"{title} (median / p95 error / in 90 %): " + "; ".join(cells)
    if trust is not None:
        line += f"; credibility right {100 * trust.accuracy:.1f} %"
    print(line, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep", type=Path)
    ap.add_argument("--n", type=int, default=10_000, help="training + validation designs")
    ap.add_argument("--repeats", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--groups", default=None, help="TrainConfig.groups")
    ap.add_argument("--config", default="{}", help="other TrainConfig fields, as JSON")
    ap.add_argument("--old-trust", action="store_true", help="read_sweep(per_protocol=False)")
    ap.add_argument("--cv", type=int, default=0, help="K-fold cross-validation instead")
    ap.add_argument("--json", type=Path, default=None, help="write the scores here")
    ap.add_argument("--rebuild-table", action="store_true")
    args = ap.parse_args()
    if args.rebuild_table:
        rebuild_table(args.sweep)
        return
    import torch

    from surrogate._io import read_sweep

    torch.set_num_threads(1)  # a background FE sweep keeps the cores busy
    data = read_sweep(args.sweep, per_protocol=not args.old_trust)
    config = _config(args)
    runs = cross_validation(args, data, config) if args.cv else fixed_split(args, data, config)
    if len(runs) > 1:
        means = {
            m: {k: float(np.mean([r["scores"][m][k] for r in runs])) for k in SCORE_KEYS}
            for m in CHECKED
        }
        _print(f"mean of {len(runs)} repeats", means, None)
    if args.json:
        from sim.provenance import json_text

        given = {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()}
        args.json.write_text(json_text({"args": given, "runs": runs}, indent=1) + "\n")


if __name__ == "__main__":
    main()
