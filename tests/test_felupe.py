"""Comparison with an independent FE code, FElupe: the same P2 mesh, quadrature and neo-Hookean
energy; FElupe's own assembly, Newton solver and rigid-plane contact.

FElupe 11.3.0's six-node triangle has a wrong shape-function gradient (see
``sim.verification.cases.felupe_p2_element``); the comparison uses the corrected derivative of
FElupe's own shape functions, and the stock element only where stated.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim import REFERENCE_GEOMETRY
from sim.fe import Discretization
from sim.fe._reactions import internal_forces
from sim.geometry import DEFAULT_MESH, build_mesh
from sim.materials import Material, NeoHookean
from sim.verification import (
    felupe_internal_forces,
    felupe_p2_element,
    felupe_plate_comparison,
    shape_gradient_error,
)

fem = pytest.importorskip("felupe")
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

LAW = NeoHookean(mu_MPa=0.1, nu=0.45)


def test_felupe_p2_gradient_is_the_derivative_of_its_shape_functions() -> None:
    element, patched = felupe_p2_element()
    assert shape_gradient_error(element) < 1e-8  # central differences, h = 1e-6
    if patched:  # the stock element is off by O(1) at two of the three quadrature points
        assert shape_gradient_error(fem.QuadraticTriangle()) > 0.1


def test_internal_forces_equal_felupe_assembly() -> None:
    """Same nodes, element, rule and energy: the nodal internal forces agree to round-off at a
    smooth non-affine displacement with strains of ~10 %."""
    disc = Discretization(build_mesh(REFERENCE_GEOMETRY, (), DEFAULT_MESH), [Material(LAW)])
    X = disc.X
    u = np.column_stack(
        [0.1 * np.sin(0.8 * X[:, 0]) * X[:, 1] / 5, -0.08 * X[:, 1] + 0.01 * X[:, 0] ** 2]
    )
    ours = internal_forces(disc, u, disc.initial_states())
    theirs = felupe_internal_forces(disc, LAW, u)
    scale = np.abs(ours).max()
    np.testing.assert_allclose(theirs, ours, rtol=0, atol=1e-12 * scale)  # measured 1.6e-14


def test_plate_force_displacement_matches_felupe() -> None:
    """Plate pushed 1 mm onto the elastic fingertip in 10 steps: forces within 1e-3, and the
    difference is the penalty regularisation alone (ten times the penalties: ten times less)."""
    depths = np.linspace(0.1, 1.0, 10)
    base = felupe_plate_comparison(LAW, depths)
    assert base.ours[-1] > 0.15  # a real indentation (0.185 N/mm at 1 mm)
    # the two penalty forms differ by O(penetration / depth) ~ 1e-4 (measured 2.7e-4)
    assert np.abs(base.relative_difference).max() < 1e-3, base.relative_difference
    stiff = felupe_plate_comparison(LAW, depths, penalty_factor=10.0)
    assert np.abs(stiff.relative_difference).max() < 0.2 * np.abs(base.relative_difference).max()
