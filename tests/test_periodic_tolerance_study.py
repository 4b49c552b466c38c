"""``studies/periodic_tolerance.py``: one run with the stopping rule off gives the tap at which
``run_tapping`` stops, as the study claims."""

from __future__ import annotations

import importlib
from pathlib import Path

import sim

ROOT = Path(__file__).resolve().parents[1]


def test_the_study_stops_where_run_tapping_stops(monkeypatch) -> None:
    """Design 5 of the default 3D space (its 2D section: a relaxing pad that settles in four
    taps): the study's stopping tap at the default tolerance is the tap count of a default
    tapping run, and a looser tolerance stops no later."""
    monkeypatch.syspath_prepend(str(ROOT / "studies"))
    study = importlib.import_module("periodic_tolerance")
    log = study.tap_log(5, "2d", 6)
    assert len(log) == 6
    opts = sim.SimOptions().tapping
    stop = study.stopping_tap(log, opts.settle_tol, opts.min_taps)
    design = study.default3d_design(5)
    run = sim.simulate(design, ("tapping",), sim.SimOptions())
    assert stop == run.protocols["tapping"]["taps"]
    assert study.stopping_tap(log, 10 * opts.settle_tol, opts.min_taps) <= stop
