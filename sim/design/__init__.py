"""What a skin is and which skins a study explores; no FE here.

- ``skin``: a design (``Design``: layers, 2D section, 3D pad) and its TOML file;
- ``space``: design spaces, their parameters and the map from a unit-cube point to a design;
- ``families``: the continuous material families a space's layers may use;
- ``targets``: what a design is compared with (the human fingertip, or a user's file).
"""

from .families import (
    FAMILIES,
    FAMILY_KEYS,
    GEL_NU,
    Family,
    family_material,
    family_uses,
    is_family,
)
from .skin import (
    MIN_CORE_MM,
    MIN_LAYER_MM,
    Design,
    Layer,
    design_from_dict,
    design_to_toml,
    homogeneous_design,
    load_design,
)
from .space import (
    DEFAULT_SPACE_3D_PATH,
    DEFAULT_SPACE_PATH,
    LAYER_ROLES,
    PARAM_MATERIAL_KEYS,
    PRONY_TIME_RATIOS,
    DesignSpace,
    Parameter,
    active_roles,
    inactive_value,
    is_active,
    load_space,
    mask_inactive,
    param_material,
    point_from_design,
    point_to_design,
    space_from_dict,
    with_every_layer,
)
from .targets import (
    ALLOWED_KEYS,
    DEFAULT_TARGETS_PATH,
    LOADING_CURVE_SOURCE,
    READINGS,
    LoadingCurve,
    Targets,
    load_targets,
    loading_curve,
)

__all__ = [
    "ALLOWED_KEYS",
    "DEFAULT_SPACE_3D_PATH",
    "DEFAULT_SPACE_PATH",
    "DEFAULT_TARGETS_PATH",
    "FAMILIES",
    "FAMILY_KEYS",
    "GEL_NU",
    "LAYER_ROLES",
    "LOADING_CURVE_SOURCE",
    "MIN_CORE_MM",
    "MIN_LAYER_MM",
    "PARAM_MATERIAL_KEYS",
    "PRONY_TIME_RATIOS",
    "READINGS",
    "Design",
    "DesignSpace",
    "Family",
    "Layer",
    "LoadingCurve",
    "Parameter",
    "Targets",
    "active_roles",
    "design_from_dict",
    "design_to_toml",
    "family_material",
    "family_uses",
    "homogeneous_design",
    "inactive_value",
    "is_active",
    "is_family",
    "load_design",
    "load_space",
    "load_targets",
    "loading_curve",
    "mask_inactive",
    "param_material",
    "point_from_design",
    "point_to_design",
    "space_from_dict",
    "with_every_layer",
]
