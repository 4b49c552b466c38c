"""Per-metric output normalisation, fitted on the training designs only.

A metric that is strictly positive on every training design is learnt as ``log(y)``, any other
as ``y``; either is then standardised, ``z = (t(y) - shift) / scale``. The network's Gaussian
lives in z; ``to_physical`` maps a Gaussian in z back to the metric's units (a log-normal for
log metrics: mean ``exp(m + s^2 / 2)``, quantiles ``exp(m +- q s)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Z90", "OutputNormaliser"]

#: the standard-normal quantile of a central 90 % interval
Z90 = 1.6448536269514722


@dataclass(frozen=True, eq=False)
class OutputNormaliser:
    """``log`` (bool), ``shift``, ``scale`` and ``observed`` (training values) per metric.

    A metric without any finite training value cannot be predicted: its predictions are NaN.
    """

    log: np.ndarray
    shift: np.ndarray
    scale: np.ndarray
    observed: np.ndarray

    @classmethod
    def fit(cls, y_train: np.ndarray) -> OutputNormaliser:
        """Fit on the TRAINING rows (n, n_metrics); NaN = missing."""
        y = np.asarray(y_train, dtype=np.float64)
        finite = np.isfinite(y)
        observed = finite.sum(axis=0)
        log = np.array(
            [bool(observed[j]) and bool(np.all(y[finite[:, j], j] > 0)) for j in range(y.shape[1])]
        )
        t = cls._t(y, log)
        shift = np.zeros(y.shape[1])
        scale = np.ones(y.shape[1])
        for j in range(y.shape[1]):
            v = t[finite[:, j], j]
            if v.size:
                shift[j] = v.mean()
                sd = v.std()
                scale[j] = sd if sd > 1e-12 * max(1.0, abs(shift[j])) else 1.0
        return cls(log, shift, scale, observed.astype(np.int64))

    @staticmethod
    def _t(y: np.ndarray, log: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(log, np.log(np.where(y > 0, y, np.nan)), y)

    def transform(self, y: np.ndarray) -> np.ndarray:
        """Metrics in their units -> z (NaN stays NaN; a nonpositive value of a log metric
        becomes NaN)."""
        return (self._t(np.asarray(y, dtype=np.float64), self.log) - self.shift) / self.scale

    def to_physical(self, mean_z: np.ndarray, std_z: np.ndarray) -> dict[str, np.ndarray]:
        """A Gaussian in z -> ``mean``, ``std``, ``lower_90``, ``upper_90`` in metric units."""
        m = self.shift + self.scale * mean_z
        s = self.scale * std_z
        lo, hi = m - Z90 * s, m + Z90 * s
        with np.errstate(over="ignore", invalid="ignore"):
            ln_mean = np.exp(m + 0.5 * s * s)
            ln_std = ln_mean * np.sqrt(np.expm1(s * s))
            out = {
                "mean": np.where(self.log, ln_mean, m),
                "std": np.where(self.log, ln_std, s),
                "lower_90": np.where(self.log, np.exp(lo), lo),
                "upper_90": np.where(self.log, np.exp(hi), hi),
            }
        missing = self.observed == 0
        if missing.any():
            for v in out.values():
                v[..., missing] = np.nan
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {
            "log": self.log.astype(np.uint8),
            "shift": self.shift,
            "scale": self.scale,
            "observed": self.observed,
        }

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> OutputNormaliser:
        return cls(
            np.asarray(a["log"]).astype(bool),
            np.asarray(a["shift"], dtype=np.float64),
            np.asarray(a["scale"], dtype=np.float64),
            np.asarray(a["observed"], dtype=np.int64),
        )
