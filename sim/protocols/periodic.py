"""The periodic (quasi-steady) state of repeated taps, with a residual and an error estimate.

Serina et al. measured the fingertip after minutes of tapping, so the tapping metrics belong to
the *periodic* state of the body under the repeated load. The only state that carries memory from
one tap to the next is the set of Prony internal stresses ``H`` at the start of a tap (the
displacements follow from them by equilibrium): a tap maps it to the next, ``x -> Phi(x)``, and
the periodic state is the fixed point ``x* = Phi(x*)``.

**Per-term closed form (the preconditioner).** A Prony term whose input repeats each period obeys
``H_end = e_i H_start + c_i`` with ``e_i = exp(-period / tau_i)``, so its periodic value is
``(H_end - e_i H_start) / (1 - e_i)``, exact after one tap. The map
``G(x) = (Phi(x) - e x) / (1 - e)`` has the same fixed points as ``Phi``; it settles terms with
``tau_i << period`` (``e_i -> 0``: ``G = Phi``) and ``tau_i >> period`` alike. What ``G`` does not
capture is the coupling through the geometry: a soft body creeping under force control drifts with
retardation times ``tau_i / g_inf``, much longer than any ``tau_i``.

**Anderson acceleration** (type II, depth ``m``) over the iterates of ``G`` captures that slow,
nearly linear mode: with residuals ``f_j = G(x_j) - x_j`` it finds ``gamma`` minimising
``|f_k - dF gamma|`` and continues from ``G(x_k) - dG gamma`` (Walker & Ni 2011, SIAM J. Numer.
Anal. 49:1715).

**Stopping rule: a residual, with an estimate of each metric's remaining error.**

- The residual is ``|f_k| / |H_peak|``: the distance of the tap's starting Prony state from its
  periodic value under the per-term closed form, relative to the size of the Prony state at the
  tap's peak load, in the norm ``|H|^2 = sum_i g_i^2 sum_q w_q |H_i(q)|^2`` (quadrature weights
  ``w_q``; the term weight ``g_i`` is how much the term adds to the stress).
- The same secant model that Anderson uses predicts the fixed point ``x_k - dX gamma``, where the
  metrics are ``m_k - dM gamma`` (``dM``: the metrics' differences between the same taps). The
  estimated error of the last tap's metric is therefore ``|dM gamma|``, plus the part of the
  residual that the model does not explain, ``|f_k - dF gamma|``, times the metric's sensitivity
  along the last step, ``|m_k - m_{k-1}| / |x_k - x_{k-1}|``.

Taps stop when the residual and every metric's estimated relative error are below their
tolerances. Both come from the last tap, which is exactly what is reported: nothing is
extrapolated into the metrics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fe import Body, Control

__all__ = ["PeriodicState", "PeriodicStatus"]


@dataclass(frozen=True)
class PeriodicStatus:
    """After one tap: the relative residual of the periodic Prony state and, per metric, the
    estimated absolute error of that tap's value (``inf`` where there is no estimate yet, ``nan``
    for a metric the tap did not reach)."""

    residual: float
    error: np.ndarray

    def relative_error(self, metrics: np.ndarray) -> np.ndarray:
        """The estimated error relative to each metric's value."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.error / np.maximum(np.abs(metrics), 1e-12)

    def converged(self, metrics: np.ndarray, residual_tol: float, error_tol: float) -> bool:
        """Residual and every reached metric's estimated relative error within tolerance."""
        rel = self.relative_error(metrics)
        rel = rel[np.isfinite(metrics)]
        return bool(self.residual <= residual_tol and np.all(rel <= error_tol))


class PeriodicState:
    """Drives a body's Prony state to the periodic state of repeated taps (module docstring).

    Call :meth:`after_tap` after each tap with the Prony state at the tap's start and at its peak
    and the tap's metrics; it returns the residual and the error estimate. :meth:`accelerate` then
    moves the body to the accelerated next iterate (and re-equilibrates its displacements).
    """

    def __init__(self, body: Body, period_s: float, depth: int = 3) -> None:
        self.body = body
        self.depth = depth
        mats = body.disc.materials
        self._decay = [np.exp(-period_s / np.asarray(m.prony.tau_s, dtype=float)) for m in mats]
        # weights of the norm: per term, g_i (k_i on the volumetric part of a split state)
        # times the quadrature weights of the layer's elements
        self._weights = []
        for m, sl in zip(mats, body.disc.slices, strict=True):
            g = np.asarray(m.prony.g, dtype=float)
            if getattr(m, "split_relaxation", False):  # H: (N_G, 2 = iso/vol, 3, n_el, n_q)
                coef = np.stack([g, np.asarray(m.prony_k, dtype=float)], axis=1)[:, :, None]
            else:  # H: (N_G, 3, n_el, n_q)
                coef = g[:, None]
            w = body.disc.w[sl]
            self._weights.append(np.sqrt(coef[..., None, None] ** 2 * w))
        self.xs: list[np.ndarray] = []
        self.gs: list[np.ndarray] = []
        self.ms: list[np.ndarray] = []
        #: how each tap's next iterate was made: Anderson, the plain per-term jump, or neither
        #: (no accelerated state could be equilibrated: plain tapping)
        self.used = {"anderson": 0, "jump": 0, "plain": 0}

    # -- vectors ------------------------------------------------------------------------------
    def _flat(self, Hs: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([h.ravel() for h in Hs]) if Hs else np.zeros(0)

    def _weight_vector(self, Hs: list[np.ndarray]) -> np.ndarray:
        parts = [
            np.broadcast_to(w, h.shape).ravel() for h, w in zip(Hs, self._weights, strict=True)
        ]
        return np.concatenate(parts) if parts else np.zeros(0)

    def _jump(self, H_start: list[np.ndarray], H_end: list[np.ndarray]) -> list[np.ndarray]:
        out = []
        for e, hs, he in zip(self._decay, H_start, H_end, strict=True):
            if e.size == 0:
                out.append(he)
                continue
            e = e.reshape(-1, *([1] * (he.ndim - 1)))
            out.append((he - e * hs) / (1.0 - e))
        return out

    # -- one tap -----------------------------------------------------------------------------
    def after_tap(
        self, H_start: list[np.ndarray], H_peak: list[np.ndarray], metrics: np.ndarray
    ) -> PeriodicStatus:
        """Record the tap that started from ``H_start`` (the body now holds its end state)."""
        H_end = [s.H for s in self.body.states]
        w = self._weight_vector(H_end)
        x = self._flat(H_start)
        g = self._flat(self._jump(H_start, H_end))
        m = np.asarray(metrics, dtype=float)
        self.xs.append(x)
        self.gs.append(g)
        self.ms.append(m)
        self.xs, self.gs, self.ms = (v[-(self.depth + 1) :] for v in (self.xs, self.gs, self.ms))
        f = g - x
        scale = float(np.linalg.norm(w * self._flat(H_peak)))
        residual = float(np.linalg.norm(w * f)) / max(scale, 1e-300)
        return PeriodicStatus(residual, self._error(w, f, m))

    def _secant(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Differences between consecutive taps in the window: dX, dF, dG, dM, and gamma."""
        xs, gs, ms = self.xs, self.gs, self.ms
        fs = [g - x for g, x in zip(gs, xs, strict=True)]
        dF = np.column_stack([fs[j + 1] - fs[j] for j in range(len(fs) - 1)])
        dG = np.column_stack([gs[j + 1] - gs[j] for j in range(len(gs) - 1)])
        dM = np.column_stack([ms[j + 1] - ms[j] for j in range(len(ms) - 1)])
        gamma = np.linalg.lstsq(w[:, None] * dF, w * fs[-1], rcond=None)[0]
        return dF, dG, dM, gamma

    def _error(self, w: np.ndarray, f: np.ndarray, m: np.ndarray) -> np.ndarray:
        if len(self.xs) < 2:
            return np.where(np.isfinite(m), np.inf, np.nan)
        dF, _, dM, gamma = self._secant(w)
        dM = np.nan_to_num(dM)  # a metric the taps did not reach has no error to estimate
        explained = np.abs(dM @ gamma)
        unexplained = float(np.linalg.norm(w * (f - dF @ gamma)))
        step = float(np.linalg.norm(w * (self.xs[-1] - self.xs[-2])))
        sensitivity = np.abs(dM[:, -1]) / max(step, 1e-300)
        err = explained + sensitivity * unexplained
        return np.where(np.isfinite(m), err, np.nan)

    # -- the next iterate --------------------------------------------------------------------
    def accelerate(self) -> None:
        """Move the body to the accelerated next iterate and re-equilibrate it.

        Anderson's candidate first, then the plain per-term jump; if neither can be equilibrated
        the body continues from where the tap left it (plain tapping)."""
        body = self.body
        snap = body.snapshot()
        candidates = []
        if len(self.xs) >= 2:
            w = self._weight_vector([s.H for s in body.states])
            _, dG, _, gamma = self._secant(w)
            candidates.append(("anderson", self.gs[-1] - dG @ gamma))
        candidates.append(("jump", self.gs[-1]))
        for name, cand in candidates:
            if self._set(cand):
                self.used[name] += 1
                return
            body.restore(snap)
        self.used["plain"] += 1

    def _set(self, flat: np.ndarray) -> bool:
        offset = 0
        for state in self.body.states:
            n = state.H.size
            state.H = flat[offset : offset + n].reshape(state.H.shape).copy()
            offset += n
        return self.body.advance(self.body.t, Control.free(), frozen_history=True).converged
