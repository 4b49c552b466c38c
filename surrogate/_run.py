"""``train_surrogate``: a sweep folder in, a training run folder out.

The run folder (created atomically, never overwritten) holds ``config.json`` (what was trained,
on which data), ``meta.json`` (provenance), ``model.safetensors`` (the checkpoint),
``history.json`` (loss curves), ``report.json`` + ``report.md`` + ``figures/parity_*.png``
(evaluation on the held-out test designs).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from sim.errors import DesignError, check_seed
from sim.provenance import check_new_folder, provenance, run_folder, write_json

from ._checkpoint import CHECKPOINT_NAME, save_checkpoint
from ._evaluate import evaluate, write_report
from ._io import read_sweep
from ._train import TrainConfig, fit

__all__ = ["CHECKPOINT_NAME", "default_out", "train_surrogate"]


def default_out(sweep_dir: str | Path) -> Path:
    """``runs/SWEEP`` -> ``runs/SWEEP-surrogate``."""
    sweep_dir = Path(sweep_dir)
    return sweep_dir.parent / f"{sweep_dir.resolve().name}-surrogate"


def train_config(
    seed: int, members: int, max_epochs: int | None, hyper: dict[str, Any]
) -> TrainConfig:
    """The ``TrainConfig`` of a training command, its options checked: a ``DesignError`` naming
    ``--members`` / ``--max-epochs`` / the seed, a ``TypeError`` for an unknown ``hyper`` key."""
    names = {f.name for f in dataclasses.fields(TrainConfig)}
    unknown = sorted(set(hyper) - names)
    if unknown:
        raise TypeError(f"unknown training option {unknown[0]!r}; known: {sorted(names)}")
    check_seed(seed)
    if members < 1:
        raise DesignError("--members", f"must be >= 1, got {members}")
    if max_epochs is not None:
        if max_epochs < 1:
            raise DesignError("--max-epochs", f"must be >= 1, got {max_epochs}")
        hyper = {**hyper, "max_epochs": max_epochs}
    return TrainConfig(seed=seed, members=members, **hyper)


def train_surrogate(
    sweep_dir: str | Path,
    out_dir: str | Path | None = None,
    seed: int = 0,
    members: int = 5,
    *,
    max_epochs: int | None = None,
    progress: bool = True,
    speed_n: int = 65536,
    include_untrusted: bool = False,
    **hyper,
) -> Path:
    """Train an ensemble surrogate on a sweep and write a run folder; returns the checkpoint.

    By default the designs whose taps did not reach their periodic state or whose deformation
    went beyond the validity limits are left out (and counted in the report);
    ``include_untrusted`` keeps them.

    ``hyper`` overrides other ``TrainConfig`` fields (``hidden``, ``patience``, ``lr``, ...).
    ``out_dir`` defaults to ``<sweep>-surrogate`` beside the sweep and must not exist yet.
    """
    out = Path(out_dir) if out_dir is not None else default_out(sweep_dir)
    check_new_folder(out)  # fail before training, not after
    config = train_config(seed, members, max_epochs, hyper)
    data = read_sweep(sweep_dir, trusted_only=not include_untrusted)
    if len(data.points) < 4:
        raise DesignError(
            "SWEEP", f"{sweep_dir} has {len(data.points)} designs with FE results; need >= 4"
        )
    result = fit(data, config, progress=progress)
    run_config = {
        "sweep": str(Path(sweep_dir).resolve()),
        "table_sha256": data.table_sha256,
        "solver_version": data.solver_version,
        "include_untrusted": include_untrusted,
        "train": config.to_dict(),
        # torch's intra-op threads of the training (``surrogate._threads``)
        "torch_threads": result.surrogate.header["training"]["torch_threads"],
    }
    split = result.split
    with run_folder(out) as tmp:
        write_json(tmp / "config.json", run_config)
        write_json(tmp / "meta.json", provenance(run_config, seed, kind="train"))
        save_checkpoint(result.surrogate, tmp / CHECKPOINT_NAME)
        write_json(
            tmp / "history.json",
            {**result.history, "best_epoch": list(result.best_epoch), "epochs": result.epochs},
        )
        report = evaluate(
            result.surrogate,
            [data.points[i] for i in split.test],
            data.scored_targets()[split.test],  # the FE metrics of settled, valid designs
            speed_n=speed_n,
        )
        info = {
            "checkpoint": CHECKPOINT_NAME,
            "seed": seed,
            "members": members,
            "epochs": result.epochs,
            "n_train": len(split.train),
            "n_val": len(split.val),
            "table_sha256": data.table_sha256,
            "validation": result.surrogate.header.get("validation"),
            "calibration": result.surrogate.header.get("calibration"),
            # designs with FE results left out of training and testing, by reason
            "excluded": dict(data.excluded),
            "unchecked": data.unchecked,
            # of the excluded, those whose protocols trusted on their own were learnt
            "partial": data.partial,
        }
        write_report(report, tmp, json.loads(json.dumps(info)))
    return out / CHECKPOINT_NAME
