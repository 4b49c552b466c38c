"""The viscoelastic stress and tangent of every layer at the quadrature points: the step of
the assembly that the 2D (``sim.fe.fe2d``) and the 3D (``sim.fe.fe3d``) discretisations share.

``C`` has shape ``(nv, E, Q)``: plane strain ``[C11, C22, C12]`` (nv = 3) or 3D ``[C11, C22,
C33, C12, C23, C13]`` (nv = 6); elements are ordered by layer, layer ``k`` the slice
``slices[k]``. The materials tell the two apart by ``nv`` (``Material.instantaneous_stress``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..materials import Material

__all__ = ["LayerState", "initial_states", "layer_stresses"]


@dataclass
class LayerState:
    """History of one layer at the quadrature points: the instantaneous stress ``S0`` and the
    Prony internal stresses ``H`` (MPa), shapes (nv, n_el, n_q) and (N_G, nv, n_el, n_q); for a
    material whose shear and bulk relax apart (``Material.split_relaxation``) the isochoric and
    volumetric parts are kept apart on an axis of length 2: (2, nv, ...) and (N_G, 2, nv, ...).
    The Prony term axis of ``H`` is always first (and matches ``mat.prony.tau_s``)."""

    S0: np.ndarray
    H: np.ndarray


def initial_states(
    materials: list[Material], slices: list[slice], n_q: int, n_voigt: int
) -> list[LayerState]:
    """Zero history of every layer (undeformed, at rest)."""
    return [
        LayerState(*mat.initial_state((sl.stop - sl.start, n_q), n_voigt))
        for mat, sl in zip(materials, slices, strict=True)
    ]


def layer_stresses(
    materials: list[Material],
    slices: list[slice],
    C: np.ndarray,
    states: list[LayerState],
    dt_s: float,
    tangent: bool,
    frozen_history: bool,
) -> tuple[np.ndarray, np.ndarray | None, list[LayerState]]:
    """``(S, D, new_states)``: the stress (nv, E, Q), its tangent (nv, nv, E, Q) or None, and
    each layer's trial history, one step of ``dt_s`` from the committed ``states``.

    With ``frozen_history`` the Prony internal stresses keep their committed values (S = g_inf
    S0(u) + sum g_i H_i, plus the bulk terms when shear and bulk relax apart): used to
    re-equilibrate after a cycle jump. Extreme trial states are not warned about: the caller
    rejects a non-finite result."""
    nv = C.shape[0]
    S = np.empty_like(C)
    D = np.empty((nv, nv, *C.shape[1:])) if tangent else None
    new_states = []
    with np.errstate(all="ignore"):
        for mat, sl, st in zip(materials, slices, states, strict=True):
            # S0/D0 of the instantaneous law, split [iso, vol] when shear and bulk relax
            # apart (Material.split_relaxation); otherwise exactly the whole-stress path
            if tangent:
                S0, D0 = mat.instantaneous_stress_tangent(C[:, sl])
            else:
                S0 = mat.instantaneous_stress(C[:, sl])
            if frozen_history:
                Hk = st.H
                Sk, factor = mat.history_stress(S0, Hk)
            else:
                Sk, Hk, factor = mat.relax(S0, st.S0, st.H, dt_s)
            S[:, sl] = Sk
            if tangent:
                D[:, :, sl] = mat.tangent(D0, factor)
            new_states.append(LayerState(S0, Hk))
    return S, D, new_states
