"""Benchmark: the 3D elastic plate, ours against FElupe on the same problem, whole process.

    python benchmarks/bench_felupe.py [--mesh {tiny,coarse,default,xF}] [--ours-mesh MESH]
        [--repeats 3] [--formulation q1p0 [q2-displacement q2-mixed]] [--step-mm 0.1]
        [--json out.json]

The problem (``tests/test_fe3d_felupe.py``'s): the elastic quarter pad (the reference
``PadGeometry()``, one layer of neo-Hookean mu = 0.05 MPa, nu = 0.49), a rigid frictionless flat
plate pressed 1 mm into it from first touch at the apex, in plate increments of ``--step-mm``
(the same plate positions in both codes: a uniform grid plus the recorded depths, a failed
increment halved), the force on the quarter pad recorded at 0.25, 0.5 and 1 mm. The mesh is
shared: ``sim.geometry.build_pad_mesh`` with the tests' tiny or coarse options, the default
``MeshOptions3D()`` or ``xF``, ``MeshOptions3D().refined(F)`` (``x1`` is the default).
``--ours-mesh`` gives ours another mesh than FElupe's: at equal accuracy rather than at equal
nodes (``studies/felupe_work_precision.py`` measures which meshes those are).

- ``ours``: the project's 3D model (``sim.fe.Discretization3D`` + ``sim.fe.solver.Body`` +
  ``Plate``), 27-node hexahedra, pure displacement, as ``our_plate_force`` in the tests but
  with Newton as ``fingertip simulate --model 3d`` runs it (``sim.fe.model_newton``: modified
  Newton with the contact update);
- ``FElupe``: ``sim.verification.felupe_pad.solve_plate`` (what ``felupe_plate_force`` calls)
  with ``--formulation``: ``q1p0`` (default; FElupe's standard nearly incompressible
  hexahedron, the mean-dilatation Q1/P0 on the 2 x 2 x 2 split of our elements: an
  independent discretisation), ``q2-displacement`` (FElupe's 27-node hexahedron, pure
  displacement: the SAME discretisation as ours) or ``q2-mixed``; several may be given.

Whole process: each run is a FRESH child process (``python bench_felupe.py --child ...``) timed
by the parent around ``subprocess.run``: interpreter start, imports (numba loading its cached
compiled kernels for ours, FElupe's own imports), meshing, assembly, solving and exit. One
thread (OMP/MKL/OPENBLAS/NUMBA_NUM_THREADS=1 in the child's environment; FElupe's linear
solver is pypardiso, MKL, where installed). Before the timed runs each code runs once untimed
(``--warmup``): it fills numba's on-disk cache after a code change and the OS's file cache, so
that no timed run pays a first-ever compilation. Each child prints a JSON line: its forces,
its in-process times (imports; meshing + assembly + solving) and its counts (Newton
iterations, factorisations, cut increments).

Printed: a markdown table (code, formulation, mesh, dofs, whole-process s as median and min of
``--repeats``, in-process s, the forces, FElupe's relative to ours), the counts, and the
speed-up of ours against each FElupe row. Equal accuracy: the forces are printed next to each
other with their relative difference, and beside it the agreement documented in
``sim/verification/felupe_pad.py`` (Q1/P0 converges to ours from below under refinement:
-0.73 % / -0.57 % at 0.5 / 1 mm on the default mesh; the same discretisation agrees to the
contact penalties' regularisation, ~1e-3).

The issue's target: ours >= 10x faster than FElupe on this problem at equal accuracy, whole
process. Seconds mean something only on a QUIET machine (nothing else running: the
counts do not depend on the load, the times do); the speed claim is made from this printout,
never asserted in a test (``tests/test_benchmarks.py`` only smoke-tests it on the tiny mesh).
"""

from __future__ import annotations

import os

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
for _var in THREAD_VARS:
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

MU, NU = 0.05, 0.49  # tests/test_fe3d_felupe.py's material (a soft, nearly incompressible skin)
DEPTHS = (0.25, 0.5, 1.0)
#: our 3D elements (``sim.fe.ELEMENTS_3D``) by the name the rows give their formulation
OUR_FORMULATIONS = {"q2": "q2-displacement", "q2p1": "q2p1-projected"}
MESHES = ("tiny", "coarse", "default", "xF")
FORMULATIONS = ("q1p0", "q2-mixed", "q2-displacement")  # sim.verification.felupe_pad's
#: FElupe / ours - 1 at 0.25, 0.5, 1 mm as documented in sim/verification/felupe_pad.py (and
#: tests/test_fe3d_felupe.py) for context; None where nothing is documented
DOCUMENTED = {
    ("q1p0", "coarse"): "-1.5 %, -3.3 %, -1.9 %",
    ("q1p0", "default"): "-1.30 %, -0.73 %, -0.57 %",
    ("q2-mixed", "default"): "1 mm: -0.23 %",
    ("q2-displacement", "tiny"): "+4.4e-4, +1.4e-4 at 0.25, 0.5 mm",
    ("q2-displacement", "coarse"): "within 4e-4",
}


def mesh_name(text: str) -> str:
    """``--mesh``'s argument checked: a name of ``MESHES`` or ``x`` and a refinement factor in
    [0.25, 4] (``x0.7``)."""
    if text in MESHES[:-1]:
        return text
    try:
        factor = float(text[1:]) if text.startswith("x") else math.nan
    except ValueError:
        factor = math.nan
    if not 0.25 <= factor <= 4.0:
        raise argparse.ArgumentTypeError(
            f"mesh must be tiny, coarse, default or xF with F in [0.25, 4], got {text!r}"
        )
    return f"x{factor:g}"


def mesh_options(name: str):
    """The mesh options by name: ``tiny`` is the FElupe comparison's smallest
    (``sim.verification.felupe_pad.TINY_MESH_3D``, 76 elements, 2421 dofs), ``coarse``
    ``sim.geometry.COARSE_MESH_3D`` (180 elements, 5373 dofs), ``default`` ``MeshOptions3D()``
    (1448 elements, 38 901 dofs), ``xF`` ``MeshOptions3D().refined(F)``."""
    from sim.geometry import COARSE_MESH_3D, MeshOptions3D

    name = mesh_name(name)
    if name == "tiny":  # sim.verification only here: it is no part of our whole process
        from sim.verification.felupe_pad import TINY_MESH_3D

        return TINY_MESH_3D
    if name.startswith("x"):
        return MeshOptions3D().refined(float(name[1:]))
    return {"coarse": COARSE_MESH_3D, "default": MeshOptions3D()}[name]


def plate_positions(depths, step_mm: float) -> list[float]:
    """The plate positions (mm from first touch) solved in turn: a uniform grid of ``step_mm``
    up to the deepest depth plus the recorded depths, ascending, without near-duplicates (the
    increments of ``sim.verification.felupe_pad._increments``, so both codes solve the same
    plate positions)."""
    deepest = max(depths)
    n = math.ceil(deepest / step_mm - 1e-9)
    grid = [round(step_mm * k, 12) for k in range(1, n + 1)]
    values = sorted({g for g in grid if g < deepest - 1e-9} | {float(d) for d in depths})
    out: list[float] = []
    for v in values:
        if not out or v - out[-1] > 1e-9:
            out.append(v)
    return out


# ---------------------------------------------------------------------------- children
def child_ours(mesh: str, step_mm: float, element: str = "q2") -> dict:
    """Our quarter-pad plate force, as ``our_plate_force`` in ``tests/test_fe3d_felupe.py``
    at FElupe's plate positions: ``sim.verification.press_plate``'s loop written out, because
    importing ``sim.verification`` (scipy.optimize and the verification cases, ~0.7 s) is no
    part of our model's whole process, and the steps and cuts are counted here. ``element``:
    ``sim.fe.ELEMENTS_3D``."""
    t0 = time.perf_counter()
    from sim.fe import Body, Control, Discretization3D, NewtonOptions, Plate, model_newton
    from sim.geometry import PadGeometry, build_pad_mesh
    from sim.materials._material import material_from_table
    from sim.simulate import SINGLE_PRECISION_PROTOCOLS

    t1 = time.perf_counter()
    pmesh = build_pad_mesh(PadGeometry(), (), mesh_options(mesh))
    t_mesh = time.perf_counter() - t1
    mat = material_from_table({"model": "neo_hookean", "mu_MPa": MU, "nu": NU})
    # Newton and the linear solver as the 3D model's plate runs them (sim.simulate): modified
    # Newton with the contact update, PARDISO in single precision (SINGLE_PRECISION_PROTOCOLS)
    disc = Discretization3D(pmesh, [mat], element=element)
    body = Body(disc, Plate(), model_newton(NewtonOptions(), 3))
    body.single_precision = "plate" in SINGLE_PRECISION_PROTOCOLS
    top = body.top_height()
    d = 0.0
    forces, steps, cuts = [], 0, 0
    recorded = set(DEPTHS)
    for target in plate_positions(DEPTHS, step_mm):
        while d < target - 1e-12:
            dd = target - d
            while not body.advance(d + dd, Control.position(top - d - dd)).converged:
                dd *= 0.5
                cuts += 1
                if dd < 1e-3:
                    raise RuntimeError(f"our plate step at {d} mm failed")
            d += dd
            steps += 1
        if target in recorded:
            forces.append(float(body.force))
    if body.base_contact_nodes() != 0:  # FElupe's model has no base contact
        raise RuntimeError("the pad touched the base")
    t_end = time.perf_counter()
    return {
        "code": "ours",
        "formulation": OUR_FORMULATIONS[element],
        "mesh": mesh,
        "dofs": 3 * body.disc.n_nodes,
        "dofs_free": int(body.disc.n_free),
        "force_quarter_N": forces,
        "newton_iterations": int(body.newton_iterations),
        "factorizations": int(body.factorizations),
        "evaluations": int(body.evaluations),
        "increments": steps,
        "cutbacks": cuts,
        "max_penetration_mm": float(body.max_penetration()),
        "imports_s": t1 - t0,
        "mesh_s": t_mesh,
        "solve_s": t_end - t1,  # meshing + assembly + solving
        "timings_s": {k: float(v) for k, v in body.timings.items()},
        "linear_solver": str(body.solver_name),
    }


def child_felupe(mesh: str, step_mm: float, formulation: str) -> dict:
    """FElupe's quarter-pad plate force: ``felupe_plate_force``'s two lines (mesh, then
    ``solve_plate``), so that its counts are kept."""
    t0 = time.perf_counter()
    import felupe  # noqa: F401  (its import is part of its cost)

    from sim.geometry import PadGeometry, build_pad_mesh
    from sim.verification.felupe_pad import bulk_modulus, solve_plate

    t1 = time.perf_counter()
    options = mesh_options(mesh)
    pmesh = build_pad_mesh(PadGeometry(), (), options)
    t_mesh = time.perf_counter() - t1
    res = solve_plate(
        pmesh,
        MU,
        bulk_modulus(MU, NU),
        DEPTHS,
        formulation=formulation,
        step_mm=step_mm,
        h_apex_mm=options.h_apex_mm,
    )
    t_end = time.perf_counter()
    return {
        "code": "FElupe",
        "formulation": formulation,
        "mesh": mesh,
        "dofs": int(res.dofs_total),
        "dofs_free": int(res.dofs_free),
        "force_quarter_N": list(res.force_quarter_N),
        "newton_iterations": int(res.newton_iterations),
        # FElupe's Newton solves one linear system (a fresh factorisation) per iteration
        "factorizations": int(res.newton_iterations),
        "evaluations": None,
        "increments": len(res.increments_mm),
        "cutbacks": int(res.cutbacks),
        "max_penetration_mm": float(res.max_penetration_mm),
        "imports_s": t1 - t0,
        "mesh_s": t_mesh,
        "solve_s": t_end - t1,  # meshing + assembly + solving
        "linear_solver": res.linear_solver,
    }


def run_child(
    code: str, mesh: str, step_mm: float, formulation: str | None, element: str = "q2"
) -> tuple[float, dict]:
    """One fresh child process: (its wall time measured here, its JSON result); ``element``:
    ours' (``OUR_FORMULATIONS``)."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", code, "--mesh", mesh]
    cmd += ["--step-mm", repr(step_mm)]
    if formulation is not None:
        cmd += ["--formulation", formulation]
    if code == "ours":
        cmd += ["--ours-element", element]
    env = dict(os.environ, **dict.fromkeys(THREAD_VARS, "1"), PYTHONWARNINGS="ignore")
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr}")
    return wall, json.loads(proc.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------- parent
def measure(
    code, mesh, step_mm, formulation, repeats: int, warmup: int, element: str = "q2"
) -> dict:
    for _ in range(warmup):
        run_child(code, mesh, step_mm, formulation, element)
    walls, results = [], []
    for _ in range(repeats):
        wall, res = run_child(code, mesh, step_mm, formulation, element)
        walls.append(wall)
        results.append(res)
    best = results[walls.index(min(walls))]
    return {
        **best,
        "whole_s": walls,
        "whole_median_s": statistics.median(walls),
        "whole_min_s": min(walls),
        "solve_median_s": statistics.median(r["solve_s"] for r in results),
        "imports_median_s": statistics.median(r["imports_s"] for r in results),
    }


def _forces(row) -> str:
    return " | ".join(f"{f:.5f}" for f in row["force_quarter_N"])


def report(rows: list[dict], args) -> None:
    ours = rows[0]
    f_ours = ours["force_quarter_N"]
    depth_cols = " | ".join(f"F {d:g} mm (N)" for d in DEPTHS)
    print(
        f"\nPlate on the elastic quarter pad (mu = {MU} MPa, nu = {NU}), meshes: ours "
        f"{ours['mesh']}, FElupe {args.mesh}, "
        f"steps of {args.step_mm:g} mm, one thread, {args.repeats} fresh processes per code "
        f"(after {args.warmup} untimed), load average {os.getloadavg()[0]:.2f}\n"
    )
    print(
        f"| code | formulation | mesh | dofs | whole-process s (median, min) | in-process s "
        f"| {depth_cols} | relative to ours |"
    )
    print("|---|---|---|---|---|---|" + "---|" * len(DEPTHS) + "---|")
    for row in rows:
        if row is ours:
            rel = "-"
        else:
            rel = ", ".join(
                f"{b / a - 1:+.2%}" for a, b in zip(f_ours, row["force_quarter_N"], strict=True)
            )
        print(
            f"| {row['code']} | {row['formulation']} | {row['mesh']} | {row['dofs']} "
            f"| {row['whole_median_s']:.2f}, {row['whole_min_s']:.2f} "
            f"| {row['solve_median_s']:.2f} | {_forces(row)} | {rel} |"
        )
    print(
        "\nin-process s: meshing + assembly + solving (median); whole-process s adds the "
        "interpreter, the imports and the exit\n"
    )
    print(
        "| code | formulation | imports s | Newton iterations | factorisations | increments "
        "| cut increments | max penetration mm | linear solver |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        print(
            f"| {row['code']} | {row['formulation']} | {row['imports_median_s']:.2f} "
            f"| {row['newton_iterations']} | {row['factorizations']} | {row['increments']} "
            f"| {row['cutbacks']} | {row['max_penetration_mm']:.1e} | {row['linear_solver']} |"
        )
    print()
    for row in rows[1:]:
        whole = row["whole_median_s"] / ours["whole_median_s"]
        inproc = row["solve_median_s"] / ours["solve_median_s"]
        documented = DOCUMENTED.get((row["formulation"], row["mesh"]))
        note = f"; documented FElupe / ours - 1: {documented}" if documented else ""
        print(
            f"speed-up of ours against FElupe {row['formulation']}: {whole:.1f}x whole process "
            f"(medians), {inproc:.1f}x in process (target >= 10x whole process){note}"
        )


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--mesh", type=mesh_name, default="default", help="both codes' (" + ", ".join(MESHES) + ")"
    )
    ap.add_argument("--ours-mesh", type=mesh_name, help="ours' mesh, if not --mesh")
    ap.add_argument(
        "--ours-element", choices=tuple(OUR_FORMULATIONS), default="q2", help="ours' element"
    )
    ap.add_argument("--repeats", type=int, default=3, help="timed fresh processes per code")
    ap.add_argument("--warmup", type=int, default=1, help="untimed processes per code first")
    ap.add_argument(
        "--formulation", choices=FORMULATIONS, nargs="+", default=["q1p0"], help="FElupe's"
    )
    ap.add_argument("--step-mm", type=float, default=0.1, help="plate increment, both codes")
    ap.add_argument("--json", type=Path, help="write the rows here")
    ap.add_argument("--child", choices=["ours", "felupe"], help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child == "ours":  # the parent passes ours' mesh as --mesh
        print(json.dumps(child_ours(args.mesh, args.step_mm, args.ours_element)))
        return []
    if args.child == "felupe":
        print(json.dumps(child_felupe(args.mesh, args.step_mm, args.formulation[0])))
        return []
    ours_mesh = args.ours_mesh or args.mesh
    rows = [
        measure("ours", ours_mesh, args.step_mm, None, args.repeats, args.warmup, args.ours_element)
    ]
    for formulation in args.formulation:
        rows.append(
            measure("felupe", args.mesh, args.step_mm, formulation, args.repeats, args.warmup)
        )
    report(rows, args)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    return rows


if __name__ == "__main__":
    main()
