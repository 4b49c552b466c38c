"""How close a design is to the targets (the human fingertip by default).

Single-objective closeness score (lower is better, 0 = every tapping target met with no wedge
force)::

    score = sqrt(mean_i e_i^2) + w * F_wedge / F_ref

where e_i are the relative errors (value - target) / target of the three tapping targets
(displacement at 1 N, at 4 N, hysteresis; read as the targets file says, like with like),
F_wedge is the wedge's peak force and F_ref = 2.35 N, the paper's silicone on the reference
geometry, so a wedge effort of 1 means "as hard to indent as the softer of the paper's materials".
The weight w = 0.1 makes conformance a tie-breaker, as the paper treats it: the human fingertip
wraps the wedge with near-zero force, so lower is better. Multi-objective mode keeps the three
parts apart: compliance error sqrt((e_1N^2 + e_4N^2) / 2), hysteresis error |e_hyst| and wedge
effort F_wedge / F_ref.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from sim.targets import Targets

__all__ = ["WEDGE_REFERENCE_N", "WEDGE_WEIGHT", "Closeness", "closeness", "objectives"]

WEDGE_REFERENCE_N = 2.35  # silicone GLS 40 on the reference geometry (docs/validation.md)
WEDGE_WEIGHT = 0.1
TAPPING = ("disp_at_1N_mm", "disp_at_4N_mm", "hysteresis_Nmm")


@dataclass(frozen=True)
class Closeness:
    """Relative errors per tapping target, wedge effort (F / F_ref) and the score.

    Arrays when the metrics were arrays (one entry per design)."""

    errors: dict[str, np.ndarray]
    wedge_effort: np.ndarray
    score: np.ndarray


def closeness(
    metrics: Mapping[str, float | np.ndarray],
    targets: Targets,
    wedge_weight: float = WEDGE_WEIGHT,
    wedge_reference_N: float = WEDGE_REFERENCE_N,
) -> Closeness:
    """The closeness of ``metrics`` (simulator metric names -> values or arrays) to ``targets``.

    A missing metric (None/NaN: the protocol failed or did not reach it) gives an infinite
    score, never a flattering one."""
    errors = {}
    for name in TAPPING:
        value = np.asarray(_value(metrics, targets.metric(name)), dtype=float)
        errors[name] = (value - targets.values[name]) / targets.values[name]
    wedge = np.asarray(_value(metrics, "wedge_peak_force_N"), dtype=float)
    effort = wedge / wedge_reference_N
    rms = np.sqrt(np.mean([e**2 for e in errors.values()], axis=0))
    score = rms + wedge_weight * effort
    score = np.where(np.isfinite(score), score, np.inf)
    return Closeness(errors, effort, score)


def objectives(c: Closeness) -> np.ndarray:
    """The multi-objective triple (compliance error, hysteresis error, wedge effort), shape
    (..., 3); non-finite entries become inf."""
    comp = np.sqrt(0.5 * (c.errors["disp_at_1N_mm"] ** 2 + c.errors["disp_at_4N_mm"] ** 2))
    out = np.stack([comp, np.abs(c.errors["hysteresis_Nmm"]), c.wedge_effort], axis=-1)
    return np.where(np.isfinite(out), out, np.inf)


def _value(metrics: Mapping, name: str):
    v = metrics.get(name)
    if v is None:
        return np.nan
    return v
