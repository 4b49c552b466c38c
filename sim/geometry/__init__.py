"""The fingertip's shape and its meshes, 2D and 3D.

- ``section``: the 2D cross-section (``Geometry``: a superellipse pulp in layers on a flat base);
- ``pad``: the 3D pad (``PadGeometry``: the section swept along the finger);
- ``mesh2d``: conforming P2 triangle meshes of the half section (Triangle);
- ``mesh3d``: structured Q2 hexahedral meshes of the quarter pad (numpy), written as VTU;
- ``_p2``, ``_q2``: the elements they are made of (the P2 triangle's basis arrays, as scikit-fem
  computes them; the 27-node hexahedron in VTK's node order, its shape functions and rules).

The helpers of a mesh (Jacobians, face areas, ``level``, ...) are imported from their module.
"""

from .mesh2d import DEFAULT_MESH, FingertipMesh, MeshOptions, build_mesh
from .mesh3d import (
    COARSE_MESH_3D,
    DEFAULT_MESH_3D,
    PAD_MESH_3D,
    MeshOptions3D,
    PadMesh,
    build_pad_mesh,
    extruded_section_mesh,
    first_touch_mm,
    half_pad_mesh,
)
from .pad import HALF_LENGTH_RANGE_MM, LENGTH_EXPONENT_RANGE, REFERENCE_PAD, PadGeometry
from .section import REFERENCE_GEOMETRY, Geometry

__all__ = [
    "COARSE_MESH_3D",
    "DEFAULT_MESH",
    "DEFAULT_MESH_3D",
    "HALF_LENGTH_RANGE_MM",
    "LENGTH_EXPONENT_RANGE",
    "PAD_MESH_3D",
    "REFERENCE_GEOMETRY",
    "REFERENCE_PAD",
    "FingertipMesh",
    "Geometry",
    "MeshOptions",
    "MeshOptions3D",
    "PadGeometry",
    "PadMesh",
    "build_mesh",
    "build_pad_mesh",
    "extruded_section_mesh",
    "first_touch_mm",
    "half_pad_mesh",
]
