"""Benchmark: sparse direct solvers that install with pip, on the FE's 2D and 3D systems.

    python benchmarks/bench_linear_solvers.py [--repeats 5] [--json out.json]

One core (BLAS/MKL/OpenMP threads pinned to 1 before numpy loads): the sweep runs one design
per core. Each (solver, system) pair runs in a fresh child process, so that its peak memory
(``ru_maxrss``, measured before and after the factorisation) is its own. Printed per pair:

- ``first``: symbolic analysis + numeric factorisation (ms), once per mesh;
- ``refactor``: numeric factorisation with the analysis reused (ms, best of ``--repeats``):
  what a Newton iteration pays when the tangent changes but not its pattern;
- ``solve``: forward/back substitution for one right-hand side (ms, best of ``--repeats``);
- ``held MB``: resident memory the factorisation holds (read while it is alive), and
  ``peak MB``: growth of the child's peak resident memory, 0 where the peak was set before
  (the matrix is built by the parent and loaded from a file, so both are the solver's own);
- ``rel. residual``: ``|A x - b| / |b|`` (the solver's accuracy on this system).

Systems:

- ``2d``: the FE's own free-dof tangent (P2 plane strain, the reference design of one layer
  of ``silicone_gls40`` at rest; ``2d-x2``: the mesh refined twice).
- ``pad``: the 3D model's own tangent (``sim.fe.fe3d``: the reference pad, the default 3D mesh,
  one layer of ``silicone_gls40`` at rest).
- ``3d-N``: a nearly incompressible 3D elastic block (nu = 0.499, fixed base) of
  ``N x N x N`` triquadratic (27-node) hexahedra, assembled by scikit-fem: the pattern and
  conditioning of a 3D Q2 tangent of that size.

Solvers: ``qdldl`` (LDL^T, AMD ordering; the FE's solver), ``superlu`` (scipy's LU, of the
full matrix), ``pardiso`` (MKL PARDISO through pypardiso, symmetric indefinite, mtype -2,
as the FE runs it: ``sim.fe._linear.Pardiso`` with its settings ``PARDISO_IPARM``),
``pardiso-defaults``, ``pardiso-md``, ``pardiso-bk`` (the same with PARDISO's default
settings, with minimum degree ordering, with Bunch-Kaufman pivoting: ``PARDISO_VARIANTS``),
``pardiso-single`` (the FE's single-precision PARDISO, ``sim.fe._linear.PardisoSingle``),
``cholmod`` (CHOLMOD's supernodal Cholesky through
cholespy, for symmetric positive definite systems only: it cannot factorise an indefinite
tangent; needs ``pip install cholespy``). A solver that is not installed is reported as such.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402

#: PARDISO as the FE runs it and with one setting changed (iparm, 1-based as in Intel's manual)
PARDISO_VARIANTS = {
    "pardiso": {},
    "pardiso-defaults": {1: 0},  # PARDISO's defaults: METIS, Bunch-Kaufman pivoting
    "pardiso-md": {2: 0},  # minimum degree ordering
    "pardiso-bk": {21: 1},  # Bunch-Kaufman 1 x 1 and 2 x 2 pivoting
    "pardiso-single": {},  # single precision (sim.fe._linear.PardisoSingle: iparm(28) = 1)
}
SOLVERS = ("qdldl", "superlu", *PARDISO_VARIANTS, "cholmod")
#: the solvers without supernodes: beyond ``--slow-max-dofs`` they take minutes a system
SLOW = ("qdldl", "superlu")
SYSTEMS = ("2d", "2d-x2", "3d-6", "3d-9", "3d-12", "3d-15", "pad")


def system(name: str):
    """The free-dof matrix (scipy CSC, symmetric) of system ``name``."""
    import scipy.sparse as sp

    if name.startswith("2d"):
        from sim import SimOptions, homogeneous_design
        from sim.fe import Discretization
        from sim.geometry import build_mesh

        design = homogeneous_design("silicone_gls40")
        options = SimOptions()
        mesh_opts = options.mesh.refined(2.0) if name == "2d-x2" else options.mesh
        disc = Discretization(
            build_mesh(design.geometry, design.thicknesses_mm, mesh_opts), design.materials
        )
        ev = disc.evaluate(np.zeros((disc.n_nodes, 2)), disc.initial_states(), 0.01)
        return sp.csc_matrix(disc.pattern_matrix(ev.tangent()))
    if name == "pad":
        from sim import homogeneous_design
        from sim.fe import Discretization3D
        from sim.geometry import PadGeometry, build_pad_mesh

        mat = homogeneous_design("silicone_gls40").materials[0]
        disc = Discretization3D(build_pad_mesh(PadGeometry()), [mat])
        ev = disc.evaluate(np.zeros((disc.n_nodes, 3)), disc.initial_states(), 0.01)
        return sp.csc_matrix(disc.pattern_matrix(ev.tangent()))
    from skfem import Basis, ElementHex2, ElementVector, MeshHex, asm, condense
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    n = int(name.split("-")[1])
    grid = np.linspace(0.0, 1.0, n + 1)
    mesh = MeshHex.init_tensor(grid, grid, grid)
    basis = Basis(mesh, ElementVector(ElementHex2()))
    K = asm(linear_elasticity(*lame_parameters(1.0, 0.499)), basis)
    fixed = basis.get_dofs(lambda x: np.isclose(x[2], 0.0)).all()
    A = condense(K, D=fixed, expand=False)
    return sp.csc_matrix(A)


def _best_ms(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times)


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _rss_mb() -> float:
    """The process's resident memory now (Linux ``/proc/self/statm``)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _import(solver: str) -> None:
    """Load the solver's library before the memory is read (MKL alone is ~100 MB of code)."""
    modules = {
        "qdldl": "qdldl",
        "superlu": "scipy.sparse.linalg",
        **{name: "pypardiso" for name in PARDISO_VARIANTS},
        "cholmod": "cholespy",
    }
    __import__(modules[solver])


def measure(solver: str, name: str, path: str, repeats: int) -> dict:
    """Time ``solver`` on system ``name`` (saved by the parent to ``path``) in this process."""
    import scipy.sparse as sp

    A = sp.load_npz(path).tocsc()
    n = A.shape[0]
    b = np.random.default_rng(0).standard_normal(n)
    upper = sp.triu(A, format="csc")
    upper.sort_indices()
    out = {"solver": solver, "system": name, "dofs": n, "nnz_upper": int(upper.nnz)}
    _import(solver)
    if solver.startswith("pardiso"):  # MKL maps its code on first use: a 1x1 system first
        from pypardiso import spsolve

        spsolve(sp.identity(1, format="csr"), np.ones(1))
    rss0, peak0 = _rss_mb(), _maxrss_mb()
    if solver == "qdldl":
        import qdldl

        t0 = time.perf_counter()
        lu = qdldl.Solver(upper, upper=True)
        first = time.perf_counter() - t0
        refactor = _best_ms(lambda: lu.update(upper, upper=True), repeats)
        solve = _best_ms(lambda: lu.solve(b), repeats)
        x = lu.solve(b)
    elif solver == "superlu":
        import scipy.sparse.linalg as spla

        t0 = time.perf_counter()
        lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A")
        first = time.perf_counter() - t0
        refactor = _best_ms(lambda: spla.splu(A, permc_spec="MMD_AT_PLUS_A"), repeats)
        solve = _best_ms(lambda: lu.solve(b), repeats)
        x = lu.solve(b)
    elif solver in PARDISO_VARIANTS:
        from sim.fe._linear import SOLVERS as FE_SOLVERS

        # the FE's own solver: its settings (sim.fe._linear.PARDISO_IPARM)
        ps = FE_SOLVERS["pardiso-single" if solver == "pardiso-single" else "pardiso"]()
        for k, value in PARDISO_VARIANTS[solver].items():
            ps._ps.iparm[k - 1] = value  # 1-based, as in Intel's manual
        t0 = time.perf_counter()
        ps.factor(upper)
        first = time.perf_counter() - t0
        refactor = _best_ms(lambda: ps.refactor(upper.data), repeats)
        solve = _best_ms(lambda: ps.solve(b), repeats)
        x = ps.solve(b)
        out["factor_entries"] = int(ps._ps.iparm[17])
    elif solver == "cholmod":
        from cholespy import CholeskySolverD, MatrixType

        coo = A.tocoo()
        rows, cols = coo.row.astype(np.int32), coo.col.astype(np.int32)

        def factor():
            return CholeskySolverD(n, rows, cols, coo.data, MatrixType.COO)

        t0 = time.perf_counter()
        ch = factor()
        first = time.perf_counter() - t0
        refactor = _best_ms(factor, repeats)  # cholespy has no numeric-only refactorisation
        x = np.zeros(n)
        solve = _best_ms(lambda: ch.solve(b, x), repeats)
    else:
        raise ValueError(f"unknown solver {solver!r}; known: {', '.join(SOLVERS)}")
    out.update(
        held_mb=_rss_mb() - rss0,
        first_ms=1e3 * first,
        refactor_ms=refactor,
        solve_ms=solve,
        peak_mb=_maxrss_mb() - peak0,
        rel_residual=float(np.linalg.norm(A @ x - b) / np.linalg.norm(b)),
    )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    ap.add_argument("--systems", nargs="+", default=list(SYSTEMS), choices=SYSTEMS)
    ap.add_argument("--json", help="also write the figures to this JSON file")
    ap.add_argument(
        "--slow-max-dofs",
        type=int,
        default=10000,
        help="skip qdldl and SuperLU on larger systems (default 10000: minutes beyond)",
    )
    ap.add_argument("--one", nargs=3, help=argparse.SUPPRESS)  # SOLVER SYSTEM PATH
    args = ap.parse_args()
    if args.one:
        print(json.dumps(measure(*args.one, args.repeats)))
        return
    import tempfile

    import scipy.sparse as sp

    tmp = tempfile.TemporaryDirectory()
    header = (
        f"{'system':7s} {'dofs':>7s} {'solver':16s} {'first ms':>9s} {'refactor ms':>11s} "
        f"{'solve ms':>9s} {'held MB':>8s} {'peak MB':>8s} {'rel. residual':>13s}"
    )
    print(header)
    rows = []
    for name in args.systems:
        path = os.path.join(tmp.name, f"{name}.npz")  # built once; each child only loads it
        A = system(name)
        sp.save_npz(path, A)
        for solver in args.solvers:
            if solver in SLOW and A.shape[0] > args.slow_max_dofs:
                print(f"{name:7s} {A.shape[0]:7d} {solver:16s} skipped (> --slow-max-dofs)")
                continue
            cmd = [sys.executable, __file__, "--one", solver, name, path]
            cmd += ["--repeats", str(args.repeats)]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                last = (proc.stderr.strip().splitlines() or ["failed"])[-1]
                print(f"{name:7s} {'':>7s} {solver:16s} {last[:80]}")
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            rows.append(r)
            print(
                f"{name:7s} {r['dofs']:7d} {solver:16s} {r['first_ms']:9.1f} "
                f"{r['refactor_ms']:11.1f} {r['solve_ms']:9.2f} {r['held_mb']:8.0f} "
                f"{r['peak_mb']:8.0f} "
                f"{r['rel_residual']:13.1e}"
                + (f"  factor entries {r['factor_entries']}" if "factor_entries" in r else ""),
                flush=True,
            )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
