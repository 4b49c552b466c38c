"""Mesh convergence of the 3D pad's metrics: regenerates ``docs/mesh3d_convergence.json``
(used by ``docs/model_3d.md``, "Mesh convergence").

    python studies/mesh3d_convergence.py                 # every level, resumes
    python studies/mesh3d_convergence.py --levels 1 1.41  # a quick look
    python studies/mesh3d_convergence.py --wedge --levels 1 1.41 2   # the wedge instead
    python studies/mesh3d_convergence.py --element q2p1 --levels 1 1.41 2  # locking-free

Each design is simulated on the mesh family ``BASE.refined(f)`` (every target size / f) with
the elastic tap (one tap to 5 N) and the plate; the validity stop is off so every level gives
every metric. Per metric the script fits err(h) = C h^p to the differences between successive
levels (``np.polyfit`` on the logs), extrapolates (Richardson) and prints each level's error
against the extrapolated value: the coarsest level within 1 % is the one to simulate with.
Results are written after each run, so an interrupted study resumes where it stopped.
``--wedge`` runs the wedge (its default protocol: the edge pressed 1 mm in 1 s, held 100 s)
instead of the tap and the plate, and reports the wedge's metrics (its runs are kept in the
same file under ``name@f:wedge``; the wedge refined along its edge alone:
``studies/wedge3d_band.py``). ``--element q2p1`` runs the locking-free Q2/P1 element
(``model.element``; its runs are kept under ``name@f:q2p1``, ``name@f:wedge:q2p1``)."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path

import numpy as np

from sim.design import design_from_dict
from sim.geometry import COARSE_MESH_3D
from sim.options import ELEMENTS_3D, ModelOptions, SimOptions
from sim.simulate import simulate

OUT = Path(__file__).resolve().parents[1] / "docs" / "mesh3d_convergence.json"
#: the family's coarsest member; the levels refine it by f
BASE = COARSE_MESH_3D
LEVELS = (1.0, 1.41, 2.0, 2.83)
METRICS = (
    "disp_at_1N_mm",
    "disp_at_4N_mm",
    "contact_area_at_1N_mm2",
    "contact_area_at_4N_mm2",
    "plate_force_at_1mm_N",
)
#: the wedge's metrics (``--wedge``)
WEDGE_METRICS = (
    "wedge_peak_force_N",
    "wedge_force_at_100s_N",
    "profile_1s_area_2mm_mm2",
    "profile_1s_defl_at_1mm_mm",
)
#: the main job's gel answer, elastic (its long-term Ogden law, docs/fingertip_3d.md), and the
#: paper's GLS40 silicone over the reference outline, elastic: a soft, nearly incompressible
#: pad strained to ~0.6 and a stiffer one
DESIGNS = {
    "gel": {
        "geometry": {"half_width_mm": 7.89, "height_mm": 6.45, "exponent": 1.31},
        "layers": [
            {"material": {"model": "ogden", "mu_MPa": [0.0101], "alpha": [3.84], "nu": 0.499}}
        ],
    },
    "silicone": {
        "layers": [{"material": {"model": "neo_hookean", "mu_MPa": 0.06, "nu": 0.499}}],
    },
}


def measured(design, protocols: tuple[str, ...], options: SimOptions, metrics) -> dict:
    """Simulate ``protocols``: the figures a mesh study keeps (the largest protocol mesh's
    dofs, the ``metrics``, the factorisations, the wall time and any failures)."""
    t0 = time.perf_counter()
    res = simulate(design, protocols, options)
    return {
        "dofs": max(p.get("n_dofs", res.n_dofs) for p in res.protocols.values()),
        "metrics": {m: res.metrics.get(m) for m in metrics},
        "factorizations": sum(p.get("factorizations", 0) for p in res.protocols.values()),
        "wall_s": time.perf_counter() - t0,
        "failures": [fl.__dict__ for fl in res.failures],
    }


def run_cases(out: Path, cases: Iterable[tuple[str, Callable[[], dict]]]) -> dict:
    """Each ``(key, case)`` whose key the JSON file ``out`` does not hold yet: run, and write
    the file after each (a killed study resumes where it stopped)."""
    done = json.loads(out.read_text()) if out.exists() else {}
    for key, case in cases:
        if key in done:
            continue
        done[key] = case()
        out.write_text(json.dumps(done, indent=1) + "\n")
        print(key, done[key], flush=True)
    return done


def run(levels: tuple[float, ...], wedge: bool = False, element: str = "q2") -> dict:
    protocols, metrics, tag = (
        (("wedge",), WEDGE_METRICS, ":wedge") if wedge else (("tapping", "plate"), METRICS, "")
    )
    if element != "q2":  # the pure-displacement runs keep the keys they had before the option
        tag += f":{element}"

    def case(name: str, f: float) -> dict:
        model = ModelOptions("3d", element=element)
        options = SimOptions(model=model, mesh3d=BASE.refined(f))
        figures = measured(
            design_from_dict(DESIGNS[name]), protocols, options.without_validity_stop(), metrics
        )
        return {"design": name, "refine": f, "element": element, **figures}

    return run_cases(
        OUT,
        ((f"{n}@{f:g}{tag}", partial(case, n, f)) for n in DESIGNS for f in levels),
    )


def richardson(h: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``(p, y_inf)``: the rate of err(h) = C h^p fitted to the differences between successive
    values ``y`` at the sizes ``h`` (coarsest first; ``np.polyfit`` on the logs) and the value
    extrapolated from the last two (Richardson); NaN where no positive rate fits."""
    diff = np.abs(np.diff(y))
    p = float(np.polyfit(np.log(h[1:]), np.log(diff), 1)[0]) if np.all(diff > 0) else np.nan
    if not p > 0:
        return p, np.nan
    return p, float(y[-1] + (y[-1] - y[-2]) / ((h[-2] / h[-1]) ** p - 1.0))


def report(done: dict, wedge: bool = False, element: str = "q2") -> None:
    metrics = WEDGE_METRICS if wedge else METRICS
    for name in DESIGNS:
        rows = sorted(
            (
                v
                for k, v in done.items()
                if v["design"] == name
                and (":wedge" in k) == wedge
                and v.get("element", "q2") == element
            ),
            key=lambda v: v["refine"],
        )
        if len(rows) < 3:
            continue
        print(f"\n{name} ({element}): dofs {[r['dofs'] for r in rows]}")
        h = 1.0 / np.array([r["refine"] for r in rows])
        for m in metrics:
            y = np.array([r["metrics"][m] or np.nan for r in rows])
            p, best = richardson(h, y)
            errs = ", ".join(f"{100 * (v / best - 1):+.2f}%" for v in y) if best == best else "-"
            print(f"  {m:26s} rate {p:4.2f}  extrapolated {best:.4g}  errors {errs}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=float, nargs="+", default=list(LEVELS))
    ap.add_argument("--wedge", action="store_true", help="the wedge instead of tap and plate")
    ap.add_argument("--element", choices=ELEMENTS_3D, default="q2", help="the 3D element")
    args = ap.parse_args()
    report(run(tuple(args.levels), args.wedge, args.element), args.wedge, args.element)
