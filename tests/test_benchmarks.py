"""Smoke tests of the benchmarks in ``benchmarks/``: each runs on its smallest problem and its
printout is checked for content and physics, never for time (the speed figures are read from a
benchmark's printout on a quiet machine)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def load_benchmark(name: str):
    """``benchmarks/<name>.py`` as a module (the folder is not a package)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bench_felupe_prints_both_codes_with_agreeing_forces(monkeypatch, capsys):
    """``bench_felupe.py --mesh tiny --repeats 1``: ours and FElupe each in a fresh process.
    FElupe's 27-node hexahedra (the same discretisation) agree with ours to ~1e-3 (the contact
    penalties): within 5 %; its Q1/P0 hexahedra, an independent discretisation, differ on the
    76-element mesh by their discretisation errors (about -10, -6, -4 % at 0.25, 0.5, 1 mm;
    under 1 % on the default mesh, ``tests/test_fe3d_felupe.py``): within 15 %."""
    pytest.importorskip("felupe")
    bench = "bench_felupe"
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        monkeypatch.setenv(var, "1")  # the module pins them on import: restored afterwards
    module = load_benchmark(bench)
    argv = ["--mesh", "tiny", "--repeats", "1", "--warmup", "0"]
    rows = module.main([*argv, "--formulation", "q1p0", "q2-displacement"])
    out = capsys.readouterr().out
    table = [line for line in out.splitlines() if line.startswith("| ours |")]
    assert len(table) == 2, out  # the times and the counts
    assert "| FElupe | q1p0 | tiny |" in out and "| FElupe | q2-displacement | tiny |" in out
    assert "speed-up of ours against FElupe q1p0" in out
    ours, q1p0, q2 = rows
    assert ours["code"] == "ours" and ours["dofs"] == q1p0["dofs"] == q2["dofs"]
    f = [r["force_quarter_N"] for r in rows]
    assert all(len(x) == len(module.DEPTHS) for x in f)
    assert f[0][1] > 0.05  # a real indentation: 0.096 N on the quarter at 0.5 mm
    for theirs, bound in ((f[2], 0.05), (f[1], 0.15)):
        rel = [b / a - 1.0 for a, b in zip(f[0], theirs, strict=True)]
        assert max(abs(r) for r in rel) < bound, rel
