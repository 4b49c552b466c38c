"""How fast other sparse factorisations are on the FE's own tangent (issue 11 item 7).

    python scripts/linear_solver_study.py [--record RECORD.json]

Simulates the plate protocol of one design (a record's ``params``; default: ``DEFAULT_RECORD``,
a two-layer design of runs/main_v28, if it exists, else one layer of silicone_gls40), keeps
the first tangent the solver factorises (its upper triangle, as qdldl receives it), and
times on it, in this one process (BLAS on one thread; best of many repeats, so the
machine's load matters less than for a whole run):

- qdldl's numeric refactorisation (``Solver.update``, the symbolic analysis reused: what the
  solver does every Newton iteration) and its triangular solves;
- SuperLU (``scipy.sparse.linalg.splu``) on the full symmetric matrix with two fill-reducing
  orderings, and its factor's non-zeros.

Session 11, the default record (2698 free dofs): qdldl 2.4 ms (solve 0.18 ms), SuperLU
11-12 ms beside a nice-19 sweep; 3.8 ms and 12-14 ms beside the test suite. SuperLU's L has
90,888 non-zeros with MMD: about 3 times the upper triangle's 30,675.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

DEFAULT_RECORD = Path("runs/main_v28/fe/records/1d36624b2f73e54e5c79.json")


def best_ms(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times)


def main() -> None:
    import qdldl
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from sim import homogeneous_design, simulate
    from sim.solver import Body
    from sim.space import load_space

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--record", type=Path, default=DEFAULT_RECORD)
    args = ap.parse_args()
    if args.record.exists():
        design = load_space().design(json.loads(args.record.read_text())["params"])
    else:
        design = homogeneous_design("silicone_gls40")
    kept: list = []
    factor = Body._factor

    def keep_first(self, data):
        if not kept:
            kept.append(self.disc.upper_matrix(data).copy())
        return factor(self, data)

    Body._factor = keep_first
    try:
        simulate(design, ["plate"])
    finally:
        Body._factor = factor
    upper = kept[0].tocsc()
    full = (upper + sp.triu(upper, 1).T).tocsc()
    print(f"{upper.shape[0]} free dofs, {upper.nnz} non-zeros in the upper triangle")
    solver = qdldl.Solver(upper, upper=True)
    b = np.random.default_rng(0).random(upper.shape[0])
    print(f"qdldl refactorisation: {best_ms(lambda: solver.update(upper, upper=True), 50):.2f} ms")
    print(f"qdldl solve: {best_ms(lambda: solver.solve(b), 50):.2f} ms")
    for ordering in ("MMD_AT_PLUS_A", "COLAMD"):

        def lu(o=ordering):
            return spla.splu(full, permc_spec=o, diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True})  # fmt: skip

        ms = best_ms(lu, 20)
        print(f"SuperLU ({ordering}): {ms:.2f} ms, L with {lu().L.nnz} non-zeros")


if __name__ == "__main__":
    main()
