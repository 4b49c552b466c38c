"""For docs/fe_speed.md: where the FE time of default-space designs goes (protocols, taps and
phases), in counts.

    python studies/fe_time_study.py --n 12 --seed 1
    python studies/fe_time_study.py --sweep FOLDER
    python studies/fe_time_study.py --breakdown --n 64 --seed 0
    python studies/fe_time_study.py --breakdown --n 32 --seed 0 --set newton.reuse_ratio=0.5 ...

Simulates ``n`` designs of the default space (a scrambled Sobol sample,
``sim.sweep.run.sample_points``) with every protocol and prints, summed over the designs:

- the steps, LDL^T factorisations and residual evaluations of the plate, the wedge and the
  tapping, the tapping split by tap (the first, the second, the later ones) and phase (plate
  in contact, rest) from its ``cost`` log, and the factorisations per step of each. Counts,
  not seconds: they do not depend on the machine's load;
- how many of those factorisations came after the protocol's first step beyond the default
  validity limits (``sim.protocols.validity.check`` after every recorded step): the work a protocol
  stopped at its first violation would not do (its metrics are untrusted from there on);
- the solver's own timings (``timings_s``) per factorisation and per evaluation, and the wall
  time per design: seconds, meaningful on a quiet machine only.

``--breakdown`` instead simulates the designs as the sweep does (``SimOptions()``: a protocol
stops at its first violation; ``--seed 0`` gives the first designs of the default sweep, those
of ``benchmarks/bench_sweep.py``) and splits the mean wall time per design into the solver's
timed parts (factorisation, triangular solves, tangent assembly, residual + material law) and
the rest (Python's Newton loop, contact, recording, metrics, and any protocol that failed:
the solver's figures of a failed protocol are not returned), with the counts per design. The
factorisations and solves alone are a floor for any faster assembly or law on this mesh:
seconds, so on a quiet machine only. ``--set`` changes an option as ``fingertip --set`` does (for
example the 2D model with the 3D model's modified Newton: docs/fe_speed.md, "Modified Newton in
2D?").

``--sweep FOLDER`` instead reads a sweep's ``table.csv`` and prints the share of its FE wall
time spent on designs beyond the validity limits (as recorded), by protocol.
"""

from __future__ import annotations

import argparse
import csv
import time
from collections import defaultdict
from pathlib import Path

import sim.protocols.validity as validity
from sim import SimOptions, simulate
from sim.design import load_space, point_to_design
from sim.errors import DesignError
from sim.fe import Wedge
from sim.options import apply_overrides, parse_override
from sim.sweep import open_table, sample_points, table_path

COUNTS = ("steps", "factorizations", "evaluations")


def tap_group(tap: int) -> str:
    """The first tap has no earlier tap to start Newton from; the second starts from the
    first (before the periodic-state jump); the later ones from a tap near their own."""
    return {1: "tap 1", 2: "tap 2"}.get(tap, "taps 3+")


def watch_violations() -> None:
    """Make every ``DeformationTracker`` note the body's factorisation count at the first
    recorded step beyond the default limits (``first_violation``). The wedge is judged
    without the strain limit, as ``sim.protocols.validity`` does by default; tapping and the plate
    with."""
    limits = validity.ValidityOptions()
    observe = validity.DeformationTracker.observe

    def observe_and_check(self, body) -> None:
        observe(self, body)
        if getattr(self, "first_violation", None) is None:
            protocol = "wedge" if isinstance(body.indenter, Wedge) else "plate"
            if validity.check(self.summary(), limits, protocol):
                self.first_violation = body.factorizations

    validity.DeformationTracker.observe = observe_and_check


def study(n: int, seed: int) -> None:
    from sim.protocols.loading import _Recorder

    watch_violations()
    info = _Recorder.info
    _Recorder.info = lambda self: {
        **info(self),
        "first_violation": getattr(self.tracker, "first_violation", None),
    }
    rows: dict[str, dict[str, int]] = defaultdict(lambda: dict.fromkeys(COUNTS, 0))
    after = defaultdict(int)  # factorisations after the first violation, per protocol
    body_total = 0  # every factorisation, the periodic-state jumps' included
    seconds = defaultdict(float)
    wall, taps = 0.0, 0
    for i, point in enumerate(sample_points(load_space(), n, seed)):
        t0 = time.perf_counter()
        # to the end: the study counts what a stop at the first violation saves
        res = simulate(point_to_design(point), options=SimOptions().without_validity_stop())
        wall += time.perf_counter() - t0
        for name, fig in res.protocols.items():
            body_total += fig.get("factorizations", 0)
            for key, s in fig.get("timings_s", {}).items():
                seconds[key] += s
            first = fig.get("first_violation")
            if first is not None:
                after[name] += fig["factorizations"] - first
            if name != "tapping":
                for c in COUNTS:
                    rows[name][c] += fig.get(c, 0) or 0
        tapping = res.protocols.get("tapping", {})
        taps += tapping.get("taps", 0)
        for entry in tapping.get("cost", []):
            key = f"tapping, {tap_group(entry['tap'])}, {entry['phase']}"
            for c in COUNTS:
                rows[key][c] += entry[c]
        # what no tap's phase counts: re-equilibrating after each periodic-state jump
        jumps = rows["tapping, periodic-state jumps"]
        for c in ("factorizations", "evaluations"):
            jumps[c] += tapping.get(c, 0) - sum(e[c] for e in tapping.get("cost", []))
        print(f"design {i}: {time.perf_counter() - t0:.1f} s, {tapping.get('taps')} taps")
    total = sum(r["factorizations"] for r in rows.values())
    evaluations = sum(r["evaluations"] for r in rows.values())
    print(f"\n{n} designs (seed {seed}), {taps} taps in all")
    print("| part | steps | factorisations | share | per step | evaluations |")
    print("|---|---|---|---|---|---|")
    for key in sorted(rows):
        r = rows[key]
        per = r["factorizations"] / r["steps"] if r["steps"] else float("nan")
        print(
            f"| {key} | {r['steps']} | {r['factorizations']} | "
            f"{100 * r['factorizations'] / max(total, 1):.0f} % | {per:.2f} | {r['evaluations']} |"
        )
    print(f"| all | | {total} | 100 % | | {evaluations} |")
    gone = sum(after.values())
    print(
        f"\nafter a protocol's first validity violation: {gone} of {body_total} factorisations "
        f"({100 * gone / max(body_total, 1):.0f} %); "
        + ", ".join(f"{name} {after[name]}" for name in sorted(after))
    )
    print(
        f"\nseconds (load-dependent): {1e3 * seconds['LDL^T factorisation'] / total:.1f} ms a "
        f"factorisation, {1e3 * seconds['tangent assembly'] / total:.1f} ms a tangent, "
        f"{1e3 * seconds['residual+material'] / evaluations:.1f} ms an evaluation; "
        f"{wall / n:.1f} s per design"
    )


def breakdown(n: int, seed: int, options: SimOptions | None = None) -> None:
    from sim.fe.solver import TIMED

    options = SimOptions() if options is None else options
    seconds = dict.fromkeys(TIMED, 0.0)
    counts = dict.fromkeys(("factorizations", "evaluations", "newton_iterations"), 0)
    wall = 0.0
    for i, point in enumerate(sample_points(load_space(), n, seed)):
        t0 = time.perf_counter()
        res = simulate(point_to_design(point), options=options)
        dt = time.perf_counter() - t0
        wall += dt
        for fig in res.protocols.values():
            for key in seconds:
                seconds[key] += fig.get("timings_s", {}).get(key, 0.0)
            for key in counts:
                counts[key] += fig.get(key, 0) or 0
        made = sum(f.get("factorizations", 0) or 0 for f in res.protocols.values())
        print(f"design {i}: {dt:.2f} s, {made} factorisations")
    other = wall - sum(seconds.values())
    changed = "default options" if options == SimOptions() else "options changed by --set"
    print(f"\n{n} designs (seed {seed}), {changed} (stop at the first violation)")
    print("per design: " + ", ".join(f"{v / n:.0f} {k}" for k, v in counts.items()))
    print("| part | s per design | share | per call |")
    print("|---|---|---|---|")
    calls = {
        "LDL^T factorisation": counts["factorizations"],
        "tangent assembly": counts["factorizations"],
        "residual+material": counts["evaluations"],
    }
    for key, s in seconds.items():
        per = f"{1e3 * s / calls[key]:.2f} ms" if calls.get(key) else "-"
        print(f"| {key} | {s / n:.3f} | {100 * s / wall:.0f} % | {per} |")
    print(f"| the rest | {other / n:.3f} | {100 * other / wall:.0f} % | - |")
    print(f"| wall | {wall / n:.3f} | 100 % | - |")
    floor = (seconds["LDL^T factorisation"] + seconds["triangular solves"]) / n
    print(f"\nfactorisations and solves alone: {floor:.2f} s per design (a floor at these counts)")


def sweep_shares(folder: Path) -> None:
    with open_table(table_path(folder)) as fh:
        rows = [r for r in csv.DictReader(fh) if r["status"] == "ok"]
    wall = [float(r["wall_time_s"]) for r in rows]
    total = sum(wall)
    groups = {
        "valid": lambda r: r["valid"] == "True",
        "invalid": lambda r: r["valid"] != "True",
        **{
            f"invalid in {p}": (lambda r, p=p: f"({p})" in r["violations"])
            for p in ("tapping", "plate", "wedge")
        },
    }
    print(f"{folder}: {len(rows)} designs simulated, {total:.0f} s of FE wall time")
    for name, keep in groups.items():
        picked = [w for w, r in zip(wall, rows, strict=True) if keep(r)]
        print(f"{name}: {len(picked)} designs, {100 * sum(picked) / total:.0f} % of the time")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sweep", type=Path, help="a sweep folder: time shares by validity")
    ap.add_argument("--breakdown", action="store_true", help="seconds per part, as swept")
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        help="with --breakdown: a simulation option changed, as fingertip's --set",
    )
    args = ap.parse_args()
    if args.breakdown:
        try:
            options = apply_overrides(SimOptions(), dict(parse_override(t) for t in args.set))
        except DesignError as exc:
            ap.error(str(exc))
        breakdown(args.n, args.seed, options)
    elif args.sweep is not None:
        sweep_shares(args.sweep)
    else:
        study(args.n, args.seed)


if __name__ == "__main__":
    main()
