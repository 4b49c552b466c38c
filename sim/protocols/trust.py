"""What a surrogate learns of an FE result's trust, and the rule that turns it into flags.

An FE result is trusted when its taps reached the periodic state (``settled``) and its
deformation stayed within the validity limits (``valid``, :mod:`sim.protocols.validity`). The flags
are yes/no answers to thresholds that are options, so a surrogate learns the continuous figures
behind them instead (``TRUST_OUTPUTS``, read from the diagnostic columns of a sweep's ``table.csv``
or from ``SimResult.diagnostics()``), and :func:`trust_flags` applies the same thresholds to its
predictions as the solver and ``sim.protocols.validity.check`` apply to an FE result:

- the largest compressive log strain in tapping and plate (the protocols the strain limit
  applies to by default), and the smallest J of each protocol;
- whether the free surface reached the base or folded, in any protocol, and whether the FE
  failed to converge in any protocol (0/1: the mean of an ensemble of such predictions reads
  as a probability, flagged at 0.5; a design the FE cannot simulate is no answer either);
- the tapping's periodic-state residual and largest estimated relative error (settled when
  both are within ``TappingOptions.residual_tol`` / ``settle_tol``).

Besides, where a sweep's table has them (solver 2.3 and later records), each layer's largest
compressive log strain in tapping and plate, by role (``LAYER_STRAIN_OUTPUTS``): each layer is
held to its own material's tested limit (``role_limits``), not the design's largest strain to
the largest of its layers' limits. A gel skin over a foam core is then judged on the skin's 0.53
as well as the core's 1.05.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..design.space import LAYER_ROLES
from ..metrics import role_strain_name

__all__ = [
    "LAYER_STRAIN_OUTPUTS",
    "PROBABILITY_OUTPUTS",
    "TRUST_OUTPUTS",
    "layer_strain_excess",
    "strain_limit_of",
    "trust_censoring",
    "trust_flags",
    "trust_values",
]

#: output name -> the protocol whose net learns it ("any": the plate/wedge net)
TRUST_OUTPUTS: dict[str, str] = {
    "tapping_max_compressive_log_strain": "tapping",
    "plate_max_compressive_log_strain": "plate",
    "tapping_min_J": "tapping",
    "plate_min_J": "plate",
    "wedge_min_J": "wedge",
    "reached_base": "any",
    "folded": "any",
    "failed": "any",
    "tapping_residual": "tapping",
    "tapping_max_estimated_error": "tapping",
}
_PROTOCOLS = ("tapping", "plate", "wedge")
#: output name -> (protocol, layer role): each layer's largest compressive log strain, by role,
#: in the protocols whose largest strain is a trust output (``sim.metrics.role_strains``)
LAYER_STRAIN_OUTPUTS: dict[str, tuple[str, str]] = {
    role_strain_name(p, r): (p, r) for p in ("tapping", "plate") for r in LAYER_ROLES
}
#: the 0/1 outputs: a prediction of one (an ensemble's mean of 0/1 values) reads as a
#: probability, so it and its interval lie in [0, 1] (``surrogate.Surrogate.predict``)
PROBABILITY_OUTPUTS = ("reached_base", "folded", "failed")


def _float(v: Any) -> float:
    if v is None or v == "" or isinstance(v, bool):
        return float(v) if isinstance(v, bool) else np.nan
    if isinstance(v, str):
        low = v.strip().lower()
        if low in ("true", "false"):
            return float(low == "true")
    try:
        return float(v)
    except (TypeError, ValueError):
        return np.nan


def trust_values(diagnostics: Mapping[str, Any]) -> dict[str, float]:
    """The ``TRUST_OUTPUTS`` and ``LAYER_STRAIN_OUTPUTS`` of one FE result, from its
    diagnostics (``SimResult.diagnostics()`` or a ``table.csv`` row: text cells are parsed;
    ``failed`` from a row's ``status``); NaN where the result does not have one (a layer the
    design does not have, a table from before the layers' strains were columns)."""
    out = {
        name: _float(diagnostics.get(name))
        for name in TRUST_OUTPUTS
        if name not in PROBABILITY_OUTPUTS
    }
    status = diagnostics.get("status")  # a table row's: "ok" or "failed"
    out["failed"] = np.nan if status in (None, "") else float(status != "ok")
    for flag in ("reached_base", "folded"):
        seen = [_float(diagnostics.get(f"{p}_{flag}")) for p in _PROTOCOLS]
        seen = [v for v in seen if np.isfinite(v)]
        out[flag] = float(max(seen)) if seen else np.nan
    if _stopped(diagnostics):  # a protocol stopped early: a flag still 0, or "not failed",
        for flag in PROBABILITY_OUTPUTS:  # might have turned 1 later
            if out[flag] == 0.0:
                out[flag] = np.nan
    layers = {name: _float(diagnostics.get(name)) for name in LAYER_STRAIN_OUTPUTS}
    return {**{name: out[name] for name in TRUST_OUTPUTS}, **layers}


def _stopped(diagnostics: Mapping[str, Any]) -> tuple[str, ...]:
    """The protocols stopped at their first step beyond the validity limits (solver >= 2.3;
    ``SimResult.diagnostics()["stopped"]`` or a table cell, comma-separated)."""
    cell = diagnostics.get("stopped") or ""
    return tuple(p.strip() for p in str(cell).split(",") if p.strip())


def trust_censoring(diagnostics: Mapping[str, Any]) -> dict[str, int]:
    """Per ``TRUST_OUTPUTS`` and ``LAYER_STRAIN_OUTPUTS`` name, how its value of this FE result
    is known: 0 exactly, +1 as a lower bound, -1 as an upper bound. A protocol stopped at its
    first violation (solver 2.3) recorded its extremes up to the stop: its largest strain would
    only have grown (+1), its smallest J only fallen (-1). (Its 0/1 flags that were still 0 are
    unknown: ``trust_values`` gives them as NaN.)"""
    out = dict.fromkeys([*TRUST_OUTPUTS, *LAYER_STRAIN_OUTPUTS], 0)
    for p in _stopped(diagnostics):
        if f"{p}_max_compressive_log_strain" in out:
            out[f"{p}_max_compressive_log_strain"] = 1
        for name, (protocol, _) in LAYER_STRAIN_OUTPUTS.items():
            if protocol == p:
                out[name] = 1
        if f"{p}_min_J" in out:
            out[f"{p}_min_J"] = -1
    return out


def strain_limit_of(validity, strain_limit: Any = None) -> Any:
    """The compressive log strain a predicted largest strain is held to: ``strain_limit`` when
    given (per design: ``sim.protocols.validity.design_strain_limit``), else the override
    ``validity.max_compressive_log_strain``, else the paper's 0.60
    (``sim.protocols.validity.PAPER_LOG_STRAIN``: without the designs' materials, the limit the
    earlier results were made with)."""
    from .validity import PAPER_LOG_STRAIN

    if strain_limit is not None:
        return strain_limit
    override = validity.max_compressive_log_strain
    return PAPER_LOG_STRAIN if override is None else override


def trust_flags(
    values: Mapping[str, Any],
    validity,
    tapping,
    strain_limit: Any = None,
    role_limits: Mapping[str, Any] | None = None,
) -> dict[str, np.ndarray]:
    """Predicted ``valid`` and ``settled`` (bool arrays) and the first reason a design fails
    (``why``: text array, "" when it passes), from predicted ``TRUST_OUTPUTS`` (arrays; an
    output the predictor does not have is not judged). ``validity``: ``ValidityOptions``;
    ``tapping``: ``TappingOptions`` (its tolerances); ``strain_limit``: the compressive log
    strain each design's largest strain is held to (a number or an array, one per design:
    ``strain_limit_of``). With ``role_limits`` (layer role -> each design's limit of that
    layer, NaN where it has no such layer) and the predicted ``LAYER_STRAIN_OUTPUTS`` of a
    protocol, each layer is held to its own limit instead (``layer_strain_excess``)."""
    n = len(np.atleast_1d(next(iter(values.values()))))
    why = np.full(n, "", dtype=object)
    valid = np.ones(n, dtype=bool)
    settled = np.ones(n, dtype=bool)

    def fail(mask: np.ndarray, text: str, which: np.ndarray) -> None:
        mask = np.asarray(mask, dtype=bool)  # NaN compares False: not judged
        why[mask & (why == "")] = text
        which &= ~mask

    def get(name: str) -> np.ndarray | None:
        v = values.get(name)
        return None if v is None else np.asarray(v, dtype=float).reshape(n)

    limit = np.broadcast_to(np.asarray(strain_limit_of(validity, strain_limit), float), (n,))
    overridden = " (overridden)" if validity.max_compressive_log_strain is not None else ""
    for p in validity.strain_limited:
        v = get(f"{p}_max_compressive_log_strain")
        layers = layer_strain_excess(values, p, role_limits, n)
        if layers:
            for role, (excess, own) in layers.items():
                for x in np.unique(own[excess > 0]):
                    fail((excess > 0) & (own == x), f"{p} {role} strain > {x:g}", valid)
        elif v is not None:
            with np.errstate(invalid="ignore"):
                beyond = v > limit
            for x in np.unique(limit[beyond]):  # the reason names each design's own limit
                fail(beyond & (limit == x), f"{p} strain > {x:g}{overridden}", valid)
    for p in _PROTOCOLS:
        v = get(f"{p}_min_J")
        if v is not None:
            with np.errstate(invalid="ignore"):
                fail(v < validity.min_J, f"{p} J < {validity.min_J:g}", valid)
    for flag, allowed in (("reached_base", validity.allow_base_contact),
                          ("folded", validity.allow_folding), ("failed", False)):  # fmt: skip
        v = get(flag)
        if v is not None and not allowed:
            with np.errstate(invalid="ignore"):
                fail(v > 0.5, flag.replace("_", " "), valid)
    res, err = get("tapping_residual"), get("tapping_max_estimated_error")
    with np.errstate(invalid="ignore"):
        if res is not None:
            fail(res > tapping.residual_tol, "unsettled (residual)", settled)
        if err is not None:
            fail(err > tapping.settle_tol, "unsettled (error estimate)", settled)
    return {"valid": valid, "settled": settled, "why": why}


def layer_strain_excess(
    values: Mapping[str, Any], protocol: str, role_limits: Mapping[str, Any] | None, n: int
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per layer role whose strain in ``protocol`` is among the predicted ``values``
    (``LAYER_STRAIN_OUTPUTS``) and whose limit is in ``role_limits``: (how far each design's
    strain passes its limit, relative: strain / limit - 1, 0 within it or where the design has
    no such layer; the limit). Empty without ``role_limits`` or without those outputs: the
    design's largest strain is judged instead."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if role_limits is None:
        return out
    for name, (p, role) in LAYER_STRAIN_OUTPUTS.items():
        if p != protocol or values.get(name) is None or role not in role_limits:
            continue
        v = np.asarray(values[name], dtype=float).reshape(n)
        own = np.broadcast_to(np.asarray(role_limits[role], dtype=float), (n,))
        with np.errstate(invalid="ignore", divide="ignore"):
            excess = np.nan_to_num(np.maximum(v / own - 1.0, 0.0), nan=0.0, posinf=0.0)
        out[role] = (excess, own)
    return out
