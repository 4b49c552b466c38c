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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.design import Targets
from sim.protocols import LAYER_STRAIN_OUTPUTS, TRUST_OUTPUTS

TRUST_NAMES = (*TRUST_OUTPUTS, *LAYER_STRAIN_OUTPUTS)

__all__ = [
    "OBJECTIVE_NAMES",
    "WEDGE_REFERENCE_3D_N",
    "WEDGE_REFERENCE_N",
    "WEDGE_WEIGHT",
    "Closeness",
    "closeness",
    "infeasibility",
    "objectives",
    "point_layer_limits",
    "point_strain_limits",
    "wedge_reference_N",
]

WEDGE_REFERENCE_N = 2.35  # silicone GLS 40 on the reference geometry (docs/validation.md)
#: The same reference for the 3D model, whose wedge force is the whole pad's (N): silicone GLS 40
#: on the reference outline as the default pad (c = 11 mm, m = 2), the simulations' mesh with
#: its band along the wedge's edge (``sim.geometry.DEFAULT_MESH_3D``),
#: `fingertip simulate --material silicone_gls40 --model 3d --protocol wedge` (solver 2.9:
#: 0.5215 N; 0.6060 N on the mesh without the band, which does not resolve the flanks'
#: contact). A straight edge across the curved pad touches it over a few millimetres only,
#: so the pad takes about a fifth of the plane-strain section's force per 10 mm.
WEDGE_REFERENCE_3D_N = 0.5215
#: the wedge reference of each model's forces (by ``SimOptions.dimension``): a score compares
#: like with like, a 2D force per 10 mm of finger with the 2D reference, a pad's with the pad's
_WEDGE_REFERENCES = {"2d": WEDGE_REFERENCE_N, "3d": WEDGE_REFERENCE_3D_N}
WEDGE_WEIGHT = 0.1
#: the names of the multi-objective triple of :func:`objectives`, in its order
OBJECTIVE_NAMES = ("compliance_error", "hysteresis_error", "wedge_effort")
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


def wedge_reference_N(dimension: str) -> float:
    """The wedge force (N) a wedge effort of 1 stands for, in the model ``dimension`` ("2d":
    ``WEDGE_REFERENCE_N``, per 10 mm of finger; "3d": ``WEDGE_REFERENCE_3D_N``, the pad's)."""
    try:
        return _WEDGE_REFERENCES[dimension]
    except KeyError:
        raise ValueError(f"no wedge reference for the model {dimension!r}") from None


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


def point_layer_limits(
    points: Sequence[Mapping[str, Any]], catalogue: Mapping[str, Any] | None, validity
) -> dict[str, np.ndarray] | None:
    """Per layer role (``sim.design.LAYER_ROLES``), the compressive log strain each design
    point's layer of that role is held to (its material's tested limit:
    ``sim.protocols.validity.design_strain_limit`` of the one material; NaN where the design has
    no such layer); None when ``validity`` overrides every layer's (then that one number
    applies). A layer's limit depends on its material only (a family's on the family, whatever
    its parameters within the family's bounds), so each material name is looked up once."""
    if validity.max_compressive_log_strain is not None or not points:
        return None
    from sim.design import LAYER_ROLES, active_roles, family_material, is_family
    from sim.design.families import FAMILIES
    from sim.materials import catalogue_material
    from sim.protocols.validity import design_strain_limit

    seen: dict[str, float] = {}

    def limit(point: Mapping[str, Any], role: str) -> float:
        name = point[f"{role}.material"]
        if name not in seen:
            if is_family(name):
                keys = FAMILIES[name].keys
                material = family_material(name, {k: point[f"{role}.{k}"] for k in keys})
            else:
                material = catalogue_material(name, f"{role}.material", catalogue)
            seen[name] = design_strain_limit([material], validity)
        return seen[name]

    out = {role: np.full(len(points), np.nan) for role in LAYER_ROLES}
    for i, point in enumerate(points):
        for role in active_roles(point["layers.count"]):
            out[role][i] = limit(point, role)
    return out


def point_strain_limits(
    points: Sequence[Mapping[str, Any]], catalogue: Mapping[str, Any] | None, validity
) -> np.ndarray | None:
    """Per design point, the compressive log strain its predicted largest strain is held to
    when its layers' own strains are not predicted (a surrogate trained on a table without
    them): the largest of its layers' limits (:func:`point_layer_limits`); None when
    ``validity`` overrides every layer's (then that one number applies)."""
    return _largest(point_layer_limits(points, catalogue, validity))


def _largest(layer_limits: Mapping[str, np.ndarray] | None) -> np.ndarray | None:
    """Per design, the largest of its layers' limits (None for None)."""
    if layer_limits is None:
        return None
    return np.nanmax(np.stack(list(layer_limits.values())), axis=0)


def infeasibility(
    values: Mapping[str, np.ndarray],
    targets: Targets,
    validity,
    tapping,
    strain_limit: np.ndarray | None = None,
    layer_limits: Mapping[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """How far predicted designs are from credible, and why: ``(penalty, why)``.

    A credible design is one whose FE result can be an answer: it settles, stays within the
    validity limits (``sim.protocols.trust.trust_flags`` on the predicted trust outputs: each
    layer's strain held to its own limit, ``layer_limits``, per design:
    :func:`point_layer_limits`, where the surrogate predicts the layers' strains; else the
    largest strain held to ``strain_limit``, per design, by default the largest of the
    ``layer_limits``: :func:`point_strain_limits`) and
    recovers between taps (``sag_mm`` within ``targets.max_sag_mm``). ``penalty`` is 0 for a
    credible design and ``1 + excess`` otherwise, ``excess`` summing how far each limit is passed
    (relative: strain / limit - 1, limit J / J - 1, sag / limit - 1, and 1 per failed yes/no limit),
    so that a search ranks every credible design first and still sees the way back towards the
    credible ones. Outputs the predictor does not have are not judged."""
    from sim.protocols import layer_strain_excess, strain_limit_of, trust_flags

    if strain_limit is None:
        strain_limit = _largest(layer_limits)

    n = len(np.atleast_1d(next(iter(values.values())))) if values else 0
    excess = np.zeros(n)
    why = np.full(n, "", dtype=object)
    if not n:
        return excess, why

    def get(name: str) -> np.ndarray | None:
        v = values.get(name)
        return None if v is None else np.asarray(v, dtype=float).reshape(n)

    trust = {k: v for k in TRUST_NAMES if (v := get(k)) is not None}
    if trust:
        flags = trust_flags(trust, validity, tapping, strain_limit, layer_limits)
        bad = ~(flags["valid"] & flags["settled"])
        why = np.where(bad, flags["why"], why)
        excess += bad.astype(float)
        limit = strain_limit_of(validity, strain_limit)
        with np.errstate(invalid="ignore", divide="ignore"):
            for p in validity.strain_limited:
                if layers := layer_strain_excess(trust, p, layer_limits, n):
                    excess += sum(e for e, _ in layers.values())
                elif (v := trust.get(f"{p}_max_compressive_log_strain")) is not None:
                    excess += np.nan_to_num(np.maximum(v / limit - 1, 0))
            for p in ("tapping", "plate", "wedge"):
                if (v := trust.get(f"{p}_min_J")) is not None:
                    excess += np.nan_to_num(np.maximum(validity.min_J / v - 1, 0), posinf=10.0)
    sag = get("sag_mm")
    if sag is not None and targets.max_sag_mm is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            over = sag > targets.max_sag_mm
            why = np.where(over & (why == ""), f"sag > {targets.max_sag_mm:g} mm", why)
            rel = np.maximum(sag / max(targets.max_sag_mm, 1e-9) - 1, 0)
            excess += np.where(over, 1.0 + np.nan_to_num(rel), 0.0)
    penalty = np.where(why != "", 1.0 + excess, 0.0)
    return penalty, why
