"""``studies/stall_rule3d.py``: its jobs are the protocols that failed in the 3D dataset and the
main job's four failed confirmations, and each job runs with the rule it names."""

from __future__ import annotations

import csv
import importlib
from pathlib import Path

import pytest

import sim
from sim.design import load_design

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def study(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "studies"))
    return importlib.import_module("stall_rule3d")


def test_the_jobs_are_the_datasets_failed_protocols_and_the_four_designs(study) -> None:
    failed = {}
    for table in (ROOT / "datasets" / "default3d").glob("seg_*/table.csv"):
        with open(table) as f:
            rows = [r for r in csv.DictReader(f) if r["status"] != "ok"]
        failed |= {int(r["index"]): r["reason"] for r in rows}
    jobs = study.jobs_for(["failed"])
    assert {int(j.split()[0]) for j in jobs} == set(failed)
    for job in jobs:  # each protocol its reason names, once
        index, protocol = job.split()
        assert f"{protocol} at t = " in failed[int(index)]
    assert len(jobs) == sum(r.count(" at t = ") for r in failed.values())
    main = study.jobs_for(["main"])
    assert len(main) == 4 and all(j.endswith(".toml tapping") for j in main)
    for job in main:  # two-layer pads the 3D model accepts
        assert len(load_design(job.rsplit(" ", 1)[0]).layers) == 2
    assert study.jobs_for(["3"]) == ["3 tapping", "3 plate", "3 wedge"]


def test_a_job_runs_with_the_rule_it_names(study, monkeypatch) -> None:
    """The rule reaches the simulation as ``newton.stall_rule_3d`` (checked on the options
    ``simulate`` receives, without running it)."""
    seen = []

    def fake_simulate(design, protocols, options):
        seen.append((protocols, options.newton.stall_rule_3d, options.dimension))
        raise RuntimeError("stop")

    monkeypatch.setattr(importlib.import_module("sim.simulate"), "simulate", fake_simulate)
    for rule in ("halving", "stagnation"):
        with pytest.raises(RuntimeError, match="stop"):
            study.run("5 plate", rule)
    assert seen == [(("plate",), "halving", "3d"), (("plate",), "stagnation", "3d")]
    assert sim.SimOptions().newton.stall_rule_3d == "stagnation"
