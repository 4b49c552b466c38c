"""Runs of one protocol on default-space 3D designs in two variants at once, in two processes,
so that both share whatever else the machine is doing (``wedge_precision.py``,
``tap_factors.py``, ``wedge_steps.py``, ``retry_precision.py``), with the counts these studies
print: the step attempts that failed (``count_failed``), each pair's lines
(``print_pair``) and each variant's totals (``Totals``)."""

from __future__ import annotations

import importlib
import math
import resource
import time
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from same_metrics import sweep_options

from sim.design import Design, load_design, point_to_design
from sim.options import apply_overrides
from sim.sweep import read_config, sample_points
from sim.sweep.run import load_space_config

FOLDER = Path(__file__).resolve().parents[1] / "datasets" / "default3d" / "seg_0-31"


def default3d_design(design_index: int) -> Design:
    """Design ``design_index`` of the default 3D space's sample (its dataset's space, seed and
    sampler)."""
    config, space = read_config(FOLDER), load_space_config(FOLDER)
    points = sample_points(space, design_index + 1, config["seed"], config["sampler"])
    return point_to_design(points[design_index])


def simulate_design(
    design_index: int | str, protocol: str, overrides: Mapping[str, str] | None = None
) -> dict:
    """Design ``design_index`` of the default 3D space, or the design file of that path, run
    with the default 3D dataset's options (``overrides`` as ``--set`` gives them) through
    ``protocol`` with ``sim`` as it is now: its figures, metrics, seconds and the process's
    peak resident memory."""
    simulate_module = importlib.import_module("sim.simulate")
    if isinstance(design_index, str) and not design_index.isdigit():
        design = load_design(design_index)
    else:
        design = default3d_design(int(design_index))
    options = apply_overrides(sweep_options(FOLDER), dict(overrides or {}))
    t0 = time.perf_counter()
    res = simulate_module.simulate(design, (protocol,), options)
    return {
        "ok": res.ok,
        "figures": res.protocols.get(protocol, {}),
        "metrics": res.metrics,
        "seconds": time.perf_counter() - t0,
        "max_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def in_pairs(
    run: Callable[[int, str], dict], designs: list[int], variants: tuple[str, str]
) -> Iterator[tuple[int, dict[str, dict]]]:
    """``run(design, variant)`` for both variants of each design at once (a fresh process for
    each run: a variant may set module constants); yields each design and its two runs."""
    with ProcessPoolExecutor(2, max_tasks_per_child=1) as pool:
        for d in designs:
            runs = pool.map(run, [d, d], variants)
            yield d, dict(zip(variants, runs, strict=True))


def largest_change(new: dict, old: dict) -> float:
    """The largest relative change of a metric both have a number for (nan: none)."""
    return max(
        (
            abs(new[m] - v) / max(abs(v), 1e-12)
            for m, v in old.items()
            if isinstance(v, float) and isinstance(new.get(m), float) and math.isfinite(v)
        ),
        default=float("nan"),
    )


def count_failed(method: str = "advance") -> dict[str, int]:
    """Count, in this process from now on, the calls of ``Body.<method>`` that did not converge
    and the factorisations they made: ``advance``, a step after any retry of it; ``_advance``,
    every attempt. Returns the live counts ``{"attempts": ..., "factorizations": ...}``."""
    body_class = importlib.import_module("sim.fe.solver").Body
    failed = {"attempts": 0, "factorizations": 0}
    original = getattr(body_class, method)

    def counted(self, *args, **kwargs):
        before = self.factorizations
        res = original(self, *args, **kwargs)
        if not res.converged:
            failed["attempts"] += 1
            failed["factorizations"] += self.factorizations - before
        return res

    setattr(body_class, method, counted)
    return failed


class Totals:
    """Seconds and factorisations of each variant, summed over a study's runs."""

    def __init__(self, variants: tuple[str, ...]) -> None:
        self.sums = {v: {"seconds": 0.0, "factorizations": 0} for v in variants}

    def add(self, variant: str, run: dict) -> None:
        """Add a run of ``simulate_design`` (its ``seconds`` and figures)."""
        self.sums[variant]["seconds"] += run["seconds"]
        self.sums[variant]["factorizations"] += run["figures"].get("factorizations") or 0

    def print(self) -> None:
        for variant, t in self.sums.items():
            print(f"{variant}: {t['factorizations']} factorisations, {t['seconds']:.1f} s in all")


def print_pair(
    label: str,
    runs: dict[str, dict],
    describe: Callable[[dict], str],
    totals: Totals,
    what: str = "metric",
) -> None:
    """Print ``label, variant: describe(run)`` for each run of a pair (``in_pairs``), add them
    to ``totals``, then the largest relative change of a ``what`` from the second variant's
    metrics to the first's."""
    first, second = runs
    for variant, run in runs.items():
        totals.add(variant, run)
        print(f"{label}, {variant}: {describe(run)}", flush=True)
    change = largest_change(runs[first]["metrics"], runs[second]["metrics"])
    print(f"{label}: largest relative change of a {what} {change:.1e}", flush=True)


def describe(run: dict) -> str:
    """One run's outcome and counts (``simulate_design`` with ``count_failed``'s ``failed``)."""
    fig, failed = run["figures"], run["failed"]
    return (
        f"ok {run['ok']}, failed attempts {failed['attempts']} "
        f"({failed['factorizations']} factorisations), factorisations "
        f"{fig.get('factorizations')}, Newton iterations {fig.get('newton_iterations')}, "
        f"steps {fig.get('steps')}, {run['seconds']:.1f} s"
    )
