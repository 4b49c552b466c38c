"""Finite-element model of a visco-hyperelastic fingertip skin under the paper's protocols.

Public API: designs (``Design``, ``Layer``, ``load_design``, ``homogeneous_design``), the geometry,
``simulate`` with its options and result (with the validity of the result, ``ValidityOptions``),
and the error types. ``sim`` never imports torch.
"""

from .design import Design, Layer, design_from_dict, homogeneous_design, load_design
from .errors import DesignError, SimulationError
from .geometry import DEFAULT_MESH, REFERENCE_GEOMETRY, Geometry, MeshOptions
from .metrics import METRICS, PROTOCOLS, SOLVER_VERSION
from .options import SimOptions
from .protocols import PlateOptions, TappingOptions, ValidityOptions, WedgeOptions
from .simulate import SimResult, simulate

__all__ = [
    "DEFAULT_MESH",
    "METRICS",
    "PROTOCOLS",
    "REFERENCE_GEOMETRY",
    "SOLVER_VERSION",
    "Design",
    "DesignError",
    "Geometry",
    "Layer",
    "MeshOptions",
    "PlateOptions",
    "SimOptions",
    "SimResult",
    "SimulationError",
    "TappingOptions",
    "ValidityOptions",
    "WedgeOptions",
    "design_from_dict",
    "homogeneous_design",
    "load_design",
    "simulate",
]
