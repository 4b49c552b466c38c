"""Active learning's retraining: the surrogate on its training sweep plus the FE-confirmed
designs of the rounds so far, each counted ``CONFIRMED_WEIGHT`` times: a 2D surrogate
warm-started (``surrogate.fine_tune``), a multi-fidelity one trained afresh as its checkpoint
records, on its 3D sweep (``surrogate.retrain_multifidelity``)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from sim.provenance import nan_if_none

from ._types import Confirmation

__all__ = [
    "CONFIRMED_DIGITS",
    "CONFIRMED_WEIGHT",
    "CONVERGENCE_DIGITS",
    "reproducible",
    "retrain",
    "retrain_epochs",
    "training_rows",
]

#: confirmed FE designs count this many times in a warm-started retraining (they are few, and
#: they sit where the search wants the surrogate to be right)
CONFIRMED_WEIGHT = 10

#: Significant digits a confirmed design's FE values keep as retraining targets
#: (``reproducible``), so that every machine retrains on the same numbers (the sweep's rows
#: come from one shipped file). The FE of a design differs between CPUs in its last bits:
#: numpy's and OpenBLAS's AVX-512 and AVX2 code paths (this project's host,
#: ``NPY_DISABLE_CPU_FEATURES``, ``OPENBLAS_CORETYPE``) gave metrics and validity figures up to
#: 2e-11 apart (relative). torch learns from float32, spaced 6e-8 to 1.2e-7 (relative): a value
#: that close to a float32 boundary, 1 in 3000 to 6000, becomes another target, and a
#: retraining that starts from other bits ends elsewhere (``surrogate._arithmetic``). Five
#: digits, spaced 1e-5 to 1e-4, leave one value in 500 000 or more to round apart, and move a
#: value by at most 5e-5, a twelfth of the smallest median held-out error of any learnt output
#: (6e-4, wedge_min_J; the displacements' 1.2e-3, ``surrogate/pretrained/default/report.json``).
#: Not covered: a last bit that makes the solver halve one more time step moves that FE result
#: by its time-step error (2e-5 relative, a wedge's peak force), which no rounding finer than
#: the surrogate's error absorbs (README, "Same answer on every machine?").
CONFIRMED_DIGITS = 5
#: The same for the solver's own convergence figures (``CONVERGENCE``), which differ up to 4e-8
#: between those code paths (half of them land on another float32): two digits leave one in
#: 250 000 or more to round apart and move a value by at most 5 %, a tenth of their median
#: held-out error (41 % and 54 %): the surrogate learns their order of magnitude, no more.
CONVERGENCE_DIGITS = 2
#: the tapping's periodic-state residual and estimated error (``sim.protocols.trust``)
CONVERGENCE = ("tapping_residual", "tapping_max_estimated_error")


def reproducible(targets: np.ndarray, metric_names: Sequence[str]) -> np.ndarray:
    """``targets`` (one row per design, the columns of ``metric_names``) rounded to
    ``CONFIRMED_DIGITS`` significant digits (``CONVERGENCE_DIGITS`` for ``CONVERGENCE``), by
    Python's correctly rounded formatting: the same float on every machine; NaN stays NaN."""
    digits = [CONVERGENCE_DIGITS if m in CONVERGENCE else CONFIRMED_DIGITS for m in metric_names]
    rows = np.asarray(targets, dtype=np.float64).reshape(-1, len(digits))
    rounded = [[float(f"{v:.{d}g}") for v, d in zip(row, digits, strict=True)] for row in rows]
    return np.array(rounded, dtype=np.float64).reshape(rows.shape)


def training_rows(
    confirmed: Sequence[Confirmation], metric_names: Sequence[str]
) -> tuple[list[Confirmation], np.ndarray]:
    """The confirmations a surrogate learns from, and their targets (one row each, the columns
    of ``metric_names``; NaN: not learnt; rounded by ``reproducible``). An unsettled or invalid
    result teaches no metric, but it does teach what made it so (the trust outputs, when the
    surrogate learns them), as in ``surrogate.read_sweep``."""
    from sim.protocols import TRUST_OUTPUTS, trust_censoring, trust_values

    learns_trust = set(TRUST_OUTPUTS) <= set(metric_names)
    ok = [c for c in confirmed if c.trusted or (learns_trust and c.status == "ok")]

    def target_row(c: Confirmation) -> list[float]:
        trust = trust_values({**c.diagnostics, "status": c.status})
        # a protocol stopped at its first violation: its strain and J are bounds, not values
        # (the sweep's rows learn them as such; these few rows leave them out)
        bounds = trust_censoring(c.diagnostics)
        trust = {k: math.nan if bounds[k] else v for k, v in trust.items()}
        return [
            trust[m] if m in trust else nan_if_none(c.fe_metrics.get(m)) if c.trusted else math.nan
            for m in metric_names
        ]

    return ok, reproducible(np.array([target_row(c) for c in ok]), metric_names)


def retrain_epochs(surrogate, epochs: int) -> int:
    """The most epochs :func:`retrain` trains ``surrogate`` for: ``epochs`` for a 2D surrogate's
    fine-tuning, the recorded ``max_epochs`` of a multi-fidelity one's training."""
    if _is_multifidelity(surrogate):
        return int(surrogate.header.get("training", {}).get("max_epochs", epochs))
    return epochs


def _is_multifidelity(surrogate) -> bool:
    from surrogate import MultiFidelitySurrogate

    return isinstance(surrogate, MultiFidelitySurrogate)


def retrain(
    surrogate,
    dataset: Path,
    confirmed: list[Confirmation],
    epochs: int,
    seed: int,
    progress: Callable[[int], None] | None = None,
    batch_size: int | None = None,
    replay: int = 0,
    fe_workers: int = 0,
):
    """The surrogate retrained on its training sweep plus the FE-confirmed designs: a 2D one
    warm-started (``fine_tune``: at most ``epochs``, ``batch_size`` and ``replay`` as its), a
    multi-fidelity one trained afresh as recorded (``retrain_multifidelity``: its 3D sweep is
    small; ``epochs``, ``batch_size`` and ``replay`` are the 2D fine-tuning's and not used);
    ``progress`` is called with the number of epochs done since its last call; ``fe_workers``:
    the FE processes that run meanwhile, whose cores torch's threads leave alone
    (``surrogate._threads``)."""
    from surrogate import fine_tune, read_sweep, retrain_multifidelity
    from surrogate._threads import torch_threads

    multifidelity = _is_multifidelity(surrogate)
    data = read_sweep(dataset, dimension="3d" if multifidelity else "2d")
    ok, targets = training_rows(confirmed, data.metric_names)
    points = [c.candidate.point for c in ok]
    threads = torch_threads(fe_workers)
    if multifidelity:
        model = retrain_multifidelity(
            surrogate, data, points, targets, seed=seed, weight=CONFIRMED_WEIGHT,
            progress=progress or False, threads=threads,
        )  # fmt: skip
    else:
        model = fine_tune(
            surrogate, data, points, targets, epochs=epochs, seed=seed,
            weight=CONFIRMED_WEIGHT, batch_size=batch_size, replay=replay,
            progress=progress or False, threads=threads,
        )  # fmt: skip
    model.header["active_learning"] = {
        "confirmed_designs": len(ok),
        "weight": CONFIRMED_WEIGHT,
        # the checkpoint it continues (a multi-fidelity one's split, method and seed-free setup)
        ("retrained_from" if multifidelity else "warm_start_from"): surrogate.header.get(
            "sha256", ""
        ),
    }
    return model
