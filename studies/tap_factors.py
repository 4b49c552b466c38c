"""Whether the 3D tapping gains from one kept factorisation per loading step (solver 2.15):
default-space designs' tapping with ``sim.protocols.loading.KEEP_STEP_FACTORS`` and without.

    python studies/tap_factors.py [--designs 0 1 2 3 4 5]
    python studies/tap_factors.py --memory

Runs each design's tapping twice at once, in two processes, with the factorisations kept per
loading step (``Body.step_factors``: each loading step begins with the factorisation the same
step made in an earlier tap, and one it makes goes to its own PARDISO slot) and without (2.14's
path: each step begins with the last factorisation of this tap), so that both runs share
whatever else the machine is doing. Prints for each: whether it completed, the taps, whether
it settled (an unsettled design's metrics move with any change of Newton's path), the steps
that began with a kept factorisation, the factorisations kept, the factorisations, the Newton
iterations, the residual evaluations, the seconds, the process's peak resident memory, and
the largest relative change of a tapping metric.

``--memory``: the resident memory each PARDISO slot's first factorisation takes on the
reference pad's tangent in single precision, against PARDISO's own count (iparm(17)).
"""

from __future__ import annotations

import argparse
import importlib
import resource

from paired import in_pairs, largest_change, simulate_design

MODES = ("kept", "last")


def run_tapping(design_index: int, mode: str) -> dict:
    """One design's tapping with (``kept``) or without (``last``) the per-step factorisations."""
    loading = importlib.import_module("sim.protocols.loading")
    loading.KEEP_STEP_FACTORS = mode == "kept"
    return simulate_design(design_index, "tapping")


def slot_memory(slots: int = 8) -> None:
    """Resident memory of each slot's first factorisation of the reference pad's tangent."""
    import numpy as np
    import scipy.sparse as sp

    from sim import homogeneous_design
    from sim.fe import Discretization3D
    from sim.fe._linear import make_solver
    from sim.geometry import PadGeometry, build_pad_mesh

    def rss_MB() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * resource.getpagesize() / 2**20

    mat = homogeneous_design("silicone_gls40").materials[0]
    disc = Discretization3D(build_pad_mesh(PadGeometry()), [mat])
    ev = disc.evaluate(np.zeros((disc.n_nodes, 3)), disc.initial_states(), 0.01)
    upper = sp.triu(sp.csc_matrix(disc.pattern_matrix(ev.tangent())), format="csc")
    upper.sort_indices()
    solver = make_solver("pardiso-single", slots)
    before = rss_MB()
    solver.factor(upper)
    first = rss_MB() - before
    print(
        f"{upper.shape[0]} dofs; slot 1: {first:.0f} MB resident, iparm(17) "
        f"{solver._ps.iparm[16] / 1024:.0f} MB; slot_memory_MB {solver.slot_memory_MB():.0f}"
    )
    for slot in range(2, slots + 1):
        solver.slot = slot
        before = rss_MB()
        solver.refactor(upper.data * (1.0 + 0.01 * slot))
        print(f"slot {slot}: {rss_MB() - before:.0f} MB resident")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    ap.add_argument("--memory", action="store_true", help="the memory of a slot, then stop")
    args = ap.parse_args()
    if args.memory:
        slot_memory()
        return
    totals = dict.fromkeys(MODES, 0.0)
    for d, runs in in_pairs(run_tapping, args.designs, MODES):
        for mode, run in runs.items():
            fig = run["figures"]
            totals[mode] += run["seconds"]
            print(
                f"design {d}, {mode}: ok {run['ok']}, taps {fig.get('taps')}, settled "
                f"{fig.get('settled')}, takes {fig.get('step_factor_takes', 0)}, kept "
                f"{fig.get('step_factors', 0)}, factorisations {fig.get('factorizations')}, "
                f"Newton iterations {fig.get('newton_iterations')}, evaluations "
                f"{fig.get('evaluations')}, {run['seconds']:.1f} s, {run['max_rss_MB']:.0f} MB",
                flush=True,
            )
        change = largest_change(runs["kept"]["metrics"], runs["last"]["metrics"])
        print(f"design {d}: largest relative change of a tapping metric {change:.1e}")
    print("seconds in all: " + ", ".join(f"{m} {s:.1f}" for m, s in totals.items()))


if __name__ == "__main__":
    main()
