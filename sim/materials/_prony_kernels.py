"""The compiled step of the Prony recursion (:mod:`sim.materials._prony`).

One loop over the stress components of a layer's points does what numpy did in a dozen array
operations (the history's decay, its increment, the weighted sums), each of which walked the
whole history once (docs/fe_speed.md, "Compiled material laws"). Compiled on first use and
cached on disk by numba; imported lazily so that ``import sim`` does not load numba.
"""

from __future__ import annotations

import numba as nb

__all__ = ["prony_step"]


@nb.njit(cache=True)
def prony_step(S0_new, S0_old, H_old, decay, gamma, coef, inf, S, H_new):
    """One step of the recursion for ``P`` parts (1: the whole stress; 2: ``[iso, vol]``)
    relaxing with their own coefficients over ``N`` shared relaxation times.

    ``S0_new``, ``S0_old`` (P, m): the instantaneous stress at the end and the start of the
    step; ``H_old`` (N, P, m): the history; ``decay[i] = exp(-dt/tau_i)``, ``gamma[i] = (1 -
    exp(-dt/tau_i)) / (dt/tau_i)`` (N,); ``coef`` (N, P): ``g_i`` (and ``k_i``); ``inf`` (P,):
    ``g_inf`` (and ``k_inf``). Writes ``H_new[i, p] = decay[i] H_old[i, p] + gamma[i]
    (S0_new[p] - S0_old[p])`` and ``S = sum_p (inf[p] S0_new[p] + sum_i coef[i, p] H_new[i,
    p])`` (m,). ``decay = 1``, ``gamma = 0`` hold the history as it is."""
    n_terms, n_parts, m = H_old.shape
    for j in range(m):
        s = 0.0
        for p in range(n_parts):
            new = S0_new[p, j]
            jump = new - S0_old[p, j]
            s += inf[p] * new
            for i in range(n_terms):
                h = decay[i] * H_old[i, p, j] + gamma[i] * jump
                H_new[i, p, j] = h
                s += coef[i, p] * h
        S[j] = s
