"""The main job's answers (2D) simulated with the 3D pad: the table of ``docs/model_3d.md``,
"The 2D answers as fingertips", written to ``docs/answers3d.json``.

    python studies/answers3d.py runs/main            # every answers/*.toml of the run
    python studies/answers3d.py runs/main --refine 1  # the coarser mesh of the family

Each answer design is simulated with all three protocols in 2D (the run's model) and in 3D
(the pad's default length, ``sim.geometry.pad``; the mesh ``studies/mesh3d_convergence.py``'s
family at ``--refine``), run to the end beyond the validity limits too (the violations are
recorded beside the metrics), and the tapping metrics read from touch are set against the human
targets (``sim/data/human_targets.toml``). Results are written after each design (resumes)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from sim.design import load_design, load_targets
from sim.geometry import COARSE_MESH_3D as BASE  # studies/mesh3d_convergence.py's mesh family
from sim.options import ModelOptions, SimOptions
from sim.simulate import simulate

OUT = Path(__file__).resolve().parents[1] / "docs" / "answers3d.json"
READ = ("disp_at_1N_from_touch_mm", "disp_at_4N_from_touch_mm", "hysteresis_Nmm")
SHOWN = (*READ, "sag_mm", "contact_area_at_1N_mm2", "contact_area_at_4N_mm2", "wedge_peak_force_N")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a search run folder with answers/*.toml")
    ap.add_argument("--refine", type=float, default=1.41)
    args = ap.parse_args()
    done = json.loads(OUT.read_text()) if OUT.exists() else {}
    targets = load_targets().values
    for path in sorted((args.run / "answers").glob("*.toml")):
        design = load_design(path)
        for model in ("2d", "3d"):
            key = f"{path.stem}@{model}" + (f"@{args.refine:g}" if model == "3d" else "")
            if key in done:
                continue
            options = SimOptions(model=ModelOptions(model), mesh3d=BASE.refined(args.refine))
            # every metric, also beyond the validity limits (the violations are recorded)
            options = options.without_validity_stop()
            t0 = time.perf_counter()
            res = simulate(design, options=options)
            done[key] = {
                "answer": path.stem,
                "model": model,
                "refine": args.refine if model == "3d" else None,
                "dofs": res.n_dofs,
                "metrics": {m: res.metrics.get(m) for m in SHOWN if m in res.metrics},
                "valid": res.validity["valid"],
                "violations": res.validity["violations"],
                "settled": res.protocols.get("tapping", {}).get("settled"),
                "failures": [f.__dict__ for f in res.failures],
                "wall_s": time.perf_counter() - t0,
            }
            OUT.write_text(json.dumps(done, indent=1) + "\n")
            m = done[key]["metrics"]
            errs = []
            for n in READ:
                target = targets[n.replace("_from_touch", "")]
                value = m.get(n)
                shown = (
                    "-" if value is None else f"{value:.3g} ({100 * (value / target - 1):+.0f} %)"
                )
                errs.append(f"{n.split('_from')[0]} {shown}")
            errs.append(f"valid {done[key]['valid']}  {done[key]['wall_s']:.0f} s")
            print(
                f"{key:22s} {'  '.join(errs)}",
                flush=True,
            )


if __name__ == "__main__":
    main()
