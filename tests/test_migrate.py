"""``fingertip migrate-sweep`` (``sim.sweep._migrate``): a sweep of the previous solver carried over
to this one."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from sweep_fixtures import FAST, TINY

import explore.cli
from sim.errors import DesignError
from sim.metrics import METRICS, SAME_METRICS_AS, SOLVER_VERSION, role_strain_names
from sim.sweep import SweepStore, read_config, with_todays_defaults, write_config
from sim.sweep._migrate import carried, largest_difference, migrate

#: a strict strain limit, so that some of the tiny designs are beyond it (their tapping strains
#: are 0.31-0.49 with the FAST options)
STRICT = ["--set", "validity.max_compressive_log_strain=0.4"]


def _sweep(space: Path, out: Path, *extra: str) -> None:
    argv = ["sweep", space, "--n", "6", "--out", out, "--no-progress", *FAST, *STRICT, *extra]
    assert explore.cli.main([str(a) for a in argv]) == 0


def _as_previous_solver(folder: Path) -> None:
    """Make ``folder`` look like a sweep of the previous solver (no stop option, no
    ``stopped`` column), as a sweep of solver 2.2 is."""
    config = read_config(folder)
    config["solver_version"] = SAME_METRICS_AS[0]
    del config["options"]["validity"]["stop_at_violation"]
    write_config(folder, config)
    for path in (folder / "records").glob("*.json"):
        rec = json.loads(path.read_text())
        rec["solver_version"] = SAME_METRICS_AS[0]
        rec.get("diagnostics", {}).pop("stopped", None)
        path.write_text(json.dumps(rec))


@pytest.mark.slow
def test_valid_records_carry_over_and_the_resumed_sweep_computes_the_rest(tmp_path, capsys):
    space = tmp_path / "space.toml"
    space.write_text(TINY)
    old, new = tmp_path / "old", tmp_path / "new"
    _sweep(space, old, "--set", "validity.stop_at_violation=false")  # as the old solver ran
    _as_previous_solver(old)
    before = SweepStore(old).load()
    valid = {k for k, r in before.items() if carried(r)}
    assert 0 < len(valid) < len(before), "the sample needs designs on both sides of the limit"
    capsys.readouterr()
    assert explore.cli.main(["migrate-sweep", str(old), str(new), "--verify", "1"]) == 0
    out = capsys.readouterr().out
    assert f"{len(valid)} of 6 designs carried over to {new}" in out
    assert "metrics, diagnostics and curves identical" in out  # --verify 1: re-simulated
    assert f"resume: fingertip sweep --n 6 --out {new} --seed 0" in out
    after = SweepStore(new).load()
    kept = list(after)
    assert len(kept) == len(valid)
    for key in kept:
        rec = after[key]
        src = before[rec["migrated"]["key"]]
        assert rec["metrics"] == src["metrics"] and rec["curves"] == src["curves"]
        assert rec["diagnostics"] == {**src["diagnostics"], "stopped": ""}
        assert rec["solver_version"] == SAME_METRICS_AS[0]  # the solver that computed it
        assert rec["migrated"]["by"] == "fingertip migrate-sweep"
    # the same command as a fresh sweep of this solver resumes it: only the rest is computed
    capsys.readouterr()
    _sweep(space, new)
    final = SweepStore(new).load()
    with (new / "table.csv").open() as fh:
        keys = [row["key"] for row in csv.DictReader(fh)]  # every design of the sample
    assert len(set(keys)) == 6 and set(final) == set(keys) >= set(kept)
    assert all(final[k] == after[k] for k in kept)  # left as they were
    stopped = [r for r in final.values() if r["diagnostics"].get("stopped")]
    assert stopped and all(not r["diagnostics"]["valid"] for r in stopped)
    with pytest.raises(DesignError, match=r"TARGET: .* exists"):
        migrate(old, new)


def _previous_solver_config(folder: Path, space: Path) -> None:
    """A sweep folder of the previous solver with no records (no FE run)."""
    from sim.design import load_space
    from sim.options import SimOptions
    from sim.sweep import sweep_config

    config = sweep_config(load_space(space), 6, 0, "sobol", SimOptions())
    config["solver_version"] = SAME_METRICS_AS[0]
    del config["options"]["validity"]["stop_at_violation"]
    folder.mkdir()
    write_config(folder, config)


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    space = tmp_path / "space.toml"
    space.write_text(TINY)
    old = tmp_path / "old"
    _previous_solver_config(old, space)
    other = tmp_path / "other"
    other.mkdir()
    (other / "config.json").write_text(json.dumps({"solver_version": "1.3"}))
    (tmp_path / "taken").mkdir()
    for argv, words in (
        ([tmp_path / "none", tmp_path / "new"], "SOURCE: "),
        (
            [other, tmp_path / "new"],
            f"SOURCE: {other} is a sweep of solver 1.3; only one of "
            f"{', '.join(SAME_METRICS_AS)} is carried over to {SOLVER_VERSION}",
        ),
        ([old, tmp_path / "taken"], f"TARGET: {tmp_path / 'taken'} exists"),
        ([old, tmp_path / "new", "--verify", "-1"], "--verify: must be >= 0"),
        (
            [old, tmp_path / "new", "--verify", "1", "--rtol", "0.01"],
            "--rtol: must be in [0, 0.001]",
        ),
        (
            [old, tmp_path / "new", "--verify", "1", "--rtol", "nan"],
            "--rtol: must be in [0, 0.001]",
        ),
        ([old, tmp_path / "new", "--rtol", "1e-6"], "--rtol: applies to --verify K with K >= 1"),
    ):
        assert explore.cli.main(["migrate-sweep", *map(str, argv)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"fingertip: error: {words}"), err
    assert not (tmp_path / "new").exists() and not any((tmp_path / "taken").iterdir())


def test_options_added_since_the_source_take_their_defaults(tmp_path):
    """A source sweep made before an option existed (its config lacks the field, as solver
    2.4's lacks ``newton.contact_update``) is carried over, the new field at its default (which
    reproduces it); the source's own option values are kept."""
    space = tmp_path / "space.toml"
    space.write_text(TINY)
    old = tmp_path / "old"
    _previous_solver_config(old, space)
    config = read_config(old)
    for field in ("contact_update", "contact_update_dofs"):
        del config["options"]["newton"][field]
    write_config(old, config)
    config["options"]["newton"]["rtol"] = 1e-7
    write_config(old, config)
    migrate(old, tmp_path / "new")  # no records: nothing carried, the folder written
    new = read_config(tmp_path / "new")
    assert new["solver_version"] == SOLVER_VERSION
    assert new["options"]["newton"]["rtol"] == 1e-7
    assert new["options"]["newton"]["contact_update"] is False


@pytest.mark.parametrize(("source", "carried_as"), [(0.25, 0.5), (0.3, 0.3)])
def test_an_option_at_a_default_changed_since_takes_todays(tmp_path, source, carried_as):
    """A source made at the old default of an option whose default a carried-over solver
    changed (``newton.reuse_ratio``: 0.25 until 2.12) is carried over to today's default, and
    the resume command sets nothing; a source made at another value keeps it; a config of
    today's solver is never changed."""
    from sim.metrics import DEFAULTS_BEFORE
    from sim.options import SimOptions
    from sim.sweep._migrate import resume_command

    assert DEFAULTS_BEFORE[("newton", "reuse_ratio")] == ("2.12", 0.25)
    assert SimOptions().newton.reuse_ratio == 0.5
    space = tmp_path / "space.toml"
    space.write_text(TINY)
    old = tmp_path / "old"
    _previous_solver_config(old, space)
    config = read_config(old)
    config["solver_version"] = "2.11"  # a carried-over solver from before the default changed
    config["options"]["newton"]["reuse_ratio"] = source
    write_config(old, config)
    *_, new_config = migrate(old, tmp_path / "new")
    assert read_config(tmp_path / "new")["options"]["newton"]["reuse_ratio"] == carried_as
    command = resume_command(tmp_path / "new", new_config)
    assert ("--set newton.reuse_ratio" in command) == (carried_as != 0.5)
    today = {**config, "solver_version": SOLVER_VERSION}
    assert with_todays_defaults(today) == today
    assert with_todays_defaults(config)["options"]["newton"]["reuse_ratio"] == carried_as
    # carried over from its table (--revalidate) alike
    from sim.sweep._revalidate import revalidate

    config["options"]["validity"]["stop_at_violation"] = True
    write_config(old, config)
    (old / "table.csv").write_text("index\n")
    revalidate(old, tmp_path / "from_table")
    got = read_config(tmp_path / "from_table")["options"]["newton"]["reuse_ratio"]
    assert got == carried_as


def test_the_resume_command_names_the_options_the_folder_keeps(tmp_path):
    """An option the folder keeps at another value than today's default (as a 2D sweep keeps
    ``newton.contact_update_dofs = 96`` from before its default became 32) is in the printed
    command as ``--set``; those options applied to the defaults give the folder's options."""
    from sim.options import SimOptions, apply_overrides, options_from_dict
    from sim.sweep._migrate import resume_command

    space = tmp_path / "space.toml"
    space.write_text(TINY)
    old = tmp_path / "old"
    _previous_solver_config(old, space)
    config = read_config(old)
    config["options"]["newton"]["contact_update_dofs"] = 96
    config["options"]["newton"]["rtol"] = 1e-7
    command = resume_command(tmp_path / "new", config)
    assert command.startswith(f"fingertip sweep --n 6 --out {tmp_path / 'new'} --seed 0 ")
    sets = dict(part.split("=") for part in command.split(" --set ")[1:])
    assert sets == {"newton.contact_update_dofs": "96", "newton.rtol": "1e-07"}
    expected = options_from_dict(config["options"])
    assert apply_overrides(SimOptions(), sets) == expected
    # a segment (designs 32 to 63 of the sample) resumes as that segment
    segment = {**config, "start": 32, "n": 64}
    assert resume_command(tmp_path / "s", segment).startswith("fingertip sweep --start 32 --n 64 ")


@pytest.mark.parametrize("source_stopped", [True, False])
def test_designs_beyond_the_limits_carry_over_when_the_source_stopped_there(
    tmp_path, source_stopped
):
    """A design beyond the validity limits is carried when the source's protocols stopped at
    the limits as ours do (the record is what this solver computes), and left to the resumed
    sweep when the source ran past them (this solver stops early: another record). Records
    made by hand (no FE): which ones the migration takes is the question here; that a carried
    record is reproduced is ``--verify``'s (the slow test above)."""
    from sim.design import load_space
    from sim.options import options_from_dict
    from sim.provenance import json_safe
    from sim.sweep import sample_points
    from sim.sweep.run import record_key

    space = tmp_path / "space.toml"
    space.write_text(TINY)
    old = tmp_path / "old"
    _previous_solver_config(old, space)
    config = read_config(old)
    config["options"]["validity"]["stop_at_violation"] = source_stopped
    write_config(old, config)
    options = options_from_dict(config["options"])
    sp = load_space(space)
    store = SweepStore(old)
    expected = set()
    for i, point in enumerate(sample_points(sp, 6, 0, "sobol")):
        valid, status = i % 2 == 0, "failed" if i == 5 else "ok"
        stopped = "tapping: stopped at t = 1 s" if source_stopped and not valid else ""
        rec = {
            "params": json_safe(point),
            "solver_version": SAME_METRICS_AS[0],
            "status": status,
            "metrics": {},
            "diagnostics": {"valid": valid, "stopped": stopped},
            "curves": {},
        }
        key = record_key(point, options, sp.catalogue)
        store.write(key, rec)
        if status == "ok" and (valid or source_stopped):
            expected.add(key)
    kept, _, _ = migrate(old, tmp_path / "new")
    after = SweepStore(tmp_path / "new").load()
    assert {r["migrated"]["key"] for r in after.values()} == expected
    assert len(kept) == len(expected) == (5 if source_stopped else 3)
    for rec in after.values():  # the stop the source recorded is kept
        assert rec["diagnostics"]["stopped"] == ("" if rec["diagnostics"]["valid"] else
                                                 "tapping: stopped at t = 1 s")  # fmt: skip


def test_a_tolerance_compares_metrics_and_validity_not_newtons_path():
    """``--rtol``: a 3D solver that changed Newton's path gives other curves (sub-steps) and
    counts, and metrics within Newton's tolerance; with ``metrics_only`` those metrics are
    compared within it, and a change of validity or settling is never within any tolerance."""
    rec = {
        "status": "ok",
        "metrics": {"disp_at_1N_mm": 0.78, "hysteresis_Nmm": 0.1176, "sag_mm": None},
        "diagnostics": {"valid": True, "settled": True, "stopped": "", "tapping_taps": 13},
        "curves": {"tapping": {"time_s": [0.0, 0.5, 1.0]}},
    }
    moved = {
        "status": "ok",
        "metrics": {"disp_at_1N_mm": 0.78 * (1 + 3e-7), "hysteresis_Nmm": 0.1176, "sag_mm": None},
        "diagnostics": {"valid": True, "settled": True, "stopped": "", "tapping_taps": 12},
        "curves": {"tapping": {"time_s": [0.0, 0.25, 0.5, 1.0]}},  # a cut step
    }
    assert largest_difference(rec, moved)[0] == float("inf")  # the curves' structure
    worst, where = largest_difference(rec, moved, metrics_only=True)
    assert worst == pytest.approx(3e-7, rel=1e-6) and where == "metrics.disp_at_1N_mm"
    for name, value in (("valid", False), ("settled", False), ("stopped", "tapping")):
        flipped = {**moved, "diagnostics": {**moved["diagnostics"], name: value}}
        assert largest_difference(rec, flipped, metrics_only=True) == (
            float("inf"),
            f"diagnostics.{name}",
        )


# ----------------------------------------------------------------------------- --revalidate
#: gel (tested to a log strain of 0.53) and foam (1.05) layers, soft enough that some designs
#: pass the old global limit of 0.60 and some pass the gel's own
LAYERED = """
[geometry]
half_width_mm = { value = 5.84 }
height_mm = { value = 5.48 }
exponent = { value = 1.5 }
[layers]
count = { choice = [1, 2] }
[layers.skin]
thickness_mm = { low = 0.5, high = 1.0 }
material = { choice = ["gel"] }
mu0_MPa = { low = 0.02, high = 0.1, log = true }
alpha = { low = 2.0, high = 3.0 }
g_total = { low = 0.1, high = 0.3 }
tau_s = { low = 0.1, high = 1.0, log = true }
[layers.core]
material = { choice = ["gel", "foam"] }
mu0_MPa = { low = 0.008, high = 0.05, log = true }
alpha = { low = 2.0, high = 3.0 }
nu = { low = 0.1, high = 0.3 }
g_total = { low = 0.1, high = 0.3 }
tau_s = { low = 0.1, high = 1.0, log = true }
"""


def _table_rows(folder: Path) -> dict[str, dict[str, str]]:
    with (folder / "table.csv").open() as fh:
        return {r["index"]: r for r in csv.DictReader(fh)}


def test_revalidating_from_the_table_and_resuming_gives_the_fresh_sweep(tmp_path, capsys):
    """A sweep made under one global strain limit (0.60), carried over from its table alone to
    each layer's own limit and resumed, is the sweep made under the layers' limits from the
    start: every design's status, validity, settling and metrics, and each layer's strain."""
    import shutil
    import subprocess
    import sys

    space = tmp_path / "space.toml"
    space.write_text(LAYERED)
    old, new, fresh = tmp_path / "old", tmp_path / "new", tmp_path / "fresh"
    n = ["--n", "8"]
    common = [*n, "--no-progress", *FAST]
    argv = [
        "sweep",
        space,
        "--out",
        old,
        *common,
        "--set",
        "validity.max_compressive_log_strain=0.6",
    ]
    assert explore.cli.main([str(a) for a in argv]) == 0
    shutil.rmtree(old / "records")  # the shipped surrogate's folder has its table only
    (old / "curves.jsonl").unlink()
    capsys.readouterr()
    assert explore.cli.main(["migrate-sweep", str(old), str(new), "--revalidate"]) == 0
    out = capsys.readouterr().out
    carried = int(out.split(" of 8 designs carried over")[0].rsplit("\n", 1)[-1])
    assert 0 < carried < 8, out  # the sample needs designs on both sides of the rule
    assert "re-run:" in out
    resume = next(line for line in out.splitlines() if line.startswith("resume: "))
    cmd = resume.removeprefix("resume: fingertip ").split()
    assert "--set" not in cmd or "validity.max_compressive_log_strain" not in resume
    args = [sys.executable, "-m", "explore.cli", *cmd[:1], str(space), *cmd[1:], "--no-progress"]
    done = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    assert f"{8 - carried} computed now" in done.stdout
    assert explore.cli.main([str(a) for a in ["sweep", space, "--out", fresh, *common]]) == 0
    a, b = _table_rows(new), _table_rows(fresh)
    assert a.keys() == b.keys() and {r["key"] for r in a.values()} == {r["key"] for r in b.values()}
    judged = ["status", "valid", "settled", "stopped", *METRICS]
    for i in a:
        assert {k: a[i][k] for k in judged} == {k: b[i][k] for k in judged}, i
        stopped = a[i]["stopped"].split(",") if a[i]["stopped"] else []
        for name in role_strain_names():
            if name.split("_")[0] not in stopped:
                assert a[i][name] == b[i][name], (i, name)
            elif a[i][name] != "":  # the strain up to the stop: a carried design stopped at
                assert float(a[i][name]) >= float(b[i][name])  # the old limit, no earlier
    assert {r["valid"] for r in b.values()} == {"True", "False"}
    assert any(r["layers.count"] == "2" and r["valid"] == "True" for r in b.values())
    # a folder made under the layers' own limits, kept as its table alone (as a segment is in
    # git), is rebuilt whole on another machine: every design carried, nothing to compute
    shutil.rmtree(fresh / "records")
    again = tmp_path / "again"
    assert explore.cli.main(["migrate-sweep", str(fresh), str(again), "--revalidate"]) == 0
    assert "8 of 8 designs carried over" in capsys.readouterr().out
    assert _table_rows(again) == b


def test_the_rule_reruns_what_the_layers_own_limits_change():
    """``rerun_reason``: a design is carried when no protocol's course changes under its
    layers' own limits, else re-run (each case of the module's docstring)."""
    from sim.sweep._revalidate import rerun_reason

    def row(**cells: str) -> dict[str, str]:
        base = {"status": "ok", "valid": "True", "stopped": "",
                "tapping_max_compressive_log_strain": "0.4",
                "plate_max_compressive_log_strain": "0.3"}  # fmt: skip
        return {**base, **cells}

    gel, foam, old = [0.5276], [1.0498], 0.6
    assert rerun_reason(row(), gel, old) is None  # within every limit, ran to its end
    assert "beyond a layer's own" in rerun_reason(
        row(tapping_max_compressive_log_strain="0.55"), gel, old
    )
    stopped = row(valid="False", stopped="tapping", tapping_max_compressive_log_strain="0.61")
    assert rerun_reason(stopped, gel, old) is None  # the gel's own limit stops it no later
    assert "may go further" in rerun_reason(stopped, foam, old)
    assert "several layers" in rerun_reason(row(), [0.5276, 1.0498], old)
    layered_invalid = {**stopped}
    assert rerun_reason(layered_invalid, [0.5276, 0.5276], old) is None
    assert rerun_reason(row(status="failed"), foam, old) is None  # within 0.60 up to the failure
    assert "failed" in rerun_reason(row(status="failed"), gel, old)
    # stopped by another limit (J) within the old strain limit: carried when within the own
    by_j = row(valid="False", stopped="plate", plate_max_compressive_log_strain="0.45")
    assert rerun_reason(by_j, gel, old) is None
    assert rerun_reason({**by_j, "plate_max_compressive_log_strain": "0.58"}, gel, old)
