"""What would close the gap: the surrogate's sensitivities around the best design.

When the best credible design misses a target, the designer's next question is which material
property to change, and how far. For every float parameter the best design uses, the surrogate
is evaluated at the design with that parameter moved by ``STEP`` of its range (on the space's
scale: log for log parameters) each way, within the bounds; the change of each tapping target's
relative error tells which parameters move a missed target towards its value, by how much per
step, and whether the design already sits on the bound that stops it (then the space, not the
search, is what limits the answer). A move that makes the design not credible (predicted beyond
the validity limits, unsettled, or sagging: ``explore._objective.infeasibility``) is reported as
such. These are local, first-order statements of the surrogate, not FE results.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.design import Targets

from ._objective import TAPPING, closeness

__all__ = ["STEP", "Sensitivity", "sensitivities", "sensitivity_notes"]

#: the move of a parameter, as a fraction of its range on the space's scale: a local, first-
#: order probe (small next to the range), yet a move whose predicted effect stands above the
#: ensemble's noise (a designer's "a bit softer", not a derivative)
STEP = 0.10


@dataclass(frozen=True)
class Sensitivity:
    """One parameter moved by ``STEP`` of its range in ``direction`` (+1 up, -1 down) from
    ``value`` to ``moved``: the change of each tapping target's relative error
    (``d_error``, fractions) and whether the moved design is still predicted credible."""

    name: str
    value: float
    moved: float
    direction: int
    at_bound: bool
    d_error: dict[str, float]
    credible: bool


def _moved(p, value: float, direction: int) -> tuple[float, bool]:
    if p.log:
        lo, hi, v = math.log(p.low), math.log(p.high), math.log(value)
    else:
        lo, hi, v = p.low, p.high, value
    w = v + direction * STEP * (hi - lo)
    at_bound = w <= lo if direction < 0 else w >= hi
    w = min(max(w, lo), hi)
    return (math.exp(w) if p.log else w), at_bound and abs(w - v) < 1e-12 * max(1.0, abs(v))


def sensitivities(surrogate, point: Mapping[str, Any], targets: Targets) -> list[Sensitivity]:
    """The ``Sensitivity`` of every float parameter ``point`` uses, both directions."""
    return _scan(surrogate, point, targets)[1]


def _scan(
    surrogate, point: Mapping[str, Any], targets: Targets
) -> tuple[dict[str, float], list[Sensitivity]]:
    """The predicted relative error of each tapping target at ``point``, and the
    ``sensitivities`` around it (one batch through the surrogate)."""
    from ._search import predict_rows

    space = surrogate.space
    base = {k: (math.nan if v is None else v) for k, v in point.items()}
    moves, points = [], []
    for p in space.parameters:
        v = base.get(p.name)
        if p.kind != "float" or not isinstance(v, int | float) or not math.isfinite(v):
            continue
        for direction in (-1, 1):
            w, stuck = _moved(p, float(v), direction)
            moves.append((p.name, float(v), w, direction, stuck))
            points.append({**base, p.name: w})
    rows = predict_rows(surrogate, [base, *points], targets, allow_untrusted=True)
    preds = [{m: r.predicted[m]["median"] for m in r.predicted} for r in rows]
    errs = [closeness(pr, targets).errors for pr in preds]
    out = []
    for (name, v, w, direction, stuck), err, row in zip(moves, errs[1:], rows[1:], strict=True):
        d = {m: float(err[m] - errs[0][m]) for m in TAPPING}
        ok = not any(f.startswith("predicted not credible") for f in row.flags)
        out.append(Sensitivity(name, v, w, direction, stuck, d, ok))
    return {m: float(errs[0][m]) for m in TAPPING}, out


#: the largest exponent ``_needed`` takes (exp(709) is the largest float's order)
_MAX_EXPONENT = 700.0


def _needed(surrogate, s: Sensitivity, error: float, d: float) -> tuple[float, bool]:
    """The value of ``s``'s parameter at which the missed target's error would reach zero,
    extrapolating the surrogate's change per step linearly (on the space's scale), and whether
    it lies beyond the space's bounds."""
    p = surrogate.space[s.name]
    steps = abs(error / d)
    if p.log:  # a change per step of nearly nothing puts it at 0 or infinity: far outside
        exponent = math.log(s.value) + s.direction * steps * STEP * math.log(p.high / p.low)
        v = math.exp(min(exponent, _MAX_EXPONENT))
    else:
        v = s.value + s.direction * steps * STEP * (p.high - p.low)
    return v, not p.low <= v <= p.high


def sensitivity_notes(
    surrogate, point: Mapping[str, Any], targets: Targets, tol: float, top: int = 3
) -> list[str]:
    """One note per missed tapping target: the ``top`` parameter moves that bring it closest
    to its value while staying credible, with the predicted change per step, and the moves a
    bound stops."""
    error, sens = _scan(surrogate, point, targets)
    notes = []
    for m in TAPPING:
        e = float(error[m])
        if not np.isfinite(e) or abs(e) <= tol:
            continue
        helpful = sorted(
            (s for s in sens if s.d_error[m] * e < 0), key=lambda s: -abs(s.d_error[m])
        )
        if not helpful:
            notes.append(
                f"to close {m} ({100 * e:+.0f} % by the surrogate at the best design): no single "
                f"parameter moved by {100 * STEP:.0f} % of its range helps"
            )
            continue
        first = next((s for s in helpful if not s.at_bound and s.credible), None)
        reach = ""
        if first is not None:
            v, outside = _needed(surrogate, first, e, first.d_error[m])
            sign = "<=" if first.direction < 0 else ">="
            if outside:
                p = surrogate.space[first.name]
                stop = p.low if first.direction < 0 else p.high
                reach = (
                    f" Extrapolated linearly, {first.name} alone cannot meet {m}: the space "
                    f"stops at {stop:.3g}, short of what it would take (the others unchanged)."
                )
            else:
                reach = (
                    f" Extrapolated linearly, {m} is met at {first.name} {sign} {v:.3g} (within "
                    "the space), the others unchanged."
                )
        parts = []
        for s in helpful[:top]:
            way = "higher" if s.direction > 0 else "lower"
            if s.at_bound:
                parts.append(f"{s.name} {way} — already at the space's bound {s.value:.3g}")
                continue
            extra = "" if s.credible else ", but then predicted not credible"
            parts.append(
                f"{s.name} {way} ({s.value:.3g} -> {s.moved:.3g}: {100 * s.d_error[m]:+.1f} "
                f"points{extra})"
            )
        notes.append(
            f"to close {m} ({100 * e:+.0f} % by the surrogate at the best design), the surrogate's "
            f"sensitivities ({100 * STEP:.0f} % of a parameter's range): "
            + "; ".join(parts)
            + "."
            + reach
        )
    return notes
