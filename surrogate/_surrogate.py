"""A trained surrogate: encoder + ensemble + output normaliser, and its predictions."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from sim.design import DesignSpace
from sim.metrics import METRICS
from sim.protocols import PROBABILITY_OUTPUTS
from sim.provenance import finite_or_none

from ._encoding import ELASTIC_FEATURE, Encoder
from ._model import EnsembleMLP, FrozenEnsemble
from ._normalise import PHYSICAL, OutputNormaliser

__all__ = ["ZERO_IF_ELASTIC", "Prediction", "Surrogate", "clip_probabilities", "rule_mask"]

#: metrics that vanish identically for an elastic design: without relaxation a closed load
#: cycle dissipates nothing (contact is frictionless). The FE gives |h| < 1e-3 N mm there, the
#: error of its time steps. The surrogate predicts exactly 0 for those designs (std 0) and never
#: trains on them, so the log scale of the metric serves the designs that do dissipate.
ZERO_IF_ELASTIC = frozenset({"hysteresis_Nmm"})


def clip_probabilities(out: Mapping[str, np.ndarray], metric_names: Sequence[str]) -> None:
    """Keep the predictions of the 0/1 outputs (``sim.protocols.trust.PROBABILITY_OUTPUTS``, read as
    probabilities) in [0, 1], in place: their point predictions and 90 % interval (a Gaussian
    fitted to 0/1 values reaches below 0 and above 1: "-0.12 to 0.31" is "0 to 0.31"); their
    std is left as it is."""
    columns = [j for j, m in enumerate(metric_names) if m in PROBABILITY_OUTPUTS]
    if columns:
        for key in ("mean", "median", "lower_90", "upper_90"):
            out[key][:, columns] = np.clip(out[key][:, columns], 0.0, 1.0)


def rule_mask(encoder: Encoder, features: np.ndarray, metric_names: Sequence[str]) -> np.ndarray:
    """(n, n_metrics) bool: True where the value is known by rule (``ZERO_IF_ELASTIC``)."""
    elastic = features[:, encoder.feature_names.index(ELASTIC_FEATURE)] > 0.5
    zero = np.asarray([m in ZERO_IF_ELASTIC for m in metric_names], dtype=bool)
    return elastic[:, None] & zero[None, :]


#: designs per forward pass: small enough that a layer's activations (nets x batch x hidden
#: floats, ~4 MB) stay in cache, large enough to amortise per-operation overhead (2-core
#: machine, one thread, predict_features on 65,536 designs with the shipped 10-net
#: checkpoint: 512 to 2048 within a few % of each other, 256 5-10 % slower; with 3 x 5 nets
#: 16384 gave 31k/s). Any batch size gives the same bits (``ROWS_MULTIPLE``).
BATCH = 1024


@dataclass(frozen=True, eq=False)
class Prediction:
    """Surrogate predictions for ``n`` designs, in each metric's unit (``units``).

    ``median``: (n, n_metrics) the point prediction (the predictive distribution's median:
    for a log-scale metric robust where the ensemble is unsure, where the mean is pulled up by
    the log-normal's tail; equal to the mean for a linear metric).
    ``mean``, ``std``: (n, n_metrics) mean and standard deviation of the ensemble's predictive
    distribution; ``lower_90``, ``upper_90``: its central 90 % interval. ``in_domain`` (n,):
    False for a design outside the training domain (then ``reasons[i]`` says why); such
    predictions are extrapolations. ``by_rule`` (n, n_metrics): True where the value is exact
    by physics, not learnt (the hysteresis of an elastic design is 0, ``ZERO_IF_ELASTIC``).
    Columns follow ``metric_names``.
    """

    metric_names: tuple[str, ...]
    units: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    lower_90: np.ndarray
    upper_90: np.ndarray
    in_domain: np.ndarray
    reasons: tuple[str, ...]
    median: np.ndarray | None = None
    by_rule: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.mean)

    def metric(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``(mean, std)`` of one metric, each (n,)."""
        j = self.metric_names.index(name)
        return self.mean[:, j], self.std[:, j]

    def to_records(self) -> list[dict[str, Any]]:
        """One JSON-able dict per design (None for a metric the surrogate cannot predict)."""

        out = []
        for i in range(len(self)):
            out.append(
                {
                    "in_domain": bool(self.in_domain[i]),
                    "domain_note": self.reasons[i],
                    **{
                        key: {m: finite_or_none(a[i, j]) for j, m in enumerate(self.metric_names)}
                        for key, a in (
                            ("mean", self.mean),
                            ("median", self.median if self.median is not None else self.mean),
                            ("std", self.std),
                            ("lower_90", self.lower_90),
                            ("upper_90", self.upper_90),
                        )
                    },
                    "by_rule": [
                        m
                        for j, m in enumerate(self.metric_names)
                        if self.by_rule is not None and self.by_rule[i, j]
                    ],  # metrics exact by physics for this design (an elastic one: hysteresis)
                }
            )
        return out


def predict_points(model: Any, points: Sequence[Mapping[str, Any]] | Mapping[str, Sequence]):
    """The ``Prediction`` of ``model`` (a ``Surrogate`` or a multi-fidelity one: its
    ``encoder.encode`` and ``predict_features``) for design points or a table."""
    enc = model.encoder.encode(points)
    out = model.predict_features(enc.features)
    return Prediction(
        model.metric_names,
        model.units,
        out["mean"],
        out["std"],
        out["lower_90"],
        out["upper_90"],
        enc.in_domain,
        enc.reasons,
        out["median"],
        out["by_rule"],
    )


class Surrogate:
    """Predicts every FE metric of a design, with uncertainty, in microseconds.

    Made by ``train_surrogate`` and ``load_checkpoint``; ``header`` is the checkpoint's JSON
    header (space, metrics, normalisers, provenance, validation metrics).
    """

    def __init__(
        self,
        model: EnsembleMLP,
        encoder: Encoder,
        normaliser: OutputNormaliser,
        metric_names: Sequence[str],
        header: Mapping[str, Any] | None = None,
    ) -> None:
        self.model = model.eval()
        self.encoder = encoder
        self.normaliser = normaliser
        self.metric_names = tuple(metric_names)
        self.units = tuple(METRICS[m][1] if m in METRICS else "" for m in self.metric_names)
        self.header = dict(header or {})
        self._fast: FrozenEnsemble | None = None

    @property
    def space(self) -> DesignSpace:
        return self.encoder.space

    @property
    def members(self) -> int:
        return self.model.members

    def predict(self, points: Sequence[Mapping[str, Any]] | Mapping[str, Sequence]) -> Prediction:
        """Predict a list of design points (dicts ``name -> value``) or a table (dict ``name ->
        column``). Missing fixed parameters take the space's value; values of parameters a
        design does not use are ignored. A ``DesignError`` for a missing active value or an
        unknown parameter name; designs outside the training domain are flagged, not refused.
        """
        return predict_points(self, points)

    def predict_features(self, features: np.ndarray) -> dict[str, np.ndarray]:
        """Predict already encoded designs (n, n_features): ``mean``, ``median``, ``std``,
        ``lower_90``, ``upper_90`` in metric units, each (n, n_metrics), and ``by_rule`` (the
        entries set by ``ZERO_IF_ELASTIC``: exactly 0 with std 0); a probability within
        [0, 1] (``clip_probabilities``)."""
        n, m = len(features), len(self.metric_names)
        out: dict[str, np.ndarray] = {key: np.empty((n, m)) for key in PHYSICAL}
        for rows, mean_z, std_z in self._batches(features):  # each batch's arrays stay in cache
            self.normaliser.to_physical(mean_z, std_z, {k: a[rows] for k, a in out.items()})
        clip_probabilities(out, self.metric_names)
        rule = rule_mask(self.encoder, np.asarray(features), self.metric_names)
        for key in PHYSICAL:
            np.copyto(out[key], 0.0, where=rule)
        out["by_rule"] = rule
        return out

    def predict_normalised(self, features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ensemble mixture's mean and std in normalised units (float64, (n, n_metrics))."""
        n, m = len(features), len(self.metric_names)
        mean, std = np.empty((n, m)), np.empty((n, m))
        for rows, mean_z, std_z in self._batches(features):
            mean[rows], std[rows] = mean_z, std_z
        return mean, std

    def _batches(self, features: np.ndarray) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
        """``(rows, mean_z, std_z)`` (float32) of ``BATCH`` designs at a time, on one thread."""
        x = torch.from_numpy(np.ascontiguousarray(features, dtype=np.float32))
        net = self._frozen()
        workspace = net.workspace(min(len(x), BATCH))
        threads = torch.get_num_threads()
        # small matrices: one thread is several times faster than torch's default pool (and
        # does not fight other work for the cores); restored afterwards for training
        torch.set_num_threads(1)
        try:
            with torch.inference_mode():
                for s in range(0, len(x), BATCH):
                    mu, sd = net(x[s : s + BATCH], workspace)
                    rows = slice(s, s + len(mu))
                    yield rows, mu.numpy(), sd.numpy()
        finally:
            torch.set_num_threads(threads)

    def _frozen(self) -> FrozenEnsemble:
        """The model laid out for prediction, made again if its weights changed."""
        if self._fast is None or not self._fast.matches(self.model):
            self._fast = FrozenEnsemble(self.model)
        return self._fast
