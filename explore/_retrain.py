"""Active learning's retraining: the surrogate, warm-started, on its training sweep plus the
FE-confirmed designs of the rounds so far (``surrogate.fine_tune``), each counted
``CONFIRMED_WEIGHT`` times."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from sim.provenance import nan_if_none

from ._types import Confirmation

__all__ = ["CONFIRMED_WEIGHT", "retrain", "training_rows"]

#: confirmed FE designs count this many times in a warm-started retraining (they are few, and
#: they sit where the search wants the surrogate to be right)
CONFIRMED_WEIGHT = 10


def training_rows(
    confirmed: Sequence[Confirmation], metric_names: Sequence[str]
) -> tuple[list[Confirmation], np.ndarray]:
    """The confirmations a surrogate learns from, and their targets (one row each, the columns
    of ``metric_names``; NaN: not learnt). An unsettled or invalid result teaches no metric,
    but it does teach what made it so (the trust outputs, when the surrogate learns them), as
    in ``surrogate.read_sweep``."""
    from sim.trust import TRUST_OUTPUTS, trust_censoring, trust_values

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

    return ok, np.array([target_row(c) for c in ok]).reshape(-1, len(metric_names))


def retrain(
    surrogate,
    dataset: Path,
    confirmed: list[Confirmation],
    epochs: int,
    seed: int,
    progress: Callable[[int], None] | None = None,
    batch_size: int | None = None,
    replay: int = 0,
):
    """Warm-started retraining on the training sweep plus the FE-confirmed designs;
    ``progress`` is called with the number of epochs done since its last call; ``replay``
    as ``fine_tune``'s (0: every epoch over the whole sweep)."""
    from surrogate import fine_tune, read_sweep

    data = read_sweep(dataset)
    ok, targets = training_rows(confirmed, data.metric_names)
    model = fine_tune(
        surrogate, data, [c.candidate.point for c in ok], targets, epochs=epochs, seed=seed,
        weight=CONFIRMED_WEIGHT, batch_size=batch_size, replay=replay,
        progress=progress or False,
    )  # fmt: skip
    model.header["active_learning"] = {
        "confirmed_designs": len(ok),
        "weight": CONFIRMED_WEIGHT,
        "warm_start_from": surrogate.header.get("sha256", ""),
    }
    return model
