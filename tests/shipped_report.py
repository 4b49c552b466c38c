"""The check both shipped checkpoints' tests make: the numbers in a shipped folder's
report.json are what its checkpoint does on its held-out designs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from sim.protocols import PROBABILITY_OUTPUTS
from surrogate import read_sweep
from surrogate._evaluate import parity_data, score


def assert_report_reproduced(model: Any, folder: Path, dimension: str = "2d") -> int:
    """Score ``model`` (either kind of surrogate) on its test split of the table shipped in
    ``folder`` and compare every metric with ``folder/report.json``: the coverage exactly, R²
    and the median relative error within 1e-6. Returns how many metrics were compared in full."""
    data = read_sweep(folder, dimension=dimension)
    report = json.loads((folder / "report.json").read_text())
    rows = {int(i): r for r, i in enumerate(data.index)}
    test = [rows[i] for i in model.header["training_data"]["split_table_index"]["test"]]
    assert len(test) == report["n_test"]
    scored = data.scored_targets()  # settled, valid designs (as when the report was written)
    checked = 0
    for p in parity_data(model, [data.points[i] for i in test], scored[test]):
        s, m = score(p), p.metric
        want = report["metrics"][m]
        if want["r2"] is None:
            continue
        # the intervals too (calibrated on the validation designs)
        assert s.coverage_90 == pytest.approx(want["coverage_90"], abs=1e-12)
        if m in PROBABILITY_OUTPUTS:
            # predictions of a probability are now clipped to [0, 1] (the 2D report was written
            # before): clipping moves a prediction toward every target in [0, 1], so each
            # error can only shrink, and an interval clipped to [0, 1] holds the same targets
            assert s.r2 >= want["r2"] - 1e-12
            assert s.median_rel_error <= want["median_rel_error"] + 1e-12
            continue
        assert s.r2 == pytest.approx(want["r2"], rel=1e-6)
        assert s.median_rel_error == pytest.approx(want["median_rel_error"], rel=1e-6)
        checked += 1
    return checked
