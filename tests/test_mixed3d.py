"""The locking-free 3D element Q2/P1 (``sim.fe._mixed``, ``model.element = "q2p1"``): the
projection, the residual as the gradient of the projected energy, the tangent as the
residual's derivative, the patch test, and the physics it is for: a nearly incompressible pad
whose force does not grow with the bulk modulus (no volumetric locking)."""

from __future__ import annotations

import numpy as np
import pytest
from test_fe3d import CORE, PAD, SKIN, _smooth

from sim.errors import DesignError
from sim.fe import Body, Discretization3D, NewtonOptions, Plate, _kernels, _mixed
from sim.fe._assembly import determinant
from sim.geometry import PadGeometry, build_pad_mesh
from sim.materials._material import material_from_table
from sim.options import ModelOptions, SimOptions
from sim.verification import press_plate
from sim.verification.felupe_pad import TINY_MESH_3D


@pytest.fixture(scope="module")
def tiny_two_layers() -> Discretization3D:
    pmesh = build_pad_mesh(PAD, (1.0,), TINY_MESH_3D)
    mats = [material_from_table(SKIN), material_from_table(CORE)]
    return Discretization3D(pmesh, mats, element="q2p1")


def test_the_projection_keeps_linear_fields_and_is_orthogonal(tiny_two_layers):
    """``J̄`` is the L2 projection on span{1, X, Y, Z} per element: a linear field is its own
    projection, and the remainder of any field is orthogonal to every mode."""
    disc = tiny_two_layers
    N, Minv = disc.dilatation
    X = disc.quadrature_points()  # (3, E, Q)
    linear = 1.0 + 0.02 * X[0] - 0.05 * X[1] + 0.03 * X[2]
    np.testing.assert_allclose(_mixed.project(linear, disc.w, N, Minv), linear, rtol=1e-12)
    field = np.cos(X[0] / 3) * np.exp(X[1] / 7) + X[2] ** 2 / 50
    rest = field - _mixed.project(field, disc.w, N, Minv)
    moments = np.einsum("eq,eq,eqk->ek", disc.w, rest, N)
    assert np.abs(moments).max() < 1e-12 * np.abs(np.einsum("eq,eq->e", disc.w, field)).max()
    assert np.abs(rest).max() > 1e-4  # the field is not linear: the test is not empty


def _energy(disc: Discretization3D, u: np.ndarray) -> float:
    """``Σ_e Σ_q w_q W(C̄_q)`` of a one-layer elastic discretisation (the module docstring)."""
    F = disc.deformation_gradient(u)
    J = determinant(F)
    Jbar = _mixed.project(J, disc.w, *disc.dilatation)
    C = _kernels.right_cauchy_green(F, _kernels.VOIGT[3]) * np.cbrt(Jbar / J) ** 2
    return float(np.sum(disc.materials[0].law.evaluate3(C)[0] * disc.w))


def test_the_residual_is_the_projected_energys_gradient():
    """Finite differences of the projected energy along random directions against the
    residual: the effective stress is the energy's exact first variation."""
    pmesh = build_pad_mesh(PAD, (), TINY_MESH_3D)
    disc = Discretization3D(pmesh, [material_from_table(CORE)], element="q2p1")
    u = 3 * _smooth(disc.X)  # J from 0.4 to 1.2 on the pad: far from linear
    u[disc.fixed] = 0.0
    r = disc.evaluate(u, disc.initial_states(), 0.0).residual
    rng = np.random.default_rng(0)
    for _ in range(3):
        du = np.zeros_like(u)
        du.ravel()[disc.free] = 1e-2 * rng.standard_normal(disc.n_free)
        h = 1e-5
        fd = (_energy(disc, u + h * du) - _energy(disc, u - h * du)) / (2 * h)
        assert r @ du.ravel()[disc.free] == pytest.approx(fd, rel=1e-7)


def test_the_tangent_is_the_residuals_derivative(tiny_two_layers):
    """Two viscoelastic layers (shear and bulk relaxing apart), a committed history: the
    assembled tangent, symmetric, against central differences of the residual."""
    disc = tiny_two_layers
    u = _smooth(disc.X)
    u[disc.fixed] = 0.0
    states = disc.evaluate(0.5 * u, disc.initial_states(), 0.02).states
    ev = disc.evaluate(u, states, 0.01)
    K = disc.pattern_matrix(ev.tangent())
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    rng = np.random.default_rng(2)
    for _ in range(2):
        du = np.zeros_like(u)
        du.ravel()[disc.free] = 1e-2 * rng.standard_normal(disc.n_free)
        h = 1e-5
        rp = disc.evaluate(u + h * du, states, 0.01, tangent=False).residual
        rm = disc.evaluate(u - h * du, states, 0.01, tangent=False).residual
        fd = (rp - rm) / (2 * h)
        np.testing.assert_allclose(K @ du.ravel()[disc.free], fd, rtol=0, atol=2e-7 * abs(fd).max())


def test_a_homogeneous_state_is_the_displacement_elements():
    """A homogeneous deformation has a constant J, so J̄ = J and F̄ = F: the same residual
    as the pure-displacement element, and the patch test (interior forces vanish) holds."""
    pmesh = build_pad_mesh(PAD, (), TINY_MESH_3D)
    boundary = np.zeros(len(pmesh.nodes), dtype=bool)
    for nodes in (pmesh.base, pmesh.sym_x, pmesh.sym_z, pmesh.surface_nodes):
        boundary[nodes] = True
    fixed = lambda X: np.repeat(boundary[:, None], 3, axis=1)  # noqa: E731
    mats = [material_from_table(CORE)]
    mixed = Discretization3D(pmesh, mats, fixed=fixed, element="q2p1")
    plain = Discretization3D(pmesh, mats, fixed=fixed)
    assert mixed.n_free > 0
    F0 = np.array([[1.08, 0.04, -0.02], [0.03, 0.9, 0.05], [-0.04, 0.02, 1.05]])
    u = mixed.X @ (F0 - np.eye(3)).T
    np.testing.assert_allclose(
        mixed.material_deformation_gradient(u), mixed.deformation_gradient(u), atol=1e-12
    )
    a = mixed.evaluate(u, mixed.initial_states(), 0.0)
    b = plain.evaluate(u, plain.initial_states(), 0.0)
    S = b._tangent_args[1]
    scale = np.abs(S).max() * np.mean(plain.w) ** (2 / 3)
    assert np.abs(a.residual).max() < 1e-10 * scale
    np.testing.assert_allclose(a.residual, b.residual, rtol=0, atol=1e-12 * scale)


def test_the_material_sees_the_projected_volume_ratio(tiny_two_layers):
    """``material_deformation_gradient`` (what the validity's strains are read from) is
    F̄: its determinant is the projected J̄, and its isochoric part is F's."""
    disc = tiny_two_layers
    u = _smooth(disc.X)
    u[disc.fixed] = 0.0
    F = disc.deformation_gradient(u)
    Fbar = disc.material_deformation_gradient(u)
    J, Jbar = determinant(F), determinant(Fbar)
    np.testing.assert_allclose(Jbar, _mixed.project(J, disc.w, *disc.dilatation), rtol=1e-12)
    np.testing.assert_allclose(Fbar / np.cbrt(Jbar), F / np.cbrt(J), rtol=1e-12)
    assert np.abs(Jbar - J).max() > 1e-4  # J is not linear in the elements


def _plate_force_1mm(element: str, nu: float) -> float:
    pmesh = build_pad_mesh(PadGeometry(), (), TINY_MESH_3D)
    mat = material_from_table({"model": "neo_hookean", "mu_MPa": 0.05, "nu": nu})
    body = Body(Discretization3D(pmesh, [mat], element=element), Plate(), NewtonOptions())
    return float(press_plate(body, (0.5, 1.0), 0.125)[-1])


def test_the_force_does_not_grow_with_the_bulk_modulus():
    """No volumetric locking: from ν = 0.499 to 0.4999 the bulk modulus grows tenfold (500 to
    5000 times the shear modulus); the exact solution of a nearly incompressible pad barely
    changes (its volume change is already O(1 / κ) small), so the plate's force at 1 mm must
    not either. The locking-free element moves by 0.3 % on the 76-element mesh; the
    pure-displacement element, which locks, by 4.3 % (measured; it shows the test can fail)."""
    mixed = _plate_force_1mm("q2p1", 0.4999) / _plate_force_1mm("q2p1", 0.499) - 1
    plain = _plate_force_1mm("q2", 0.4999) / _plate_force_1mm("q2", 0.499) - 1
    assert 0 <= mixed < 0.005
    assert plain > 0.02


def test_the_element_option():
    """``model.element``: 3D only, one of the elements; left out of the options' dict form
    at its default, so the records made before it existed keep their keys."""
    three = SimOptions(model=ModelOptions(dimension="3d"))
    assert "element" not in three.as_dict()["model"]
    mixed = SimOptions(model=ModelOptions(dimension="3d", element="q2p1"))
    assert mixed.as_dict()["model"]["element"] == "q2p1"
    with pytest.raises(DesignError, match=r"model\.element.*q2, q2p1"):
        ModelOptions(dimension="3d", element="q1")
    with pytest.raises(DesignError, match=r"model\.element.*3d model only"):
        ModelOptions(dimension="2d", element="q2p1")
    with pytest.raises(ValueError, match="element must be one of"):
        Discretization3D(
            build_pad_mesh(PAD, (), TINY_MESH_3D), [material_from_table(CORE)], element="p1"
        )
