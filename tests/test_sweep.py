"""Design spaces and sweeps: sampling, inactive parameters, resume after kill -9, Dask."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sweep_fixtures import FAST, TINY

from sim.design import load_space, param_material, space_from_dict
from sim.errors import DesignError
from sim.metrics import SAME_METRICS_AS, SOLVER_VERSION
from sim.simulate import SimOptions
from sim.sweep import record_key, run_sweep, sample_points


@pytest.fixture
def tiny_space(tmp_path):
    path = tmp_path / "space.toml"
    path.write_text(TINY)
    return path


def _cli(*args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "explore.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=900,
        **kw,
    )


def _table(folder: Path) -> list[dict]:
    with (folder / "table.csv").open() as fh:
        return list(csv.DictReader(fh))


# ----------------------------------------------------------------------------- spaces
def test_default_space_loads_and_samples_valid_designs():
    space = load_space()
    points = sample_points(space, 64, seed=1)
    counts = {p["layers.count"] for p in points}
    assert counts == {1, 2}
    for p in points:
        space.design(p)  # every sampled point is a valid design
        roles = {1: {"core"}, 2: {"skin", "core"}}[p["layers.count"]]
        for role in ("skin", "core"):
            mat = p[f"{role}.material"]
            assert (mat != "") == (role in roles)  # inactive layers are recorded as such
            mu = p[f"{role}.mu0_MPa"]
            assert (not math.isnan(mu)) == (role in roles and mat in ("gel", "foam"))
            nu = p.get(f"{role}.nu", math.nan)
            assert (not math.isnan(nu)) == (role in roles and mat == "foam")  # a gel's is fixed


def test_wide_space_adds_a_middle_layer():
    space = load_space(Path(__file__).resolve().parents[1] / "sim" / "data" / "wide_space.toml")
    points = sample_points(space, 64, seed=1)
    assert {p["layers.count"] for p in points} == {1, 2, 3}
    for p in points:
        design = space.design(p)
        assert len(design.materials) == p["layers.count"]
        assert (p["middle.material"] != "") == (p["layers.count"] == 3)


def test_sobol_samples_nest_and_are_reproducible():
    space = load_space()
    a = sample_points(space, 16, seed=3)
    b = sample_points(space, 40, seed=3)
    c = sample_points(space, 16, seed=4)
    opts = SimOptions()
    assert [record_key(p, opts) for p in a] == [record_key(p, opts) for p in b[:16]]
    assert [record_key(p, opts) for p in a] != [record_key(p, opts) for p in c]


def test_log_bounds_cover_decades_evenly():
    space = load_space()
    mus = [p["core.mu0_MPa"] for p in sample_points(space, 256, seed=0)]
    mus = np.log10([m for m in mus if not math.isnan(m)])
    lo, hi = math.log10(space["core.mu0_MPa"].low), math.log10(space["core.mu0_MPa"].high)
    assert mus.min() >= lo and mus.max() <= hi
    # each decade gets its share: below 0.025 MPa is half the log range (a linear draw would
    # put ~6 % there)
    assert np.mean(mus < math.log10(0.025)) > 0.4


def test_param_material_is_valid_and_documented():
    m = param_material(0.01, 3.0, 0.47, 0.6, 0.3)
    assert m.moduli == "long_term"
    assert m.instantaneous.initial_shear_modulus_MPa == pytest.approx(0.01 / 0.4)
    np.testing.assert_allclose(m.prony.tau_s, [0.1, 0.3, 0.9])
    assert param_material(0.01, 3.0, 0.47, 0.0, 0.3).is_elastic


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda d: d["geometry"].update(height_mm={"low": 6, "high": 5}), "geometry.height_mm"),
        (
            lambda d: d["layers"]["core"].update(mu0_MPa={"low": 0, "high": 1, "log": True}),
            "core.mu0_MPa",
        ),
        (lambda d: d["layers"]["core"].update(g_total={"low": 0.5, "high": 1.0}), "core.g_total"),
        (lambda d: d["layers"]["core"].update(material={"choice": ["nope"]}), "core.material"),
        (lambda d: d["layers"].update(count={"choice": [1, 4]}), "layers.count"),
        (
            lambda d: d["layers"]["skin"].update(thickness_mm={"low": 1, "high": 6}),
            "layers.thickness_mm",
        ),
        (lambda d: d["layers"].pop("skin"), "layers.skin"),
        (lambda d: d["layers"]["core"].update(colour={"value": 1}), "core.colour"),
        (lambda d: d["layers"]["core"].update(alpha=3.0), "core.alpha"),
        (lambda d: d.update(extra={}), "extra"),
    ],
)
def test_invalid_spaces_name_the_field(mutate, field):
    import tomllib

    data = tomllib.loads(TINY)
    mutate(data)
    with pytest.raises(DesignError) as exc:
        space_from_dict(data)
    assert exc.value.field == field


def test_space_round_trips():
    space = load_space()
    assert space_from_dict(space.to_dict()) == space


def test_the_3d_space_is_the_default_space_with_the_pads_length_and_profile():
    """``default_space_3d.toml`` extends the default space: the same section and layers, plus
    c and m within their argued ranges (docs/fingertip_3d.md); its designs carry their pad,
    the inverse map recovers the point, and its dict form needs no ``extends`` to be read back."""
    from sim.design import DEFAULT_SPACE_3D_PATH, point_from_design
    from sim.geometry import PadGeometry

    space2, space3 = load_space(), load_space(DEFAULT_SPACE_3D_PATH)
    pad_names = ["geometry.half_length_mm", "geometry.length_exponent"]
    assert [n for n in space3.names if n not in pad_names] == space2.names
    assert all(space3[n] == space2[n] for n in space2.names)
    assert (space3[pad_names[0]].low, space3[pad_names[0]].high) == (8.0, 14.0)
    assert (space3[pad_names[1]].low, space3[pad_names[1]].high) == (2.0, 8.0)
    points = sample_points(space3, 32, seed=1)
    for point in points:
        design = space3.design(point)
        assert design.pad == PadGeometry(design.geometry, point[pad_names[0]], point[pad_names[1]])
        back = point_from_design(design, space3)
        assert all(back[n] == point[n] for n in pad_names)
    cs = [p[pad_names[0]] for p in points]
    assert min(cs) < 9.0 and max(cs) > 13.0  # the sample spans the range
    assert space_from_dict(space3.to_dict()) == space3
    # the 2D space leaves every design's pad unstated (so 2D record keys are unchanged)
    design2 = space2.design(sample_points(space2, 1, seed=1)[0])
    assert design2.half_length_mm is None and design2.length_exponent is None


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('extends = "nowhere.toml"', "extends"),
        ('extends = "default_space.toml"\n[geometry]\nhalf_length_mm = { low = 0.5, high = 9 }',
         "geometry.half_length_mm"),
        ('extends = "default_space.toml"\n[geometry]\nlength_exponent = { value = 9.0 }',
         "geometry.length_exponent"),
        ('extends = "default_space.toml"\n[geometry]\nlength_mm = { value = 9.0 }',
         "geometry.length_mm"),
    ],
)  # fmt: skip
def test_a_bad_3d_space_names_the_field(tmp_path, text, field):
    import shutil

    from sim.design import DEFAULT_SPACE_PATH

    shutil.copy(DEFAULT_SPACE_PATH, tmp_path / "default_space.toml")
    path = tmp_path / "space.toml"
    path.write_text(text + "\n")
    with pytest.raises(DesignError) as exc:
        load_space(path)
    assert exc.value.field == field


def test_cli_invalid_space_is_one_line_exit_2(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY.replace("low = 0.3, high = 1.0", "low = 1.0, high = 0.3"))
    p = _cli("sweep", bad, "--n", 2, "--out", tmp_path / "s")
    assert p.returncode == 2
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "skin.thickness_mm" in lines[0] and "Traceback" not in p.stderr


# ----------------------------------------------------------------------------- sweeps
def test_sweep_records_table_and_resume(tiny_space, tmp_path):
    out = tmp_path / "sweep"
    p = _cli("sweep", tiny_space, "--n", 3, "--out", out, "--no-progress", *FAST)
    assert p.returncode == 0, p.stderr
    assert "3 ok, 0 failed" in p.stdout
    rows = _table(out)
    assert len(rows) == 3 and all(r["status"] == "ok" for r in rows)
    assert all(float(r["plate_force_at_1mm_N"]) > 0 for r in rows)
    one_layer = [r for r in rows if r["layers.count"] == "1"]
    assert all(r["skin.material"] == "" and r["skin.thickness_mm"] == "" for r in one_layer)
    config = json.loads((out / "config.json").read_text())
    meta = json.loads((out / "meta.json").read_text())
    assert config["n"] == 3 and config["seed"] == 0 and "git_commit" in meta and "packages" in meta
    assert len((out / "curves.jsonl").read_text().splitlines()) == 3
    # every FE result says whether its taps reached the periodic state and whether it is valid
    for r in rows:
        assert r["settled"] in ("True", "False") and r["valid"] in ("True", "False")
        assert 1 <= int(r["tapping_taps"]) <= 3 and float(r["tapping_residual"]) >= 0
        assert float(r["tapping_max_compressive_log_strain"]) > 0 and 0 < float(r["plate_min_J"])
    record = json.loads(next((out / "records").glob("*.json")).read_text())
    assert {"settled", "valid", "violations", "tapping_residual"} <= set(record["diagnostics"])
    # each layer's largest strain by role: the outer one is the skin, the inner the core, and
    # the design's largest strain is the largest of its layers'
    for r in rows:
        for p in ("tapping", "plate", "wedge"):
            skin, core = (r[f"{p}_{role}_max_compressive_log_strain"] for role in ("skin", "core"))
            layers = [float(x) for x in (skin, core) if x != ""]
            assert (skin == "") == (r["layers.count"] == "1") and core != ""
            assert max(layers) == pytest.approx(float(r[f"{p}_max_compressive_log_strain"]))
            assert r[f"{p}_middle_max_compressive_log_strain"] == ""
    assert {r["layers.count"] for r in rows} == {"1", "2"}
    # the same command again computes nothing; a larger n computes only the new designs
    again = _cli("sweep", tiny_space, "--n", 3, "--out", out, "--no-progress", *FAST)
    assert "0 computed now" in again.stdout
    more = _cli("sweep", tiny_space, "--n", 5, "--out", out, "--no-progress", *FAST)
    assert "2 computed now" in more.stdout and len(_table(out)) == 5
    # a different seed in the same folder is refused
    other = _cli("sweep", tiny_space, "--n", 5, "--out", out, "--seed", 7, *FAST)
    assert other.returncode == 2 and "seed" in other.stderr


def test_failed_designs_are_recorded_and_retried(tiny_space, tmp_path):
    out = tmp_path / "fail"
    broken = ["--set", "newton.max_iterations=1"]
    p = _cli("sweep", tiny_space, "--n", 2, "--out", out, "--no-progress", *FAST, *broken)
    assert p.returncode == 0 and "0 ok, 2 failed" in p.stdout
    rows = _table(out)
    assert all(r["status"] == "failed" and "convergence" in r["reason"] for r in rows)
    # the options are part of the record key: retrying needs the same options
    retry = _cli("sweep", tiny_space, "--n", 2, "--out", out, "--retry-failed", "--no-progress",
                 *FAST, *broken)  # fmt: skip
    assert "2 computed now" in retry.stdout


def test_an_internal_error_in_one_design_is_recorded_not_raised(monkeypatch):
    """One design hitting a bug must not stop a sweep of thousands (it once did: a TypeError
    from the solver killed the process pool); the record names the error."""
    import sim.sweep.run

    def bug(*args, **kwargs):
        raise TypeError("cannot unpack non-iterable NoneType object")

    monkeypatch.setattr(sim.sweep.run, "simulate", bug)
    point = sample_points(load_space(), 1, 0)[0]
    record = sim.sweep.run.evaluate_point(point, dataclasses.asdict(SimOptions()))
    assert record["status"] == "failed"
    assert record["reason"] == (
        "internal error TypeError: cannot unpack non-iterable NoneType object"
    )


def test_a_record_counts_its_cpu_seconds_apart_from_its_wall_time(monkeypatch):
    """The CPU seconds of a design are not inflated by a paused process (``kill -STOP``) or
    by other jobs on the core: a simulation that sleeps 0.3 s of its wall time uses none of
    it."""
    import sim.sweep.run

    def sleepy(*args, **kwargs):
        time.sleep(0.3)
        raise ValueError("stop")

    monkeypatch.setattr(sim.sweep.run, "simulate", sleepy)
    point = sample_points(load_space(), 1, 0)[0]
    record = sim.sweep.run.evaluate_point(point, dataclasses.asdict(SimOptions()))
    assert record["wall_time_s"] >= 0.3
    assert 0.0 <= record["cpu_time_s"] < 0.2


def test_sweep_survives_kill_9_without_losing_or_repeating_work(tiny_space, tmp_path):
    out = tmp_path / "killed"
    args = [sys.executable, "-m", "explore.cli", "sweep", str(tiny_space), "--n", "6",
            "--out", str(out), "--no-progress", *FAST]  # fmt: skip
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    records = out / "records"
    deadline = time.time() + 300
    while time.time() < deadline:
        if records.exists() and len(list(records.glob("*.json"))) >= 2:
            break
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    before = {p.name: p.stat().st_mtime_ns for p in records.glob("*.json")}
    assert 2 <= len(before) < 6
    for path in records.glob("*.json"):
        json.loads(path.read_text())  # no half-written record
    p = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert f"{6 - len(before)} computed now" in p.stdout
    after = {p.name: p.stat().st_mtime_ns for p in records.glob("*.json")}
    assert len(after) == 6
    assert all(after[name] == t for name, t in before.items())  # nothing computed twice
    assert sorted(int(r["index"]) for r in _table(out)) == list(range(6))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sweep_on_a_real_dask_cluster(tiny_space, tmp_path):
    pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    bindir = Path(sys.executable).parent
    dask = str(bindir / "dask") if (bindir / "dask").exists() else "dask"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    sched = subprocess.Popen(
        [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
    )  # fmt: skip
    worker = None
    try:
        worker = subprocess.Popen(
            [dask, "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
        )  # fmt: skip
        from dask.distributed import Client

        deadline = time.time() + 60
        while time.time() < deadline:
            try:
                with Client(address, timeout="2s") as c:
                    if c.scheduler_info()["workers"]:
                        break
            except OSError:
                pass
            time.sleep(0.5)
        else:
            pytest.fail("the Dask cluster did not come up")
        out = tmp_path / "dask"
        p = _cli("sweep", tiny_space, "--n", 2, "--out", out, "--scheduler", address,
                 "--no-progress", *FAST)  # fmt: skip
        assert p.returncode == 0, p.stderr
        assert "2 ok, 0 failed" in p.stdout
        local = tmp_path / "local"
        _cli("sweep", tiny_space, "--n", 2, "--out", local, "--no-progress", *FAST)
        a, b = _table(out), _table(local)
        assert [r["key"] for r in a] == [r["key"] for r in b]
        for ra, rb in zip(a, b, strict=True):  # the cluster computes exactly what we compute
            assert float(ra["hysteresis_Nmm"]) == pytest.approx(
                float(rb["hysteresis_Nmm"]), rel=1e-9
            )
    finally:
        for proc in (worker, sched):
            if proc is not None:
                proc.terminate()
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()


def test_run_sweep_api_in_process(tiny_space, tmp_path):
    from sim.design import load_space as load

    seen = []
    summary = run_sweep(
        load(tiny_space),
        2,
        tmp_path / "api",
        options=SimOptions(),
        progress=False,
        on_record=lambda k, r: seen.append((k, r["status"])),
    )
    assert summary.ok == 2 and summary.computed == 2 and len(seen) == 2


@pytest.mark.slow
def test_default_space_brackets_every_human_value():
    """FE runs of a few points of the shipped space land below and above each human target."""
    from sim.design import load_targets
    from sim.sweep._bracket import bracket

    _, results = bracket()
    for name, target in load_targets().values.items():
        vals = [r[name] for r in results.values()]
        assert min(vals) < target < max(vals), (name, vals)


# ----------------------------------------------------------------------------- segments
def _fake_fe(point, options_dict, materials=None):
    """A record without FE: metrics that are functions of the point (same point, same bits)."""
    from sim.metrics import METRICS
    from sim.provenance import json_safe

    h = float(point["core.mu0_MPa"]) * 10 + float(point["core.alpha"])
    metrics = {m: h + k for k, m in enumerate(METRICS)}
    return {"params": json_safe(point), "status": "ok", "reason": "", "metrics": metrics,
            "diagnostics": {}, "curves": {}, "wall_time_s": 0.0}  # fmt: skip


def test_segments_of_a_sample_merge_into_the_whole_sweep(tiny_space, tmp_path, monkeypatch):
    """``run_sweep(start=)`` runs the sample's designs start..n-1 only, indexed by their position
    in the sample; ``merge_sweeps`` of segments [0, 3) and [3, 6) gives the very table of one
    sweep of 6, which ``read_sweep`` reads; overlapping segments, segments of another seed, a
    start out of range or with another sampler, and resuming a merged folder are refused with
    the field named."""
    import sim.sweep.run as sweep_mod
    from sim.sweep import merge_sweeps
    from surrogate._io import read_sweep

    monkeypatch.setattr(sweep_mod, "evaluate_point", _fake_fe)
    space = load_space(tiny_space)
    kw = {"workers": 1, "progress": False}
    run_sweep(space, 6, tmp_path / "whole", **kw)
    run_sweep(space, 3, tmp_path / "a", **kw)
    seg = run_sweep(space, 6, tmp_path / "b", start=3, **kw)
    assert seg.n_designs == 3 and seg.computed == 3
    assert [r["index"] for r in _table(tmp_path / "b")] == ["3", "4", "5"]
    assert json.loads((tmp_path / "b" / "config.json").read_text())["start"] == 3
    assert "start" not in json.loads((tmp_path / "a" / "config.json").read_text())
    rows, n = merge_sweeps([tmp_path / "b", tmp_path / "a"], tmp_path / "ab")
    assert (rows, n) == (6, 2)
    assert _table(tmp_path / "ab") == _table(tmp_path / "whole")
    config = json.loads((tmp_path / "ab" / "config.json").read_text())
    assert config["n"] == 6 and "start" not in config and len(config["segments"]) == 2
    data = read_sweep(tmp_path / "ab", trusted_only=False)
    assert sorted(int(i) for i in data.index) == list(range(6))
    # refusals, each naming its field
    run_sweep(space, 4, tmp_path / "a4", **kw)
    with pytest.raises(DesignError, match="more than one table"):
        merge_sweeps([tmp_path / "a", tmp_path / "a4"], tmp_path / "x")
    assert not (tmp_path / "x").exists()
    run_sweep(space, 6, tmp_path / "s7", start=3, seed=7, **kw)
    with pytest.raises(DesignError, match="another --seed"):
        merge_sweeps([tmp_path / "a", tmp_path / "s7"], tmp_path / "y")
    with pytest.raises(DesignError, match=r"--start.*\[0, 5\]"):
        run_sweep(space, 6, tmp_path / "z", start=6, **kw)
    with pytest.raises(DesignError, match=r"--start.*sobol"):
        run_sweep(space, 6, tmp_path / "z", start=3, sampler="lhs", **kw)
    with pytest.raises(DesignError, match="merge of sweep folders"):
        run_sweep(space, 6, tmp_path / "ab", **kw)
    # a segment of an earlier solver whose metrics are this one's joins; of another, not
    config_a = json.loads((tmp_path / "a" / "config.json").read_text())
    for version, joins in ((SAME_METRICS_AS[0], True), ("0.9", False)):
        (tmp_path / "a" / "config.json").write_text(
            json.dumps({**config_a, "solver_version": version})
        )
        out = tmp_path / f"mixed_{version}"
        if joins:
            merge_sweeps([tmp_path / "a", tmp_path / "b"], out)
            config = json.loads((out / "config.json").read_text())
            assert config["solver_version"] == SOLVER_VERSION
            assert config["solver_versions"] == sorted([version, SOLVER_VERSION])
            assert _table(out) == _table(tmp_path / "whole")
        else:
            with pytest.raises(DesignError, match="another solver version"):
                merge_sweeps([tmp_path / "a", tmp_path / "b"], out)
    (tmp_path / "a" / "config.json").write_text(json.dumps(config_a))
    with pytest.raises(DesignError, match="another --start"):
        run_sweep(space, 6, tmp_path / "b", start=2, **kw)


def test_a_gzipped_table_reads_hashes_and_merges_as_the_plain_one(
    tiny_space, tmp_path, monkeypatch
):
    """A sweep folder whose table is ``table.csv.gz`` (the shipped surrogate's: git keeps files
    under 5 MB) is the same sweep: the same hash (of the CSV bytes), the same ``read_sweep`` and
    ``read_points``, the same merge; the gzip bytes do not depend on when they were written; a
    damaged one is refused naming the file."""
    import shutil

    import sim.sweep.run as sweep_mod
    from sim.provenance import sha256_file
    from sim.sweep import merge_sweeps, table_path, table_sha256, write_table_gz
    from surrogate._io import read_points, read_sweep

    monkeypatch.setattr(sweep_mod, "evaluate_point", _fake_fe)
    space = load_space(tiny_space)
    kw = {"workers": 1, "progress": False}
    run_sweep(space, 6, tmp_path / "whole", **kw)
    run_sweep(space, 3, tmp_path / "a", **kw)
    run_sweep(space, 6, tmp_path / "b", start=3, **kw)
    for name in ("whole", "a"):
        src, gz = tmp_path / name, tmp_path / f"{name}_gz"
        gz.mkdir()
        shutil.copy(src / "config.json", gz / "config.json")
        write_table_gz(src / "table.csv", gz / "table.csv.gz")
        assert table_path(gz) == gz / "table.csv.gz" and table_path(src) == src / "table.csv"
    plain, gz = tmp_path / "whole" / "table.csv", tmp_path / "whole_gz" / "table.csv.gz"
    assert table_sha256(gz) == table_sha256(plain) == sha256_file(plain)
    first = gz.read_bytes()
    time.sleep(1.1)  # a gzip header's time stamp counts seconds
    write_table_gz(plain, gz)
    assert gz.read_bytes() == first
    a, b = read_sweep(tmp_path / "whole", False), read_sweep(tmp_path / "whole_gz", False)
    assert a.points == b.points and a.table_sha256 == b.table_sha256
    np.testing.assert_array_equal(a.targets, b.targets)
    assert read_points(gz, space) == read_points(plain, space)
    merge_sweeps([tmp_path / "a_gz", tmp_path / "b"], tmp_path / "ab")
    assert _table(tmp_path / "ab") == _table(tmp_path / "whole")
    gz.write_bytes(first[: len(first) // 2])  # a copy cut short
    with pytest.raises(DesignError, match=r"damaged gzip file .*table\.csv\.gz"):
        read_sweep(tmp_path / "whole_gz")
    with pytest.raises(DesignError, match=r"damaged gzip file .*table\.csv\.gz"):
        read_points(gz, space)
    with pytest.raises(DesignError, match="SWEEPS"):
        merge_sweeps([tmp_path / "whole_gz", tmp_path / "b"], tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_cli_sweep_start_out_of_range_is_one_line(tiny_space, tmp_path):
    p = _cli("sweep", tiny_space, "--n", 3, "--start", 3, "--out", tmp_path / "s")
    assert p.returncode == 2 and "--start" in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and not (tmp_path / "s").exists()


def test_cli_merge_sweeps_joins_segments_and_refuses_bad_input_in_one_line(
    tiny_space, tmp_path, monkeypatch, capsys
):
    """``fingertip merge-sweeps`` (``sim.sweep.run.merge_sweeps``): segments [0, 3) and [3, 6) of
    one sample give the table of one sweep of 6; one folder, an existing --out, a folder that is
    no sweep or segments of other seeds are one line naming the field, and write nothing."""
    import sim.sweep.run as sweep_mod
    from explore.cli import main

    monkeypatch.setattr(sweep_mod, "evaluate_point", _fake_fe)
    space = load_space(tiny_space)
    kw = {"workers": 1, "progress": False}
    run_sweep(space, 6, tmp_path / "whole", **kw)
    run_sweep(space, 3, tmp_path / "a", **kw)
    run_sweep(space, 6, tmp_path / "b", start=3, **kw)
    run_sweep(space, 6, tmp_path / "s7", start=3, seed=7, **kw)
    capsys.readouterr()
    ab = tmp_path / "ab"
    assert main(["merge-sweeps", str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(ab)]) == 0
    assert capsys.readouterr().out == f"{ab}: 6 designs from 2 sweep folders\n"
    assert _table(ab) == _table(tmp_path / "whole")
    (tmp_path / "empty").mkdir()
    for argv, words in (
        ([tmp_path / "a", "--out", tmp_path / "x"], "SWEEPS: give at least two sweep folders"),
        ([tmp_path / "a", tmp_path / "b", "--out", ab], f"--out: {ab} exists"),
        ([tmp_path / "a", tmp_path / "empty", "--out", tmp_path / "x"], "SWEEPS: "),
        ([tmp_path / "a", tmp_path / "s7", "--out", tmp_path / "x"], "another --seed"),
    ):
        assert main(["merge-sweeps", *map(str, argv)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("fingertip: error: ") and words in err[0], err
    assert not (tmp_path / "x").exists() and not any((tmp_path / "empty").iterdir())


def test_a_record_without_the_layers_strains_by_role_gets_them_from_its_lists(tmp_path):
    """Records made before the table had each layer's strain by role (solver 2.3 to 2.8 keep
    the per-layer lists, outermost first) get the columns when the table is rebuilt; a record
    without the lists (older) gets empty cells, which a surrogate does not learn from."""
    from sim.sweep import SweepStore

    store = SweepStore(tmp_path)
    names = ["layers.count"]
    lists = {
        "tapping_max_compressive_log_strain": 0.8,
        "tapping_max_compressive_log_strain_by_layer": [0.8, 0.3],
        "plate_max_compressive_log_strain_by_layer": [0.2, 0.5],
    }
    store.write("a", {"params": {"layers.count": 2}, "status": "ok", "diagnostics": lists})
    old = {"tapping_max_compressive_log_strain": 0.4}
    store.write("b", {"params": {"layers.count": 1}, "status": "ok", "diagnostics": old})
    store.consolidate(["a", "b"], names)
    a, b = _table(tmp_path)
    assert a["tapping_skin_max_compressive_log_strain"] == "0.8"
    assert a["tapping_core_max_compressive_log_strain"] == "0.3"
    assert a["plate_skin_max_compressive_log_strain"] == "0.2"
    assert a["plate_core_max_compressive_log_strain"] == "0.5"
    assert a["wedge_core_max_compressive_log_strain"] == ""
    assert b["tapping_core_max_compressive_log_strain"] == ""
    assert b["tapping_max_compressive_log_strain"] == "0.4"
