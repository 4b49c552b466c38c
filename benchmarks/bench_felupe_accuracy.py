"""Benchmark: ours against FElupe at EQUAL ACCURACY on the 3D elastic plate (work and precision).

    python benchmarks/bench_felupe_accuracy.py --json docs/felupe_accuracy.json
        [--ours x0.5 x0.7 x1 x1.41 x2] [--felupe x0.5 x0.7 x1 x1.5] [--repeats 3]
        [--ours-element q2p1] [--time-up-to 110000] [--also OTHER.json ...]
        [--figure docs/figures/felupe_accuracy.png]

``benchmarks/bench_felupe.py`` compares the two codes on the same nodes. But the issue's target
is the speed-up at equal accuracy, and the two discretisations err differently (ours: 27-node
hexahedra, pure displacement, a curved surface; FElupe's mean-dilatation Q1/P0 on the same
nodes: trilinear, faceted, mixed), so the same nodes are not the same accuracy. This script
measures both codes on a ladder of meshes ``MeshOptions3D().refined(F)`` (``xF``: every size
divided by F), each run a fresh process as in ``bench_felupe.py`` (whole process, one thread,
after an untimed warm-up run of each code), and then:

1. **The reference forces.** At each recorded depth (0.25, 0.5, 1 mm) the mean of the two
   codes' finest meshes, with half their difference as its uncertainty (printed): two codes
   that share nothing but the nodes and converge from either side bracket the limit. As a
   check, each code's F(h) = F_inf + C h^p, h = 1/F, fitted to its three finest meshes
   (``fit_limit``) where such a curve passes through them; near the contact's edge the forces
   need not converge monotonically (the edge jumps from node to node), and then no rate is
   claimed.
2. **Each run's error**: |F / F_ref - 1| at each depth, and the largest over the three depths
   (the force-indentation curve to that accuracy).
3. **The speed-up at equal accuracy** (``equal_accuracy``): for each timed FElupe run, the
   cheapest timed run of ours whose error is at most FElupe's, by each measure (at 1 mm; the
   largest over the depths), and the ratio of their whole-process medians: conservative, ours
   on a mesh at least as accurate. Beside it, ours' seconds interpolated to FElupe's error
   on ours' work-precision line (log seconds linear in log error between the two runs of
   ours that bracket it, ``interpolated_seconds``), where two neighbouring runs do.

``--ours-element q2p1`` runs ours' ladder with the locking-free Q2/P1 element
(``sim.fe._mixed``) as the series "ours q2p1", beside the pure-displacement "ours" (q2): the
reference stays the mean of "ours" and FElupe's finest meshes, and each series of ours is
matched against FElupe.

Meshes above ``--time-up-to`` dofs are run once, untimed (the reference's finest meshes: ours
``x2`` took about an hour, FElupe's ``x1.5`` 25 minutes, beside each other); their seconds are
printed but take no part in a speed-up. Each run is saved in ``--json`` as it ends; a rerun
with the same file skips the runs already there (resume), and ``--also`` adds runs saved in
other files (the untimed finest meshes can run at the same time, one file each). Seconds mean
something only on a QUIET machine: the printout gives the load average before each run; the
forces and counts do not depend on the load. ``--figure`` draws error against whole-process
seconds, both codes, both measures (the info object ``work_precision_info`` and its renderer
``render``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_felupe as bf  # the sibling benchmark: its children and meshes

#: the two codes whose finest meshes make the reference
CODES = ("ours", "FElupe")
#: ours' series by element (``bench_felupe.OUR_FORMULATIONS``): the pure-displacement "ours"
#: keeps the name it had before the element was an option
OUR_SERIES = {"q2": "ours", "q2p1": "ours q2p1"}
MEASURES = ("at 1 mm", "largest over the depths")


def run_key(code: str, mesh: str) -> str:
    return f"{code} {mesh}"


def fit_limit(h: np.ndarray, f: np.ndarray) -> tuple[float, float, float]:
    """(F_inf, C, p) of F(h) = F_inf + C h^p through the points (h, f): exact through three,
    least squares through more (``scipy.optimize.curve_fit``, p within [0.3, 8]). Raises
    ``ValueError`` when fewer than three points are given or when three are not monotone in h
    (no such curve passes through them)."""
    from scipy.optimize import brentq, curve_fit

    h, f = np.asarray(h, float), np.asarray(f, float)
    order = np.argsort(h)
    h, f = h[order], f[order]
    if len(h) < 3:
        raise ValueError("a limit needs at least three meshes")
    d1, d2 = f[1] - f[0], f[2] - f[1]
    if d1 * d2 <= 0.0:
        raise ValueError("the finest three values are not monotone in h: no rate to fit")

    def ratio(p: float) -> float:  # (f2 - f1) / (f1 - f0) on the curve minus the data's
        return (h[2] ** p - h[1] ** p) / (h[1] ** p - h[0] ** p) - d2 / d1

    # rates of a force under h-refinement lie between ~0.5 (a contact edge, volumetric locking:
    # docs/model_3d.md's plate force at rate 0.5) and 2 (p + 1) = 6 (Q2's superconvergent
    # energy-like quantities); [0.3, 8] encloses both without admitting a flat or a jump
    lo, hi = 0.3, 8.0
    if ratio(lo) * ratio(hi) > 0.0:
        raise ValueError("no rate within [0.3, 8] passes through the finest three values")
    p = brentq(ratio, lo, hi, xtol=1e-12)
    c = d1 / (h[1] ** p - h[0] ** p)
    f_inf = f[0] - c * h[0] ** p
    if len(h) == 3:
        return float(f_inf), float(c), float(p)
    (f_inf, c, p), _ = curve_fit(
        lambda x, a, b, q: a + b * x**q,
        h,
        f,
        p0=(f_inf, c, p),
        bounds=([-np.inf, -np.inf, lo], [np.inf, np.inf, hi]),
    )
    return float(f_inf), float(c), float(p)


@dataclass(frozen=True)
class Limits:
    """Per depth: the reference force (N, quarter pad) and its uncertainty (relative), and as a
    check each code's extrapolated force and fitted rate (None where no curve F_inf + C h^p
    with p in [0.3, 8] passes through its finest three values: not monotone, or converging
    more slowly than such a curve, i.e. not yet in its asymptotic range)."""

    depths_mm: tuple[float, ...]
    finest: dict[str, str]
    reference_N: tuple[float, ...]
    uncertainty: tuple[float, ...]
    f_inf_N: dict[str, tuple[float | None, ...]]
    rate: dict[str, tuple[float | None, ...]]


def series(rows: list[dict]) -> tuple[str, ...]:
    """The series present: "FElupe", then ours' in the order of ``OUR_SERIES``."""
    present = {r["code"] for r in rows}
    return tuple(c for c in ("FElupe", *OUR_SERIES.values()) if c in present)


def limits(rows: list[dict], fit_meshes: int = 3) -> Limits:
    """The reference: the mean of the two codes' finest meshes (``CODES``), its uncertainty
    their half difference. Not an extrapolation, because near the contact's edge the forces
    need not converge monotonically (the edge moves from node to node); where the
    ``fit_meshes`` finest values of a series are monotone, its extrapolation is given beside,
    as a check."""
    f_inf, rate, finest = {}, {}, {}
    for code in series(rows):
        mine = sorted((r for r in rows if r["code"] == code), key=lambda r: r["refine"])
        finest[code] = mine[-1]
        if len(mine) < fit_meshes:
            f_inf[code] = rate[code] = (None,) * len(bf.DEPTHS)
            continue
        mine = mine[-fit_meshes:]
        h = np.array([1.0 / r["refine"] for r in mine])
        fits = []
        for k in range(len(bf.DEPTHS)):
            try:
                fits.append(fit_limit(h, np.array([r["force_quarter_N"][k] for r in mine])))
            except ValueError:
                fits.append((None, None, None))
        f_inf[code] = tuple(f[0] for f in fits)
        rate[code] = tuple(f[2] for f in fits)
    a, b = (finest[c]["force_quarter_N"] for c in CODES)
    ref = tuple(0.5 * (x + y) for x, y in zip(a, b, strict=True))
    unc = tuple(0.5 * abs(x - y) / r for x, y, r in zip(a, b, ref, strict=True))
    meshes = {c: finest[c]["mesh"] for c in CODES}
    return Limits(tuple(bf.DEPTHS), meshes, ref, unc, f_inf, rate)


def errors(row: dict, lim: Limits) -> dict[str, float]:
    """A run's relative error by each measure of ``MEASURES``."""
    rel = [abs(f / r - 1.0) for f, r in zip(row["force_quarter_N"], lim.reference_N, strict=True)]
    return {MEASURES[0]: rel[list(lim.depths_mm).index(1.0)], MEASURES[1]: max(rel)}


@dataclass(frozen=True)
class Match:
    """FElupe's run and the cheapest of ours at least as accurate by ``measure``."""

    measure: str
    felupe_mesh: str
    felupe_error: float
    felupe_s: float
    ours_mesh: str | None
    ours_error: float | None
    ours_s: float | None
    #: ours' seconds at exactly FElupe's error, interpolated (``interpolated_seconds``)
    ours_interpolated_s: float | None = None
    #: the series of ours (``OUR_SERIES``)
    ours_code: str = "ours"

    @property
    def speedup(self) -> float | None:
        return None if self.ours_s is None else self.felupe_s / self.ours_s

    @property
    def interpolated_speedup(self) -> float | None:
        s = self.ours_interpolated_s
        return None if s is None else self.felupe_s / s


def interpolated_seconds(points: list[tuple[float, float]], error: float) -> float | None:
    """The seconds at ``error`` on the work-precision line of ``points`` ((seconds, error),
    any order): log-linear between the two runs, in order of seconds, where the line first
    comes down to it (the run before above, the run after at or below). None where the
    cheapest run is already that accurate (its seconds are the answer, no interpolation) or
    the line never comes down to it (no extrapolation)."""
    pts = sorted(points)
    for (s0, e0), (s1, e1) in itertools.pairwise(pts):
        if e0 <= error:
            return None
        if error >= e1 > 0.0:
            w = np.log(e0 / error) / np.log(e0 / e1)
            return float(np.exp((1.0 - w) * np.log(s0) + w * np.log(s1)))
    return None


def equal_accuracy(rows: list[dict], lim: Limits) -> list[Match]:
    """For every timed FElupe run and measure, the cheapest timed run of ours whose error is at
    most FElupe's (None when no run of ours is that accurate)."""
    timed = [r for r in rows if r.get("whole_median_s") is not None]
    out = []
    for measure, code in itertools.product(MEASURES, series(rows)[1:]):
        ours = sorted((r for r in timed if r["code"] == code), key=lambda r: r["whole_median_s"])
        for fe in (r for r in timed if r["code"] == "FElupe"):
            e_fe = errors(fe, lim)[measure]
            best = next((r for r in ours if errors(r, lim)[measure] <= e_fe), None)
            line = [(r["whole_median_s"], errors(r, lim)[measure]) for r in ours]
            out.append(
                Match(
                    measure,
                    fe["mesh"],
                    e_fe,
                    fe["whole_median_s"],
                    None if best is None else best["mesh"],
                    None if best is None else errors(best, lim)[measure],
                    None if best is None else best["whole_median_s"],
                    interpolated_seconds(line, e_fe),
                    code,
                )
            )
    return out


@dataclass(frozen=True)
class WorkPrecisionInfo:
    """What the figure shows: per measure and code, the timed runs' (seconds, error, mesh),
    and per measure the reference's own uncertainty (errors below it are not resolved)."""

    points: dict[str, dict[str, tuple[tuple[float, float, str], ...]]]
    matches: tuple[Match, ...]
    uncertainty: dict[str, float]


def work_precision_info(rows: list[dict], lim: Limits) -> WorkPrecisionInfo:
    points = {
        m: {
            code: tuple(
                (r["whole_median_s"], errors(r, lim)[m], r["mesh"])
                for r in sorted(rows, key=lambda r: r["refine"])
                if r["code"] == code and r.get("whole_median_s") is not None
            )
            for code in series(rows)
        }
        for m in MEASURES
    }
    at_1mm = lim.uncertainty[list(lim.depths_mm).index(1.0)]
    floor = {MEASURES[0]: at_1mm, MEASURES[1]: max(lim.uncertainty)}
    return WorkPrecisionInfo(points, tuple(equal_accuracy(rows, lim)), floor)


def render(info: WorkPrecisionInfo, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(1, len(MEASURES), figsize=(10, 4), sharey=True)
    for ax, measure in zip(axes, MEASURES, strict=True):
        for code, marker in zip(info.points[measure], ("s--", "o-", "^-"), strict=False):
            pts = info.points[measure][code]
            ax.loglog([p[0] for p in pts], [100 * p[1] for p in pts], marker, label=code)
            for s, e, mesh in pts:
                ax.annotate(
                    mesh, (s, 100 * e), textcoords="offset points", xytext=(4, 4), fontsize=7
                )
        plain = matplotlib.ticker.FuncFormatter(lambda y, _: f"{y:g}")
        # label the minor ticks 2 and 5 of each decade only: all of them overlap
        sparse = matplotlib.ticker.FuncFormatter(
            lambda y, _: f"{y:g}" if f"{y:.0e}"[0] in "25" else ""
        )
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(sparse)
        ax.xaxis.set_major_formatter(plain)
        ax.set_title(f"plate force error, {measure}")
        ax.set_xlabel("whole process (s, one core)")
        ax.grid(True, which="both", alpha=0.3)
    low, high = axes[0].get_ylim()  # shared: every series plotted
    for ax, measure in zip(axes, MEASURES, strict=True):
        floor = 100 * info.uncertainty[measure]
        ax.axhspan(min(low, floor), floor, color="0.88", zorder=0)
        ax.text(
            0.02, floor, " reference's uncertainty", transform=ax.get_yaxis_transform(),
            va="bottom", fontsize=7, color="0.35",
        )  # fmt: skip
    axes[0].set_ylim(min(low, 0.5 * min(100 * u for u in info.uncertainty.values())), high)
    axes[0].set_ylabel("relative error (%)")
    axes[0].legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def measure_row(code: str, mesh: str, repeats: int, timed: bool) -> dict:
    """One run of a series ("FElupe" or one of ``OUR_SERIES``), timed or not."""
    element = {v: k for k, v in OUR_SERIES.items()}.get(code)
    formulation = None if element else "q1p0"
    child = "ours" if element else "felupe"
    load = os.getloadavg()[0]
    if timed:
        row = bf.measure(child, mesh, 0.1, formulation, repeats, 1, element or "q2")
    else:
        wall, row = bf.run_child(child, mesh, 0.1, formulation, element or "q2")
        row = {**row, "whole_s": [wall], "whole_median_s": None, "untimed_wall_s": wall}
    return {**row, "code": code, "refine": float(mesh[1:]), "load_average_before": load}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, required=True, help="the runs, saved as they end")
    ap.add_argument(
        "--ours", nargs="*", type=bf.mesh_name, default=["x0.5", "x0.7", "x1", "x1.41", "x2"]
    )
    ap.add_argument(
        "--felupe", nargs="*", type=bf.mesh_name, default=["x0.5", "x0.7", "x1", "x1.5"]
    )
    ap.add_argument(
        "--also", nargs="+", type=Path, default=[], help="runs saved by other runs of this script"
    )
    ap.add_argument(
        "--ours-element", choices=tuple(OUR_SERIES), default="q2", help="the element of ours' runs"
    )
    ap.add_argument("--repeats", type=int, default=3, help="timed fresh processes per run")
    # 110 000 dofs: ours x1.41 (103 401, 98 s a run) is timed, FElupe x1.5 (132 117, about
    # 25 minutes a run) and ours x2 (284 985, about an hour) are not
    ap.add_argument("--time-up-to", type=int, default=110_000, help="dofs: larger are untimed")
    ap.add_argument("--fit-meshes", type=int, default=3, help="finest meshes of each fit")
    ap.add_argument("--figure", type=Path, help="error against seconds (PNG)")
    args = ap.parse_args(argv)
    for name in args.ours + args.felupe:
        if not name.startswith("x"):
            ap.error(f"meshes are xF refinements of the default mesh, got {name!r}")
    doc = json.loads(args.json.read_text()) if args.json.exists() else {"runs": []}
    others = [r for path in args.also for r in json.loads(path.read_text())["runs"]]
    done = {run_key(r["code"], r["mesh"]) for r in doc["runs"] + others}
    ours = OUR_SERIES[args.ours_element]
    todo = [(ours, m) for m in args.ours] + [("FElupe", m) for m in args.felupe]
    for code, mesh in todo:
        if run_key(code, mesh) in done:
            continue
        from sim.geometry import PadGeometry, build_pad_mesh

        dofs = 3 * build_pad_mesh(PadGeometry(), (), bf.mesh_options(mesh)).n_nodes
        timed = dofs <= args.time_up_to
        print(f"{code} {mesh}: {dofs} dofs, {'timed' if timed else 'untimed'} ...", flush=True)
        doc["runs"].append(measure_row(code, mesh, args.repeats, timed))
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(doc, indent=1) + "\n")
    rows = doc["runs"] + [
        r
        for r in others
        if run_key(r["code"], r["mesh"]) not in {run_key(q["code"], q["mesh"]) for q in doc["runs"]}
    ]
    for code in CODES:
        if sum(r["code"] == code for r in rows) < args.fit_meshes:
            print(f"{code}: fewer than {args.fit_meshes} meshes, no comparison (runs saved)")
            return doc
    lim = limits(rows, args.fit_meshes)

    def fit(code: str, k: int) -> str:
        f, p = lim.f_inf_N[code][k], lim.rate[code][k]
        return "no rate" if f is None else f"{f:.5f}, {p:.2f}"

    print(
        f"\nPlate force on the quarter pad: the reference is the mean of ours {lim.finest['ours']} "
        f"and FElupe {lim.finest['FElupe']} (+- half their difference); beside it, "
        f"F(h) = F_inf + C h^p fitted to each code's {args.fit_meshes} finest meshes:\n"
    )
    names = series(rows)
    print(
        "| depth (mm) | reference (N) | +- | "
        + " | ".join(f"{c}: F_inf (N), p" for c in names)
        + " |"
    )
    print("|---|---|---|" + "---|" * len(names))
    for k, d in enumerate(lim.depths_mm):
        print(
            f"| {d:g} | {lim.reference_N[k]:.5f} | {lim.uncertainty[k]:.2%} | "
            + " | ".join(fit(c, k) for c in names)
            + " |"
        )
    print(
        "\n| code | mesh | dofs | whole-process s (median of timed runs) | Newton iterations "
        "| factorisations | error 0.25 / 0.5 / 1 mm | load before |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["code"], r["refine"])):
        rel = [f / ref - 1 for f, ref in zip(r["force_quarter_N"], lim.reference_N, strict=True)]
        s = (
            "untimed ({:.0f})".format(r["untimed_wall_s"])
            if r.get("whole_median_s") is None
            else f"{r['whole_median_s']:.2f}"
        )
        print(
            f"| {r['code']} | {r['mesh']} | {r['dofs']} | {s} | {r['newton_iterations']} "
            f"| {r['factorizations']} | {' / '.join(f'{x:+.2%}' for x in rel)} "
            f"| {r['load_average_before']:.2f} |"
        )
    info = work_precision_info(rows, lim)
    print()
    for m in info.matches:
        if m.ours_mesh is None:
            print(
                f"{m.measure}: FElupe {m.felupe_mesh} ({m.felupe_error:.2%}, {m.felupe_s:.1f} s): "
                f"no timed run of {m.ours_code} is as accurate"
            )
        else:
            between = (
                ""
                if m.interpolated_speedup is None
                else f"; {m.interpolated_speedup:.1f}x against ours interpolated to "
                f"{m.felupe_error:.2%} ({m.ours_interpolated_s:.1f} s)"
            )
            print(
                f"{m.measure}: FElupe {m.felupe_mesh} ({m.felupe_error:.2%}, {m.felupe_s:.1f} s) "
                f"against {m.ours_code} {m.ours_mesh} ({m.ours_error:.2%}, {m.ours_s:.2f} s): "
                f"{m.speedup:.1f}x faster at equal accuracy{between} (target >= 10x)"
            )
    if args.figure:
        render(info, args.figure)
        print(f"wrote {args.figure}")
    doc["limits"] = {
        "depths_mm": list(lim.depths_mm),
        "f_inf_N": {k: list(v) for k, v in lim.f_inf_N.items()},
        "rate": {k: list(v) for k, v in lim.rate.items()},
        "finest": lim.finest,
        "reference_N": list(lim.reference_N),
        "uncertainty": list(lim.uncertainty),
    }
    doc["command"] = "python benchmarks/bench_felupe_accuracy.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    args.json.write_text(json.dumps(doc, indent=1) + "\n")
    return doc


if __name__ == "__main__":
    main()
