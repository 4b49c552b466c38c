"""Per-metric output normalisation, fitted on the training designs only.

A metric that is nonnegative on the training designs (up to round-off: a value that is 0 in
exact arithmetic may come out as -1e-4) is learnt as ``log(y + offset)``, any other as ``y``;
either is then standardised, ``z = (t(y) - shift) / scale``. ``offset`` is 0 for a strictly
positive metric (a plain log), else a floor of ``OFFSET_FRACTION`` of the median training
value above the most negative one, so that values near zero neither dominate the loss nor
vanish from it. (The hysteresis of an elastic design, exactly 0 by physics, is not learnt at
all, see ``surrogate._surrogate.ZERO_IF_ELASTIC``: the rest is strictly positive, a plain
log.) The network's Gaussian lives in z; ``to_physical`` maps a Gaussian in z back to the
metric's units (a shifted log-normal for log metrics: mean ``exp(m + s^2 / 2) - offset``,
quantiles ``exp(m +- q s) - offset``).

``interval_scale`` widens or narrows the ensemble's spread per metric before that mapping
(``s = scale * interval_scale * std_z``): 1 by default; ``surrogate._train.fit`` sets it so
that 90 % of the validation designs' FE values fall inside the 90 % interval
(``calibration_factors``: split conformal).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import torch

__all__ = ["NEGATIVE_TOLERANCE", "OFFSET_FRACTION", "PHYSICAL", "Z90", "OutputNormaliser"]

#: a metric whose most negative training value is above -NEGATIVE_TOLERANCE x its median |value|
#: counts as nonnegative (the negatives are round-off) and is learnt on a shifted log scale
NEGATIVE_TOLERANCE = 0.01
#: the log offset of a nonnegative metric, as a fraction of its median training value
OFFSET_FRACTION = 0.05

#: the standard-normal quantile of a central 90 % interval
Z90 = 1.6448536269514722

#: what ``OutputNormaliser.to_physical`` gives, in metric units (the ``Prediction`` fields)
PHYSICAL = ("mean", "median", "std", "lower_90", "upper_90")


def _exp(x: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``np.exp(x, out=out)`` (float64) by torch's vectorised exp: 2.5 times faster than
    NumPy's, which calls the C library element by element on a CPU without AVX-512; the two
    agree to 1 unit in the last place (2.2e-16 relative); an element's result does not depend
    on its position in the array."""
    torch.exp(torch.from_numpy(x), out=torch.from_numpy(out))
    return out


def _expm1(x: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``np.expm1(x, out=out)`` (float64) by torch (see ``_exp``; 2.8 times faster)."""
    torch.expm1(torch.from_numpy(x), out=torch.from_numpy(out))
    return out


def _runs(mask: np.ndarray) -> list[slice]:
    """The runs of consecutive True entries of ``mask`` (1-d), as slices."""
    edges = np.flatnonzero(np.diff(np.concatenate([[False], mask, [False]]).astype(np.int8)))
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


@dataclass(frozen=True, eq=False)
class OutputNormaliser:
    """``log`` (bool), ``shift``, ``scale``, ``observed`` (training values), ``offset``
    (of the log, metric units) and ``interval_scale`` (of the spread; None: 1) per metric.

    A metric without any finite training value cannot be predicted: its predictions are NaN.
    """

    log: np.ndarray
    shift: np.ndarray
    scale: np.ndarray
    observed: np.ndarray
    offset: np.ndarray
    interval_scale: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        if self.interval_scale is None:
            object.__setattr__(self, "interval_scale", np.ones_like(self.scale))

    def calibrated(self, interval_scale: np.ndarray) -> OutputNormaliser:
        """The same normaliser with another ``interval_scale`` (one positive factor per metric)."""
        factors = np.asarray(interval_scale, dtype=np.float64)
        if factors.shape != self.scale.shape or not np.all(factors > 0):
            raise ValueError("interval_scale needs one positive factor per metric")
        return replace(self, interval_scale=factors)

    @classmethod
    def fit(cls, y_train: np.ndarray) -> OutputNormaliser:
        """Fit on the TRAINING rows (n, n_metrics); NaN = missing."""
        y = np.asarray(y_train, dtype=np.float64)
        finite = np.isfinite(y)
        observed = finite.sum(axis=0)
        log = np.zeros(y.shape[1], dtype=bool)
        offset = np.zeros(y.shape[1])
        for j in range(y.shape[1]):
            v = y[finite[:, j], j]
            if v.size == 0:
                continue
            if np.all(v > 0):
                log[j] = True
                continue
            typical = float(np.median(np.abs(v)))
            if typical > 0 and v.min() > -NEGATIVE_TOLERANCE * typical:
                log[j] = True
                offset[j] = max(0.0, -float(v.min())) + OFFSET_FRACTION * typical
        t = cls._t(y, log, offset)
        shift = np.zeros(y.shape[1])
        scale = np.ones(y.shape[1])
        for j in range(y.shape[1]):
            v = t[finite[:, j], j]
            if v.size:
                shift[j] = v.mean()
                sd = v.std()
                scale[j] = sd if sd > 1e-12 * max(1.0, abs(shift[j])) else 1.0
        return cls(log, shift, scale, observed.astype(np.int64), offset)

    @staticmethod
    def _t(y: np.ndarray, log: np.ndarray, offset: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            u = y + offset
            return np.where(log, np.log(np.where(u > 0, u, np.nan)), y)

    def transform(self, y: np.ndarray) -> np.ndarray:
        """Metrics in their units -> z (NaN stays NaN; a value of a log metric at or below
        ``-offset`` becomes NaN)."""
        y = np.asarray(y, dtype=np.float64)
        return (self._t(y, self.log, self.offset) - self.shift) / self.scale

    def to_physical(
        self,
        mean_z: np.ndarray,
        std_z: np.ndarray,
        out: dict[str, np.ndarray] | None = None,
    ) -> dict[str, np.ndarray]:
        """A Gaussian in z -> ``mean``, ``median``, ``std``, ``lower_90``, ``upper_90`` in metric
        units (for a log metric the median ``exp(m) - offset`` is the robust point prediction:
        the log-normal mean grows like ``exp(s^2 / 2)`` where the ensemble is unsure).

        ``mean_z``, ``std_z``: (..., n_metrics), float32 or float64 (computed in float64).
        ``out``: float64 arrays of that shape to write into (returned), else new ones."""
        if out is None:
            shape = np.broadcast_shapes(np.shape(mean_z), np.shape(std_z))
            out = {key: np.empty(shape) for key in PHYSICAL}
        mean, median, std = out["mean"], out["median"], out["std"]
        lower, upper = out["lower_90"], out["upper_90"]
        c = self.offset
        m = np.multiply(self.scale, mean_z)
        m += self.shift
        s = np.multiply(self.scale * self.interval_scale, std_z)
        zs = np.multiply(Z90, s)
        lo = np.subtract(m, zs)
        hi = np.add(m, zs, out=zs)
        with np.errstate(over="ignore", invalid="ignore"):
            # every column as a log metric (a linear one is overwritten below): the shifted
            # log-normal's mean exp(m + s^2 / 2) - c, std, median and quantiles exp(.) - c
            t = np.multiply(0.5, s)
            t *= s
            t += m
            _exp(t, mean)
            v = np.multiply(s, s, out=t)
            _expm1(v, v)
            np.sqrt(v, out=v)
            np.multiply(mean, v, out=std)
            mean -= c
            # the median (the point prediction) by NumPy, as before: the same bits
            np.subtract(np.exp(m, out=median), c, out=median)
            np.subtract(_exp(lo, lower), c, out=lower)
            np.subtract(_exp(hi, upper), c, out=upper)
        for cols in _runs(~self.log):  # the linear metrics: the Gaussian itself
            for a, value in ((mean, m), (median, m), (std, s), (lower, lo), (upper, hi)):
                a[..., cols] = value[..., cols]
        missing = self.observed == 0
        if missing.any():
            for a in out.values():
                a[..., missing] = np.nan
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {
            "log": self.log.astype(np.uint8),
            "shift": self.shift,
            "scale": self.scale,
            "observed": self.observed,
            "offset": self.offset,
            "interval_scale": self.interval_scale,
        }

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> OutputNormaliser:
        return cls(
            np.asarray(a["log"]).astype(bool),
            np.asarray(a["shift"], dtype=np.float64),
            np.asarray(a["scale"], dtype=np.float64),
            np.asarray(a["observed"], dtype=np.int64),
            np.asarray(a["offset"], dtype=np.float64),
            # checkpoints before the calibration have none: the ensemble's own spread
            None if "interval_scale" not in a else np.asarray(a["interval_scale"], np.float64),
        )
