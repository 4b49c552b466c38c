"""Structured Q2 hexahedral meshes of the layered quarter pad (x >= 0, z >= 0), pure numpy.

Every protocol is symmetric about x = 0 and z = 0 (a flat plate; a wedge whose edge runs along x
at z = 0), so only the quarter x >= 0, z >= 0 of the pad (``sim.geometry.pad``) is meshed. A
plate inclined about x (``model.inclination_deg``) is symmetric about x = 0 only: its model is
the half x >= 0, the quarter and its mirror image in z = 0 (``half_pad_mesh``), graded toward
the plate's first-touch point (``first_touch_mm``) instead of the apex. It is
topologically an eighth of a ball with its corner at the origin (the centre of the base), meshed
by an o-grid of four structured blocks of 27-node triquadratic hexahedra (``sim.geometry._q2``): an
inner box at the origin and three blocks X, Y, Z joining its faces x = e_x, y = e_y, z = e_z to the
curved surfaces.

Parameters. Every node is labelled by a point v of the unit cube [0, 1]^3: the box by all of
it, block X by its face v_x = 1 (and a radial level), Y by v_y = 1, Z by v_z = 1. The faces are
gridded by tensor products of three 1D distributions, one per axis and shared by the two faces
that use it, so the blocks' grids match on their shared faces by construction; a shared node is
computed from identical inputs, numbered once, with no coordinate search. On the box and its
faces the distributions are uniform (U_x, U_y, U_z); on the curved surfaces they are graded
(D_x, D_y, D_z, below).

Surfaces. Along the scaled direction v the boundary of B(a', b', c') is
diag(a', b', c') U(v) with U(v) = sigma(v) v, sigma(v) = G_1(v)^(-1/m) in closed form
(``sim.geometry.pad``: the level function is homogeneous, the body star-shaped), so no root is
sought. The shells (every layer but the last) are foliated by the inset bodies:

    P(v, T) = diag(a - T, b - T, c - T) U(v),   T the depth,

so the outer surface (T = 0) and every interface (T = a cumulative thickness) are coordinate
surfaces: element faces lie on them and each element is in one layer. dP/dT = -U is never
tangent to the surface at depth T (its normal is diag(a - T, ...)^-1 grad G_1(U), and
U . grad G_1(U) = m > 0 by Euler's relation, every term >= 0), so the shells' map has a positive
Jacobian through any thickness.

Core (the last layer). The box [0, e] has the proportions of the core's semi-axes d_K less a
common inset (0.6 of the least; ``_BOX_INSET``), scaled so that its corner is at most
``MeshOptions3D.box_fraction`` of the way out to the core's surface: long in z and thin in y
like the core, so the segments below are closer to the surface normals than rays from the
origin (which a box proportional to d_K would give) are on a long pad. The core's nodes lie on
the straight segments from the box's face point C = diag(e) v (uniform parameters) to the
core's surface point S = diag(d_K) U(v) (graded parameters): P = (1 - w) C + w S, w in [0, 1].
Their Jacobian is not positive by construction (rays would be, but are far from normal on a
long core): the tests check every Gauss point on the parameter ranges and their extremes.

Q2 nodes. The map is evaluated exactly at all 27 nodes of each element -- mid-edge, mid-face and
centre nodes at the parametric midpoints -- so the elements interpolate the curved surfaces and
interfaces to third order.

Why this construction: conforming to the interfaces by construction, closed form (no root
finding, no search), deterministic (pure numpy, no randomness), no degenerate elements (a single
block mapped onto the octant would have 180-degree "corners" at its seams), and the same code
for any semi-axes and exponents (it works in the scaled directions v).

Grading. D_x, D_y, D_z and the radial levels equidistribute the target size
``MeshOptions3D.size`` (smallest at the apex (0, b, 0) and in the contact region around it,
growing away), measured along the outer-surface lines of each family and below the apex. The
apex is the corner v = (0, 1, 0) of block Y: the wedge's edge (z = 0) and the plate's patch
around the apex get the finest elements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from . import _q2
from .pad import REFERENCE_PAD, PadGeometry, level, unit_radius

__all__ = [
    "COARSE_MESH_3D",
    "DEFAULT_MESH_3D",
    "PAD_MESH_3D",
    "MeshOptions3D",
    "PadMesh",
    "boundary_faces",
    "build_pad_mesh",
    "element_volumes",
    "extruded_section_mesh",
    "face_areas",
    "first_touch_mm",
    "half_pad_mesh",
    "jacobian_determinants",
    "scaled_jacobians",
    "surface_weights",
    "write_vtu",
]

_FINE = 1000  # samples of each 1D line when equidistributing the element size
_BOX_INSET = 0.6  # the inner box's shape: the core's semi-axes less this fraction of the least


@dataclass(frozen=True)
class MeshOptions3D:
    """Target element sizes (mm) and division counts of the quarter pad's mesh.

    The target size at a point X of the outer surface is

        h(X) = min(h_max, h_apex + grading * |X - apex|, h_contact + grading * d_contact(X))

    with d_contact the distance from the contact region x <= f a, z <= f c (f =
    ``contact_fraction``; the top of the pad, where the plate touches and along which the
    wedge's edge runs); through the thickness, below the apex, h(d) = min(h_max, h_apex +
    grading * d) at depth d. The 1D node distributions equidistribute h, so their element counts
    are about the length over h.

    Attributes:
        h_apex_mm: element size at the apex (0, b, 0).
        h_contact_mm: element size in the contact region.
        contact_fraction: f, the contact region's extent as a fraction of a (across) and c
            (along the finger).
        grading: growth of the size per mm of distance.
        h_max_mm: largest element size.
        layer_divisions: at least this many elements through each layer but the last.
        around_divisions: at least this many elements along each edge of the o-grid's blocks
            around the octant (and radially through the core).
        box_fraction: the inner box's corner at most this fraction of the way out to the
            core's surface along its ray (the box's shape: the core's semi-axes less 0.6 of the
            least). Above about 0.6 the core's straight segments fold on long pads (m = 4,
            c = 20 mm: negative Jacobians at 0.7).
        edge_h_mm: the wedge's mesh (``sim.simulate`` builds it for the wedge protocol only;
            0, the default: the wedge runs on the mesh of the other protocols): along the
            finger (the z distribution) and through the depth below the surface, the size is
            at most ``edge_h_mm + edge_grading * |z|`` and ``edge_h_mm + edge_grading * d``,
            so that the band along the wedge's edge (z = 0, across the pad) and its first
            millimetres of depth, where the flanks wrap the edge, are finely meshed. The
            other distributions are not refined (the edge is the same at every x).
        edge_grading: growth of that size per mm away from the edge (and from the surface).
    """

    h_apex_mm: float = 0.3
    h_contact_mm: float = 0.6
    contact_fraction: float = 0.5
    grading: float = 0.4
    h_max_mm: float = 2.0
    layer_divisions: int = 2
    around_divisions: int = 2
    box_fraction: float = 0.5
    edge_h_mm: float = 0.0
    #: the 2D model's growth away from its finely meshed apex
    #: (``sim.geometry.mesh2d.MeshOptions.grading``); studies/wedge3d_band.py measured a
    #: narrower band, 0.5, to keep its dofs down (docs/model_3d.md, "Mesh convergence")
    edge_grading: float = 0.3

    def __post_init__(self) -> None:
        positive = ("h_apex_mm", "h_contact_mm", "grading", "h_max_mm", "edge_grading")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"MeshOptions3D.{name} must be > 0, got {getattr(self, name)}")
        if not 0 < self.contact_fraction <= 1:
            raise ValueError(f"contact_fraction must be in (0, 1], got {self.contact_fraction}")
        if not 0 < self.box_fraction < 1:
            raise ValueError(f"box_fraction must be in (0, 1), got {self.box_fraction}")
        if not self.edge_h_mm >= 0:
            raise ValueError(f"MeshOptions3D.edge_h_mm must be >= 0, got {self.edge_h_mm}")
        for name in ("layer_divisions", "around_divisions"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) >= 1):
                raise ValueError(f"MeshOptions3D.{name} must be an int >= 1")

    def size(
        self,
        points: np.ndarray,
        geometry: PadGeometry,
        inclination_deg: float = 0.0,
        along_z: bool = False,
    ) -> np.ndarray:
        """Target size h (...,) in mm at surface ``points`` (..., 3) of ``geometry``.

        ``inclination_deg`` > 0 (a plate tilted about x, ``first_touch_mm``): the apex is
        replaced by the plate's first-touch point (0, y*, z*) and the contact region is
        centred on it, |z - z*| <= f c, so that the patch is as finely meshed as at 0 deg.
        ``points`` may have z < 0 (the heel's side of the half pad, ``half_pad_mesh``)."""
        a, b, c = geometry.semi_axes_mm()
        p = np.asarray(points, dtype=float)
        if inclination_deg != 0.0:
            _, y_t, z_t = first_touch_mm(geometry, inclination_deg)
            d_apex = np.sqrt(p[..., 0] ** 2 + (p[..., 1] - y_t) ** 2 + (p[..., 2] - z_t) ** 2)
            dz = np.maximum(np.abs(p[..., 2] - z_t) - self.contact_fraction * c, 0.0)
        else:
            d_apex = np.sqrt(p[..., 0] ** 2 + (p[..., 1] - b) ** 2 + p[..., 2] ** 2)
            dz = np.maximum(np.abs(p[..., 2]) - self.contact_fraction * c, 0.0)
        dx = np.maximum(p[..., 0] - self.contact_fraction * a, 0.0)
        h = np.minimum(self.h_max_mm, self.h_apex_mm + self.grading * d_apex)
        h = np.minimum(h, self.h_contact_mm + self.grading * np.sqrt(dx * dx + dz * dz))
        if along_z and self.edge_h_mm > 0.0:  # the wedge's band (the z distribution only)
            h = np.minimum(h, self.edge_h_mm + self.edge_grading * np.abs(p[..., 2]))
        return h

    def depth_size(self, depth_mm: np.ndarray) -> np.ndarray:
        """Target size h (...,) in mm at ``depth_mm`` below the apex (and below the wedge's
        edge, ``edge_h_mm``)."""
        depth = np.asarray(depth_mm)
        h = np.minimum(self.h_max_mm, self.h_apex_mm + self.grading * depth)
        if self.edge_h_mm > 0.0:
            h = np.minimum(h, self.edge_h_mm + self.edge_grading * depth)
        return h

    def without_edge(self) -> MeshOptions3D:
        """The mesh of the protocols other than the wedge (no band along its edge; the band's
        grading back at its field default, as it means nothing without the band)."""
        return replace(self, edge_h_mm=0.0, edge_grading=MeshOptions3D.edge_grading)

    def refined(self, factor: float) -> MeshOptions3D:
        """All sizes and the gradings divided by ``factor``, the minimum counts multiplied by it
        (rounded up): the target size h / factor everywhere (for convergence studies)."""
        return MeshOptions3D(
            self.h_apex_mm / factor,
            self.h_contact_mm / factor,
            self.contact_fraction,
            self.grading / factor,
            self.h_max_mm / factor,
            math.ceil(self.layer_divisions * factor - 1e-9),
            math.ceil(self.around_divisions * factor - 1e-9),
            self.box_fraction,
            self.edge_h_mm / factor,
            # without a band its grading means nothing and keeps its default (the options'
            # dict leaves both out then, so that the records keep their keys)
            self.edge_grading / factor if self.edge_h_mm > 0.0 else self.edge_grading,
        )


#: The simulations' mesh (``SimOptions.mesh3d``): the family of ``studies/mesh3d_convergence.py``
#: (its coarsest member, below, refined by f) at f = 1.41, about 11 000-12 000 dofs on the
#: default-size pads. Over f = 1, 1.41, 2 the displacements at 1 N and 4 N moved by at most
#: 0.7 % on a soft gel and a stiffer silicone pad, so this member is within 1 % on them; the
#: plate force is within 1.5-3 % of the finest and the contact area at 4 N within 1.3 %, at
#: 1 N only within 10-15 % (docs/model_3d.md, "Mesh convergence"). The field defaults of
#: ``MeshOptions3D`` are the finer mesh of the FElupe comparison (``tests/test_fe3d_felupe.py``).
#: The wedge runs on that mesh with a band of 0.05 mm elements along its edge, growing by 0.5
#: per mm (``edge_h_mm``, ``edge_grading``): without it the wedge's force and profile are 20-33 %
#: too high, with it within 1.6-1.8 % of the values extrapolated from bands of 0.4 to 0.05 mm
#: (fitted rates 0.8-1.1; ``studies/wedge3d_band.py``, docs/model_3d.md, "Mesh convergence").
#: 0.05 mm is also the 2D model's element at the wedge's apex (``MeshOptions.h_apex_mm``), so
#: the two models resolve the tip alike. A 1 % wedge needs about 0.025 mm at roughly twice the
#: cost of the band's factorisations, not taken for the 3D datasets (docs/model_3d.md).
COARSE_MESH_3D = MeshOptions3D(h_apex_mm=1.0, h_contact_mm=1.5, h_max_mm=3.0, grading=0.6)
DEFAULT_MESH_3D = replace(COARSE_MESH_3D.refined(1.41), edge_h_mm=0.05, edge_grading=0.5)
#: ``DEFAULT_MESH_3D`` without the band: the mesh of the tapping and the plate
PAD_MESH_3D = DEFAULT_MESH_3D.without_edge()


@dataclass(frozen=True, eq=False)
class PadMesh:
    """A Q2 hexahedral mesh of the quarter pad (or, ``half``, of the half pad x >= 0:
    ``half_pad_mesh``) with its labelled boundaries (read-only arrays).

    Attributes:
        nodes: (N, 3) node coordinates (mm).
        hexes: (M, 27) node indices of each element in VTK_TRIQUADRATIC_HEXAHEDRON order
            (``sim.geometry._q2``; positive Jacobian).
        layer: (M,) layer index of each element, 0 = outermost.
        base: indices of the nodes on the bonded base y = 0 (fully fixed).
        sym_x: indices of the nodes on the symmetry plane x = 0 (u_x = 0).
        sym_z: indices of the nodes on the symmetry plane z = 0 (u_z = 0); none on the half.
        surface_faces: (F, 9) the free outer surface's faces, 9-node quadrilaterals in
            VTK_BIQUADRATIC_QUAD order, numbered so that dX/ds x dX/dt points outwards.
        interfaces: node indices on each layer interface, outermost first.
        geometry: the pad.
        thicknesses_mm: the thicknesses of all layers but the last.
        half: the half pad x >= 0 (symmetric about x = 0 only), not the quarter.
        inclination_deg: the plate inclination the mesh is graded for (``first_touch_mm``).
        edge_h_mm: the element size of the band along the wedge's edge (``MeshOptions3D``;
            0: no band).
    """

    nodes: np.ndarray
    hexes: np.ndarray
    layer: np.ndarray
    base: np.ndarray
    sym_x: np.ndarray
    sym_z: np.ndarray
    surface_faces: np.ndarray
    interfaces: tuple[np.ndarray, ...]
    geometry: PadGeometry = field(default=REFERENCE_PAD)
    thicknesses_mm: tuple[float, ...] = ()
    half: bool = False
    inclination_deg: float = 0.0
    edge_h_mm: float = 0.0

    @property
    def mirrors(self) -> int:
        """Copies of the meshed part that make the whole pad: 4 (quarter) or 2 (half)."""
        return 2 if self.half else 4

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_dofs(self) -> int:
        """Three displacement components per node (before the boundary conditions)."""
        return 3 * self.n_nodes

    @property
    def surface_nodes(self) -> np.ndarray:
        """Indices of the nodes on the free outer surface, ascending."""
        return np.unique(self.surface_faces)


# ----------------------------------------------------------------------------- construction
def build_pad_mesh(
    geometry: PadGeometry = REFERENCE_PAD,
    thicknesses_mm: tuple[float, ...] = (),
    options: MeshOptions3D = PAD_MESH_3D,
    inclination_deg: float = 0.0,
    half: bool | None = None,
) -> PadMesh:
    """Mesh the quarter pad with interfaces at the cumulative depths of ``thicknesses_mm``
    (the thicknesses of all layers but the last, outermost first). By default the mesh of the
    tapping and the plate; ``DEFAULT_MESH_3D`` itself, with its band along the wedge's edge, is
    the wedge's (``sim.simulate.discretize``).

    ``inclination_deg`` > 0: graded for a plate tilted by that angle about x (the finest
    elements at its first-touch point, ``MeshOptions3D.size``) and, as the tilted plate breaks
    the symmetry about z = 0, the half pad x >= 0 (``half_pad_mesh``): the quarter z >= 0
    graded for the plate, glued to a quarter z <= 0 graded as the same target sizes ask there
    (coarser: the plate touches on the side z > 0). ``half``: the half pad
    (default: whenever ``inclination_deg`` > 0; ``half=True`` at 0 deg for comparisons with
    the quarter). Raises ``DesignError`` if the layers leave no core
    (``PadGeometry.check_layers``).
    """
    if half is None:
        half = inclination_deg != 0.0
    if inclination_deg != 0.0 and not half:
        raise ValueError("an inclined plate needs the half pad (half=True)")
    quarter = _build_quarter(geometry, thicknesses_mm, options, inclination_deg)
    if not half:
        return quarter
    heel = None  # at 0 deg the heel's side is the quarter's mirror image
    if inclination_deg != 0.0:
        heel = _build_quarter(geometry, thicknesses_mm, options, inclination_deg, heel=True)
    return half_pad_mesh(quarter, heel)


def _build_quarter(
    geometry: PadGeometry,
    thicknesses_mm: tuple[float, ...],
    options: MeshOptions3D,
    inclination_deg: float,
    heel: bool = False,
) -> PadMesh:
    """The quarter pad's mesh (``build_pad_mesh``), graded for ``inclination_deg``; ``heel``:
    the quarter's z distribution graded for its mirror image z <= 0 (the heel's side of the half
    pad, ``half_pad_mesh``), its other distributions those of the quarter, so that the two
    meet node for node on z = 0."""
    thicknesses_mm = tuple(float(t) for t in thicknesses_mm)
    geometry.check_layers(thicknesses_mm)
    depths = np.concatenate([[0.0], np.cumsum(thicknesses_mm)])  # surface, then interfaces
    core = _Core.of(geometry, float(depths[-1]), options.box_fraction)

    # 1D vertex distributions (graded: D, on the surfaces; uniform: U, on the box), then the
    # Q2 node parameters (vertices and midpoints)
    graded = [
        _with_midpoints(_tangential(d, geometry, options, inclination_deg, heel and d == 2))
        for d in range(3)
    ]
    uniform = [_with_midpoints(np.linspace(0.0, 1.0, (len(D) + 1) // 2)) for D in graded]
    w, shell_depths, radial_layer, levels = _radial_levels(geometry, depths, core, options)
    w = _with_midpoints(w)
    shell_depths = _with_midpoints(np.concatenate([[depths[-1]], shell_depths]))[1:]

    ids = _node_ids(*(len(U) for U in uniform), len(w) + len(shell_depths))
    nodes = np.empty((int(max(b.max() for b in ids.values())) + 1, 3))
    v = np.stack(np.meshgrid(*uniform, indexing="ij"), axis=-1)
    nodes[ids["box"].ravel()] = (core.box * v).reshape(-1, 3)
    for axis, name in enumerate(("x", "y", "z")):
        coords = _block_coordinates(axis, uniform, graded, w, shell_depths, geometry, core)
        coords = np.moveaxis(coords, 0, axis)  # the level along the block's radial axis
        nodes[ids[name].ravel()] = coords.reshape(-1, 3)

    hexes, layer, surface = [], [], []
    for name, face in (("box", None), ("x", 1), ("y", 3), ("z", 5)):
        h = _block_hexes(ids[name])
        hexes.append(h)
        if face is None:
            layer.append(np.full(len(h), len(depths) - 1))
            continue
        axis = face // 2
        shape = tuple((s - 1) // 2 for s in ids[name].shape)
        radial_index = np.indices(shape)[axis].ravel()
        layer.append(radial_layer[radial_index])
        outer = radial_index == shape[axis] - 1
        surface.append(h[outer][:, _q2.FACE_NODES[face]])
    hexes = np.concatenate(hexes)
    layer = np.concatenate(layer)

    out = PadMesh(
        nodes=nodes,
        hexes=hexes,
        layer=layer,
        base=np.flatnonzero(nodes[:, 1] == 0.0),
        sym_x=np.flatnonzero(nodes[:, 0] == 0.0),
        sym_z=np.flatnonzero(nodes[:, 2] == 0.0),
        surface_faces=np.concatenate(surface),
        interfaces=tuple(_level_nodes(ids, 2 * levels[k]) for k in range(1, len(depths))),
        geometry=geometry,
        thicknesses_mm=thicknesses_mm,
        inclination_deg=float(inclination_deg),
        edge_h_mm=float(options.edge_h_mm),
    )
    return _read_only(out)


def _read_only(out: PadMesh) -> PadMesh:
    """``out`` with its arrays made read-only."""
    for arr in (out.nodes, out.hexes, out.layer, out.base, out.sym_x, out.sym_z):
        arr.setflags(write=False)
    out.surface_faces.setflags(write=False)
    for arr in out.interfaces:
        arr.setflags(write=False)
    return out


def _reflection(points: np.ndarray, signs: tuple[float, ...]) -> np.ndarray:
    """The permutation k -> j of reference nodes ``points`` (K, d) with points[j] =
    signs * points[k]: a cell's local nodes reflected in the coordinates of sign -1."""
    reflected = points * np.asarray(signs)
    return np.array([np.flatnonzero(np.all(points == r, axis=1))[0] for r in reflected])


def half_pad_mesh(quarter: PadMesh, heel: PadMesh | None = None) -> PadMesh:
    """The half pad x >= 0: the quarter ``quarter`` (z >= 0) and the mirror image in z = 0 of
    ``heel``, a quarter of the same pad meshed for the side z <= 0 (default: ``quarter``
    itself, the symmetric half).

    The mirror of node i is (x, y, -z)_i. The nodes on z = 0 (``sym_z``: z is exactly 0.0 there
    by construction, every one computed from v_z = 0) are shared and numbered once; the heel's
    others are appended after the quarter's nodes (which keep their indices). The two quarters
    meet node for node on z = 0: ``heel`` differs from ``quarter`` in its z distribution only
    (``build_pad_mesh``), and each numbers its nodes block by block in C order with v_z last,
    so the k-th node on the plane of one is the k-th of the other (checked to 1e-9 mm; no
    coordinate search). Reflecting z turns a cell inside out: each mirrored hexahedron's local
    nodes are reflected in zeta (VTK order, ``sim.geometry._q2``) and each mirrored surface
    face's in s, so every Jacobian stays positive and every face normal points out. No node is
    on a symmetry plane z = 0 any more (``sym_z`` empty)."""
    heel = quarter if heel is None else heel
    X, Xh = np.asarray(quarter.nodes), np.asarray(heel.nodes)
    n = len(X)
    plane, plane_h = np.asarray(quarter.sym_z), np.asarray(heel.sym_z)
    if len(plane) != len(plane_h) or not np.allclose(X[plane], Xh[plane_h], rtol=0.0, atol=1e-9):
        raise ValueError("the heel's quarter does not meet the quarter node for node on z = 0")
    on_plane = np.zeros(len(Xh), dtype=bool)
    on_plane[plane_h] = True
    mirror = np.empty(len(Xh), dtype=np.int64)  # the index of each heel node's mirror image
    mirror[plane_h] = plane
    mirror[~on_plane] = n + np.arange(int(np.count_nonzero(~on_plane)))
    nodes = np.concatenate([X, Xh[~on_plane] * np.array([1.0, 1.0, -1.0])])
    flip_cell = _reflection(_q2.REFERENCE_POINTS, (1.0, 1.0, -1.0))
    flip_face = _reflection(_q2.FACE_REFERENCE_POINTS, (-1.0, 1.0))
    hexes, faces = np.asarray(quarter.hexes), np.asarray(quarter.surface_faces)
    hexes_h, faces_h = np.asarray(heel.hexes), np.asarray(heel.surface_faces)
    out = PadMesh(
        nodes=nodes,
        hexes=np.concatenate([hexes, mirror[hexes_h][:, flip_cell]]),
        layer=np.concatenate([quarter.layer, heel.layer]),
        base=np.flatnonzero(nodes[:, 1] == 0.0),
        sym_x=np.flatnonzero(nodes[:, 0] == 0.0),
        sym_z=np.zeros(0, dtype=np.int64),
        surface_faces=np.concatenate([faces, mirror[faces_h][:, flip_face]]),
        interfaces=tuple(
            np.union1d(ids, mirror[ids_h])
            for ids, ids_h in zip(quarter.interfaces, heel.interfaces, strict=True)
        ),
        geometry=quarter.geometry,
        thicknesses_mm=quarter.thicknesses_mm,
        half=True,
        inclination_deg=quarter.inclination_deg,
        edge_h_mm=quarter.edge_h_mm,
    )
    return _read_only(out)


def first_touch_mm(geometry: PadGeometry, inclination_deg: float) -> tuple[float, float, float]:
    """The point (0, y*, z*) of the outer surface where a plate tilted by t =
    ``inclination_deg`` about x (outward normal e = (0, cos t, sin t), ``sim.fe.contact.Plate``)
    first touches it: where the surface's normal is e, on x = 0 (each section's top).

    On x = 0 the surface is (y/b)^m + (z/c)^m = 1; its normal is parallel to
    (y^(m-1) / b^m, z^(m-1) / c^m) in (y, z), which is parallel to (cos t, sin t) where
    (u / s)^(m-1) = (c / b) tan t with u = z / c, s = y / b = s(z). With
    r = ((c / b) tan t)^(1/(m-1)):

        s = (1 + r^m)^(-1/m),   u = r s,   (y*, z*) = (b s, c u)

    (docs/fingertip_3d.md, the table of first-touch points). t = 0 gives the apex (0, b, 0)."""
    _, b, c = geometry.semi_axes_mm()
    m = float(geometry.length_exponent)
    t = math.radians(inclination_deg)
    r = ((c / b) * math.tan(t)) ** (1.0 / (m - 1.0))
    s = (1.0 + r**m) ** (-1.0 / m)
    return 0.0, b * s, c * r * s


def extruded_section_mesh(pmesh: PadMesh, thickness_mm: float) -> PadMesh:
    """The 2D model's half section as a slab of Q2 hexahedra: the face z = 0 of ``pmesh`` (its
    9-node quadrilaterals, the section x >= 0 with its layers) extruded by one element of
    ``thickness_mm`` along z. With u_z = 0 at every node (the caller's boundary condition) the
    slab is in plane strain exactly, as the middle of a long extrusion is, so its forces per
    unit thickness must equal the 2D model's line loads up to the two discretisations' errors
    (``tests/test_fe3d.py``). Node sets as ``build_pad_mesh``'s; ``sym_z`` is the face z = 0,
    ``surface_faces`` the extruded outer curve; ``interfaces`` the extruded interfaces."""
    X = np.asarray(pmesh.nodes)
    on_plane = X[:, 2] == 0.0
    faces, parents = [], []
    for f in (4, 5):  # the zeta faces of each element: the one lying on z = 0, if any
        nodes = np.asarray(pmesh.hexes)[:, _q2.FACE_NODES[f]]
        hit = np.all(on_plane[nodes], axis=1)
        faces.append(nodes[hit])
        parents.append(np.flatnonzero(hit))
    faces, parents = np.concatenate(faces), np.concatenate(parents)
    section = np.unique(faces)  # the section's nodes, renumbered 0 .. n2 - 1 per plane
    local = -np.ones(len(X), dtype=np.int64)
    local[section] = np.arange(len(section))
    n2 = len(section)
    nodes = np.concatenate(
        [X[section] + [0.0, 0.0, z] for z in (0.0, thickness_mm / 2, thickness_mm)]
    )
    # hexahedron node a at reference (xi, eta, zeta): the face node at (s, t) = (xi, eta) on
    # the plane of zeta (-1: z = 0); faces point out of their element (towards -z), so the
    # slab's elements are mirrored in s to keep a positive Jacobian
    face_at = {tuple(pt): k for k, pt in enumerate(_q2.FACE_REFERENCE_POINTS.astype(int))}
    pick = np.array([face_at[(-int(x), int(y))] for x, y, _ in _q2.REFERENCE_POINTS])
    plane = np.array([int(z) + 1 for _, _, z in _q2.REFERENCE_POINTS])
    hexes = local[faces][:, pick] + plane * n2
    if np.any(jacobian_determinants(nodes, hexes) <= 0.0):
        raise ValueError("the extruded section has an inverted element")
    outer = np.zeros(len(nodes), dtype=bool)
    curve = local[np.intersect1d(section, np.asarray(pmesh.surface_nodes))]
    outer[np.concatenate([curve + k * n2 for k in range(3)])] = True
    surface = []
    for f in range(4):  # the side faces of each element on the outer curve, outward
        nodes_f = hexes[:, _q2.FACE_NODES[f]]
        surface.append(nodes_f[np.all(outer[nodes_f], axis=1)])

    def extruded(ids: np.ndarray) -> np.ndarray:
        ids = local[np.intersect1d(section, ids)]
        return np.concatenate([ids + k * n2 for k in range(3)])

    return PadMesh(
        nodes=nodes,
        hexes=hexes,
        layer=np.asarray(pmesh.layer)[parents],
        base=np.flatnonzero(nodes[:, 1] == 0.0),
        sym_x=np.flatnonzero(nodes[:, 0] == 0.0),
        sym_z=np.flatnonzero(nodes[:, 2] == 0.0),
        surface_faces=np.concatenate(surface),
        interfaces=tuple(extruded(ids) for ids in pmesh.interfaces),
        geometry=pmesh.geometry,
        thicknesses_mm=pmesh.thicknesses_mm,
    )


@dataclass(frozen=True, eq=False)
class _Core:
    """The core body B(d_K) (``axes`` d_K, exponents n, m) and the inner box [0, box]."""

    axes: np.ndarray
    box: np.ndarray
    n: float
    m: float

    @classmethod
    def of(cls, geometry: PadGeometry, depth_mm: float, fraction: float) -> _Core:
        """The core below ``depth_mm``; the box's shape is the core's semi-axes less a common
        inset (``_BOX_INSET`` of the smallest; at least a tenth of each), scaled so that its
        corner is at most ``fraction`` of the way out to the core's surface along its ray."""
        axes = np.array(geometry.semi_axes_mm(depth_mm))
        n, m = geometry.exponents
        box = np.maximum(axes - _BOX_INSET * axes.min(), 0.1 * axes)
        out = float(level(box, axes, n, m)) ** (1.0 / m)  # the corner's fraction of its ray
        return cls(axes, box * min(1.0, fraction / out), n, m)


def _unit_points(directions: np.ndarray, n: float, m: float) -> np.ndarray:
    """U(v) = sigma(v) v (..., 3): the unit body's surface points along ``directions``."""
    v = np.asarray(directions, dtype=float)
    return unit_radius(v, n, m)[..., None] * v


def _face_directions(axis: int, t1: np.ndarray, t2: np.ndarray) -> np.ndarray:
    """Points (T1, T2, 3) of the unit cube's face v_axis = 1 with the other two coordinates
    (in order) ``t1`` and ``t2``."""
    a1, a2 = (d for d in range(3) if d != axis)
    v = np.empty((len(t1), len(t2), 3))
    v[..., axis] = 1.0
    v[..., a1] = t1[:, None]
    v[..., a2] = t2[None, :]
    return v


def _block_coordinates(
    axis: int,
    uniform: list[np.ndarray],
    graded: list[np.ndarray],
    w: np.ndarray,
    shell_depths: np.ndarray,
    geometry: PadGeometry,
    core: _Core,
) -> np.ndarray:
    """Nodes (L, T1, T2, 3) of the block on the cube's face v_axis = 1, by radial level and the
    other two axes' node indices: the core levels on the segments from the box's face
    (uniform parameters) to the core's surface (graded ones), (1 - w) C + w S; the shell levels
    at diag(d - T) S / d_K for their depths T."""
    a1, a2 = (d for d in range(3) if d != axis)
    C = core.box * _face_directions(axis, uniform[a1], uniform[a2])
    U = _unit_points(_face_directions(axis, graded[a1], graded[a2]), core.n, core.m)
    S = core.axes * U
    inner = (1.0 - w)[:, None, None, None] * C + w[:, None, None, None] * S
    scale = np.array([geometry.semi_axes_mm(float(t)) for t in shell_depths]).reshape(-1, 3)
    shells = scale[:, None, None, :] * U
    return np.concatenate([inner, shells])


def _with_midpoints(x: np.ndarray) -> np.ndarray:
    """The vertex values ``x`` (k,) with their midpoints between: (2k - 1,)."""
    out = np.empty(2 * len(x) - 1)
    out[::2] = x
    out[1::2] = 0.5 * (x[:-1] + x[1:])
    return out


def _equidistribute(param: np.ndarray, density: np.ndarray, n_min: int) -> np.ndarray:
    """Vertices in ``param`` (K + 1,) (monotone, from 0 to 1) so that each element holds an
    equal share of int density (``density`` (K,): elements per sample interval); at least
    ``n_min`` elements, and about the integral's count."""
    count = np.concatenate([[0.0], np.cumsum(density)])
    n_el = max(n_min, math.ceil(count[-1] - 1e-9))
    out = np.interp(np.linspace(0.0, count[-1], n_el + 1), count, param)
    out[0], out[-1] = param[0], param[-1]
    return out


def _tangential(
    axis: int,
    geometry: PadGeometry,
    options: MeshOptions3D,
    inclination_deg: float = 0.0,
    mirrored: bool = False,
) -> np.ndarray:
    """The vertex distribution D_axis on [0, 1]: the number of elements needed along the
    outer-surface lines v_axis = t of the two cube faces that use it (five lines on each), the
    densest line deciding each interval; ``mirrored``: the sizes those lines' mirror images in
    z = 0 ask for (the heel's side of the half pad)."""
    t = np.linspace(0.0, 1.0, _FINE + 1)
    lines = []
    for face in range(3):
        if face == axis:
            continue
        other = 3 - axis - face
        for value in np.linspace(0.0, 1.0, 5):
            v = np.zeros((len(t), 3))
            v[:, axis], v[:, face], v[:, other] = t, 1.0, value
            lines.append(v)
    X = geometry.surface_points(np.stack(lines))  # (L, K + 1, 3) on the outer surface
    seg = np.linalg.norm(np.diff(X, axis=1), axis=-1)
    mid = 0.5 * (X[:, 1:] + X[:, :-1])
    if mirrored:
        mid = mid * np.array([1.0, 1.0, -1.0])
    size = options.size(mid, geometry, inclination_deg, along_z=axis == 2)
    density = np.max(seg / size, axis=0)
    return _equidistribute(t, density, options.around_divisions)


def _radial_levels(
    geometry: PadGeometry, depths: np.ndarray, core: _Core, options: MeshOptions3D
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """The radial vertex levels from the box's faces out to the surface, graded by the size
    below the apex: the core's w (from 0 on the box to 1 on its surface, along the apex's
    segment x = z = 0), then the shells' depths (innermost first, the innermost interface's
    left out: it is w = 1). Returns w, the depths, the layer of each radial element and the
    vertex level of each of ``depths``."""
    b = geometry.semi_axes_mm()[1]
    t = np.linspace(0.0, 1.0, _FINE + 1)
    depth_w = b - (core.box[1] + t * (core.axes[1] - core.box[1]))
    density = np.abs(np.diff(depth_w)) / options.depth_size(0.5 * (depth_w[1:] + depth_w[:-1]))
    w = _equidistribute(t, density, options.around_divisions)
    n_layers = len(depths)
    radial_layer = [np.full(len(w) - 1, n_layers - 1)]
    levels = [0] * n_layers
    levels[-1] = len(w) - 1
    shell_depths = []
    for k in range(n_layers - 2, -1, -1):  # layer k from depths[k + 1] up to depths[k]
        top, bottom = float(depths[k]), float(depths[k + 1])
        d = bottom + t * (top - bottom)
        density = np.abs(np.diff(d)) / options.depth_size(0.5 * (d[1:] + d[:-1]))
        u = _equidistribute(t, density, options.layer_divisions)
        d_nodes = bottom + u[1:] * (top - bottom)
        d_nodes[-1] = top
        shell_depths.append(d_nodes)
        radial_layer.append(np.full(len(d_nodes), k))
        levels[k] = levels[k + 1] + len(d_nodes)
    return (
        w,
        np.concatenate([np.zeros(0), *shell_depths]),
        np.concatenate(radial_layer),
        levels,
    )


def _node_ids(nx: int, ny: int, nz: int, nr: int) -> dict[str, np.ndarray]:
    """Global node indices of the four blocks' Q2 node grids, each shared node numbered once.

    ``box`` (nx, ny, nz) over (v_x, v_y, v_z); ``x`` (nr, ny, nz) over (level, v_y, v_z);
    ``y`` (nx, nr, nz) over (v_x, level, v_z); ``z`` (nx, ny, nr) over (v_x, v_y, level).
    Level 0 is the box's face; the blocks X, Y share their faces v_x = v_y = 1, etc.
    """
    ids = {
        "box": np.full((nx, ny, nz), -1),
        "x": np.full((nr, ny, nz), -1),
        "y": np.full((nx, nr, nz), -1),
        "z": np.full((nx, ny, nr), -1),
    }
    counter = 0

    def number(block: np.ndarray) -> None:
        nonlocal counter
        free = block.ravel() == -1  # in C order: deterministic
        flat = block.reshape(-1)
        flat[free] = np.arange(counter, counter + np.count_nonzero(free))
        counter += int(np.count_nonzero(free))

    number(ids["box"])
    ids["x"][0] = ids["box"][-1]
    number(ids["x"])
    ids["y"][:, 0] = ids["box"][:, -1]
    ids["y"][-1] = ids["x"][:, -1, :]  # v_x = v_y = 1: X's (level, v_z) = Y's (level, v_z)
    number(ids["y"])
    ids["z"][:, :, 0] = ids["box"][:, :, -1]
    ids["z"][-1] = ids["x"][:, :, -1].T  # v_x = v_z = 1: X's (level, v_y) -> Z's (v_y, level)
    ids["z"][:, -1] = ids["y"][:, :, -1]  # v_y = v_z = 1: Y's (v_x, level) = Z's (v_x, level)
    number(ids["z"])
    return ids


_LOCAL = np.rint(_q2.REFERENCE_POINTS).astype(int) + 1  # (27, 3) offsets 0, 1, 2


def _block_hexes(ids: np.ndarray) -> np.ndarray:
    """The (M, 27) elements of a structured Q2 node grid ``ids`` (2A + 1, 2B + 1, 2C + 1), in C
    order of the element indices, local nodes in VTK order."""
    shape = tuple((s - 1) // 2 for s in ids.shape)
    e = np.indices(shape).reshape(3, -1)  # (3, M)
    i = 2 * e[0][:, None] + _LOCAL[:, 0]
    j = 2 * e[1][:, None] + _LOCAL[:, 1]
    k = 2 * e[2][:, None] + _LOCAL[:, 2]
    return ids[i, j, k]


def _level_nodes(ids: dict[str, np.ndarray], level: int) -> np.ndarray:
    """Indices of the nodes at the Q2 radial level ``level`` of the three blocks."""
    parts = [ids["x"][level].ravel(), ids["y"][:, level].ravel(), ids["z"][:, :, level].ravel()]
    return np.unique(np.concatenate(parts))


# ----------------------------------------------------------------------------- element geometry
def _jacobians(nodes: np.ndarray, hexes: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """dX/dxi (M, 27, 3, 3) at the 27 Gauss points: ``[e, g, i, d]`` = dX_i/dxi_d."""
    points, _ = _q2.gauss_rule()
    dN = _q2.shape_gradients(points)  # (27 g, 27 a, 3 d)
    out = np.empty((len(hexes), len(points), 3, 3))
    for s in range(0, len(hexes), chunk):
        X = nodes[hexes[s : s + chunk]]  # (m, 27 a, 3 i)
        out[s : s + chunk] = np.einsum("mai,gad->mgid", X, dN)
    return out


def jacobian_determinants(nodes: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """det(dX/dxi) (M, 27) at the 3 x 3 x 3 Gauss points (``sim.geometry._q2.gauss_rule`` order)."""
    return np.linalg.det(_jacobians(nodes, hexes))


def scaled_jacobians(nodes: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Each element's smallest scaled Jacobian over its 27 Gauss points (M,):
    det J / (|J e_xi| |J e_eta| |J e_zeta|), in [-1, 1], 1 for a rectangular box."""
    J = _jacobians(nodes, hexes)
    norms = np.linalg.norm(J, axis=2)  # (M, 27, 3): lengths of the columns
    return np.min(np.linalg.det(J) / np.prod(norms, axis=-1), axis=1)


def element_volumes(nodes: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Volume (M,) of each element in mm^3: sum over the Gauss points of det J w."""
    _, weights = _q2.gauss_rule()
    return jacobian_determinants(nodes, hexes) @ weights


def _face_metric(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The face shape functions (9 g, 9 a) and |dX/ds x dX/dt| w (F, 9 g) at the face rule."""
    s, w = _q2.face_gauss_rule()
    N = _q2.face_shape_functions(s)
    dN = _q2.face_shape_gradients(s)  # (9 g, 9 a, 2)
    X = np.asarray(points, dtype=float)[faces]  # (F, 9 a, 3)
    tangents = np.einsum("fai,gad->fgdi", X, dN)  # (F, 9 g, 2, 3)
    normal = np.cross(tangents[:, :, 0], tangents[:, :, 1])
    return N, np.linalg.norm(normal, axis=-1) * w


def face_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area (F,) of each 9-node face (3 x 3 Gauss rule on the curved face), mm^2."""
    return _face_metric(points, faces)[1].sum(axis=1)


def surface_weights(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each node's share of the area of ``faces`` (the 3D analogue of
    ``sim.fe.contact.surface_weights``): w_i = sum over the faces of int N_i dA, by the 3 x 3 Gauss
    rule on the curved face at ``points`` (N, 3) (reference or current). Returns (N,), zero
    off the faces; sum(w) is the faces' area. On a flat parallelogram face the weights are
    area * (1/36 corners, 4/36 mid-edges, 16/36 centre), all positive."""
    N, dA = _face_metric(points, faces)
    contrib = dA @ N  # (F, 9 a): int N_a dA
    w = np.zeros(len(points))
    np.add.at(w, faces.ravel(), contrib.ravel())
    return w


def boundary_faces(hexes: np.ndarray, on_boundary: np.ndarray) -> np.ndarray:
    """The 9-node faces (F, 9) of ``hexes`` whose nine nodes are all flagged by
    ``on_boundary`` (N,) bool, oriented out of their element (a face between two flagged
    elements appears twice, once from each side)."""
    faces = hexes[:, _q2.FACE_NODES]  # (M, 6, 9)
    inside = np.all(on_boundary[faces], axis=2)
    return faces[inside]


def write_vtu(
    mesh: PadMesh,
    path,
    point_data: dict[str, np.ndarray] | None = None,
    cell_data: dict[str, np.ndarray] | None = None,
) -> None:
    """Write ``mesh`` as VTK_TRIQUADRATIC_HEXAHEDRON cells (meshio's "hexahedron27", no
    reordering) to a .vtu file, with the element ``layer`` and any ``point_data`` (name ->
    (N, ...)) and ``cell_data`` (name -> (M, ...)) arrays."""
    import meshio

    cells = {"layer": mesh.layer, **(cell_data or {})}
    meshio.Mesh(
        np.asarray(mesh.nodes),
        [("hexahedron27", np.asarray(mesh.hexes))],
        point_data=dict(point_data or {}),
        cell_data={k: [np.asarray(v)] for k, v in cells.items()},
    ).write(str(path))
