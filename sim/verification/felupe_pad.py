"""Force-indentation curve of a rigid flat plate on the elastic quarter pad, computed by FElupe
(``studies/felupe_pad.py`` regenerates ``docs/felupe_pad.json`` with it).

An independent reference for the 3D model (``sim.fe.fe3d`` + ``sim.fe.solver``): the same pad and
the same neo-Hookean energy, but FElupe's own elements, volumetric treatment, quadrature, assembly,
contact and Newton method. Nothing of ``sim`` is used beyond the mesh generator (so that both codes
discretise the same geometry), the project's mapping (mu, nu) -> K and a check that the mesh's
27-node order (``sim.geometry._q2``) is FElupe's. The tests call :func:`felupe_plate_force` on
coarse meshes (``tests/test_fe3d_felupe.py``).

Geometry and mesh. ``sim.geometry.mesh3d.build_pad_mesh`` meshes the quarter pad x >= 0, z >= 0 by
27-node hexahedra in VTK order. For the default formulation each of them is split into the
2 x 2 x 2 trilinear hexahedra that its 27 nodes span (``q1_subcells``: the sub-hexahedron at
offsets (a, b, c) in {0, 1}^3 has the corner nodes at offsets (a + i, b + j, c + k), in VTK's
hexahedron order), so FElupe gets the same nodes and the same number of displacement dofs, but
a piecewise-trilinear (faceted) interpolation of the curved surface between them.

Formulation (``--formulation``):

- ``q1p0`` (default): FElupe's ``SolidBodyNearlyIncompressible`` on ``RegionHexahedron``, the
  Hu-Washizu u/p/J three-field variation with a pressure and a volume ratio constant per cell,
  condensed on the cell (the mean-dilatation Q1/P0 element of Simo, Taylor & Pister 1985),
  2 x 2 x 2 Gauss points. Why: it is the standard locking-free hexahedron for nearly
  incompressible solids, and it shares nothing with our discretisation but the nodes: another
  element order (trilinear, not triquadratic), another geometry (faceted, not curved), another
  volumetric treatment (mixed, condensed J-bar, not pure displacement), another quadrature. So
  the two codes err in different ways and their agreement is evidence about both. It is also
  the one FElupe can afford on refined meshes (8-node cells): 3 s of CPU per Newton iteration
  on the default mesh, where FElupe's 27-node mixed element takes 17 s (measured below).
- ``q2-mixed``: the 27-node hexahedra as FElupe's ``TriQuadraticHexahedron`` with
  ``FieldsMixed`` (pressure and volume ratio trilinear and discontinuous per cell, 8 values
  each, global unknowns) and ``NearlyIncompressible(NeoHooke(mu), K)``, 3 x 3 x 3 Gauss points.
  The more accurate mixed element (0.23 % from ours on the default mesh against 0.57 % for
  Q1/P0), but about six times the cost per iteration of ``q1p0`` at equal nodes: used for
  single coarse checks, not for the convergence runs.
- ``q2-displacement``: FElupe's ``TriQuadraticHexahedron`` with ``NeoHooke(mu, K)``, pure
  displacement, 3 x 3 x 3 Gauss points: the SAME discretisation as ours (not independent as a
  discretisation), so the two codes must agree to the contact penalties' regularisation; it
  checks our implementation (element, assembly, material, contact) apart from the
  discretisation error.

Material. The project's ``neo_hookean`` law (``sim.materials.NeoHookean``) is
U = mu/2 (I1b - 3) + K/2 (J - 1)^2, I1b = J^(-2/3) I1, K = 2 mu (1 + nu) / (3 (1 - 2 nu)).
FElupe's ``NeoHooke(mu, bulk=K)`` is the same energy (``sim.verification.cases.felupe_model``);
the mixed forms use ``NeoHooke(mu)`` for the isochoric part and K/2 (J-bar - 1)^2 for the
volumetric part, the same energy with J replaced by the mixed field J-bar (= J in the limit).
Defaults mu = 0.05 MPa, nu = 0.49: mu is mid-range of the project's soft skins (the catalogue's
silicones and gels have 0.01-0.1 MPa, the design space 0.0025-0.35 MPa); a hyperelastic solid
with fixed K/mu has forces proportional to mu, so mu only scales the curve. nu = 0.49
(K/mu = 49.7) is the catalogue's GLS 40 silicone and the value of the project's 3D tests: nearly
incompressible enough that volumetric locking matters, yet a pure-displacement Q2 element (ours)
is not expected to lock badly, so the two codes can be compared. The gels' nu = 0.499 is
harder on ours: there FElupe / ours - 1 was -3.0, -1.3, -0.9 % at 0.25, 0.5, 1 mm on the
default mesh (-3.2, -4.7, -2.9 % on the tests' coarse one; ``--nu 0.499``).

Boundary conditions: base y = 0 fully fixed; u_x = 0 on x = 0; u_z = 0 on z = 0 (the mesh's
node sets ``base``, ``sym_x``, ``sym_z``).

Contact: ``felupe.MultiPointContact`` connects a centre point (appended to the mesh, no cells)
to every node of the outer surface in the y direction only (``skip=(True, False, True)``): a
node whose y passes the centre point's y gets the force multiplier * gap along y, i.e. a rigid,
frictionless plane y = y_c with a node-to-plane penalty and an active set. The centre point
sits at the apex height y_top; its y displacement is ramped to -d (its x, z are held), so the
plate face is y = y_top - d, and the plate's force on the quarter pad is minus the residual at
the centre point's y dof (the sum of the contact reactions). The multiplier is
``penalty_factor`` x E x h_apex (N/mm; E = 2 mu (1 + nu), h_apex the mesh's apex size), 1e4
by default: the largest penetration is reported (about 1e-5 mm at 1 mm, 1e-5 of the depth).

Increments: the plate moves down in steps of ``step_mm`` (0.1 mm), each solved by FElupe's
Newton-Raphson (``felupe.Job`` / ``Step``, ``tol`` on its relative residual norm 1e-8), with
FElupe's ``CutbackPlugin`` halving a step that fails. The linear solver is ``pypardiso.spsolve``
when installed (else SciPy's ``spsolve``); it only solves the linear systems FElupe assembles.
The quarter model's force is recorded at every requested depth; the whole pad's is 4 x that.

Measured (defaults: reference pad, one layer, mu = 0.05 MPa, nu = 0.49; 2 cores shared with
other engineers' test runs at load average 2-5, so wall times are inflated; docs/felupe_pad.json).
Plate force on the quarter pad (N; the whole pad's is 4 x) against ours (``sim.fe.solver.Body``,
0.1 mm steps, default penalty):

    mesh                       code     0.25 mm   0.5 mm    1 mm
    refined(1), 38 901 dofs    FElupe   0.02701   0.09288   0.36473
                               ours     0.02736   0.09357   0.36682
                               diff     -1.30 %   -0.73 %   -0.57 %
    refined(1.5), 132 117 dofs FElupe   0.02725   0.09300   0.36527
                               ours     0.02740   0.09328   0.36615
                               diff     -0.54 %   -0.30 %   -0.24 %

FElupe's force at 1 mm changes by +0.15 % from refined(1) to refined(1.5), ours by -0.18 %:
the two converge from either side (Q1/P0 softer, pure-displacement Q2 stiffer). FElupe
``q2-mixed`` on refined(1): 0.36598 N at 1 mm (-0.23 % from ours); ``q2-displacement`` on the
coarse test mesh: within 4e-4 of ours. Largest penetration 9.5e-6 mm (ours 2.0e-4 mm). Cost
(wall / CPU): ``q1p0`` refined(1) 229 s / 144 s (46 Newton iterations, 5.0 s per iteration),
refined(1.5) 1057 s / 1240 s (55, 19 s); ``q2-mixed`` refined(1) 1019 s / 765 s (44, 23 s).
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..geometry import MeshOptions3D, PadGeometry, PadMesh, build_pad_mesh
from ..geometry._q2 import REFERENCE_POINTS
from ..materials import NeoHookean

__all__ = [
    "FORMULATIONS",
    "TINY_MESH_3D",
    "PlateResult",
    "bulk_modulus",
    "felupe_plate_force",
    "q1_subcells",
    "solve_plate",
    "subcells",
]

FORMULATIONS = ("q1p0", "q2-mixed", "q2-displacement")
DEFAULT_MU_MPA = 0.05
DEFAULT_NU = 0.49
#: contact multiplier = PENALTY_FACTOR * E * h_apex (N/mm)
PENALTY_FACTOR = 1e4
#: FElupe's Newton tolerance: residual norm of the free dofs / that of the reactions
NEWTON_TOL = 1e-8
#: the comparison's smallest mesh of the reference pad: 76 elements (2421 dofs), seconds per
#: run in either code (the tests' and ``benchmarks/bench_felupe.py``'s; the next one up is
#: ``sim.geometry.COARSE_MESH_3D``: 180 elements, 5373 dofs)
TINY_MESH_3D = MeshOptions3D(
    h_apex_mm=1.5,
    h_contact_mm=2.0,
    grading=0.8,
    h_max_mm=4.0,
    layer_divisions=1,
    around_divisions=1,
)

_HEX8 = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))


@functools.cache
def subcells() -> np.ndarray:
    """(8 sub-hexahedra, 8 corners): the local 27-node index of each corner of each trilinear
    sub-hexahedron, from FElupe's own ``TriQuadraticHexahedron`` node coordinates (VTK order,
    the mesh's: checked in ``_model``)."""
    import felupe as fem

    offsets = np.rint(fem.TriQuadraticHexahedron().points).astype(int) + 1  # 0, 1, 2
    local = {tuple(int(v) for v in o): i for i, o in enumerate(offsets)}
    return np.array(
        [
            [local[(a + i, b + j, c + k)] for (i, j, k) in _HEX8]
            for c in (0, 1)
            for b in (0, 1)
            for a in (0, 1)
        ]
    )


def q1_subcells(hexes: np.ndarray) -> np.ndarray:
    """The 8-node hexahedra (8 M, 8), VTK order, spanned by the 27 nodes of each of the M
    VTK-ordered 27-node ``hexes``: each Q2 element's 2 x 2 x 2 grid of trilinear cells, in the
    orientation of their parent (positive Jacobian if the parent's is)."""
    return np.asarray(hexes)[:, subcells()].reshape(-1, 8)


def bulk_modulus(mu_MPa: float, nu: float) -> float:
    """K (MPa) of the project's neo-Hookean law for (mu, nu): 2 mu (1 + nu) / (3 (1 - 2 nu))."""
    return float(NeoHookean(mu_MPa=mu_MPa, nu=nu).bulk_modulus_MPa)


@dataclass(frozen=True)
class PlateResult:
    """FElupe's plate indentation of the quarter pad.

    ``force_quarter_N`` is the plate's vertical force on the quarter model at ``depths_mm``
    (plate displacement from first touch at the apex); ``iterations`` the Newton iterations of
    each increment (cutbacks included) and ``increments_mm`` the plate positions solved."""

    formulation: str
    depths_mm: list[float]
    force_quarter_N: list[float]
    increments_mm: list[float]
    iterations: list[int]
    cutbacks: int
    max_penetration_mm: float
    multiplier_N_per_mm: float
    n_q2_elements: int
    n_cells: int
    n_nodes: int
    dofs_displacement: int
    dofs_total: int
    dofs_free: int
    wall_s: float
    cpu_s: float
    linear_solver: str
    load_average: tuple[float, float]

    @property
    def force_N(self) -> list[float]:
        """The whole pad's force (the quarter's x 4), N."""
        return [4.0 * f for f in self.force_quarter_N]

    @property
    def newton_iterations(self) -> int:
        return int(sum(self.iterations))

    def to_dict(self) -> dict:
        out = asdict(self)
        out["force_N"] = self.force_N
        out["newton_iterations"] = self.newton_iterations
        out["s_per_iteration"] = self.wall_s / max(1, self.newton_iterations)
        return out


def _linear_solver():
    try:
        from pypardiso import spsolve

        return spsolve, "pypardiso.spsolve"
    except ImportError:  # pragma: no cover - pypardiso is in the dev environment
        from scipy.sparse.linalg import spsolve

        return spsolve, "scipy.sparse.linalg.spsolve"


def _increments(depths: np.ndarray, step_mm: float) -> np.ndarray:
    """Plate positions: a uniform grid of ``step_mm`` up to the deepest depth, plus the
    requested depths, ascending, without near-duplicates."""
    deepest = float(depths.max())
    grid = np.round(step_mm * np.arange(1, math.ceil(deepest / step_mm - 1e-9) + 1), 12)
    values = np.unique(np.concatenate([grid[grid < deepest - 1e-9], depths]))
    keep = np.concatenate([[True], np.diff(values) > 1e-9])
    return values[keep]


def _model(pmesh: PadMesh, mu: float, K: float, formulation: str):
    """FElupe's (field container, solid, mesh) of the quarter pad, plus a centre point (the
    last point, no cells) at the apex height for the plate."""
    import felupe as fem

    X = np.asarray(pmesh.nodes, dtype=float)
    points = np.vstack([X, [[0.0, float(X[:, 1].max()), 0.0]]])
    hexes = np.asarray(pmesh.hexes)
    # the mesh's 27-node order (sim.geometry._q2, VTK's) must be FElupe's
    if not np.array_equal(fem.TriQuadraticHexahedron().points, REFERENCE_POINTS):
        raise RuntimeError("FElupe's TriQuadraticHexahedron is not in VTK order")
    if formulation == "q1p0":
        mesh = fem.Mesh(points, q1_subcells(hexes), "hexahedron")
        region = fem.RegionHexahedron(mesh)
        field = fem.FieldContainer([fem.Field(region, dim=3)])
        solid = fem.SolidBodyNearlyIncompressible(fem.NeoHooke(mu=mu), field, bulk=K)
    elif formulation in ("q2-mixed", "q2-displacement"):
        mesh = fem.Mesh(points, hexes, "hexahedron27")
        region = fem.RegionTriQuadraticHexahedron(mesh)  # 3 x 3 x 3 Gauss-Legendre
        if formulation == "q2-mixed":
            field = fem.FieldsMixed(region, n=3)
            umat = fem.NearlyIncompressible(fem.NeoHooke(mu=mu), bulk=K)
        else:
            field = fem.FieldContainer([fem.Field(region, dim=3)])
            umat = fem.NeoHooke(mu=mu, bulk=K)
        solid = fem.SolidBody(umat, field)
    else:
        raise ValueError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")
    if not np.all(region.dV > 0.0):
        raise ValueError(f"{int(np.sum(region.dV <= 0))} Gauss points with dV <= 0")
    return field, solid, mesh


def solve_plate(
    pmesh: PadMesh,
    mu_MPa: float,
    bulk_MPa: float,
    depths_mm: Sequence[float] | np.ndarray,
    *,
    formulation: str = "q1p0",
    step_mm: float = 0.1,
    penalty_factor: float = PENALTY_FACTOR,
    h_apex_mm: float | None = None,
    tol: float = NEWTON_TOL,
) -> PlateResult:
    """Press FElupe's rigid frictionless plate onto the quarter pad ``pmesh`` (one material:
    neo-Hookean ``mu_MPa``, ``bulk_MPa``) to each of ``depths_mm`` (ascending, > 0) in
    increments of at most ``step_mm``. ``h_apex_mm`` (for the contact multiplier): the mesh's
    apex element size, by default the distance from the apex to its nearest surface node."""
    import felupe as fem

    depths = np.asarray(depths_mm, dtype=float)
    if depths.ndim != 1 or not np.all(depths > 0) or not np.all(np.diff(depths) > 0):
        raise ValueError(f"depths must be positive and ascending, got {depths_mm!r}")
    t_wall, t_cpu, load0 = time.perf_counter(), time.process_time(), os.getloadavg()[0]
    field, solid, mesh = _model(pmesh, mu_MPa, bulk_MPa, formulation)
    u = field[0]
    center = mesh.npoints - 1
    X = mesh.points
    surface = np.asarray(pmesh.surface_nodes)
    if h_apex_mm is None:
        apex = surface[np.argmax(X[surface, 1])]
        dist = np.linalg.norm(X[surface] - X[apex], axis=1)
        h_apex_mm = float(np.min(dist[dist > 0])) * 2.0  # Q2 nodes: half an element apart
    nu = (3 * bulk_MPa - 2 * mu_MPa) / (2 * (3 * bulk_MPa + mu_MPa))
    multiplier = penalty_factor * 2.0 * mu_MPa * (1.0 + nu) * h_apex_mm
    contact = fem.MultiPointContact(
        field, points=surface, centerpoint=center, skip=(True, False, True), multiplier=multiplier
    )

    def mask(nodes) -> np.ndarray:
        out = np.zeros(mesh.npoints, dtype=bool)
        out[np.asarray(nodes)] = True
        return out

    is_center = mask([center])
    boundaries = {
        "base": fem.Boundary(u, mask=mask(pmesh.base)),
        "sym_x": fem.Boundary(u, mask=mask(pmesh.sym_x), skip=(0, 1, 1)),
        "sym_z": fem.Boundary(u, mask=mask(pmesh.sym_z), skip=(1, 1, 0)),
        "plate_xz": fem.Boundary(u, mask=is_center, skip=(0, 1, 0)),
        "plate": fem.Boundary(u, mask=is_center, skip=(1, 0, 1)),
    }
    positions = _increments(depths, step_mm)
    record = _Recorder(center, surface, X)
    cutback = fem.CutbackPlugin(growth=1.0)
    step = fem.Step(
        items=[solid, contact],
        # the first substep is the undeformed state: the cutback needs a converged start
        ramp={boundaries["plate"]: -np.concatenate([[0.0], positions])},
        boundaries=boundaries,
    )
    solver, solver_name = _linear_solver()
    fem.Job(steps=[step], plugins=[record, cutback]).evaluate(verbose=0, tol=tol, solver=solver)
    reached = np.asarray(record.depths[1:])
    if len(reached) != len(positions) or not np.allclose(reached, positions, atol=1e-9):
        raise RuntimeError(f"FElupe reached {reached.tolist()} of {positions.tolist()} mm")
    forces = np.asarray(record.forces[1:])
    picked = [int(np.argmin(np.abs(positions - d))) for d in depths]
    _, dof1 = fem.dof.partition(field, boundaries)
    return PlateResult(
        formulation=formulation,
        depths_mm=depths.tolist(),
        force_quarter_N=forces[picked].tolist(),
        increments_mm=positions.tolist(),
        iterations=record.iterations_per_substep()[1:],
        cutbacks=int(sum(cutback.cutbacks)),
        max_penetration_mm=float(max(record.penetrations)),
        multiplier_N_per_mm=float(multiplier),
        n_q2_elements=len(pmesh.hexes),
        n_cells=int(mesh.ncells),
        n_nodes=len(pmesh.nodes),
        dofs_displacement=3 * len(pmesh.nodes),
        dofs_total=int(sum(f.values.size for f in field.fields)) - 3,  # the centre point's
        dofs_free=len(dof1),
        wall_s=time.perf_counter() - t_wall,
        cpu_s=time.process_time() - t_cpu,
        linear_solver=solver_name,
        load_average=(float(load0), float(os.getloadavg()[0])),
    )


class _Recorder:
    """A FElupe plugin: counts Newton iterations; after each substep records the plate's
    position, its force on the quarter pad and the deepest penetration of a surface node."""

    def __init__(self, center: int, surface: np.ndarray, X: np.ndarray) -> None:
        self.center, self.surface, self.X = center, surface, X
        self.depths: list[float] = []
        self.forces: list[float] = []
        self.penetrations: list[float] = []
        self.count = 0
        self._at_substep: list[int] = []

    def after_iteration(self, context, state) -> None:
        self.count += 1

    def after_substep(self, context, state) -> None:
        res = state.result
        u = res.x[0].values
        c = self.center
        plate_y = self.X[c, 1] + u[c, 1]
        self.depths.append(float(-u[c, 1]))
        self.forces.append(-float(res.fun[3 * c + 1]))  # the centre point's reaction, up > 0
        y = self.X[self.surface, 1] + u[self.surface, 1]
        self.penetrations.append(max(0.0, float(np.max(y - plate_y))))
        self._at_substep.append(self.count)

    def iterations_per_substep(self) -> list[int]:
        return np.diff(np.concatenate([[0], self._at_substep])).astype(int).tolist()


def felupe_plate_force(
    geometry: PadGeometry,
    options: MeshOptions3D,
    mu: float,
    K: float,
    depths: Sequence[float] | np.ndarray,
    **kwargs: Any,
) -> list[float]:
    """FElupe's plate force (N) on the QUARTER pad (one layer, neo-Hookean ``mu``, ``K`` in
    MPa) at the plate displacements ``depths`` (mm, ascending) from first touch, on
    ``build_pad_mesh(geometry, (), options)``; ``kwargs`` go to :func:`solve_plate`
    (``formulation``, ``step_mm``, ``penalty_factor``). Compare with
    ``sim.fe.solver.Body.force``."""
    pmesh = build_pad_mesh(geometry, (), options)
    kwargs.setdefault("h_apex_mm", options.h_apex_mm)
    return solve_plate(pmesh, mu, K, depths, **kwargs).force_quarter_N
