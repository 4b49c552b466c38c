"""sim.geometry._p2 computes scikit-fem's P2 mesh and basis arrays without importing it: the same
connectivity exactly, and the same geometry to round-off (two libraries' floating-point
operations need not give the same bits on every CPU)."""

from __future__ import annotations

import numpy as np
import pytest
from skfem import Basis, ElementTriP2, MeshTri

from sim.geometry import Geometry
from sim.geometry._p2 import P2Basis, TriMesh
from sim.geometry.mesh2d import _areas, build_mesh


def _meshes():
    # fingertip meshes of one, two and three layers, and a structured mesh of both diagonals
    for geometry, thicknesses in [
        (Geometry(), ()),
        (Geometry(7.5, 6.0, 2.2), (0.8,)),
        (Geometry(9.0, 8.0, 1.2), (0.3, 1.5)),
    ]:
        yield build_mesh(geometry, thicknesses).mesh
    m = MeshTri.init_sqsymmetric().refined(2)
    yield TriMesh(m.p, m.t)


@pytest.mark.parametrize("mesh", list(_meshes()))
def test_the_arrays_are_scikit_fems(mesh):
    reference = MeshTri(mesh.p, mesh.t)
    assert np.array_equal(mesh.facets, reference.facets)
    assert np.array_equal(mesh.t2f, reference.t2f)
    assert np.array_equal(mesh.boundary_facets(), reference.boundary_facets())
    ours, theirs = P2Basis(mesh), Basis(reference, ElementTriP2(), intorder=2)
    assert ours.N == theirs.N
    assert np.array_equal(ours.element_dofs, theirs.element_dofs)
    close = {"rtol": 1e-13, "atol": 0}  # round-off of a few operations, far below any FE effect
    np.testing.assert_allclose(ours.doflocs, theirs.doflocs, **close)
    grads = np.stack([theirs.basis[a][0].grad for a in range(6)])
    np.testing.assert_allclose(ours.grads, grads, rtol=0, atol=1e-13 * np.abs(grads).max())
    np.testing.assert_allclose(ours.dx, theirs.dx, **close)
    np.testing.assert_allclose(
        ours.global_coordinates(), np.array(theirs.global_coordinates()), **close
    )


def test_the_basis_integrates_and_differentiates_quadratics_exactly():
    """Independent of scikit-fem: the weights add up to the mesh's area, and the gradient of
    the P2 interpolant of a quadratic is the quadratic's gradient at every quadrature point."""
    mesh = next(iter(_meshes()))
    basis = P2Basis(mesh)
    area = _areas(mesh.p.T, mesh.t.T).sum()
    assert basis.dx.sum() == pytest.approx(area, rel=1e-13)
    x, y = basis.doflocs
    u = 1.0 + 0.3 * x - 0.7 * y + 0.5 * x**2 - 0.2 * x * y + 0.9 * y**2
    ue = u[basis.element_dofs]  # (6, n_el)
    grad = np.einsum("ae,aieq->ieq", ue, basis.grads)
    xq, yq = basis.global_coordinates()
    np.testing.assert_allclose(grad[0], 0.3 + 1.0 * xq - 0.2 * yq, atol=1e-12)
    np.testing.assert_allclose(grad[1], -0.7 - 0.2 * xq + 1.8 * yq, atol=1e-12)


def test_other_quadrature_orders_are_refused():
    with pytest.raises(ValueError, match="intorder 2"):
        P2Basis(next(iter(_meshes())), intorder=3)
