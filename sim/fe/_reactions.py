"""Nodal internal forces on every dof (constrained ones included) and the support reactions.

``Discretization.evaluate`` returns the residual on the free dofs only. For equilibrium checks
the reaction at the bonded base is needed too: it is the internal force on the constrained dofs,
assembled here from the element forces ``f_ai = sum_q w_q P_iL(q) dN_a/dX_L(q)`` with the
stress of the committed state (``S = g_inf S0(u) + sum_i g_i H_i``, the history held at its
committed value, which is the stress of the converged step).

Sign convention: ``f_int`` is the force the body's stresses exert back on the nodes, so at
equilibrium ``f_int = f_ext`` on every dof; on a constrained dof ``f_ext`` is the support's
reaction on the body.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .fe2d import Discretization, LayerState
    from .solver import Body

__all__ = ["contact_forces", "internal_forces", "support_reactions"]


def internal_forces(disc: Discretization, u: np.ndarray, states: list[LayerState]) -> np.ndarray:
    """Internal nodal forces (n_nodes, 2), N per unit thickness, on all dofs.

    ``states`` supplies the viscoelastic history (the committed one for a converged state)."""
    F = disc.deformation_gradient(u)  # (2, 2, e, q)
    C = np.stack(
        [
            F[0, 0] ** 2 + F[1, 0] ** 2,
            F[0, 1] ** 2 + F[1, 1] ** 2,
            F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1],
        ]
    )
    S = np.empty_like(C)
    for mat, sl, st in zip(disc.materials, disc.slices, states, strict=True):
        g = np.asarray(mat.prony.g, dtype=float)
        S0 = mat.instantaneous.stress(C[:, sl])
        S[:, sl] = mat.prony.g_inf * S0 + (np.tensordot(g, st.H, axes=1) if len(g) else 0.0)
    Sm = np.array([[S[0], S[2]], [S[2], S[1]]])
    P = np.einsum("iJeq,JLeq->iLeq", F, Sm)
    # f[e, a, i] = sum_q w P_iL dN_aL ; dN has shape (e, q, a, L)
    fe = np.einsum("iLeq,eqaL,eq->eai", P, disc.dN, disc.w)
    dofs = 2 * disc.edofs_scalar[:, :, None] + np.arange(2)
    out = np.bincount(dofs.ravel(), weights=fe.ravel(), minlength=2 * disc.n_nodes)
    return out.reshape(disc.n_nodes, 2)


def support_reactions(body: Body) -> np.ndarray:
    """Forces (n_nodes, 2) the supports (bonded base, symmetry axis) exert on the body in the
    committed state: the internal force on the constrained dofs, zero on the free ones."""
    f = internal_forces(body.disc, body.u, body.states)
    return np.where(body.disc.fixed, f, 0.0)


def contact_forces(body: Body) -> dict[str, np.ndarray]:
    """Penalty contact forces (n_nodes, 2) on the body in the committed state, per obstacle
    (``"indenter"``, ``"base"``): ``kappa_i * penetration * normal`` as ``Body._add_contact``
    applies them, i.e. on the free dofs only."""
    disc = body.disc
    s = disc.surface_nodes
    xy = disc.X[s] + body.u[s]
    out = {}
    obstacles = [("base", body.base, body.kappa_nodes, 0.0)]
    if body.indenter is not None and np.isfinite(body.indenter_position):
        obstacles.append(("indenter", body.indenter, body.kappa_indenter, body.indenter_position))
    for name, obstacle, kappa, position in obstacles:
        p, n = obstacle.penetration(xy, position)
        f = np.zeros((disc.n_nodes, 2))
        f[s] = np.where(p > 0.0, kappa * p, 0.0)[:, None] * n
        out[name] = np.where(disc.fixed, 0.0, f)
    return out
