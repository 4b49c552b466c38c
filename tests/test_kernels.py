"""The compiled assembly kernels (``sim.fe._kernels``) and the shared sparsity pattern
(``sim.fe._pattern``): in 2D their F, C and forces equal plain numpy on the P2 basis (the
whole 2D assembly is checked against scikit-fem's forms in ``tests/test_fe.py``); in 3D, on
scikit-fem's triquadratic hexahedra, the residual is scikit-fem's assembly of the same weak
form, the tangent is the residual's derivative (central differences), and a homogeneous
deformation is a patch test."""

from __future__ import annotations

import numpy as np
import pytest

from sim import homogeneous_design
from sim.design import Design, Layer
from sim.fe import Discretization
from sim.fe import _kernels as K
from sim.fe._pattern import build_pattern
from sim.geometry import Geometry, build_mesh
from sim.materials._material import material_from_table


@pytest.fixture(scope="module")
def disc2d() -> Discretization:
    design = Design(
        (
            Layer(homogeneous_design("silicone_gls40").materials[0], 0.8),
            Layer(
                material_from_table(
                    {"model": "ogden", "mu_MPa": [0.02], "alpha": [3.5], "nu": 0.49}
                )
            ),
        ),
        Geometry(7.5, 6.0, 2.2),
    )
    return Discretization(build_mesh(design.geometry, design.thicknesses_mm), design.materials)


def _smooth(X: np.ndarray) -> np.ndarray:
    """A smooth displacement field with shear, compression and curvature (mm)."""
    x, y = X[:, 0], X[:, 1]
    return np.column_stack([0.04 * x * y / 5 + 0.01 * y, -0.12 * y**2 / 6 + 0.02 * np.sin(x)])


def test_the_pattern_is_scipys_assembly_of_the_element_matrices(disc2d):
    """The pattern and its scatter maps against scipy's own summation of the element entries
    (COO -> CSR): the same structure, and the same sums of any element values."""
    import scipy.sparse as sp

    pat = disc2d.pattern
    d = 2
    conn = disc2d.edofs_scalar
    edofs = (d * conn[:, :, None] + np.arange(d)).reshape(len(conn), -1)
    fe = disc2d.gmap[edofs]
    n = fe.shape[1]
    rows = np.broadcast_to(fe[:, :, None], (len(fe), n, n)).ravel()
    cols = np.broadcast_to(fe[:, None, :], (len(fe), n, n)).ravel()
    vals = np.random.default_rng(0).standard_normal(rows.size)
    keep = (rows >= 0) & (cols >= 0)
    ref = sp.coo_matrix(
        (vals[keep], (rows[keep], cols[keep])), shape=(pat.n_free, pat.n_free)
    ).tocsr()
    ref.sum_duplicates()
    ref.sort_indices()
    assert np.array_equal(pat.indptr, ref.indptr) and np.array_equal(pat.indices, ref.indices)
    data = np.bincount(pat.scatter_K, weights=vals, minlength=pat.nnz + 1)[:-1]
    np.testing.assert_allclose(data, ref.data, rtol=0, atol=1e-12 * np.abs(vals).max())
    upper = sp.triu(ref, format="csc")
    assert np.array_equal(pat.upper_indptr, upper.indptr)
    assert np.array_equal(pat.upper_indices, upper.indices)
    r, c = rows[keep][::97], cols[keep][::97]
    pos = pat.position(r, c)
    assert np.array_equal(pat.keys[pos], r * pat.n_free + c)


def test_2d_kernels_against_numpy_on_the_p2_basis(disc2d):
    """The kernels' F, C and internal forces in 2D against plain numpy on the P2 basis's own
    gradients (scikit-fem's layout); the whole assembly (residual and tangent) is checked
    against scikit-fem's forms in ``tests/test_fe.py``."""
    from sim.fe._reactions import internal_forces

    u = 0.25 * _smooth(disc2d.X)  # J in 0.86-1.33
    u[disc2d.fixed] = 0.0
    grads = disc2d.basis.grads  # (a, J, e, q)
    F = np.einsum("eai,aJeq->iJeq", u[disc2d.edofs_scalar], grads) + np.eye(2)[:, :, None, None]
    Fk = K.deformation_gradient(u, disc2d.conn, disc2d.dN)
    np.testing.assert_allclose(Fk, F, rtol=0, atol=1e-13)
    C = K.right_cauchy_green(Fk, K.VOIGT[2])
    want_C = np.stack([F[0, 0] ** 2 + F[1, 0] ** 2, F[0, 1] ** 2 + F[1, 1] ** 2,
                       F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1]])  # fmt: skip
    np.testing.assert_allclose(C, want_C, rtol=0, atol=1e-13)
    ev = disc2d.evaluate(u, disc2d.initial_states(), 0.01)
    # the reactions' own numpy assembly over all dofs, with the history the evaluation made
    ref = internal_forces(disc2d, u, ev.states).reshape(-1)[disc2d.free]
    np.testing.assert_allclose(ev.residual, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


# ------------------------------------------------------------------------------------- 3D
@pytest.fixture(scope="module")
def hex27():
    """Two by two by two triquadratic hexahedra of a distorted block, 3 x 3 x 3 Gauss points,
    base z = 0 fixed: scikit-fem's basis, and the kernels' arrays on its numbering."""
    from skfem import Basis, ElementHex2, MeshHex

    grid = np.linspace(0.0, 2.0, 3)
    mesh = MeshHex.init_tensor(grid, grid, 0.5 * grid)
    p = mesh.p
    p = p + 0.08 * np.stack([np.sin(p[1] + p[2]), np.cos(p[0]) * p[2], 0.3 * p[0] * p[1]])
    mesh = MeshHex(p, mesh.t)
    basis = Basis(mesh, ElementHex2(), intorder=4)
    n_nodes = basis.N
    conn = basis.element_dofs.T.astype(np.int64)  # (E, 27)
    dN = np.ascontiguousarray(
        np.stack([basis.basis[a][0].grad for a in range(27)]).transpose(2, 3, 0, 1)
    )  # (E, Q, 27, 3)
    w = np.asarray(basis.dx)
    X = basis.doflocs.T
    fixed = np.zeros((n_nodes, 3), dtype=bool)
    fixed[np.isclose(X[:, 2], 0.0)] = True
    gmap = -np.ones(3 * n_nodes, dtype=np.int64)
    free = np.flatnonzero(~fixed.ravel())
    gmap[free] = np.arange(len(free))
    return {"basis": basis, "conn": conn, "dN": dN, "w": w, "X": X, "gmap": gmap,
            "pattern": build_pattern(conn, gmap, 3)}  # fmt: skip


def _law3():
    return material_from_table({"model": "ogden", "mu_MPa": [0.05, -0.01], "alpha": [4.0, -2.0],
                                "nu": 0.45}).law  # fmt: skip


def _residual_tangent(h, u, tangent=True):
    law = _law3()
    F = K.deformation_gradient(u, h["conn"], h["dN"])
    C = K.right_cauchy_green(F, K.VOIGT[3])
    S, D = law.stress_tangent3(C)
    pat = h["pattern"]
    r = K.internal_forces(F, S, h["dN"], h["w"], K.VOIGT[3], pat.scatter_r, pat.n_free + 1)
    if not tangent:
        return r[:-1], None, (F, S)
    data = K.stiffness(F, S, D, h["dN"], h["w"], K.VOIGT[3], pat.scatter_K, pat.nnz + 1)
    return r[:-1], data[:-1], (F, S)


def _u3(X: np.ndarray, scale: float = 1.0) -> np.ndarray:
    x, y, z = X.T
    u = np.column_stack([0.05 * z * y, -0.04 * z * np.sin(x), -0.08 * z**2 + 0.03 * x * z])
    return scale * u


def test_3d_residual_is_scikit_fems_assembly_of_the_weak_form(hex27):
    from skfem import Basis, ElementHex2, ElementVector, LinearForm, asm
    from skfem.helpers import ddot, grad

    u = _u3(hex27["X"])
    r, _, (F, S) = _residual_tangent(hex27, u, tangent=False)
    Sf = np.empty((3, 3, *S.shape[1:]))
    for v, (I, J) in enumerate(K.VOIGT[3]):
        Sf[I, J] = Sf[J, I] = S[v]
    P = np.einsum("iKeq,KJeq->iJeq", F, Sf)

    @LinearForm
    def virtual_work(v, w):
        return ddot(w["P"], grad(v))

    vb = Basis(hex27["basis"].mesh, ElementVector(ElementHex2()), intorder=4)
    # scikit-fem numbers component i of node a as 3 a + i, as the kernels do
    conn = hex27["conn"]
    assert np.array_equal(
        vb.element_dofs.T, (3 * conn[:, :, None] + np.arange(3)).reshape(len(conn), -1)
    )
    theirs = asm(virtual_work, vb, P=P)
    free = hex27["gmap"] >= 0  # free dofs are numbered in increasing global order
    np.testing.assert_allclose(r, theirs[free], rtol=0, atol=1e-12 * np.abs(theirs).max())


def test_3d_tangent_is_the_residuals_derivative(hex27):
    rng = np.random.default_rng(1)
    u = _u3(hex27["X"])
    _, data, _ = _residual_tangent(hex27, u)
    pat = hex27["pattern"]
    import scipy.sparse as sp

    Kmat = sp.csr_matrix((data, pat.indices, pat.indptr), shape=(pat.n_free, pat.n_free))
    assert abs(Kmat - Kmat.T).max() <= 1e-12 * abs(Kmat).max()
    gm = hex27["gmap"]
    for _ in range(3):
        du = np.zeros(3 * len(hex27["X"]))
        du[gm >= 0] = rng.standard_normal(pat.n_free)
        du = 1e-2 * du.reshape(-1, 3)
        h = 1e-4
        rp = _residual_tangent(hex27, u + h * du, tangent=False)[0]
        rm = _residual_tangent(hex27, u - h * du, tangent=False)[0]
        fd = (rp - rm) / (2 * h)
        Kdu = Kmat @ du.ravel()[gm >= 0]
        np.testing.assert_allclose(Kdu, fd, rtol=0, atol=1e-7 * np.abs(fd).max())


def test_3d_homogeneous_deformation_is_in_equilibrium_inside(hex27):
    """Patch test: u = (F0 - I) X gives the same stress everywhere, so the internal forces of
    every node not on the block's boundary vanish."""
    X = hex27["X"]
    F0 = np.array([[1.1, 0.05, -0.02], [0.03, 0.92, 0.04], [-0.05, 0.01, 1.04]])
    u = X @ (F0 - np.eye(3)).T
    r, _, (F, _) = _residual_tangent(hex27, u, tangent=False)
    np.testing.assert_allclose(F, np.broadcast_to(F0[:, :, None, None], F.shape), atol=1e-13)
    inner = np.ones(len(X), dtype=bool)
    inner[hex27["basis"].get_dofs().all()] = False  # the nodes on the block's boundary
    full = np.zeros(3 * len(X))
    full[hex27["gmap"] >= 0] = r
    assert inner.sum() > 0
    scale = np.abs(r).max()
    assert np.abs(full.reshape(-1, 3)[inner]).max() <= 1e-12 * scale
