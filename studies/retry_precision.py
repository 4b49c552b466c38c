"""What rescues a 3D step that Newton failed with single-precision PARDISO: double precision,
or a fresh start? Default-space designs' protocols with ``Body.advance``'s retry as it is
(``now``: from a fresh factorisation, in double precision only where the single-precision
factorisation solved its own tangent worse than ``INEXACT_SOLVE_RTOL``), with every retry in
double precision (``double``, solver 2.16's rule), or as it is with every single-precision
solve refined against the operator it stands for (``refined``: two steps of iterative
refinement with the residual in double precision, directions as exact as double precision's
from the same factorisations).

    python studies/retry_precision.py [--designs 0 1 2 3 4 5] [--protocols tapping plate]
        [--against double|refined] [--residuals]

Runs each design's protocol in two variants at once, in two processes (``now`` and the
``--against`` one), so that both share whatever else the machine is doing, and prints for each
the steps retried in double precision (``precision_fallbacks``) and in single
(``fresh_retries``), the step attempts that failed, the factorisations, the Newton
iterations, the seconds, and the largest relative change of a metric. A factorisation costs
1.7 times as much in double as in single precision (docs/fe_speed.md, "Single precision").
``--residuals`` also prints how well each run's single-precision factorisations solve their own
tangents (``Body.last_factor_residual``: median, 90th percentile, largest; a solve and a
product with the tangent more per factorisation, in both variants)."""

from __future__ import annotations

import argparse
import functools
import importlib

import numpy as np
from paired import Totals, count_failed, in_pairs, print_pair, simulate_design

VARIANTS = ("now", "double", "refined")


class _Refined:
    """Solves with ``solver`` (an inexact factorisation of ``matvec``'s operator), each
    refined by ``steps`` steps of iterative refinement with the residual in double precision."""

    def __init__(self, solver, matvec, steps: int = 2) -> None:
        self._solver, self._matvec, self._steps = solver, matvec, steps

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = self._solver.solve(b)
        for _ in range(self._steps):
            x = x + self._solver.solve(b - self._matvec(x))
        return x


def _refine_single_precision_solves() -> None:
    """Every Newton direction of a single-precision factorisation (kept or fresh, with the
    contact's Woodbury correction or not, bordered under force control) refined against the
    operator the factorisation and its correction stand for."""
    solver_module = importlib.import_module("sim.fe.solver")
    body_class, corrected = solver_module.Body, solver_module._ContactCorrected
    matrices: dict[int, tuple] = {}  # id(what solves) -> (it, its tangent): kept alive
    factor, newton_step = body_class._factor, body_class._newton_step

    def _factor(self, data, active, blocks):
        solver = factor(self, data, active, blocks)
        matrices[id(solver)] = (solver, self.disc.pattern_matrix(data).tocsr())
        return solver

    def matvec_of(solver):
        base = matrices.get(id(getattr(solver, "_solver", solver)))
        if base is None:
            return None
        K = base[1]
        if not isinstance(solver, corrected) or solver._Z is None:
            return lambda x: K @ x

        def with_contact(x: np.ndarray) -> np.ndarray:
            y = K @ x
            y[solver._dofs] += solver._D @ x[solver._dofs]
            return y

        return with_contact

    def _newton_step(self, solver, r, rd, coupling, control):
        matvec = matvec_of(solver) if self.solver_name == "pardiso-single" else None
        if matvec is not None:
            solver = _Refined(solver, matvec)
        return newton_step(self, solver, r, rd, coupling, control)

    body_class._factor, body_class._newton_step = _factor, _newton_step


def run_protocol(design_index: int, variant: str, protocol: str, residuals: bool = False) -> dict:
    """One design's ``protocol`` in ``variant``; its figures, metrics, seconds, failed step
    attempts and (``residuals``) its single-precision factorisations' relative residuals."""
    if variant == "double":  # every retry in double precision (solver 2.16)
        importlib.import_module("sim.fe.solver").INEXACT_SOLVE_RTOL = -1.0
    if variant == "refined":
        _refine_single_precision_solves()
    body_class = importlib.import_module("sim.fe.solver").Body
    failed = count_failed("_advance")
    solved: list[float] = []
    if residuals:
        factor = body_class._factor

        def measured(self, *args, **kwargs):
            solver = factor(self, *args, **kwargs)
            if self._last_factored is not None:  # an inexact solver's
                solved.append(self.last_factor_residual())
            return solver

        body_class._factor = measured
    res = simulate_design(design_index, protocol)
    return {**res, "failed": failed["attempts"], "residuals": solved}


def _describe(res: dict) -> str:
    """A run's line, and its factorisations' residuals (``--residuals``) on a line below."""
    fig = res["figures"]
    out = (
        f"ok {res['ok']}, retries in double {fig.get('precision_fallbacks')}, in single "
        f"{fig.get('fresh_retries')}, failed attempts {res['failed']}, factorisations "
        f"{fig.get('factorizations')}, Newton iterations {fig.get('newton_iterations')}, "
        f"{res['seconds']:.1f} s"
    )
    if res["residuals"]:
        r = np.array(res["residuals"])
        out += (
            f"\n  single-precision factorisations: {len(r)}, relative residual median "
            f"{np.median(r):.1e}, 90th percentile {np.percentile(r, 90):.1e}, largest "
            f"{r.max():.1e}, beyond 1e-2 {int(np.sum(r > 1e-2))}"
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    ap.add_argument("--protocols", nargs="+", default=["tapping", "plate"])
    ap.add_argument("--against", choices=VARIANTS[1:], default="double")
    ap.add_argument("--residuals", action="store_true")
    args = ap.parse_args()
    variants = ("now", args.against)
    totals = Totals(variants)
    for protocol in args.protocols:
        run = functools.partial(run_protocol, protocol=protocol, residuals=args.residuals)
        for d, runs in in_pairs(run, args.designs, variants):
            print_pair(f"design {d} {protocol}", runs, _describe, totals)
    totals.print()


if __name__ == "__main__":
    main()
