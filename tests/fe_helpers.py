"""Shared builders for the FE tests: a unit-square patch and small solves."""

from __future__ import annotations

import numpy as np
from skfem import MeshTri

from sim.fe import Body, Control, Discretization, NewtonOptions
from sim.geometry import FingertipMesh
from sim.materials import Material


def square_mesh(n: int = 4) -> FingertipMesh:
    """The unit square (mm) as a FingertipMesh: base y = 0, axis x = 0, surface right + top."""
    mesh = MeshTri.init_tensor(np.linspace(0.0, 1.0, n + 1), np.linspace(0.0, 1.0, n + 1))
    # a slightly distorted interior, so the patch test is not passed by a symmetric mesh alone
    p = mesh.p.copy()
    interior = (p[0] > 1e-12) & (p[0] < 1 - 1e-12) & (p[1] > 1e-12) & (p[1] < 1 - 1e-12)
    rng = np.random.default_rng(3)
    p[:, interior] += 0.15 / n * rng.uniform(-1, 1, size=(2, int(interior.sum())))
    mesh = MeshTri(p, mesh.t)
    x, y = mesh.p
    tol = 1e-12
    base = np.flatnonzero(np.abs(y) < tol)
    axis = np.flatnonzero(np.abs(x) < tol)
    right = np.flatnonzero(np.abs(x - 1) < tol)
    top = np.flatnonzero(np.abs(y - 1) < tol)
    right = right[np.argsort(y[right])]
    top = top[np.argsort(-x[top])]
    surface = np.concatenate([right, top[1:]])
    return FingertipMesh(mesh, np.zeros(mesh.t.shape[1], dtype=int), surface, base, axis)


def uniaxial_body(material: Material, n: int = 4) -> Body:
    """Plane-strain compression of the unit square: rollers on the base and the axis, the top
    moved vertically, the right side free."""

    def fixed(X: np.ndarray) -> np.ndarray:
        m = np.zeros_like(X, dtype=bool)
        m[np.abs(X[:, 1]) < 1e-12, 1] = True
        m[np.abs(X[:, 0]) < 1e-12, 0] = True
        m[np.abs(X[:, 1] - 1) < 1e-12, 1] = True
        return m

    disc = Discretization(square_mesh(n), [material], fixed=fixed)
    return Body(disc, indenter=None, options=NewtonOptions(rtol=1e-13))  # near machine precision


def compress(body: Body, stretch_y: float, t_s: float) -> None:
    """Move the top to stretch_y and solve the step to t_s (asserting convergence).

    The start is the isochoric affine field (J = 1): not the solution for a compressible law,
    which Newton finds. (A start with J far from 1 overflows the hyperfoam's J^(-alpha beta).)"""
    X = body.disc.X
    body.u[:, 1] = (stretch_y - 1.0) * X[:, 1]
    body.u[:, 0] = (1.0 / stretch_y - 1.0) * X[:, 0]
    res = body.advance(t_s, Control.free())
    assert res.converged, res.reason


def cauchy(body: Body) -> np.ndarray:
    """Cauchy stress (2, 2, n_el, n_q) from the committed state (elastic or viscoelastic)."""
    disc = body.disc
    F = disc.deformation_gradient(body.u)
    S = np.empty((3, disc.n_el, disc.n_q))
    for mat, sl, st in zip(disc.materials, disc.slices, body.states, strict=True):
        S[:, sl] = mat.history_stress(st.S0, st.H)[0]  # split into iso/vol parts or not
    Sm = np.array([[S[0], S[2]], [S[2], S[1]]])
    J = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    return np.einsum("iJeq,JKeq,kKeq->ikeq", F, Sm, F) / J


def check_contact_slope(body: Body, u, d: float, du, dd: float, control: Control) -> list[int]:
    """Assert that ``Body._contact_slope`` along the line (u + a du, d + a dd) is the contacts'
    part of the line search's g(a) = [du, dd] . residual(a) (g minus the body's own internal
    forces) at a = 0, 0.3 and 1; return the nodes touching the indenter at each."""
    import pytest

    disc = body.disc
    g_contact = body._contact_slope(u, d, du, dd, control)
    entered = []
    for a in (0.0, 0.3, 1.0):
        ua = u.copy()
        ua.reshape(-1)[disc.free] += a * du
        r, _, _, coupling, rd, *_ = body._evaluate(ua, control, d + a * dd, 0.01, False)
        own = disc.evaluate(ua, body.states, 0.01, tangent=False).residual
        g_total, g_body = du @ r + dd * rd, du @ own
        entered.append(int(np.sum(coupling > 0)))
        assert g_contact(a) == pytest.approx(g_total - g_body, rel=1e-9, abs=1e-12 * abs(g_total))
    return entered
