"""``train_multifidelity``: a 3D sweep and a 2D surrogate in, a training run folder out; and
``multifidelity_curve``: each method's held-out error against the number of 3D designs
(``studies/multifidelity_study.py``, ``docs/multifidelity.md``).

The run folder is ``train_surrogate``'s: ``config.json``, ``meta.json``, ``model.safetensors``
(a multi-fidelity checkpoint, ``load_multifidelity``), ``history.json``, ``report.json`` +
``report.md`` + ``figures/parity_*.png`` (the held-out test designs of the 70/15/15 split,
scored on the settled, valid ones).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim.errors import DesignError, check_seed
from sim.provenance import (
    check_new_folder,
    provenance,
    recorded_path,
    run_folder,
    sha256_file,
    write_json,
)

from ._checkpoint import CHECKPOINT_NAME, checkpoint_file, load_checkpoint
from ._evaluate import evaluate, parity_data, score, write_report
from ._io import SweepData, read_sweep
from ._multifidelity import (
    METHODS,
    fit_multifidelity,
    method_class,
    split_rows,
    validation_size,
)
from ._multifidelity_checkpoint import save_multifidelity
from ._run import default_out, train_config
from ._train import TrainConfig

__all__ = [
    "COVERAGE",
    "DEFAULT_METHOD",
    "MF_TARGETS",
    "format_curve",
    "held_out_3d",
    "multifidelity_curve",
    "train_multifidelity",
]

#: the method ``fingertip train SWEEP3D --low-fidelity CHECKPOINT`` trains without --method:
#: it starts from the slice model fed with the 2D prediction, so that with few 3D designs it
#: learns a correction to it. The most accurate method at 12, 30, 60 and 112 3D designs on
#: every targeted metric, by five-fold cross-validation on the 3D dataset's first 128 designs
#: (docs/multifidelity.md, "Results on FE"); ``delta`` until then
DEFAULT_METHOD = "delta-slice"
#: designs of the inference-speed figure in the report (``surrogate._evaluate.inference_speed``)
SPEED_N = 65536

#: the targets on held-out settled, valid 3D designs: the largest median relative error of each
#: displacement reading, of the hysteresis and of the contact area (issue 34, item 2)
MF_TARGETS: dict[str, float] = {
    "disp_at_1N_mm": 0.02,
    "disp_at_4N_mm": 0.02,
    "disp_at_1N_from_touch_mm": 0.02,
    "disp_at_4N_from_touch_mm": 0.02,
    "hysteresis_Nmm": 0.05,
    "contact_area_at_1N_mm2": 0.05,
    "contact_area_at_4N_mm2": 0.05,
}
#: and the share of their FE values inside the predicted 90 % interval
COVERAGE = (0.85, 0.95)
#: the fraction of the settled, valid 3D designs held out as the fixed test set of the curve
TEST_FRACTION = 0.15
#: the validation share of each subset (early stopping, interval calibration; at least
#: ``surrogate._multifidelity.validation_size``)
VAL_FRACTION = 0.15


def _check_method(method: str | None, low_fidelity: str | Path | None) -> str:
    """The method to train (``DEFAULT_METHOD`` with a low fidelity, "3d" without); a
    ``DesignError`` naming the option for a method that needs a low fidelity without one, or
    "3d" with one."""
    if method is None:
        return DEFAULT_METHOD if low_fidelity is not None else "3d"
    kind = method_class(method)
    if kind.low_fidelity and low_fidelity is None:
        raise DesignError(
            "--low-fidelity",
            f"--method {method} needs the 2D surrogate: give --low-fidelity CHECKPOINT (e.g. "
            "surrogate/pretrained/default)",
        )
    if not kind.low_fidelity and low_fidelity is not None:
        others = ", ".join(m for m, k in METHODS.items() if k.low_fidelity)
        raise DesignError(
            "--method",
            f"{method} trains on the 3D designs alone: drop --low-fidelity, or choose one of "
            f"{others}",
        )
    return method


def train_multifidelity(
    sweep3d_dir: str | Path,
    low_fidelity: str | Path | None = None,
    method: str | None = None,
    out_dir: str | Path | None = None,
    seed: int = 0,
    members: int = 5,
    *,
    max_epochs: int | None = None,
    progress: bool = True,
    include_untrusted: bool = False,
    speed_n: int | None = None,
    **hyper: Any,
) -> Path:
    """Train a multi-fidelity surrogate on the 3D sweep ``sweep3d_dir`` (``fingertip sweep
    --model 3d``) with the 2D surrogate ``low_fidelity`` (a checkpoint file or a training run
    folder, e.g. ``surrogate/pretrained/default``) by ``method`` (``METHODS``: default
    ``DEFAULT_METHOD``; without a low fidelity "3d", the 3D designs alone), and write a run
    folder (``out_dir``, default ``<sweep>-surrogate``, new); returns the checkpoint.

    ``seed``, ``members``, ``max_epochs``, ``include_untrusted`` and ``hyper`` (other
    ``TrainConfig`` fields) as ``train_surrogate``'s. Bad input: a ``DesignError`` naming the
    option, a ``CheckpointError`` for a low fidelity that is not a usable checkpoint, before any
    training."""
    out = Path(out_dir) if out_dir is not None else default_out(sweep3d_dir)
    check_new_folder(out)  # fail before training, not after
    method = _check_method(method, low_fidelity)
    config = train_config(seed, members, max_epochs, hyper)
    low_file = None if low_fidelity is None else checkpoint_file(low_fidelity)
    if low_file is not None:
        load_checkpoint(low_file)  # a refused checkpoint: one line, before reading the sweep
    data = read_sweep(sweep3d_dir, trusted_only=not include_untrusted, dimension="3d")
    if len(data.points) < 4:
        raise DesignError(
            "SWEEP", f"{sweep3d_dir} has {len(data.points)} designs with FE results; need >= 4"
        )
    result = fit_multifidelity(data, low_file, method, config, progress=progress)
    surrogate = result.surrogate
    run_config = {
        "sweep": str(Path(sweep3d_dir).resolve()),
        "model": "3d",
        "table_sha256": data.table_sha256,
        "solver_version": data.solver_version,
        "include_untrusted": include_untrusted,
        "method": method,
        "low_fidelity": None
        if low_file is None
        else {"path": recorded_path(low_file), "sha256": sha256_file(low_file)},
        "train": surrogate.header["training"],
        "torch_threads": surrogate.header["training"]["torch_threads"],
    }
    split = result.split
    with run_folder(out) as tmp:
        write_json(tmp / "config.json", run_config)
        write_json(tmp / "meta.json", provenance(run_config, seed, kind="train"))
        save_multifidelity(surrogate, tmp / CHECKPOINT_NAME)
        write_json(
            tmp / "history.json",
            {**result.history, "best_epoch": list(result.best_epoch), "epochs": result.epochs},
        )
        report = evaluate(
            surrogate,  # duck-typed: predict, predict_features, encoder, space, units
            [data.points[i] for i in split.test],
            data.scored_targets()[split.test],  # the FE metrics of settled, valid designs
            speed_n=SPEED_N if speed_n is None else speed_n,
        )
        info = {
            "checkpoint": CHECKPOINT_NAME,
            "method": method,
            "seed": seed,
            "members": surrogate.members,
            "epochs": result.epochs,
            "n_train": len(split.train),
            "n_val": len(split.val),
            "table_sha256": data.table_sha256,
            "low_fidelity": run_config["low_fidelity"],
            "validation": surrogate.header.get("validation"),
            "calibration": surrogate.header.get("calibration"),
            "excluded": dict(data.excluded),
            "unchecked": data.unchecked,
            "partial": data.partial,
        }
        write_report(report, tmp, json.loads(json.dumps(info)))
    return out / CHECKPOINT_NAME


# ----------------------------------------------------------------------------- learning curve
def held_out_3d(
    data: SweepData, seed: int, fraction: float = TEST_FRACTION
) -> tuple[np.ndarray, np.ndarray]:
    """(the fixed test designs: ``fraction`` of the settled, valid ones, drawn with ``seed``;
    the pool of every other design, the subsets' source), as row positions into ``data``."""
    n = len(data.points)
    whole = np.ones(n, dtype=bool) if data.whole is None else data.whole
    candidates = np.flatnonzero(whole)
    if len(candidates) < 2:
        raise DesignError("SWEEP", f"{data.folder} has {len(candidates)} settled, valid designs")
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    n_test = max(1, round(fraction * len(candidates)))
    test = np.sort(rng.permutation(candidates)[:n_test])
    return test, np.setdiff1d(np.arange(n), test)


def cross_validation_folds(
    data: SweepData, seed: int, folds: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``folds`` (test, pool) pairs whose tests partition the settled, valid designs (drawn with
    ``seed``, sizes within one of each other); each pool is every other design. Row positions
    into ``data``, as ``held_out_3d``'s."""
    n = len(data.points)
    whole = np.ones(n, dtype=bool) if data.whole is None else data.whole
    candidates = np.flatnonzero(whole)
    if isinstance(folds, bool) or not isinstance(folds, int) or not 2 <= folds <= len(candidates):
        raise DesignError(
            "--folds", f"must be an integer from 2 to {len(candidates)} (the settled, valid "
            f"designs of {data.folder}), got {folds!r}",
        )  # fmt: skip
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    parts = np.array_split(rng.permutation(candidates), folds)
    return [(np.sort(t), np.setdiff1d(np.arange(n), t)) for t in parts]


def _parity(surrogate: Any, data: SweepData, test: np.ndarray) -> tuple:
    """``parity_data`` of ``surrogate`` on the ``test`` designs' scored FE values."""
    scored = data.scored_targets()[test]
    return parity_data(surrogate, [data.points[i] for i in test], scored)


def _pooled(parts: Sequence[tuple]) -> tuple:
    """The parity data of several test sets (one tuple per set, the same metrics) joined."""
    if len(parts) == 1:
        return parts[0]
    return tuple(
        dataclasses.replace(
            first,
            **{
                key: np.concatenate([getattr(p[j], key) for p in parts])
                for key in ("fe", "mean", "lower_90", "upper_90", "in_domain", "by_rule")
            },
        )
        for j, first in enumerate(parts[0])
    )


def _scores(parity: tuple) -> dict[str, dict[str, float]]:
    """Per metric: R², median and 95th-percentile relative error, coverage of the 90 % interval
    on the settled, valid test designs of ``parity`` (``surrogate._evaluate.score``)."""
    out = {}
    for p in parity:
        s = score(p)
        out[p.metric] = {
            "r2": s.r2,
            "median_rel_error": s.median_rel_error,
            "p95_rel_error": s.p95_rel_error,
            "coverage_90": s.coverage_90,
            "n": s.n,
        }
    return out


def multifidelity_curve(
    sweep3d: str | Path,
    sizes: Sequence[int],
    *,
    low_fidelity: str | Path | None = None,
    methods: Sequence[str] | None = None,
    seed: int = 0,
    repeats: int = 1,
    members: int = 5,
    max_epochs: int | None = None,
    config: TrainConfig | None = None,
    test_fraction: float = TEST_FRACTION,
    folds: int | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Each method's scores on one fixed held-out set of settled, valid 3D designs
    (``held_out_3d``) against the number of 3D designs it is trained on: per size of ``sizes``
    (above the pool: all of it) and repeat r, the first n designs of the pool in the order drawn
    with ``seed + r`` (nested subsets), 85/15 training and validation, every method on the same
    subset (training seed ``seed + r``). ``methods``: default every method the inputs allow
    ("3d" alone without ``low_fidelity``). ``config``: the training's other settings (default
    ``TrainConfig``'s). ``test_fraction``: of the settled, valid designs, held out.

    ``folds`` (cross-validation, instead of one held-out set): the settled, valid designs are
    split into that many folds (``cross_validation_folds``); every size, repeat and method is
    trained once per fold, on the first n designs of the others, and scored on the held-out
    predictions of all the folds together (each settled, valid design predicted once, by the
    training that did not see it). At a few dozen 3D designs one held-out set of 15 % is a
    handful of designs, whose median moves by several per cent between draws.

    ``on_run`` is called with each training's record as it is done (with ``fold``). Returns
    the records (``runs``: one per size, repeat and method, its scores over every fold) and,
    per size and method, the scores averaged over the repeats (``rows``)."""
    if not sizes or any(isinstance(n, bool) or not isinstance(n, int) or n < 4 for n in sizes):
        raise DesignError("--sizes", f"give numbers of 3D designs >= 4, got {list(sizes)}")
    for name, value in (("--repeats", repeats), ("--members", members)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise DesignError(name, f"must be an integer >= 1, got {value!r}")
    check_seed(seed)
    if methods is None:
        methods = [m for m, k in METHODS.items() if low_fidelity is not None or not k.low_fidelity]
    for m in methods:
        if method_class(m).low_fidelity and low_fidelity is None:
            raise DesignError("--low-fidelity", f"the {m} method needs the 2D surrogate")
    low_file = None if low_fidelity is None else checkpoint_file(low_fidelity)
    low = None if low_file is None else load_checkpoint(low_file)
    data = read_sweep(sweep3d, dimension="3d")
    if folds is None:
        splits = [held_out_3d(data, seed, test_fraction)]
    else:
        splits = cross_validation_folds(data, seed, folds)
    smallest_pool = min(len(pool) for _, pool in splits)
    sizes = sorted({min(n, smallest_pool) for n in sizes})
    base = config if config is not None else TrainConfig()
    changes: dict[str, Any] = {"members": members}
    if max_epochs is not None:
        changes["max_epochs"] = max_epochs
    runs: list[dict[str, Any]] = []
    for n in sizes:
        for r in range(repeats):
            chosen = [np.random.default_rng(seed + r).permutation(pool)[:n] for _, pool in splits]
            for method in methods:
                cfg = dataclasses.replace(base, seed=seed + r, **changes)
                parts, seconds, epochs = [], 0.0, []
                for f, ((test, _), rows) in enumerate(zip(splits, chosen, strict=True)):
                    split = split_rows(rows, data.whole, validation_size(n, VAL_FRACTION), test)
                    t0 = time.perf_counter()
                    fit = fit_multifidelity(data, low, method, cfg, split=split, progress=False)
                    parts.append(_parity(fit.surrogate, data, test))
                    seconds += time.perf_counter() - t0
                    epochs.append(fit.epochs)
                    if on_run is not None:
                        on_run({"n": n, "repeat": r, "method": method, "fold": f,
                                "seconds": time.perf_counter() - t0, "epochs": fit.epochs,
                                "scores": _scores(parts[-1])})  # fmt: skip
                runs.append(
                    {
                        "n": n,
                        "repeat": r,
                        "method": method,
                        "seconds": seconds,
                        "epochs": epochs[0] if len(epochs) == 1 else epochs,
                        "scores": _scores(_pooled(parts)),
                    }
                )
    rows = []
    for n in sizes:
        for method in methods:
            mine = [x for x in runs if x["n"] == n and x["method"] == method]
            scores: dict[str, dict[str, float | None]] = {}
            for metric in mine[0]["scores"]:
                scores[metric] = {}
                for key in ("r2", "median_rel_error", "p95_rel_error", "coverage_90"):
                    vals = [x["scores"][metric][key] for x in mine]
                    finite = [v for v in vals if v is not None and math.isfinite(v)]
                    scores[metric][key] = float(np.mean(finite)) if finite else None
            rows.append({"n": n, "method": method, "scores": scores})
    return {
        "sweep": str(sweep3d),
        "table_sha256": data.table_sha256,
        "n_designs": len(data.points),
        "n_test": sum(len(test) for test, _ in splits),
        "n_pool": smallest_pool,
        "test_fraction": test_fraction if folds is None else None,
        "folds": folds,
        "low_fidelity": None
        if low_file is None
        else {"path": recorded_path(low_file), "sha256": sha256_file(low_file)},
        "methods": list(methods),
        "sizes": sizes,
        "seed": seed,
        "repeats": repeats,
        "members": members,
        "max_epochs": max_epochs,
        "targets": {"median_rel_error": MF_TARGETS, "coverage_90": list(COVERAGE)},
        "rows": rows,
        "runs": runs,
    }


def _pct(x: float | None) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{100 * x:.1f} %"


def format_curve(result: dict[str, Any]) -> str:
    """The learning curve as a Markdown table: per number of 3D designs and method, the median
    relative error of each targeted metric with its coverage of the 90 % interval in brackets,
    and how many targets are met."""
    metrics = [m for m in MF_TARGETS if any(m in row["scores"] for row in result["rows"])]
    head = ["3D designs", "method", *metrics, "targets met"]
    low = result.get("low_fidelity")
    folded = ""
    if result.get("folds"):
        folded = f"in {result['folds']} folds, each predicted by the training without it "
    lines = [
        f"Low fidelity: {low['path']} (sha256 {low['sha256'][:12]}...)." if low else "",
        f"Held out: {result['n_test']} settled, valid 3D designs of {result['n_designs']} "
        + folded
        + f"({result['sweep']}); median relative error (share of FE values inside the 90 % "
        f"interval); targets: median {', '.join(f'{m} {_pct(t)}' for m, t in MF_TARGETS.items())}"
        f"; coverage {_pct(COVERAGE[0])}-{_pct(COVERAGE[1])}; mean over {result['repeats']} "
        "repeat(s).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for row in result["rows"]:
        cells, met = [], 0
        for m in metrics:
            s = row["scores"].get(m, {})
            med, cov = s.get("median_rel_error"), s.get("coverage_90")
            ok = med is not None and med <= MF_TARGETS[m]
            ok &= cov is not None and COVERAGE[0] <= cov <= COVERAGE[1]
            met += bool(ok)
            cells.append(f"{_pct(med)} ({_pct(cov)})")
        lines.append(
            f"| {row['n']} | {row['method']} | " + " | ".join(cells) + f" | {met}/{len(metrics)} |"
        )
    return "\n".join(lines) + "\n"
