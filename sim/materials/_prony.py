"""Prony-series viscoelasticity on the hyperelastic 2nd Piola-Kirchhoff stress.

Relaxation function ``g(t) = 1 - sum_i g_i (1 - exp(-t / tau_i))`` (Eq. 5 of Cabibihan et al.),
``g_inf = 1 - sum g_i``.  The stress is the hereditary integral
``S(t) = int_0^t g(t - s) dS0/ds ds`` of the instantaneous hyperelastic stress ``S0``, updated
recursively (Simo 1987; Abaqus):

    H_i(t_{n+1}) = exp(-dt/tau_i) H_i(t_n) + gamma_i (S0_{n+1} - S0_n),
    gamma_i = (1 - exp(-dt/tau_i)) / (dt/tau_i)          (-> 1 as dt -> 0),
    S(t_{n+1}) = g_inf S0_{n+1} + sum_i g_i H_i(t_{n+1}),

exact when ``S0`` is piecewise linear in time (so exact for a step and for a linear ramp).
The consistent tangent is ``(g_inf + sum g_i gamma_i) D0``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.special import exprel

from sim.errors import DesignError
from sim.materials import _validate as v

Array = np.ndarray

# Maximum number of Prony terms N_G.
MAX_PRONY_TERMS = 6


def prony_update(
    S0_new: Array,
    S0_old: Array,
    H_old: Array,
    dt_s: float,
    g: Sequence[float],
    tau_s: Sequence[float],
) -> tuple[Array, Array, float]:
    """One step of the recursive hereditary integral.

    ``S0_new``, ``S0_old``: instantaneous hyperelastic stress at the end / start of the step
    (MPa), shape ``(3, *batch)`` (any shape works); ``H_old``: history, shape
    ``(N_G, 3, *batch)`` (MPa, zeros in the undeformed initial state); ``dt_s >= 0``: time step
    (s); ``g``, ``tau_s``: Prony coefficients and relaxation times (s).

    Returns ``(S, H_new, tangent_factor)``: the viscoelastic stress (MPa, shape of ``S0_new``),
    the new history (shape of ``H_old``) and the scalar ``g_inf + sum g_i gamma_i`` that
    multiplies the instantaneous tangent ``D0``.
    """
    if not dt_s >= 0.0:
        raise ValueError(f"dt_s must be >= 0, got {dt_s}")
    g_arr = np.asarray(g, dtype=float)
    g_inf = 1.0 - float(g_arr.sum())
    if g_arr.size == 0:
        return np.array(S0_new, dtype=float, copy=True), np.asarray(H_old), 1.0
    z = dt_s / np.asarray(tau_s, dtype=float)
    decay = np.exp(-z)
    gamma = exprel(-z)  # (1 - exp(-z)) / z, 1 at z = 0
    expand = (slice(None),) + (None,) * np.ndim(S0_new)
    H_new = decay[expand] * H_old + gamma[expand] * (S0_new - S0_old)
    S = g_inf * S0_new + np.tensordot(g_arr, H_new, axes=1)
    return S, H_new, g_inf + float(g_arr @ gamma)


@dataclasses.dataclass(frozen=True)
class Prony:
    """Prony series: ``g`` (dimensionless, each >= 0, sum < 1) and ``tau_s`` (s, > 0).

    ``Prony()`` (no terms) is elastic.
    """

    g: tuple[float, ...] = ()
    tau_s: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        g, tau = self.check(self.g, self.tau_s, "")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "tau_s", tau)

    @staticmethod
    def check(g: Any, tau_s: Any, prefix: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Validate ``prony_g``/``prony_tau_s``; errors name ``f"{prefix}prony_g"`` etc."""
        g = v.number_list(g, f"{prefix}prony_g", 0, MAX_PRONY_TERMS)
        tau = v.number_list(tau_s, f"{prefix}prony_tau_s", 0, MAX_PRONY_TERMS)
        if len(tau) != len(g):
            raise DesignError(
                f"{prefix}prony_tau_s",
                f"must have as many terms as prony_g ({len(g)}), got {len(tau)}",
            )
        for i, gi in enumerate(g):
            if not gi >= 0.0:
                raise DesignError(f"{prefix}prony_g", f"prony_g[{i}] must be >= 0, got {gi:g}")
        for i, ti in enumerate(tau):
            if not ti > 0.0:
                raise DesignError(
                    f"{prefix}prony_tau_s", f"prony_tau_s[{i}] must be > 0, got {ti:g}"
                )
        if not sum(g) < 1.0:
            raise DesignError(f"{prefix}prony_g", f"sum must be < 1, got {sum(g):g}")
        return g, tau

    @property
    def n_terms(self) -> int:
        """Number of terms ``N_G``."""
        return len(self.g)

    @property
    def g_inf(self) -> float:
        """Long-term relative modulus ``g_inf = 1 - sum g_i``."""
        return 1.0 - float(sum(self.g))

    @property
    def is_elastic(self) -> bool:
        """True when there is no relaxation (no terms or all ``g_i = 0``)."""
        return not any(self.g)

    def relaxation(self, t_s: Any) -> Array:
        """``g(t) = 1 - sum g_i (1 - exp(-t / tau_i))`` for ``t_s`` (s, any shape)."""
        t = np.asarray(t_s, dtype=float)
        out = np.ones_like(t)
        for gi, ti in zip(self.g, self.tau_s, strict=True):
            out -= gi * -np.expm1(-t / ti)
        return out

    def initial_history(self, stress_shape: tuple[int, ...]) -> Array:
        """Zero history ``H`` of shape ``(N_G, *stress_shape)`` (undeformed, at rest)."""
        return np.zeros((self.n_terms, *stress_shape))

    def update(
        self, S0_new: Array, S0_old: Array, H_old: Array, dt_s: float
    ) -> tuple[Array, Array, float]:
        """One recursive step; see :func:`prony_update` (shapes, units, return values)."""
        return prony_update(S0_new, S0_old, H_old, dt_s, self.g, self.tau_s)

    def to_dict(self) -> dict[str, list[float]]:
        """Design-file keys ``prony_g``, ``prony_tau_s`` (empty dict when there are no terms)."""
        if not self.g:
            return {}
        return {"prony_g": list(self.g), "prony_tau_s": list(self.tau_s)}
