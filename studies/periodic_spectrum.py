"""Why a creeping pad needs a dozen taps to its periodic state: the spectrum of the tap map.

    python studies/periodic_spectrum.py [--design 0] [--taps 8] [--arnoldi 12]
    python studies/periodic_spectrum.py --variants [--design 0 4 5]

The periodic state is the fixed point of the map ``G`` that one tap and the per-term jump make
of the Prony state at a tap's start (``sim.protocols.periodic``); Anderson's acceleration
(depth 3) solves ``G(x) = x`` by secants. On the default 3D space's design 0 (a skin relaxing
79 % over an elastic core) the residual falls by only about 0.6 a tap. This study takes the
design's 2D section (the same periodic machinery at a hundredth of the 3D cost), taps it
``--taps`` times as ``run_tapping`` does, and then, at the last iterate ``x``:

- **linearity**: ``(G(x + eps v) - G(x)) / eps`` along the last step ``v`` for eps from 3e-2
  to 3e-4 of ``|x|``, its norm and its change between successive eps (a smooth map keeps
  both);
- **spectrum**: ``--arnoldi`` steps of Arnoldi's iteration on the Jacobian of ``G`` (each
  product a tap from ``x + eps v``, eps = 1e-2, in the residual's weighted norm), printing
  the Ritz values after each step.

Eigenvalues of G's Jacobian near or beyond the unit circle, complex, and a dozen of them, are
what a secant method of depth 3 cannot remove in a few taps. The accelerated state is
re-equilibrated with Newton's tolerance a thousand times tighter here, so that a perturbation
of 1e-3 of the state is not lost below it (``--tight 1`` keeps the tolerance of the runs).

``--variants`` runs whole tappings of each ``--design`` to the periodic state with variants of
the scheme and prints taps, factorisations and residuals: the scheme as it is, the per-term
decays scaled by 0.75 (the residual kept the scheme's), and a jump exact for a point whose
stress, not strain, repeats each period (``(I - M)^-1 (H_end - M H_start)``, ``M = exp(A T)``
with ``A = -(I + 1 g^T / g_inf)^-1 diag(1 / tau)``).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the FE runs (before numpy)
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import importlib

import numpy as np
import scipy.linalg as sla
from paired import default3d_design

from sim.fe import Body, model_newton
from sim.options import SimOptions
from sim.protocols import periodic
from sim.protocols.loading import REGISTRY, _Taps


def tapping_body(design, options: SimOptions) -> tuple[Body, _Taps]:
    simulate_module = importlib.import_module("sim.simulate")
    disc = simulate_module.discretize(design, options, "tapping")
    proto = REGISTRY["tapping"]
    body = Body(disc, proto.make_indenter(options.tapping), model_newton(options.newton, 2))
    return body, _Taps(body, options.tapping)


class TightSet(periodic.PeriodicState):
    """The periodic state whose accelerated states are re-equilibrated with Newton's tolerance
    ``tight`` times the body's."""

    tight = 1e-3

    def _set(self, flat: np.ndarray) -> bool:
        atol = self.body.atol
        self.body.atol = atol * self.tight
        try:
            return super()._set(flat)
        finally:
            self.body.atol = atol


def spectrum(args: argparse.Namespace) -> None:
    TightSet.tight = args.tight
    design = default3d_design(args.design[0])
    options = SimOptions()
    body, taps = tapping_body(design, options)
    state = TightSet(body, taps.t_load + options.tapping.rest_s)
    steps = options.tapping.steps_settle
    for k in range(args.taps):
        H0 = [s.H for s in body.states]
        metrics, _, H_peak = taps.tap(steps)
        status = state.after_tap(H0, H_peak, metrics)
        print(f"tap {k + 1}: residual {status.residual:.2e}", flush=True)
        state.accelerate()
    snap = body.snapshot()
    x0 = state._flat([s.H for s in body.states])
    w = state._weight_vector([s.H for s in body.states])
    nx = float(np.linalg.norm(w * x0))

    def G(x: np.ndarray) -> np.ndarray:
        body.restore(snap)
        if not state._set(x):
            raise RuntimeError("the perturbed state could not be equilibrated")
        H0 = [s.H.copy() for s in body.states]
        taps.tap(steps)
        return state._flat(state._jump(H0, [s.H for s in body.states]))

    g0 = G(x0)
    v = state.xs[-1] - state.xs[-2]  # the last step
    v *= nx / float(np.linalg.norm(w * v))
    print("linearity along the last step (|J v| / |v| in the weighted norm):")
    previous = None
    for eps in (3e-2, 1e-2, 3e-3, 1e-3, 3e-4):
        Jv = (G(x0 + eps * v) - g0) / eps
        size = float(np.linalg.norm(w * Jv)) / nx
        change = ""
        if previous is not None:
            moved = np.linalg.norm(w * (Jv - previous)) / np.linalg.norm(w * Jv)
            change = f", change from the eps before {moved:.1e}"
        print(f"  eps {eps:.0e}: {size:.3f}{change}", flush=True)
        previous = Jv
    if not args.arnoldi:
        return
    print(f"Arnoldi on G's Jacobian (eps 1e-2, {args.arnoldi} taps): Ritz values")
    basis = [w * v / nx]
    basis[0] /= np.linalg.norm(basis[0])
    hess = np.zeros((args.arnoldi + 1, args.arnoldi))
    for j in range(args.arnoldi):
        step = np.divide(basis[j], w, out=np.zeros_like(x0), where=w > 0) * nx
        z = w * (G(x0 + 1e-2 * step) - g0) / (1e-2 * nx)
        for i in range(j + 1):
            hess[i, j] = basis[i] @ z
            z = z - hess[i, j] * basis[i]
        hess[j + 1, j] = np.linalg.norm(z)
        basis.append(z / hess[j + 1, j])
        ritz = np.linalg.eigvals(hess[: j + 1, : j + 1])
        ritz = ritz[np.argsort(-np.abs(ritz))]
        shown = ", ".join(
            f"{r.real:.2f}{r.imag:+.2f}i" if abs(r.imag) > 1e-9 else f"{r.real:.2f}" for r in ritz
        )
        print(f"  {j + 1}: |largest| {abs(ritz[0]):.2f}; {shown}", flush=True)


def stress_jump(state: periodic.PeriodicState, period_s: float):
    """The jump exact for a point whose stress repeats each period (module docstring)."""
    mats = []
    for m in state.body.disc.materials:
        tau = np.asarray(m.prony.tau_s, dtype=float)
        parts = [np.asarray(m.prony.g, dtype=float)]
        if getattr(m, "split_relaxation", False):
            parts.append(np.asarray(m.prony_k, dtype=float))
        per_part = []
        for c in parts if tau.size else []:
            coupling = np.eye(tau.size) + np.outer(np.ones(tau.size), c) / (1 - c.sum())
            A = -np.linalg.solve(coupling, np.diag(1 / tau))
            M = sla.expm(A * period_s)
            per_part.append((M, np.linalg.inv(np.eye(tau.size) - M)))
        mats.append(per_part)

    def jump(H_start, H_end):
        out = []
        for per_part, hs, he in zip(mats, H_start, H_end, strict=True):
            if not per_part:
                out.append(he)
                continue
            res = np.empty_like(he)
            for p, (M, R) in enumerate(per_part):
                sl = (slice(None), p) if len(per_part) > 1 else (slice(None),)
                r = he[sl] - np.tensordot(M, hs[sl], axes=(1, 0))
                res[sl] = np.tensordot(R, r, axes=(1, 0))
            out.append(res)
        return out

    return jump


def variant_run(index: int, variant: str) -> dict:
    """A whole tapping of design ``index``'s 2D section with the scheme's ``variant``."""
    design = default3d_design(index)
    options = SimOptions()
    cls = periodic.PeriodicState
    original_init, original_after = cls.__init__, cls.after_tap

    def init(self, body, period_s, depth=3):
        original_init(self, body, period_s, depth)
        self._true_jump = self._jump
        if variant == "decay x 0.75":
            self._true_decay = self._decay
            self._decay = [0.75 * e for e in self._decay]
        elif variant == "stress jump":
            self._jump = stress_jump(self, period_s)

    def after_tap(self, H_start, H_peak, metrics):
        status = original_after(self, H_start, H_peak, metrics)
        decay = self._decay
        self._decay = getattr(self, "_true_decay", decay)  # the residual of the scheme
        try:
            H_end = [s.H for s in self.body.states]
            wv = self._weight_vector(H_end)
            f = self._flat(type(self)._jump(self, H_start, H_end)) - self._flat(H_start)
            scale = float(np.linalg.norm(wv * self._flat(H_peak)))
            return periodic.PeriodicStatus(float(np.linalg.norm(wv * f)) / scale, status.error)
        finally:
            self._decay = decay

    cls.__init__, cls.after_tap = init, after_tap
    try:
        simulate_module = importlib.import_module("sim.simulate")
        res = simulate_module.simulate(design, ("tapping",), options)
    finally:
        cls.__init__, cls.after_tap = original_init, original_after
    return res.protocols["tapping"]


def variants(args: argparse.Namespace) -> None:
    for index in args.design:
        for variant in ("as it is", "decay x 0.75", "stress jump"):
            f = variant_run(index, variant)
            residuals = " ".join(f"{r:.1e}" for r in f["residual_history"])
            print(
                f"design {index}, {variant}: taps {f['taps']}, settled {f['settled']}, "
                f"factorisations {f['factorizations']}; residuals {residuals}",
                flush=True,
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", type=int, nargs="+", default=[0])
    ap.add_argument("--taps", type=int, default=8, help="taps before the spectrum is read")
    ap.add_argument("--arnoldi", type=int, default=12, help="Arnoldi steps (taps each)")
    ap.add_argument("--tight", type=float, default=1e-3, help="re-equilibration's tolerance factor")
    ap.add_argument("--variants", action="store_true", help="whole tappings with variants")
    args = ap.parse_args()
    if args.variants:
        variants(args)
    else:
        spectrum(args)


if __name__ == "__main__":
    main()
