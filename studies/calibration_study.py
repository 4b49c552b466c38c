"""For docs/surrogate_accuracy.md: what calibrating the 90 % intervals does on a checkpoint's
own test designs.

    python studies/calibration_study.py CHECKPOINT SWEEP

``CHECKPOINT``: a ``fingertip train`` checkpoint (calibrated or not); ``SWEEP``: the sweep it
was trained on. The checkpoint records its train / validation / test designs by table index.
Per FE metric: the conformal factor fitted on the validation designs
(``surrogate._train.calibration_factors``, from the ensemble's own spread), and the share of the
test designs' FE values (settled, valid: ``SweepData.scored_targets``; the hysteresis of
elastic designs, exact by rule, left out) inside the 90 % interval with the ensemble's spread
and with the calibrated one (``docs/surrogate_accuracy.md``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sim.metrics import METRICS
from surrogate import load_checkpoint
from surrogate._io import read_sweep
from surrogate._normalise import Z90
from surrogate._surrogate import rule_mask
from surrogate._train import calibration_factors


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("sweep", type=Path)
    args = ap.parse_args()
    model = load_checkpoint(args.checkpoint)
    data = read_sweep(args.sweep)
    split = model.header["training_data"]["split_table_index"]
    row_of = {int(i): r for r, i in enumerate(data.index)}
    names = list(model.metric_names)

    def normalised(key: str, targets: np.ndarray):
        rows = [row_of[i] for i in split[key]]
        x = model.encoder.encode([data.points[r] for r in rows]).features
        mean_z, std_z = model.predict_normalised(x)  # the ensemble's own spread
        y = np.where(rule_mask(model.encoder, x, names), np.nan, targets[rows])
        return mean_z, std_z, model.normaliser.transform(y)

    val = normalised("val", data.targets)  # what fit calibrates on
    test = normalised("test", data.scored_targets())
    factors, info = calibration_factors(*val, names)
    score = np.abs(test[2] - test[0]) / test[1]
    print(f"{args.checkpoint}: {len(split['val'])} validation, {len(split['test'])} test designs")
    print("\n| metric | validation values | factor | test values | inside (ensemble) | inside "
          "(calibrated) |\n|---|---|---|---|---|---|")  # fmt: skip
    for j, name in enumerate(names):
        if name not in METRICS:
            continue
        ok = np.isfinite(score[:, j])
        own = np.mean(score[ok, j] <= Z90)
        calibrated = np.mean(score[ok, j] <= Z90 * factors[j])
        print(
            f"| {name} | {info['n'][name]} | {factors[j]:.3f} | {ok.sum()} | "
            f"{100 * own:.1f} % | {100 * calibrated:.1f} % |"
        )


if __name__ == "__main__":
    main()
