"""Smoke tests of the benchmarks in ``benchmarks/``: each runs on its smallest problem and its
printout is checked for content and physics, never for time (the speed figures are read from a
benchmark's printout on a quiet machine)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def load_benchmark(name: str):
    """``benchmarks/<name>.py`` as a module (the folder is not a package)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while it loads
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


F_INF = (0.0273, 0.0931, 0.3657)


def _synthetic_runs(module) -> list[dict]:
    """Runs of both codes whose forces follow known curves F = F_inf + C h^p (h = 1 / refine):
    ours from above at rate 2, FElupe from below at rate 1.5, both towards the same limits;
    seconds grow as the dofs, FElupe's ten times ours on the same mesh."""
    rows = []
    for code, c, p, cost in (("ours", 0.004, 2.0, 1.0), ("FElupe", -0.006, 1.5, 10.0)):
        for refine in (0.5, 0.7, 1.0, 1.41, 2.0):
            h = 1.0 / refine
            rows.append(
                {
                    "code": code,
                    "mesh": f"x{refine:g}",
                    "refine": refine,
                    "force_quarter_N": [f * (1 + c * h**p) for f in F_INF],
                    "whole_median_s": None if refine > 1.5 else cost * 40 * refine**3,
                }
            )
    return rows


def test_felupe_accuracy_fits_limits_and_matches_runs_of_equal_accuracy():
    """``bench_felupe_accuracy``: the fit recovers a known limit and rate (exactly through three
    meshes, by least squares through more), refuses values that no such curve passes through,
    and the speed-up at equal accuracy takes the cheapest run of ours whose error is at most
    FElupe's."""
    module = load_benchmark("bench_felupe_accuracy")
    h = np.array([2.0, 1.0, 0.5, 0.25])
    f = 0.36 + 0.01 * h**1.7
    for n in (3, 4):
        f_inf, c, p = module.fit_limit(h[-n:], f[-n:])
        assert f_inf == pytest.approx(0.36, rel=1e-9) and p == pytest.approx(1.7, rel=1e-7)
        assert c == pytest.approx(0.01, rel=1e-6)
    with pytest.raises(ValueError, match="not monotone"):
        module.fit_limit(h[:3], np.array([1.0, 1.1, 1.0]))
    with pytest.raises(ValueError, match="three meshes"):
        module.fit_limit(h[:2], f[:2])

    rows = _synthetic_runs(module)
    lim = module.limits(rows)
    # the reference: the mean of the finest meshes (x2), ours 0.1 % above the limit and FElupe
    # 0.21 % below
    shift = 0.5 * (0.004 * 0.5**2 - 0.006 * 0.5**1.5)
    assert lim.reference_N == pytest.approx([f * (1 + shift) for f in F_INF], rel=1e-12)
    assert lim.uncertainty == pytest.approx([0.5 * (0.001 + 0.006 * 0.5**1.5) / (1 + shift)] * 3)
    assert lim.finest == {"ours": "x2", "FElupe": "x2"}
    # the fits of the three finest meshes recover the curves: the check beside the reference
    assert lim.rate["ours"] == pytest.approx((2.0,) * 3)
    assert lim.rate["FElupe"] == pytest.approx((1.5,) * 3)
    assert lim.f_inf_N["FElupe"] == pytest.approx(F_INF, rel=1e-8)
    bumpy = [dict(r, force_quarter_N=[1.0, 2.0, 3.0]) if r["mesh"] == "x1.41" else r for r in rows]
    assert module.limits(bumpy).rate["ours"] == (None, None, None)
    # against it ours' error at 1 mm is 0.46 % at x1 and 0.87 % at x0.7, FElupe's 0.54 % at x1:
    # ours x1 matches it
    match = {(m.measure, m.felupe_mesh): m for m in module.equal_accuracy(rows, lim)}
    m = match[("at 1 mm", "x1")]
    assert m.ours_mesh == "x1" and m.felupe_error == pytest.approx(0.00544, abs=1e-5)
    assert m.speedup == pytest.approx(10.0)
    m = match[("at 1 mm", "x0.5")]  # FElupe 1.64 %: ours x0.5 (1.66 %) is not enough
    assert m.ours_mesh == "x0.7" and m.ours_error == pytest.approx(0.00873, abs=1e-5)
    # interpolated on ours' line: error 0.4 % h^2 against seconds 40 / h^3, so the seconds at
    # an error e are 40 (e / 0.4 %)^(-3/2), here at FElupe x1's 0.544 % shifted by the reference
    m = match[("at 1 mm", "x1")]
    assert m.ours_interpolated_s < m.ours_s and m.interpolated_speedup > m.speedup
    line = [(40.0 / h**3, 0.004 * h**2) for h in (2.0, 1.0, 0.5)]
    assert module.interpolated_seconds(line, 0.002) == pytest.approx(40 * 0.5**-1.5)
    assert module.interpolated_seconds(line, 0.1) is None  # beyond the line: not extrapolated
    # the cheapest run is already as accurate: no interpolation (the conservative match holds)
    assert module.interpolated_seconds([(1.0, 0.01), (2.0, 0.02), (3.0, 0.001)], 0.015) is None
    # it comes down to the error first between the second and the third run
    assert module.interpolated_seconds([(1.0, 0.03), (2.0, 0.02), (4.0, 0.01)], 0.015) < 4.0
    info = module.work_precision_info(rows, lim)
    assert [p[2] for p in info.points["at 1 mm"]["FElupe"]] == ["x0.5", "x0.7", "x1", "x1.41"]
    assert info.uncertainty["at 1 mm"] == lim.uncertainty[2]
    # a second series of ours (another element), ten times as accurate at the same cost: the
    # reference is still ours' and FElupe's finest, and it is matched on its own
    q2p1 = [
        dict(
            r,
            code="ours q2p1",
            force_quarter_N=[f * (1 + 0.0004 / r["refine"] ** 2) for f in F_INF],
        )
        for r in rows
        if r["code"] == "ours"
    ]
    assert module.series(rows + q2p1) == ("FElupe", "ours", "ours q2p1")
    assert module.limits(rows + q2p1).reference_N == lim.reference_N
    by = {
        (m.ours_code, m.measure, m.felupe_mesh): m for m in module.equal_accuracy(rows + q2p1, lim)
    }
    assert by[("ours", "at 1 mm", "x1")].ours_mesh == "x1"
    assert by[("ours q2p1", "at 1 mm", "x1")].ours_mesh == "x0.5"  # 0.22 % against FElupe's 0.54 %
    # no run of ours as accurate: ours' finest timed run is less accurate than FElupe's
    worse = [
        dict(r, force_quarter_N=[f * 1.05 for f in r["force_quarter_N"]])
        if r["code"] == "ours"
        else r
        for r in rows
    ]
    assert all(m.ours_mesh is None for m in module.equal_accuracy(worse, lim))


def test_felupe_accuracy_resumes_and_names_bad_meshes(tmp_path, monkeypatch, capsys):
    """Runs already in the JSON are not run again (a rerun resumes); a mesh outside the ladder
    is one error naming the allowed forms."""
    module = load_benchmark("bench_felupe_accuracy")
    out = tmp_path / "runs.json"
    rows = [
        dict(r, dofs=1, newton_iterations=1, factorizations=1, load_average_before=0.0)
        for r in _synthetic_runs(module)
    ]
    for r in rows:
        if r["whole_median_s"] is None:
            r["untimed_wall_s"] = 1.0
    out.write_text(json.dumps({"runs": rows}))

    def refuse(*args, **kwargs):
        raise AssertionError("a saved run was run again")

    monkeypatch.setattr(module.bf, "run_child", refuse)
    monkeypatch.setattr(module.bf, "measure", refuse)
    argv = ["--json", str(out), "--ours", "x0.5", "x2", "--felupe", "x1", "x2"]
    doc = module.main([*argv, "--figure", str(tmp_path / "wp.png")])
    text = capsys.readouterr().out
    assert "10.0x faster at equal accuracy" in text and (tmp_path / "wp.png").stat().st_size > 0
    finest = [r["force_quarter_N"] for r in rows if r["mesh"] == "x2"]
    assert doc["limits"]["reference_N"] == pytest.approx(np.mean(finest, axis=0), rel=1e-12)
    assert json.loads(out.read_text())["command"].endswith("--figure " + str(tmp_path / "wp.png"))
    with pytest.raises(SystemExit):
        module.main(["--json", str(out), "--ours", "x9"])
    assert "xF with F in [0.25, 4], got 'x9'" in capsys.readouterr().err
    assert module.bf.mesh_options("x1") == module.bf.mesh_options("default")
