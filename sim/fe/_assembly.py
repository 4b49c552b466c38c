"""The residual and tangent of the total-Lagrangian solid, shared by the 2D and 3D discretisations.

One evaluation, in either dimension ``d``: the deformation gradient ``F`` from the nodal
displacements, ``J = det F`` (a state with an inverted point is refused), ``C = F^T F``, every
layer's viscoelastic stress (``sim.fe._constitutive.layer_stresses``), and the internal forces
assembled by the compiled kernels (``sim.fe._kernels``) into the free dofs. The tangent is
assembled only when the solver asks for it (``Evaluation.tangent``), with the material tangent
computed then from the same ``C`` and history as the stress: the same law on the same inputs, so
the same bits as computed beside the stress, and line-search trials or modified-Newton
iterations that are never factorised do not pay for it.

A discretisation using it (``KernelAssembly``) provides ``conn`` (E, A) int64, ``dN`` (E, Q, A,
d) and ``w`` (E, Q) as the kernels take them, ``materials``, ``slices`` (each layer's elements)
and ``pattern`` (``sim.fe._pattern``). The kernels (numba) are imported on the first
evaluation, so that ``import sim`` stays light for the command line.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ._constitutive import LayerState, layer_stresses

__all__ = ["Evaluation", "KernelAssembly"]


@dataclass
class Evaluation:
    """Residual (free dofs) at one displacement state, with the tangent assembled on demand.

    ``tangent()`` returns the CSR data of the stiffness in the fixed pattern; it is assembled
    the first time it is asked for (line-search trials that are rejected never pay for it).
    """

    residual: np.ndarray
    _tangent_args: tuple | None
    states: list[LayerState]
    ok: bool = True
    min_J: float = field(default=1.0)
    _assemble: Callable | None = None
    _data: np.ndarray | None = None

    def tangent(self) -> np.ndarray:
        if self._data is None:
            if self._tangent_args is None or self._assemble is None:
                raise ValueError("this evaluation was made without tangent=True")
            self._data = self._assemble(*self._tangent_args)
        return self._data


def determinant(F: np.ndarray) -> np.ndarray:
    """``det F`` (E, Q) of ``F`` (d, d, E, Q), d = 2 or 3, by cofactors."""
    if F.shape[0] == 2:
        return F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    return (
        F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
        - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
        + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
    )


class KernelAssembly:
    """``deformation_gradient``, ``evaluate`` and the lazy tangent of a discretisation whose
    arrays are those of the compiled kernels (the module's docstring)."""

    dim: int
    conn: np.ndarray
    dN: np.ndarray
    w: np.ndarray
    #: the P1 modes and inverse Gram matrices of the projected volume ratio
    #: (``sim.fe._mixed.dilatation_basis``) of the 3D Q2/P1 element; None: pure displacement
    dilatation: tuple[np.ndarray, np.ndarray] | None = None

    def deformation_gradient(self, u: np.ndarray) -> np.ndarray:
        """F with shape (d, d, n_el, n_q) for nodal displacements u (n_nodes, d)."""
        from . import _kernels

        return _kernels.deformation_gradient(np.ascontiguousarray(u), self.conn, self.dN)

    def material_deformation_gradient(self, u: np.ndarray) -> np.ndarray:
        """The deformation gradient the material laws see (d, d, n_el, n_q): ``F`` itself, or
        for the Q2/P1 element ``F̄ = (J̄ / J)^(1/3) F`` with the projected volume ratio
        (``sim.fe._mixed``). The validity's strains and volume ratios are read from it."""
        F = self.deformation_gradient(u)
        if self.dilatation is None:
            return F
        from . import _mixed

        with np.errstate(all="ignore"):
            J = determinant(F)
            Jbar = _mixed.project(J, self.w, *self.dilatation)
            return F * np.cbrt(Jbar / J)

    def evaluate(
        self,
        u: np.ndarray,
        states: list[LayerState],
        dt_s: float,
        tangent: bool = True,
        frozen_history: bool = False,
    ) -> Evaluation:
        """Internal-force residual (free dofs), tangent data on demand and trial history at
        ``u``.

        ``states`` is the history committed at the start of the step and ``dt_s`` the step size.
        With ``frozen_history`` the Prony internal stresses keep their committed values
        (S = g_inf S0(u) + sum g_i H_i, plus the bulk terms when shear and bulk relax apart):
        used to re-equilibrate after a cycle jump."""
        from . import _kernels

        voigt = _kernels.VOIGT[self.dim]
        F = self.deformation_gradient(u)
        with np.errstate(all="ignore"):
            J = determinant(F)
        min_J = float(J.min())
        if not min_J > 1e-8:  # also catches NaN from an overflowing trial
            return Evaluation(np.empty(0), None, states, ok=False, min_J=min_J)
        C = _kernels.right_cauchy_green(F, voigt)
        if self.dilatation is not None:
            return self._evaluate_mixed(F, J, C, states, dt_s, tangent, frozen_history)
        S, _, new_states = layer_stresses(
            self.materials, self.slices, C, states, dt_s, False, frozen_history
        )
        if not np.all(np.isfinite(S)):
            return Evaluation(np.empty(0), None, states, ok=False, min_J=min_J)
        pat = self.pattern
        r = _kernels.internal_forces(F, S, self.dN, self.w, voigt, pat.scatter_r, pat.n_free + 1)
        args = (F, S, C, states, dt_s, frozen_history) if tangent else None
        return Evaluation(r[:-1], args, new_states, ok=True, min_J=min_J, _assemble=self._tangent)

    def _evaluate_mixed(self, F, J, C, states, dt_s, tangent, frozen_history) -> Evaluation:
        """``evaluate`` for the Q2/P1 element (``sim.fe._mixed``): the laws at ``C̄ = θ C``,
        the residual from the effective stress; ``min_J`` the least of ``J`` and ``J̄``."""
        from . import _kernels, _mixed

        basis, mode = self.dilatation
        Jbar = _mixed.project(J, self.w, basis, mode)
        min_J = min(float(J.min()), float(Jbar.min()))
        if not min_J > 1e-8:
            return Evaluation(np.empty(0), None, states, ok=False, min_J=min_J)
        theta = np.cbrt(Jbar / J) ** 2  # C̄ = θ C
        Cbar = C * theta
        Sbar, _, new_states = layer_stresses(
            self.materials, self.slices, Cbar, states, dt_s, False, frozen_history
        )
        if not np.all(np.isfinite(Sbar)):
            return Evaluation(np.empty(0), None, states, ok=False, min_J=min_J)
        S, beta, eta = _mixed.effective_stress(C, J, Jbar, theta, Sbar, self.w, basis, mode)
        pat = self.pattern
        voigt = _kernels.VOIGT[3]
        r = _kernels.internal_forces(F, S, self.dN, self.w, voigt, pat.scatter_r, pat.n_free + 1)
        args = (F, J, Jbar, Cbar, Sbar, beta, eta, states, dt_s, frozen_history)
        return Evaluation(
            r[:-1],
            args if tangent else None,
            new_states,
            ok=True,
            min_J=min_J,
            _assemble=self._tangent_mixed,
        )

    def _tangent_mixed(
        self, F, J, Jbar, Cbar, Sbar, beta, eta, states, dt_s: float, frozen_history: bool
    ) -> np.ndarray:
        """The Q2/P1 tangent's data (``sim.fe._mixed.stiffness``), its material part
        computed here (lazily) from the same ``C̄`` and history as the residual's."""
        from . import _kernels, _mixed

        _, Dbar, _ = layer_stresses(
            self.materials, self.slices, Cbar, states, dt_s, True, frozen_history
        )
        pat = self.pattern
        basis, mode = self.dilatation
        data = _mixed.stiffness(
            F,
            J,
            Jbar,
            Sbar,
            Dbar,
            beta,
            eta,
            self.dN,
            self.w,
            basis,
            mode,
            _kernels.VOIGT[3],
            pat.scatter_K,
            pat.nnz + 1,
        )
        return data[:-1]

    def _tangent(self, F, S, C, states, dt_s: float, frozen_history: bool) -> np.ndarray:
        """The tangent's data, its material part computed here (lazily): the same
        law on the same ``C`` and history as the residual's. A non-finite material tangent
        gives non-finite data (the solve fails)."""
        from . import _kernels

        _, D, _ = layer_stresses(self.materials, self.slices, C, states, dt_s, True, frozen_history)
        pat = self.pattern
        voigt = _kernels.VOIGT[self.dim]
        data = _kernels.stiffness(F, S, D, self.dN, self.w, voigt, pat.scatter_K, pat.nnz + 1)
        return data[:-1]
