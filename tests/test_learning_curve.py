"""``scripts/learning_curve.py``: the power-law extrapolation; a small run on the shipped data."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from sim.sweep_folder import open_table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

from learning_curve import CHECKED, extrapolate  # noqa: E402

SHIPPED = ROOT / "surrogate" / "pretrained" / "default"


def _rows(sizes, key, values):
    return [{"n_designs": n, "m": {key: v}} for n, v in zip(sizes, values, strict=True)]


def test_extrapolation_recovers_a_power_law():
    """error = 0.6 n^-1/2 reaches 3 % at n = 400; 1 - R² = 0.5 / n reaches R² 0.99 at n = 50."""
    sizes = [25, 50, 100]
    err = extrapolate(_rows(sizes, "median_rel_error", [0.6 / math.sqrt(n) for n in sizes]),
                      "m", "median_rel_error", 0.03)  # fmt: skip
    assert err["met_at"] is None
    assert err["slope"] == pytest.approx(-0.5, rel=1e-9)
    assert err["needed"] == pytest.approx(400, rel=1e-9)
    sizes = [10, 20, 40]
    r2 = extrapolate(_rows(sizes, "r2", [1 - 0.5 / n for n in sizes]), "m", "r2", 0.99)
    assert r2["needed"] == pytest.approx(50, rel=1e-9) and r2["slope"] == pytest.approx(-1.0)
    # a size that already meets the target is reported as such, without a fit
    met = extrapolate(_rows([100, 200, 400], "median_rel_error", [0.05, 0.029, 0.02]),
                      "m", "median_rel_error", 0.03)  # fmt: skip
    assert met == {"met_at": 200, "slope": None, "needed": 200}
    # an error that does not fall never reaches the target
    flat = extrapolate(_rows([100, 200], "median_rel_error", [0.05, 0.06]), "m",
                       "median_rel_error", 0.03)  # fmt: skip
    assert flat["needed"] == math.inf


@pytest.mark.slow
def test_small_curve_on_the_shipped_dataset(tmp_path):
    """Two sizes x two repeats on the shipped table: one fixed test set, nested subsets, every
    repeat kept, and the Markdown, JSON and PNG written."""
    out = tmp_path / "lc.md"
    cmd = [sys.executable, str(ROOT / "scripts" / "learning_curve.py"), str(SHIPPED),
           "--sizes", "128", "64", "--repeats", "2", "--jobs", "2", "--out", str(out)]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(out.with_suffix(".json").read_text())
    assert [r["n_designs"] for r in result["rows"]] == [64, 128]
    with open_table(SHIPPED / "table.csv.gz") as fh:
        n = sum(1 for _ in fh) - 1  # every design of the shipped table is read (trust outputs)
    assert result["repeats"] == 2 and result["n_designs_with_results"] == n
    assert result["n_test"] == round(0.15 * n)  # the same fixed test set for every size
    for row in result["rows"]:
        for m in CHECKED:
            runs = row[m]["median_rel_error_repeats"]
            assert len(runs) == 2 and runs[0] != runs[1]  # other subsets, other seeds
            assert row[m]["median_rel_error"] == pytest.approx(sum(runs) / 2)
    text = out.read_text()
    assert "--sizes 64 128 --seed 0 --repeats 2" in text and "| 64 |" in text
    assert (tmp_path / "figures" / "learning_curve.png").stat().st_size > 10_000
