"""For docs/fe_speed.md ("The 3D model's kept factorisation"): how long the 3D model keeps a
factorisation (``newton.reuse_ratio``), its cost and its metrics; regenerates
``docs/reuse_ratio3d.json``.

    python studies/reuse_ratio3d.py [--ratios 0.25 0.5 0.75] [--workers 2]
    python studies/reuse_ratio3d.py --no-stop --ratios 0.25 0.5 \
        --pads stiff_skin_soft_core soft_fast slow_creep

The 3D model keeps its last factorisation while the residual falls at least by
``newton.reuse_ratio`` per iteration (``sim.fe.solver.NewtonOptions``). Each pad below is
simulated with all three protocols on the default 3D mesh (as ``fingertip simulate --model 3d``
runs it) at each ratio; the script keeps the counts of every protocol (Newton iterations,
factorisations, residual evaluations: they do not depend on the machine's load), the wall
times (which do: a cost comparison needs ``benchmarks/bench_simulate.py`` on a quiet machine),
the metrics, the validity and the settling, and prints per ratio the counts and the largest
relative change of each pad's metrics against the first ratio. Results are written after each
run, so an interrupted study resumes where it stopped. A design whose tapping goes beyond the
validity limits stops there and has no tapping metrics (as in a sweep); ``--no-stop`` runs
every protocol to its end (``SimOptions.without_validity_stop``, kept under ``<pad>@<ratio>:
no-stop``), so that the tapping's metrics can be compared too.

The pads: the three corner designs of ``docs/designs/`` (stiff and elastic-ish, very soft and
fast-relaxing, slowly creeping) and the two elastic pads of ``studies/mesh3d_convergence.py``
(the main job's soft gel answer and the paper's GLS40 silicone), on which the 3D wedge's
sub-step rule was chosen (docs/fe_speed.md, "The 3D wedge's sub-steps").
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

from sim import load_design  # noqa: E402
from sim.design import design_from_dict  # noqa: E402
from sim.options import ModelOptions, SimOptions  # noqa: E402
from sim.simulate import simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "reuse_ratio3d.json"
RATIOS = (0.25, 0.5, 0.75)
CORNERS = ("stiff_skin_soft_core", "soft_fast", "slow_creep")
PADS = (*CORNERS, "gel", "silicone")
COUNTS = ("newton_iterations", "factorizations", "evaluations")


def _design(name: str):
    if name in CORNERS:
        return load_design(ROOT / "docs" / "designs" / f"{name}.toml")
    import sys

    sys.path.insert(0, str(ROOT / "studies"))
    from mesh3d_convergence import DESIGNS

    return design_from_dict(DESIGNS[name])


def case(name: str, ratio: float, stop: bool = True) -> dict:
    """Simulate pad ``name`` with all protocols at ``newton.reuse_ratio = ratio`` (beyond the
    validity limits too unless ``stop``)."""
    options = SimOptions(model=ModelOptions("3d"))
    options = options if stop else options.without_validity_stop()
    options = replace(options, newton=replace(options.newton, reuse_ratio=ratio))
    t0 = time.perf_counter()
    res = simulate(_design(name), ("tapping", "plate", "wedge"), options)
    return {
        "design": name,
        "reuse_ratio": ratio,
        "wall_s": time.perf_counter() - t0,
        "protocols": {
            p: {k: info.get(k) for k in (*COUNTS, "wall_time_s")}
            for p, info in res.protocols.items()
        },
        "metrics": {k: v for k, v in res.metrics.items() if v is not None},
        "valid": res.validity["valid"],
        "stopped": list(res.stopped),
        "settled": res.protocols.get("tapping", {}).get("settled"),
        "failures": [fl.__dict__ for fl in res.failures],
    }


def key(name: str, ratio: float, stop: bool) -> str:
    return f"{name}@{ratio:g}" + ("" if stop else ":no-stop")


def run(
    ratios: tuple[float, ...],
    workers: int,
    pads: tuple[str, ...] = PADS,
    stop: bool = True,
    out: Path = OUT,
) -> dict:
    """Every (pad, ratio) case ``out`` does not hold yet, ``workers`` at a time; ``out`` is
    written after each."""
    done = json.loads(out.read_text()) if out.exists() else {}
    todo = [(n, r) for r in ratios for n in pads if key(n, r, stop) not in done]
    with ProcessPoolExecutor(workers) as pool:
        futures = {pool.submit(case, n, r, stop): key(n, r, stop) for n, r in todo}
        for fut in as_completed(futures):
            done[futures[fut]] = fut.result()
            out.write_text(json.dumps(done, indent=1, sort_keys=True) + "\n")
            print(futures[fut], f"{done[futures[fut]]['wall_s']:.1f} s", flush=True)
    return done


def relative_change(a: dict, b: dict) -> tuple[float, str]:
    """The largest |b/a - 1| over the metrics both hold (and which metric)."""
    worst, which = 0.0, ""
    for k in a.keys() & b.keys():
        x, y = a[k], b[k]
        if isinstance(x, bool) or not isinstance(x, int | float) or x == 0:
            continue
        d = abs(y / x - 1.0)
        if d > worst:
            worst, which = d, k
    return worst, which


def report(done: dict, ratios: tuple[float, ...], pads: tuple[str, ...], stop: bool) -> None:
    base = ratios[0]
    for name in pads:
        print(f"\n{name}" + ("" if stop else ", every protocol to its end"))
        ref = done.get(key(name, base, stop))
        for r in ratios:
            row = done.get(key(name, r, stop))
            if row is None:
                continue
            counts = "; ".join(
                f"{p} {info['newton_iterations']} it, {info['factorizations']} fact"
                for p, info in row["protocols"].items()
            )
            total = sum(info["factorizations"] for info in row["protocols"].values())
            change = ""
            if ref is not None and r != base:
                d, k = relative_change(ref["metrics"], row["metrics"])
                same = all(ref[k] == row[k] for k in ("valid", "stopped", "settled"))
                change = f"; largest change {d:.1e} ({k}); validity, settling same: {same}"
            print(
                f"  ratio {r:g}: {row['wall_s']:.1f} s, {total} factorisations ({counts}); "
                f"failures {[f['protocol'] for f in row['failures']]}{change}"
            )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ratios", type=float, nargs="+", default=list(RATIOS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--pads", nargs="+", choices=PADS, default=list(PADS))
    ap.add_argument("--no-stop", action="store_true", help="beyond the validity limits too")
    args = ap.parse_args()
    ratios, pads, stop = tuple(args.ratios), tuple(args.pads), not args.no_stop
    report(run(ratios, args.workers, pads, stop), ratios, pads, stop)
