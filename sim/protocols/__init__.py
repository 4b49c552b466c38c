"""The paper's loading protocols and what a result of them is worth.

- ``loading``: tapping, plate and wedge (their options, runs, metrics and ``REGISTRY``);
- ``periodic``: the periodic state of repeated taps, with a residual and an error estimate;
- ``validity``: how far a design was deformed, against the range the model covers (``check``,
  ``assess`` and the strain measures are imported from the module);
- ``trust``: the figures a surrogate learns of an FE result's trust and the flags made of them.
"""

from .loading import (
    REGISTRY,
    PlateOptions,
    Protocol,
    ProtocolResult,
    TappingOptions,
    WedgeOptions,
    contact_patch,
    hysteresis_resolution_Nmm,
    run_plate,
    run_tapping,
    run_wedge,
    shown_hysteresis,
)
from .periodic import PeriodicState, PeriodicStatus
from .trust import (
    LAYER_STRAIN_OUTPUTS,
    PROBABILITY_OUTPUTS,
    TRUST_OUTPUTS,
    layer_strain_excess,
    strain_limit_of,
    trust_censoring,
    trust_flags,
    trust_values,
)
from .validity import DeformationTracker, ValidityOptions, ValidityStop, Violation

__all__ = [
    "LAYER_STRAIN_OUTPUTS",
    "PROBABILITY_OUTPUTS",
    "REGISTRY",
    "TRUST_OUTPUTS",
    "DeformationTracker",
    "PeriodicState",
    "PeriodicStatus",
    "PlateOptions",
    "Protocol",
    "ProtocolResult",
    "TappingOptions",
    "ValidityOptions",
    "ValidityStop",
    "Violation",
    "WedgeOptions",
    "contact_patch",
    "hysteresis_resolution_Nmm",
    "layer_strain_excess",
    "run_plate",
    "run_tapping",
    "run_wedge",
    "shown_hysteresis",
    "strain_limit_of",
    "trust_censoring",
    "trust_flags",
    "trust_values",
]
