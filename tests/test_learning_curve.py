"""``fingertip learning-curve`` (``surrogate._learning_curve``): the power-law extrapolation, a
tiny curve on the first designs of the shipped table, one-line errors, and a small run on the
whole shipped table."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from sweep_fixtures import SHIPPED, shipped_table_lines

from explore.cli import main
from sim.sweep import open_table
from surrogate._learning_curve import CHECKED, extrapolate

ROOT = Path(__file__).resolve().parents[1]


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


@pytest.fixture
def small_sweep(tmp_path: Path) -> Path:
    """The first 120 designs of the shipped training table, as a sweep folder."""
    folder = tmp_path / "sweep"
    folder.mkdir()
    (folder / "config.json").write_text((SHIPPED / "config.json").read_text())
    (folder / "table.csv").write_text("".join(shipped_table_lines(121)))
    return folder


def test_a_tiny_curve_writes_its_page_json_and_figure(small_sweep: Path, tmp_path: Path, capsys):
    """Two sizes x two repeats of one-member ensembles (3 epochs) on 120 designs: one fixed test
    set, every repeat kept, the command in the page's first line, the figure beside it."""
    out = tmp_path / "pages" / "curve.md"
    argv = ["learning-curve", str(small_sweep), "--sizes", "16", "8", "--repeats", "2",
            "--members", "1", "--max-epochs", "3", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "n =     8" in printed and "n =    16" in printed and "written: " in printed
    result = json.loads(out.with_suffix(".json").read_text())
    assert [r["n_designs"] for r in result["rows"]] == [8, 16]
    assert result["n_designs_with_results"] == 120 and result["n_test"] == 18
    assert (result["repeats"], result["members"], result["max_epochs"]) == (2, 1, 3)
    for row in result["rows"]:
        runs = row["disp_at_1N_mm"]["median_rel_error_repeats"]
        assert len(runs) == 2 and runs[0] != runs[1]  # other subsets, other seeds
    assert set(result["extrapolation"]["hysteresis_Nmm"]) == {"median_rel_error",
                                                               "p95_rel_error", "r2"}  # fmt: skip
    text = out.read_text()
    command = (f"`fingertip learning-curve {small_sweep.as_posix()} --sizes 8 16 --seed 0 "
               f"--repeats 2 --members 1 --max-epochs 3 --out {out.as_posix()}`")  # fmt: skip
    assert command in text and "| 8 |" in text and "1-member ensembles" in text
    assert "![learning curve](figures/curve.png)" in text
    assert (out.parent / "figures" / "curve.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    ("extra", "field"),
    [
        (["--sizes", "3"], "--sizes"),
        (["--repeats", "0"], "--repeats"),
        (["--jobs", "0"], "--jobs"),
        (["--members", "0"], "--members"),
        (["--max-epochs", "0"], "--max-epochs"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_bad_options_are_one_line_before_any_work(small_sweep, tmp_path, capsys, extra, field):
    out = tmp_path / "curve.md"
    assert main(["learning-curve", str(small_sweep), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"fingertip: error: {field}"), err
    assert not out.exists() and not (tmp_path / "figures").exists()


def test_no_sweep_and_no_markdown_file_are_one_line(tmp_path: Path) -> None:
    for argv, words in (
        ([str(tmp_path / "nothing"), "--out", str(tmp_path / "c.md")], "SWEEP: no such sweep"),
        ([str(tmp_path), "--out", str(tmp_path / "curve.txt")], "--out: a Markdown file (.md)"),
    ):
        cmd = [sys.executable, "-m", "explore.cli", "learning-curve", *argv]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
        assert proc.returncode == 2 and proc.stdout == "", proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("fingertip: error: ") and words in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.slow
def test_small_curve_on_the_shipped_dataset(tmp_path):
    """Two sizes x two repeats on the shipped table, two trainings at once: one fixed test set,
    nested subsets, every repeat kept, and the Markdown, JSON and PNG written."""
    out = tmp_path / "lc.md"
    cmd = [sys.executable, "-m", "explore.cli", "learning-curve", str(SHIPPED), "--sizes", "128",
           "64", "--repeats", "2", "--jobs", "2", "--out", str(out)]  # fmt: skip
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
    assert (tmp_path / "figures" / "lc.png").stat().st_size > 10_000
