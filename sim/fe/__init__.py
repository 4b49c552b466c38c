"""The finite-element model: discretisations, contact and the Newton solver.

- ``fe2d``: total-Lagrangian P2 plane-strain discretisation (``Discretization``);
- ``fe3d``: its 3D sibling on Q2 hexahedra (``Discretization3D``, imported on first use);
- ``_assembly``: the residual and the lazily assembled tangent, shared by both;
- ``_constitutive``: the viscoelastic stress and tangent of every layer, shared by both;
- ``_kernels`` (compiled assembly loops, numba: imported on the first evaluation),
  ``_pattern`` (the sparsity pattern), ``_linear`` (sparse direct solvers by name),
  ``_reactions`` (nodal forces and support reactions);
- ``contact``: rigid frictionless obstacles (plate, wedge, base) and their penalty contact;
- ``solver``: ``Body`` (the committed state) and Newton with displacement or force control.
"""

from typing import TYPE_CHECKING

from .contact import Base, Plate, Wedge
from .fe2d import Discretization, LayerState
from .solver import (
    FORCE_RTOL,
    Body,
    Control,
    NewtonOptions,
    StepResult,
    model_newton,
    residual_tolerance,
    youngs_moduli,
)

if TYPE_CHECKING:
    from .fe3d import Discretization3D

#: The 3D elements (``Discretization3D(element=...)``, ``model.element``): "q2", the 27-node
#: hexahedron in displacements alone; "q2p1", the same with the volume ratio projected on
#: linear polynomials per element, free of volumetric locking (``sim.fe._mixed``;
#: docs/model_3d.md, "The locking-free element"). Here, not in ``fe3d``, so that the options
#: can name them without loading the 3D discretisation.
ELEMENTS_3D = ("q2", "q2p1")

__all__ = [
    "ELEMENTS_3D",
    "FORCE_RTOL",
    "Base",
    "Body",
    "Control",
    "Discretization",
    "Discretization3D",
    "LayerState",
    "NewtonOptions",
    "Plate",
    "StepResult",
    "Wedge",
    "model_newton",
    "residual_tolerance",
    "youngs_moduli",
]


def __getattr__(name: str):
    if name == "Discretization3D":  # only for a 3D simulation
        from .fe3d import Discretization3D

        return Discretization3D
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
