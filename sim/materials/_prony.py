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

**Shear and bulk apart** (Abaqus: ``g_i`` for shear, ``k_i`` for bulk, sharing ``tau_i``).  For a
law with a decoupled energy ``S0 = S0_iso + S0_vol`` (:mod:`sim.materials._law`) each part has
its own history, ``H_i = [H_i^iso, H_i^vol]`` updated by the same recursion, and (the
reference-configuration split of Simo 1987; Holzapfel, *Nonlinear Solid Mechanics*, 2000)

    S = g_inf S0_iso + sum_i g_i H_i^iso + k_inf S0_vol + sum_i k_i H_i^vol,   k_inf = 1 - sum k_i,

with the consistent tangent ``(g_inf + sum g_i gamma_i) D0_iso + (k_inf + sum k_i gamma_i)
D0_vol`` (:func:`prony_update_split`).  ``k_i = g_i`` is the whole-stress series above.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from sim.errors import DesignError
from sim.materials import _validate as v
from sim.materials._special import exprel

Array = np.ndarray

# Maximum number of Prony terms N_G.
MAX_PRONY_TERMS = 6


def _step(
    S0_new: Array,
    S0_old: Array,
    H_old: Array,
    dt_s: float | None,
    coef: Array,
    tau_s: Sequence[float],
    parts: int,
) -> tuple[Array, Array, Array]:
    """``(S, H_new, gamma)`` of the compiled recursion (:func:`sim.materials._prony_kernels.
    prony_step`) for ``parts`` parts stacked on the first axis of ``S0_new`` (1: the whole
    stress with a leading axis of length 1 added, ``coef`` (N,); 2: ``[iso, vol]``, ``coef``
    (N, 2)); ``dt_s = None`` holds the history as it is (``gamma = 0``)."""
    from sim.materials._prony_kernels import prony_step

    S0_new = np.asarray(S0_new, dtype=float)
    H_old = np.asarray(H_old, dtype=float)
    n = len(tau_s)
    if dt_s is None:
        decay, gamma = np.ones(n), np.zeros(n)
    else:
        z = dt_s / np.asarray(tau_s, dtype=float)
        decay = np.exp(-z)
        gamma = np.asarray(exprel(-z), dtype=float)  # (1 - exp(-z)) / z, 1 at z = 0
    coef = coef.reshape(n, parts)
    inf = 1.0 - coef.sum(axis=0)
    flat_new = S0_new.reshape(parts, -1)
    flat_old = np.asarray(S0_old, dtype=float).reshape(parts, -1)
    H_new = np.empty_like(H_old)
    S = np.empty(flat_new.shape[1])
    prony_step(
        flat_new, flat_old, H_old.reshape(n, parts, -1), decay, gamma, coef, inf, S,
        H_new.reshape(n, parts, -1),
    )  # fmt: skip
    return S.reshape(S0_new.shape[1:]), H_new, gamma


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
    if g_arr.size == 0:
        return np.array(S0_new, dtype=float, copy=True), np.asarray(H_old), 1.0
    S0 = np.asarray(S0_new, dtype=float)[None]  # one part
    S, H_new, gamma = _step(S0, S0_old, H_old, dt_s, g_arr, tau_s, 1)
    return S, H_new, 1.0 - float(g_arr.sum()) + float(g_arr @ gamma)


def prony_update_split(
    S0_new: Array,
    S0_old: Array,
    H_old: Array,
    dt_s: float,
    g: Sequence[float],
    k: Sequence[float],
    tau_s: Sequence[float],
) -> tuple[Array, Array, Array]:
    """One step of the recursion with separate shear (``g``) and bulk (``k``) coefficients.

    ``S0_new``, ``S0_old``: the instantaneous stress split as ``[iso, vol]`` (MPa), shape
    ``(2, 3, *batch)`` (any shape ``(2, ...)`` works); ``H_old``: history, shape
    ``(N_G, 2, 3, *batch)`` (MPa; the term axis first, as in :func:`prony_update`); ``dt_s``,
    ``tau_s`` as there; ``g``, ``k``: shear and bulk coefficients (same length as ``tau_s``).

    Returns ``(S, H_new, factors)``: the viscoelastic stress (MPa, shape ``S0_new.shape[1:]``),
    the new history and ``factors = [g_inf + sum g_i gamma_i, k_inf + sum k_i gamma_i]`` that
    multiply ``D0_iso`` and ``D0_vol`` in the consistent tangent.
    """
    if not dt_s >= 0.0:
        raise ValueError(f"dt_s must be >= 0, got {dt_s}")
    g_arr = np.asarray(g, dtype=float)
    k_arr = np.asarray(k, dtype=float)
    if g_arr.size == 0:
        return S0_new[0] + S0_new[1], np.asarray(H_old), np.ones(2)
    coef = np.stack((g_arr, k_arr), axis=1)
    S, H_new, gamma = _step(S0_new, S0_old, H_old, dt_s, coef, tau_s, 2)
    g_inf, k_inf = 1.0 - float(g_arr.sum()), 1.0 - float(k_arr.sum())
    return S, H_new, np.array([g_inf + float(g_arr @ gamma), k_inf + float(k_arr @ gamma)])


def prony_stress_split(
    S0: Array, H: Array, g: Sequence[float], k: Sequence[float]
) -> tuple[Array, Array]:
    """``(S, factors)`` for the split state ``S0`` (``(2, ...)``) and history ``H``
    (``(N_G, 2, ...)``) held as they are: ``S = g_inf S0_iso + sum g_i H_i^iso + k_inf S0_vol +
    sum k_i H_i^vol``, ``factors = [g_inf, k_inf]`` (the tangent with the history held fixed)."""
    g_arr = np.asarray(g, dtype=float)
    k_arr = np.asarray(k, dtype=float)
    factors = np.array([1.0 - float(g_arr.sum()), 1.0 - float(k_arr.sum())])
    if not g_arr.size:
        return factors[0] * S0[0] + factors[1] * S0[1], factors
    coef = np.stack((g_arr, k_arr), axis=1)
    return _step(S0, S0, H, None, coef, [1.0] * g_arr.size, 2)[0], factors


def prony_stress(S0: Array, H: Array, g: Sequence[float]) -> tuple[Array, float]:
    """``(S, g_inf)`` for the whole-stress state ``S0`` and history ``H`` (``(N_G, *S0.shape)``)
    held as they are: ``S = g_inf S0 + sum g_i H_i``."""
    g_arr = np.asarray(g, dtype=float)
    g_inf = 1.0 - float(g_arr.sum())
    if not g_arr.size:
        return g_inf * np.asarray(S0, dtype=float), g_inf
    S0 = np.asarray(S0, dtype=float)
    return _step(S0[None], S0, H, None, g_arr, [1.0] * g_arr.size, 1)[0], g_inf


@dataclasses.dataclass(frozen=True)
class Prony:
    """Prony series: ``g`` (dimensionless, each >= 0, sum < 1), ``tau_s`` (s, > 0) and the
    optional bulk coefficients ``k`` (same length as ``g``, each >= 0, sum < 1).

    ``k = None`` means "not given": a :class:`~sim.materials.Material` resolves it to its law's
    default (``Material.prony_k``; shear-only for the invariant laws, ``k = g`` for the hyperfoam)
    and keeps ``None`` whenever ``k`` equals that default.  The methods here act on one stress
    with ``g`` (whole-stress relaxation); the split update is :func:`prony_update_split`.
    ``Prony()`` (no terms) is elastic.
    """

    g: tuple[float, ...] = ()
    tau_s: tuple[float, ...] = ()
    k: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        g, tau = self.check(self.g, self.tau_s, "")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "tau_s", tau)
        if self.k is not None:
            object.__setattr__(self, "k", self.check_k(self.k, g, ""))

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

    @staticmethod
    def check_k(k: Any, g: tuple[float, ...], prefix: str) -> tuple[float, ...]:
        """Validate ``prony_k`` against the validated ``g``; errors name ``f"{prefix}prony_k"``.

        Bounds as for ``g`` and for the same reasons: each term is a spring of positive
        stiffness (``k_i >= 0``) and the long-term bulk modulus stays positive
        (``k_inf = 1 - sum k_i > 0``).
        """
        field = f"{prefix}prony_k"
        k = v.number_list(k, field, 0, MAX_PRONY_TERMS)
        if len(k) != len(g):
            raise DesignError(field, f"must have as many terms as prony_g ({len(g)}), got {len(k)}")
        for i, ki in enumerate(k):
            if not ki >= 0.0:
                raise DesignError(field, f"prony_k[{i}] must be >= 0, got {ki:g}")
        if not sum(k) < 1.0:
            raise DesignError(field, f"sum must be < 1, got {sum(k):g}")
        return k

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
        """True when there is no relaxation (no terms, or all ``g_i`` and ``k_i`` zero)."""
        return not any(self.g) and not any(self.k or ())

    def relaxation(self, t_s: Any, coefficients: Sequence[float] | None = None) -> Array:
        """``g(t) = 1 - sum g_i (1 - exp(-t / tau_i))`` for ``t_s`` (s, any shape).

        With ``coefficients`` (e.g. the bulk ``k_i``) the same function of those instead.
        """
        coefs = self.g if coefficients is None else tuple(coefficients)
        t = np.asarray(t_s, dtype=float)
        out = np.ones_like(t)
        for gi, ti in zip(coefs, self.tau_s, strict=True):
            out -= gi * -np.expm1(-t / ti)
        return out

    def initial_history(self, stress_shape: tuple[int, ...]) -> Array:
        """Zero history ``H`` of shape ``(N_G, *stress_shape)`` (undeformed, at rest)."""
        return np.zeros((self.n_terms, *stress_shape))

    def update(
        self, S0_new: Array, S0_old: Array, H_old: Array, dt_s: float
    ) -> tuple[Array, Array, float]:
        """One recursive step of the whole stress with ``g``; see :func:`prony_update`."""
        return prony_update(S0_new, S0_old, H_old, dt_s, self.g, self.tau_s)

    def to_dict(self) -> dict[str, list[float]]:
        """Design-file keys ``prony_g``, ``prony_tau_s`` and, when given, ``prony_k`` (empty dict
        when there are no terms)."""
        if not self.g:
            return {}
        out = {"prony_g": list(self.g), "prony_tau_s": list(self.tau_s)}
        if self.k is not None:
            out["prony_k"] = list(self.k)
        return out
