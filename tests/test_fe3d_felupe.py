"""The 3D model (``sim.fe.fe3d`` + ``sim.fe.solver``) against an independent code, FElupe
(``sim.verification.felupe_pad``, which ``studies/felupe_pad.py`` runs on finer meshes): a rigid
frictionless plate pressed onto the elastic quarter pad.

Two kinds of comparison:

- the SAME discretisation in FElupe (its 27-node hexahedron, pure displacement, the same
  nodes, rule and energy): the codes must agree to the contact penalties' regularisation, so an
  error of ours in the element, assembly, material or contact shows at the 1e-3 level;
- an INDEPENDENT discretisation (FElupe's mean-dilatation Q1/P0 hexahedra on the 2 x 2 x 2
  split of our elements): the two differ by their discretisation errors, which shrink under
  refinement. On the coarse meshes the difference is several per cent; on the default mesh
  it is within 1 % (the issue's target; the slow test).

The plate moves down in increments like ``sim.protocols.loading.run_plate``'s (0.1 mm per step
there); the force compared is the quarter model's (N).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from sim.fe import Body, Discretization3D, NewtonOptions, Plate
from sim.geometry import COARSE_MESH_3D, MeshOptions3D, PadGeometry, build_pad_mesh
from sim.materials._material import material_from_table

fem = pytest.importorskip("felupe")

from sim.verification import (  # noqa: E402
    bulk_modulus,
    felupe_plate_force,
    press_plate,
    q1_subcells,
)
from sim.verification.felupe_pad import TINY_MESH_3D  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

MU, NU = 0.05, 0.49  # the study's defaults: a soft, nearly incompressible skin
K = bulk_modulus(MU, NU)
PAD = PadGeometry()  # the reference pad: 5.84 x 5.48 mm section, n = 1.5, c = 11 mm, m = 2
TINY = TINY_MESH_3D  # 76 elements (2421 dofs): seconds per run in either code
COARSE = COARSE_MESH_3D  # 180 elements (5373 dofs), ``tests/test_fe3d.py``'s coarse mesh
DEPTHS = (0.25, 0.5, 1.0)


def our_plate_force(
    options: MeshOptions3D, depths, step_mm: float = 0.125, element: str = "q2"
) -> np.ndarray:
    """Our quarter-pad plate force (N) at ``depths`` (mm from first touch), the plate moved
    in increments of ``step_mm``, a failed step halved (``press_plate``); ``element``: ours'
    (``sim.fe.ELEMENTS_3D``)."""
    pmesh = build_pad_mesh(PAD, (), options)
    mat = material_from_table({"model": "neo_hookean", "mu_MPa": MU, "nu": NU})
    body = Body(Discretization3D(pmesh, [mat], element=element), Plate(), NewtonOptions())
    forces = press_plate(body, depths, step_mm)
    assert body.base_contact_nodes() == 0  # FElupe's model has no base contact
    return forces


def test_the_trilinear_split_fills_each_element():
    """The 8 trilinear cells of each 27-node hexahedron (``q1_subcells``): positive volumes in
    FElupe, each Q2 element's 27 nodes used, and their total volume that of the Q2 mesh up to
    the faceting of the curved surface (relative O(h^2))."""
    from sim.geometry.mesh3d import element_volumes

    pmesh = build_pad_mesh(PAD, (), COARSE)
    cells = q1_subcells(pmesh.hexes)
    assert cells.shape == (8 * len(pmesh.hexes), 8)
    per_element = cells.reshape(len(pmesh.hexes), -1)
    assert all(len(np.unique(row)) == 27 for row in per_element)
    region = fem.RegionHexahedron(fem.Mesh(np.asarray(pmesh.nodes), cells, "hexahedron"))
    assert np.all(region.dV > 0)
    q1 = region.dV.sum()
    q2 = element_volumes(pmesh.nodes, pmesh.hexes).sum()
    exact = PAD.volume_mm3(quarter=True)
    assert abs(q2 / exact - 1) < 2e-3  # the curved Q2 surface: measured -0.09 %
    assert 0 < 1 - q1 / q2 < 0.02  # the faceted one lies inside the convex pad: -0.77 %


def test_same_discretisation_in_felupe_agrees_to_the_penalty():
    """FElupe's 27-node hexahedra (pure displacement, 3 x 3 x 3 rule, the same nodes and
    energy) against ours on the tiny mesh: the difference is that of the two penalty contacts,
    ours kappa_i = 3000 E0 w_i per node (2e-4 mm penetration at 1 mm), FElupe's a stiffer
    uniform multiplier (1e-5 mm): O(penetration / depth) ~ 1e-3 (measured +4.4e-4 and +1.4e-4
    at 0.25 and 0.5 mm; +4e-4 at 1 mm on COARSE)."""
    depths = (0.25, 0.5)
    ours = our_plate_force(TINY, depths, step_mm=0.25)
    theirs = felupe_plate_force(
        PAD, TINY, MU, K, depths, formulation="q2-displacement", step_mm=0.25
    )
    rel = np.array(theirs) / ours - 1.0
    assert ours[1] > 0.05  # a real indentation (0.096 N on the quarter)
    assert np.abs(rel).max() < 2e-3, rel


def test_independent_discretisation_in_felupe_agrees_on_a_coarse_mesh():
    """FElupe's Q1/P0 mixed hexahedra on the 2 x 2 x 2 split of the 180 coarse elements: a
    different element, geometry interpolation and volumetric treatment, so the codes differ by
    their discretisation errors: measured -3.3 % at 0.5 mm and -1.9 % at 1 mm (the Q1/P0 force
    below ours), -0.73 % and -0.57 % on the default mesh (the slow test). 5 %: a coarse-mesh
    sanity check with room for small changes of either mesh; the sharp checks are the test
    above and the slow one."""
    depths = (0.5, 1.0)
    ours = our_plate_force(COARSE, depths, step_mm=0.25)
    theirs = felupe_plate_force(PAD, COARSE, MU, K, depths, step_mm=0.25)
    rel = np.array(theirs) / ours - 1.0
    assert np.all(np.abs(rel) < 0.05), rel


def test_the_locking_free_elements_of_both_codes_agree():
    """Our Q2/P1 (the volume ratio projected on linear polynomials per element,
    ``sim.fe._mixed``) against FElupe's own mixed 27-node hexahedron (``q2-mixed``: the
    pressure and volume ratio trilinear and discontinuous, global unknowns, a three-field
    variation): two locking-free treatments of the same Q2 displacements, written apart. On
    the tiny mesh they agree at 1 mm to 0.15 % (measured), where our pure-displacement element
    is 3.2 % stiffer than FElupe's; at 0.5 mm to 1.4 % (a patch a few elements wide, where the
    two pressure spaces differ most)."""
    depths = (0.5, 1.0)
    mixed = our_plate_force(TINY, depths, step_mm=0.25, element="q2p1")
    plain = our_plate_force(TINY, depths, step_mm=0.25)
    theirs = np.array(
        felupe_plate_force(PAD, TINY, MU, K, depths, formulation="q2-mixed", step_mm=0.25)
    )
    assert abs(theirs[1] / mixed[1] - 1) < 0.005, (mixed, theirs)
    assert abs(theirs[0] / mixed[0] - 1) < 0.025, (mixed, theirs)
    # the pure-displacement element is further from both (volumetric locking)
    assert plain[1] / theirs[1] - 1 > 0.02, (plain, theirs)


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("FINGERTIP_STUDIES"),
    reason="a 3.4-minute study, not part of the suite: "
    "FINGERTIP_STUDIES=1 python -m pytest tests/test_fe3d_felupe.py -m slow",
)
def test_plate_force_within_one_percent_of_felupe_on_the_default_mesh():
    """The issue's target: within 1 % of FElupe's Q1/P0 on the default mesh at 0.5 and 1 mm
    (measured -0.73 % and -0.57 %; -3.3 % and -1.9 % on the coarse mesh: the difference
    shrinks, both codes converge to one answer). At 0.25 mm, with few elements in the contact
    patch, -1.3 % (-1.5 % coarse); on ``refined(1.5)`` -0.54 %, -0.30 %, -0.24 % at 0.25,
    0.5, 1 mm (docs/felupe_pad.json and a 40-minute run of ours: too slow for a test).
    About 3.5 min on 2 shared cores."""
    rel = {}
    for name, options in (("coarse", COARSE), ("default", MeshOptions3D())):
        ours = our_plate_force(options, DEPTHS, step_mm=0.1)
        theirs = np.array(felupe_plate_force(PAD, options, MU, K, DEPTHS))
        rel[name] = theirs / ours - 1.0
    assert np.all(np.abs(rel["default"][1:]) < 0.01), rel
    assert abs(rel["default"][0]) < 0.02, rel
    assert np.all(np.abs(rel["default"][1:]) < 0.5 * np.abs(rel["coarse"][1:])), rel
