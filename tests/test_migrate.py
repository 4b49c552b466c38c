"""scripts/migrate_sweep.py: a sweep of the previous solver carried over to this one."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from sweep_fixtures import FAST, TINY

import explore.cli
from sim.metrics import SAME_METRICS_AS
from sim.sweep_folder import SweepStore, read_config, write_config

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import migrate_sweep

#: a strict strain limit, so that some of the tiny designs are beyond it (their tapping strains
#: are 0.31-0.49 with the FAST options)
STRICT = ["--set", "validity.max_compressive_log_strain=0.4"]


def _sweep(space: Path, out: Path, *extra: str) -> None:
    argv = ["sweep", space, "--n", "6", "--out", out, "--no-progress", *FAST, *STRICT, *extra]
    assert explore.cli.main([str(a) for a in argv]) == 0


def _as_previous_solver(folder: Path) -> None:
    """Make ``folder`` look like a sweep of the previous solver (no stop option, no
    ``stopped`` column), as runs/sweep_v22 is."""
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
    valid = {k for k, r in before.items() if migrate_sweep.carried(r)}
    assert 0 < len(valid) < len(before), "the sample needs designs on both sides of the limit"
    kept, keys, config = migrate_sweep.migrate(old, new)
    assert len(kept) == len(valid)
    after = SweepStore(new).load()
    assert set(after) == set(kept) <= set(keys)
    for key in kept:
        rec = after[key]
        src = before[rec["migrated"]["key"]]
        assert rec["metrics"] == src["metrics"] and rec["curves"] == src["curves"]
        assert rec["diagnostics"] == {**src["diagnostics"], "stopped": ""}
        assert rec["solver_version"] == SAME_METRICS_AS[0]  # the solver that computed it
    migrate_sweep.verify(new, kept, config, 1, seed=0)  # exits on a difference
    assert "identical" in capsys.readouterr().out
    # the same command as a fresh sweep of this solver resumes it: only the rest is computed
    capsys.readouterr()
    _sweep(space, new)
    final = SweepStore(new).load()
    assert set(final) == set(keys)
    assert all(final[k] == after[k] for k in kept)  # left as they were
    stopped = [r for r in final.values() if r["diagnostics"].get("stopped")]
    assert stopped and all(not r["diagnostics"]["valid"] for r in stopped)
    with pytest.raises(SystemExit, match="exists"):
        migrate_sweep.migrate(old, new)
