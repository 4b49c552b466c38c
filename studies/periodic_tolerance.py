"""The periodic state's tolerance against its floor: when would looser tolerances stop, and how
far from the periodic state are the metrics there?

    python studies/periodic_tolerance.py [--designs 0 1 2 3 4 5 6 7] [--model 2d] [--taps 40]

Each design of the default 3D space (its 2D section with ``--model 2d``, the default: the same
periodic machinery at a hundredth of the 3D cost) is tapped ``--taps`` times with the stopping
rule switched off (``residual_tol`` and ``settle_tol`` 1e-9, no early stop of a stalling
design), logging after every tap the residual of the periodic Prony state, the largest
estimated relative error of a tapping metric (``sim.protocols.periodic``) and the metrics.
Taps do not depend on the tolerance (it only decides when to stop), so one run gives every
tolerance's stopping tap: the first tap from ``min_taps`` on whose residual and estimated
errors are within it, as ``run_tapping`` stops.

The reference is the mean of the last ``--floor`` taps' metrics; the **floor** is their
largest relative spread (max - min over mean) over the tapping metrics: how far the iteration
gets at all, with Newton's tolerance in every step. The true error at a stopping tap is the
largest relative distance of its metrics from the reference; against a floor of the same size
it is not resolved.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the FE runs (before numpy)
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import dataclasses
import importlib

import numpy as np
from paired import FOLDER, default3d_design
from same_metrics import sweep_options

from sim.options import SimOptions
from sim.protocols import periodic

#: the default of both tolerances (``TappingOptions.residual_tol``, ``settle_tol``) and two
#: looser ones, up to the size of the time-step study's 0.5 % (docs/simulation.md, "The
#: periodic state of the taps")
TOLERANCES = (1e-3, 3e-3, 1e-2)


def tap_log(index: int, model: str, taps: int) -> list[tuple[float, float, np.ndarray]]:
    """(residual, largest estimated relative error, metrics) after each tap of design
    ``index``, tapped ``taps`` times with the stopping rule off (``[]`` for an elastic pad)."""
    base = sweep_options(FOLDER) if model == "3d" else SimOptions()
    tapping = dataclasses.replace(
        base.tapping, residual_tol=1e-9, settle_tol=1e-9, max_taps=taps, stall_window=0
    )
    options = dataclasses.replace(base, tapping=tapping)
    log: list[tuple[float, float, np.ndarray]] = []
    original = periodic.PeriodicState.after_tap

    def after_tap(self, H_start, H_peak, metrics):
        status = original(self, H_start, H_peak, metrics)
        m = np.asarray(metrics, dtype=float)
        log.append((status.residual, float(np.nanmax(status.relative_error(m))), m.copy()))
        return status

    periodic.PeriodicState.after_tap = after_tap
    try:
        importlib.import_module("sim.simulate").simulate(
            default3d_design(index), ("tapping",), options
        )
    finally:
        periodic.PeriodicState.after_tap = original
    return log


def stopping_tap(log, tol: float, min_taps: int) -> int | None:
    """The 1-based tap at which ``run_tapping`` would stop with both tolerances ``tol``."""
    for k, (residual, error, _) in enumerate(log, start=1):
        if k >= min_taps and residual <= tol and error <= tol:
            return k
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, nargs="+", default=list(range(8)))
    ap.add_argument("--model", choices=["2d", "3d"], default="2d")
    ap.add_argument("--taps", type=int, default=40, help="taps of each run")
    ap.add_argument("--floor", type=int, default=10, help="last taps that make the reference")
    args = ap.parse_args()
    min_taps = SimOptions().tapping.min_taps
    head = " | ".join(f"tol {t:g}: tap, true error" for t in TOLERANCES)
    print(f"design | taps run | floor | {head}")
    for index in args.designs:
        log = tap_log(index, args.model, args.taps)
        if not log:
            print(f"{index} | elastic: one tap")
            continue
        last = np.array([m for _, _, m in log[-args.floor :]])
        ref = last.mean(axis=0)
        scale = np.maximum(np.abs(ref), 1e-12)
        with np.errstate(invalid="ignore"):
            floor = float(np.nanmax((last.max(axis=0) - last.min(axis=0)) / scale))
        cells = []
        for tol in TOLERANCES:
            k = stopping_tap(log, tol, min_taps)
            if k is None:
                cells.append("not reached")
                continue
            with np.errstate(invalid="ignore"):
                true = float(np.nanmax(np.abs(log[k - 1][2] - ref) / scale))
            cells.append(f"{k}, {true:.1e}")
        print(f"{index} | {len(log)} | {floor:.1e} | " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
