"""A multi-fidelity surrogate: the 3D model's metrics (``sim.metrics.metric_registry("3d")``: the
2D metrics and the contact patch) from many 2D designs and few 3D ones.

The low fidelity is a trained 2D surrogate (``Surrogate``, e.g. the shipped
``surrogate/pretrained/default``), kept frozen; the high fidelity is a 3D sweep
(``fingertip sweep --model 3d``), whose space is the 2D space plus the pad's parameters
(``geometry.half_length_mm``, ``geometry.length_exponent``). A 3D design's section and layers
are a point of the 2D space: the low fidelity predicts its 2D metrics. How those predictions
enter is the method (``METHODS``, by name):

- ``"3d"``: a deep ensemble on the 3D designs alone, no low fidelity (the baseline);
- ``"input"``: the low fidelity's predicted means (its normalised outputs, z) of every 2D output
  are extra inputs of a new 3D deep ensemble;
- ``"delta"``: as ``"input"``, and each FE metric the 2D surrogate predicts is learnt as its
  difference to that prediction on the 2D surrogate's own output scale: the log ratio for a
  metric it learns on a log scale (displacements, hysteresis, forces, profile areas), the
  difference for a linear one (sag, profile deflections); the 3D-only metrics and the trust
  outputs are learnt directly. Its predictive variance adds the 2D prediction's (calibrated)
  variance to the ensemble's, and the split-conformal calibration is taken on that sum;
- ``"delta-contact"``: as ``"delta"``, and the contact patch's area, width and length at 1 N
  and 4 N learnt as their log ratio to the 2D displacement from touch at the same force (Hertz:
  the patch grows with the approach, its ratio to it depends on the pad's curvatures);
- ``"delta-trend"``: as ``"delta-contact"``, and the base of each FE metric the 2D model has
  also carries a trend linear in the logs of the pad's half-length, length exponent and
  half-width (least squares on the training designs, ``fit_trend``): the part of the 3D / 2D
  ratio that the pad's shape explains (``studies/ratio3d.py``) is fitted with four numbers, and
  the ensemble, whose predicted mean of every delta output starts at 0 (at the base and the
  training designs' mean difference to it), learns only what is left
  (Kennedy & O'Hagan 2000's autoregressive model on the log scale, its scale factor a
  regression on the pad's shape);
- ``"delta-slice"``: as ``"delta-trend"``, but the base of the four displacement readings, the
  hysteresis and the contact patch is the slice model's (``surrogate._slice``): the pad taken as
  2D sections along the finger, each pressed by the plate to its own depth with the 2D model's
  line load, so that the 3D displacement at 1 N and 4 N, the work of a tap (the hysteresis
  scales with it) and the plate's overlap with the pad (the patch) come from the 2D prediction
  and the pad's shape with no fitted constant; the trend and the ensemble learn what it leaves;
- ``"finetune"``: the 2D ensemble itself trained further on the 3D designs: its first layer
  gets the pad's inputs (zero weights), its last layer the 3D-only metrics (fresh weights), so
  that training starts from the 2D surrogate's predictions (``fine_tune``'s warm start, with
  new inputs and outputs).

Every method is an ``EnsembleMLP`` trained as ``surrogate._train.fit`` trains one (the same
loss, per-net early stopping and learning-rate decays, the tapping metrics in nets of their
own, the 90 % intervals calibrated by split conformal prediction on the validation designs:
from 9 of them, the first 9 settled, valid ones, a metric with fewer taking its net group's
pooled factor, ``calibrate``), and predicts through ``MultiFidelitySurrogate.predict``, which
gives the ``Prediction`` of ``Surrogate.predict``. Out of domain: a design outside the 3D space
or the 3D training range, or whose section and layers are outside the low fidelity's training
domain (its prediction is an extrapolation).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from sim.design import DesignSpace
from sim.errors import DesignError
from sim.geometry import PadGeometry
from sim.metrics import METRICS, metric_registry
from sim.provenance import finite_or_none

from ._encoding import Encoded, Encoder
from ._io import SweepData
from ._model import EnsembleMLP
from ._normalise import PHYSICAL, Z90, OutputNormaliser
from ._slice import PAD, SLICE_METRICS, slice_values
from ._surrogate import (
    Prediction,
    Surrogate,
    clip_probabilities,
    predict_points,
    rule_mask,
)
from ._threads import threads_set, torch_threads
from ._train import (
    CALIBRATION_COVERAGE,
    Split,
    TrainConfig,
    _Best,
    _seeds,
    _train,
    calibration_factors,
    metric_groups,
    r2_score,
    split_indices,
    training_header,
    with_new_designs,
)

__all__ = [
    "METHODS",
    "MultiFidelityEncoder",
    "MultiFidelityFit",
    "MultiFidelitySurrogate",
    "fit_multifidelity",
    "method_class",
    "retrain_multifidelity",
]

#: the metrics of the 3D model: name -> (protocol, unit, description)
METRICS_3D_MODEL = metric_registry("3d")
#: the fewest validation designs whose scores calibrate a metric's interval: the smallest n at
#: which split conformal prediction has a finite 90 % quantile (k = ceil((n + 1) 0.9) <= n);
#: ``fit`` waits for 20, but a few 3D designs give fewer, and an ensemble trained on a few
#: dozen designs is far from calibrated on its own
CALIBRATION_MIN_N = 9


# ----------------------------------------------------------------------------- methods
class Method:
    """How a multi-fidelity surrogate uses the low fidelity: a subclass per method sets the flags
    and, for a warm start, ``start``; as they are here, not at all."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    #: a low-fidelity (2D) surrogate is needed
    low_fidelity: ClassVar[bool] = False
    #: the low fidelity's predicted means are inputs of the 3D ensemble
    low_inputs: ClassVar[bool] = False
    #: FE metrics with a 2D counterpart are learnt as their difference to its prediction
    delta: ClassVar[bool] = False
    #: the 3D ensemble starts from the 2D one's weights (``start``)
    warm_start: ClassVar[bool] = False
    #: the learning rate is the configuration's times this
    lr_factor: ClassVar[float] = 1.0
    #: with ``delta``: a 3D-only metric -> the 2D output whose prediction is its base
    proxies: ClassVar[dict[str, str]] = {}
    #: with ``delta``: the parameters whose logs a delta output's base is linear in (the trend
    #: fitted on the training designs, ``fit_trend``); those that are floats of the space
    trend_inputs: ClassVar[tuple[str, ...]] = ()
    #: with ``delta``: each delta output's predicted mean starts at 0 (the last layer's weights
    #: and bias of its mean set to zero), so that training starts from the base
    zero_start: ClassVar[bool] = False
    #: with ``delta``: the displacements, hysteresis and contact patch start from the slice
    #: model (``surrogate._slice.SLICE_METRICS``) rather than from the 2D prediction itself
    slice: ClassVar[bool] = False

    @classmethod
    def start(
        cls, model: EnsembleMLP, low: Surrogate, encoder: Encoder, names: Sequence[str]
    ) -> None:
        """Set ``model``'s initial weights from the low fidelity (a warm start only)."""


class ThreeDOnly(Method):
    name = "3d"
    summary = "a deep ensemble trained on the 3D designs alone (the baseline)"


class LowFidelityInput(Method):
    name = "input"
    summary = "the 2D surrogate's predicted means (normalised) as extra inputs of a 3D ensemble"
    low_fidelity = True
    low_inputs = True


class LowFidelityDelta(LowFidelityInput):
    name = "delta"
    summary = (
        "the 2D prediction as input, and each FE metric with a 2D counterpart learnt as its "
        "difference to the 2D prediction on the 2D surrogate's scale (log ratio or difference); "
        "the 2D prediction's variance added to the interval"
    )
    delta = True


class ContactDelta(LowFidelityDelta):
    name = "delta-contact"
    summary = (
        "as delta, and the contact patch (3D only) learnt as its ratio to the 2D displacement "
        "from touch at the same force"
    )
    #: Hertz: a patch's semi-axes go as sqrt(R delta) for the radii of curvature R across and
    #: along the finger, its area as sqrt(R_x R_z) delta: the area's ratio to the approach is a
    #: function of the shape, which the pad's parameters give, more than of the materials (the
    #: semi-axes' ratio keeps a delta^-1/2, which the 2D prediction as an input gives)
    proxies: ClassVar[dict[str, str]] = {
        f"contact_{what}_at_{f}N_{unit}": f"disp_at_{f}N_from_touch_mm"
        for f in (1, 4)
        for what, unit in (("area", "mm2"), ("width", "mm"), ("length", "mm"))
    }


class ShapeTrendDelta(ContactDelta):
    name = "delta-trend"
    summary = (
        "as delta-contact, and each delta output's base with a trend linear in the logs of the "
        "pad's half-length, length exponent and half-width, fitted on the 3D designs"
    )
    #: the pad's shape decides most of the 3D / 2D ratio: on the first 64 designs of the
    #: default 3D sweep a fit of the log ratio in ln c, ln m and ln a (the section's
    #: half-width) left a leave-one-out median error of 5-7 % on the displacements, against 12-19 %
    #: for its mean alone (docs/multifidelity.md, "How far 3D is from 2D")
    trend_inputs: ClassVar[tuple[str, ...]] = (
        "geometry.half_length_mm",
        "geometry.length_exponent",
        "geometry.half_width_mm",
    )
    #: the ensemble starts from the trend: what a few designs do not teach, it does not invent
    zero_start = True


class SliceDelta(ShapeTrendDelta):
    name = "delta-slice"
    summary = (
        "as delta-trend, the displacements, hysteresis and contact patch starting from the "
        "slice model: the 2D section's line load summed along the pad's length"
    )
    #: on the 3D dataset's first 128 designs the slice model alone predicts the displacement
    #: from touch at 1 N to a median of 4.2 % (the 2D prediction: 18 %), and with the shape
    #: trend a left-out design's displacements to 4.4-6.8 % (the 2D base's trend: 5.4-6.5 %),
    #: its hysteresis to 13 % (18 %) and its contact area at 1 N and 4 N from the plate's
    #: overlap to 25 % and 14 % (docs/multifidelity.md, "The slice model")
    slice = True


class FineTune(Method):
    name = "finetune"
    summary = (
        "the 2D ensemble trained further on the 3D designs, the pad's inputs and the 3D-only "
        "metrics added (zero input weights, fresh output weights)"
    )
    low_fidelity = True
    warm_start = True
    #: a third of the rate: a warm start that a few designs should correct, not overwrite
    lr_factor = 1.0 / 3.0

    @classmethod
    def start(
        cls, model: EnsembleMLP, low: Surrogate, encoder: Encoder, names: Sequence[str]
    ) -> None:
        """The 2D ensemble's weights in ``model``: each 2D input feature's first-layer row (the
        pad's rows stay zero: the start predicts what the 2D surrogate predicts), every hidden
        layer, and the last layer's columns of each output the 2D surrogate has (mean and
        log-variance); the 3D-only outputs keep ``model``'s own initial weights."""
        src = low.model
        if (src.members, src.n_groups, src.hidden) != (model.members, model.n_groups, model.hidden):
            raise ValueError("finetune: the 3D ensemble's shape differs from the 2D one's")
        rows = {f: i for i, f in enumerate(encoder.feature_names)}
        low_features = low.encoder.feature_names
        missing = [f for f in low_features if f not in rows]
        if missing:
            raise DesignError(
                "--low-fidelity", f"the 2D surrogate's input {missing[0]!r} is not a 3D feature"
            )
        outputs = {m: k for k, m in enumerate(low.metric_names)}
        shared = [(j, outputs[m]) for j, m in enumerate(names) if m in outputs]
        for j, k in shared:
            if model.groups[j] != src.groups[k]:
                raise ValueError(f"finetune: {names[j]} is in another net group than in 2D")
        last = len(model.weights) - 1
        n3, n2 = model.n_outputs, src.n_outputs
        cols3 = [j for j, _ in shared] + [n3 + j for j, _ in shared]
        cols2 = [k for _, k in shared] + [n2 + k for _, k in shared]
        with torch.no_grad():
            first = torch.zeros_like(model.weights[0])
            first[:, [rows[f] for f in low_features], :] = src.weights[0]
            model.weights[0].copy_(first)
            model.biases[0].copy_(src.biases[0])
            for i in range(1, last):
                model.weights[i].copy_(src.weights[i])
                model.biases[i].copy_(src.biases[i])
            model.weights[last][:, :, cols3] = src.weights[last][:, :, cols2]
            model.biases[last][:, :, cols3] = src.biases[last][:, :, cols2]


#: the methods by name (the checkpoint records the name; ``fingertip train --method``)
METHODS: dict[str, type[Method]] = {
    m.name: m
    for m in (
        ThreeDOnly,
        LowFidelityInput,
        LowFidelityDelta,
        ContactDelta,
        ShapeTrendDelta,
        SliceDelta,
        FineTune,
    )
}


def method_class(name: str, field_name: str = "--method") -> type[Method]:
    """The method called ``name``; a ``DesignError`` naming ``field_name`` and the methods."""
    if name not in METHODS:
        raise DesignError(field_name, f"must be one of {', '.join(METHODS)}, got {name!r}")
    return METHODS[name]


# ----------------------------------------------------------------------------- encoding
def _section(points: Any, names: Sequence[str]) -> Any:
    """The points (a list of dicts or a table) restricted to ``names``: a 3D design's point of
    the 2D space (its section and layers)."""
    keep = set(names)
    if isinstance(points, Mapping):
        return {k: v for k, v in points.items() if k in keep}
    return [{k: v for k, v in p.items() if k in keep} for p in points]


def check_low_fidelity(low: Surrogate, space: DesignSpace) -> None:
    """A ``DesignError`` naming --low-fidelity unless every parameter of the 2D surrogate's space
    is one of the 3D space's (the 3D design's section and layers are a 2D design)."""
    extra = [n for n in low.space.names if n not in space.names]
    if extra:
        raise DesignError(
            "--low-fidelity",
            f"the 2D surrogate's parameter {extra[0]!r} is not in the 3D sweep's space: train "
            "the 2D surrogate on the 3D space's section and layers",
        )


@dataclass(frozen=True, eq=False)
class MultiFidelityEncoder:
    """A 3D design point -> the multi-fidelity surrogate's features: the 3D space's encoding
    (``encoder``, with its training domain), then, with a low fidelity, the 2D surrogate's
    predicted mean and std (normalised, z) of each of its outputs for the design's section and
    layers (``low:<name>``, ``low_std:<name>``). The network reads the first part or the first
    two (``MultiFidelitySurrogate.net_features``); the std is the delta method's base variance."""

    encoder: Encoder
    low: Surrogate | None = None

    @property
    def space(self) -> DesignSpace:
        return self.encoder.space

    @property
    def n_own(self) -> int:
        """The 3D encoding's features."""
        return self.encoder.n_features

    @property
    def n_low(self) -> int:
        """The low fidelity's outputs (each gives a mean and a std feature)."""
        return 0 if self.low is None else len(self.low.metric_names)

    @property
    def feature_names(self) -> list[str]:
        names = list(self.encoder.feature_names)
        if self.low is not None:
            names += [f"low:{m}" for m in self.low.metric_names]
            names += [f"low_std:{m}" for m in self.low.metric_names]
        return names

    @property
    def n_features(self) -> int:
        return self.n_own + 2 * self.n_low

    def encode(self, points: Any) -> Encoded:
        """Encode a list of 3D points or a table; ``in_domain`` is False outside the 3D domain
        or the low fidelity's (the reason then starts with "low fidelity: ")."""
        own = self.encoder.encode(points)
        if self.low is None:
            return own
        low = self.low.encoder.encode(_section(points, self.low.space.names))
        mean_z, std_z = self.low.predict_normalised(low.features)
        features = np.empty((len(own.features), self.n_features), dtype=np.float32)
        features[:, : self.n_own] = own.features
        features[:, self.n_own : self.n_own + self.n_low] = mean_z
        features[:, self.n_own + self.n_low :] = std_z
        reasons = tuple(
            a or (f"low fidelity: {b}" if b else "")
            for a, b in zip(own.reasons, low.reasons, strict=True)
        )
        return Encoded(features, own.in_domain & low.in_domain, reasons)


# ----------------------------------------------------------------------------- the surrogate
class MultiFidelitySurrogate:
    """Predicts the 3D model's metrics of a 3D design, with uncertainty (``predict``, as
    ``Surrogate.predict``).

    ``normaliser``: per output, the transform t of its values (log, shifted log or linear) and the
    shift and scale of what the network learns, ``z = (t(y) - base - shift) / scale``; ``base`` is
    0 but for the delta method's metrics (``delta[j]``: the 2D output whose prediction is its
    base), where t is the 2D surrogate's transform of that output and base its predicted t,
    plus, with a ``trend`` (``"delta-trend"``: (n_metrics, 1 + k), a zero row for an output
    learnt directly), ``trend[j] . [1, ln x_1, ..., ln x_k]`` for the design's values x of the
    method's ``trend_inputs`` (``trend_inputs``: those the space varies).
    """

    def __init__(
        self,
        method: str,
        model: EnsembleMLP,
        encoder: MultiFidelityEncoder,
        normaliser: OutputNormaliser,
        metric_names: Sequence[str],
        delta: Sequence[str | None] | None = None,
        header: Mapping[str, Any] | None = None,
        *,
        low_file: str | Path | None = None,
        trend: np.ndarray | None = None,
    ) -> None:
        self.method = method_class(method)
        #: the low fidelity's checkpoint file (recorded, with its sha256, by a checkpoint)
        self.low_file = None if low_file is None else Path(low_file)
        self.model = model.eval()
        self.encoder = encoder
        self.metric_names = tuple(metric_names)
        self.units = tuple(
            METRICS_3D_MODEL[m][1] if m in METRICS_3D_MODEL else "" for m in self.metric_names
        )
        self.delta = tuple(delta) if delta is not None else (None,) * len(self.metric_names)
        self.header = dict(header or {})
        low = encoder.low
        if any(d is not None for d in self.delta) and low is None:
            raise ValueError("delta outputs need a low fidelity")
        self._base_index = [
            (j, low.metric_names.index(d)) for j, d in enumerate(self.delta) if d is not None
        ]
        floats = {p.name: p for p in encoder.space.parameters if p.kind == "float"}
        #: the trend's inputs: (feature column, parameter) of each of the method's that the
        #: space varies
        self._trend_params = [
            (encoder.encoder.feature_names.index(n), floats[n])
            for n in self.method.trend_inputs
            if n in floats
        ]
        #: ``"delta-slice"``: the outputs whose base is the slice model's, and the 2D outputs
        #: it reads (their pairs of displacements; the hysteresis)
        self._slice = [
            m
            for j, m in enumerate(self.metric_names)
            if self.method.slice
            and self.delta[j] is not None
            and m in SLICE_METRICS
            and all(r in low.metric_names for r in (*SLICE_METRICS[m][2], self.delta[j]))
        ]
        self.trend = trend
        # the network's part: a Surrogate evaluates it (batched, frozen, on one thread)
        self._net = Surrogate(model, encoder.encoder, normaliser, self.metric_names)

    @property
    def trend(self) -> np.ndarray | None:
        """The trend (n_metrics, 1 + k) of each delta output's base, or None."""
        return self._trend

    @trend.setter
    def trend(self, value: np.ndarray | None) -> None:
        if value is not None:
            value = np.asarray(value, dtype=np.float64)
            if value.shape != (len(self.metric_names), 1 + len(self._trend_params)):
                raise ValueError("the trend's shape does not match the metrics and its inputs")
        self._trend = value

    @property
    def normaliser(self) -> OutputNormaliser:
        """The output normaliser (the network's part, ``_net``, holds the same)."""
        return self._net.normaliser

    @normaliser.setter
    def normaliser(self, value: OutputNormaliser) -> None:
        self._net.normaliser = value

    @property
    def space(self) -> DesignSpace:
        return self.encoder.space

    @property
    def low(self) -> Surrogate | None:
        return self.encoder.low

    @property
    def members(self) -> int:
        return self.model.members

    def net_features(self, features: np.ndarray) -> np.ndarray:
        """The network's inputs among the encoded ``features``."""
        n = self.encoder.n_own + (self.encoder.n_low if self.method.low_inputs else 0)
        return np.ascontiguousarray(features[:, :n])

    @property
    def trend_inputs(self) -> list[str]:
        """The parameters whose logs the trend is linear in (after its constant)."""
        return [p.name for _, p in self._trend_params]

    def trend_matrix(self, features: np.ndarray) -> np.ndarray:
        """[1, ln x_1, ..., ln x_k] (n, 1 + k) of the encoded designs ``features``: each trend
        input's value read back from its feature (``Encoder``: its place in [low, high])."""
        H = np.ones((len(features), 1 + len(self._trend_params)))
        for i, (col, p) in enumerate(self._trend_params, start=1):
            H[:, i] = _log_value(features[:, col], p)
        return H

    def pad(self, features: np.ndarray) -> dict[str, np.ndarray]:
        """The pad's geometry (``PAD``: a, b, n, c, m, each (n,)) of the encoded designs: a
        float parameter of the space read back from its feature, a fixed one's value, and
        ``PadGeometry``'s default for one the space does not name."""
        out = {}
        default = PadGeometry().to_dict()
        features_of = self.encoder.encoder.feature_names
        for key in PAD:
            name = f"geometry.{key}"
            p = self.space[name] if name in self.space.names else None
            if p is not None and p.kind == "float" and name in features_of:
                out[key] = np.exp(_log_value(features[:, features_of.index(name)], p))
            else:
                value = p.value if p is not None and p.kind == "fixed" else default[key]
                out[key] = np.full(len(features), float(value))
        return out

    def _slice_bases(self, features: np.ndarray, base: np.ndarray) -> None:
        """Replace ``base``'s columns of the ``"delta-slice"`` outputs (in t units) by the slice
        model's values (``surrogate._slice.slice_values``) from the 2D predictions (``base``'s
        t of each 2D output) and the pad; a design whose 2D pair gives no power law keeps the
        2D base."""
        low = self.low.normaliser
        start = self.encoder.n_own
        names = list(self.low.metric_names)
        wanted = {r for m in self._slice for r in SLICE_METRICS[m][2]}
        wanted |= {m for m in self._slice if SLICE_METRICS[m][0] == "work"}
        two = {}
        for r in wanted:
            k = names.index(r)
            two[r] = _physical_with(low, k, low.shift[k] + low.scale[k] * features[:, start + k])
        values = slice_values(two, self.pad(features), self._slice)
        for m, value in values.items():
            j = self.metric_names.index(m)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = _transform_with(low, names.index(self.delta[j]), value)
            base[:, j] = np.where(np.isfinite(t), t, base[:, j])

    def base(self, features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(base, base_std)``, each (n, n_metrics), in the transformed units t: the 2D
        prediction's mean (plus the ``trend``) and (calibrated) std of each delta output, 0
        elsewhere."""
        n = len(features)
        base = np.zeros((n, len(self.metric_names)))
        base_std = np.zeros((n, len(self.metric_names)))
        if not self._base_index:
            return base, base_std
        low = self.low.normaliser
        start = self.encoder.n_own
        for j, k in self._base_index:
            base[:, j] = low.shift[k] + low.scale[k] * features[:, start + k].astype(np.float64)
            sd = features[:, start + self.encoder.n_low + k].astype(np.float64)
            base_std[:, j] = low.scale[k] * low.interval_scale[k] * sd
        if self._slice:
            self._slice_bases(features, base)
        if self.trend is not None:
            base += self.trend_matrix(features) @ self.trend.T
        return base, base_std

    def predict_normalised(self, features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The mean and std of z (float64, (n, n_metrics)): the ensemble mixture's, with the
        base's variance added for a delta output (in z units, before the interval scale)."""
        mean, std = self._net.predict_normalised(self.net_features(features))
        if self._base_index:
            _, base_std = self.base(features)
            std = np.sqrt(std**2 + (base_std / self.normaliser.scale) ** 2)
        return mean, std

    def transform(self, targets: np.ndarray, features: np.ndarray) -> np.ndarray:
        """FE values (n, n_metrics) -> z (what the network learns; NaN stays NaN)."""
        base, _ = self.base(features)
        return self.normaliser.transform(targets) - base / self.normaliser.scale

    def predict(self, points: Sequence[Mapping[str, Any]] | Mapping[str, Sequence]) -> Prediction:
        """Predict a list of 3D design points or a table, as ``Surrogate.predict``."""
        return predict_points(self, points)

    def predict_features(self, features: np.ndarray) -> dict[str, np.ndarray]:
        """Predict encoded designs (``encoder.encode``): ``mean``, ``median``, ``std``,
        ``lower_90``, ``upper_90`` in metric units and ``by_rule``, as
        ``Surrogate.predict_features``."""
        features = np.asarray(features)
        mean_z, std_z = self.predict_normalised(features)
        base, _ = self.base(features)
        # the per-design base shifts the Gaussian in t before it is mapped back to metric units
        at = replace(self.normaliser, shift=self.normaliser.shift + base)
        out = at.to_physical(mean_z, std_z)
        clip_probabilities(out, self.metric_names)
        rule = rule_mask(self.encoder.encoder, features[:, : self.encoder.n_own], self.metric_names)
        for key in PHYSICAL:
            np.copyto(out[key], 0.0, where=rule)
        out["by_rule"] = rule
        return out


# ----------------------------------------------------------------------------- training
def validation_size(n: int, fraction: float) -> int:
    """The validation designs of ``n``: ``fraction`` of them, and at least
    ``CALIBRATION_MIN_N`` (while that leaves three quarters of them to train on), so that a few
    dozen 3D designs still calibrate their intervals."""
    return max(1, round(fraction * n), min(CALIBRATION_MIN_N, n // 4))


def split_rows(rows: np.ndarray, whole: np.ndarray | None, n_val: int, test: np.ndarray) -> Split:
    """``rows`` (in a random order) split into training and ``n_val`` validation designs, beside
    the ``test`` rows. The first ``CALIBRATION_MIN_N`` validation designs are settled, valid
    ones (``whole``; None: every design) while there are enough: they have every metric, so that
    each metric's interval is calibrated even when a few dozen 3D designs hold only a few with
    tapping metrics (a design beyond the validity limits has none); the others are the next
    designs in ``rows``' order."""
    rows = np.asarray(rows)
    ok = np.ones(len(rows), dtype=bool) if whole is None else np.asarray(whole)[rows]
    first = np.flatnonzero(ok)[: min(n_val, CALIBRATION_MIN_N)]
    rest = np.setdiff1d(np.arange(len(rows)), first)  # in order
    val = np.concatenate([first, rest[: n_val - len(first)]])
    train = np.setdiff1d(np.arange(len(rows)), val)
    return Split(np.sort(rows[train]), np.sort(rows[val]), np.sort(np.asarray(test)))


def default_split(data: SweepData, seed: int, fractions: Sequence[float]) -> Split:
    """A random split of ``data``'s designs (``split_indices``'s test designs), its validation
    designs ``validation_size`` of them, the first settled, valid ones (``split_rows``)."""
    n = len(data.points)
    f_train, f_val, f_test = fractions
    n_val = validation_size(n, f_val)
    base = split_indices(n, seed, (f_train, n_val / n, f_test))
    order = np.random.default_rng(_seeds(seed)[0]).permutation(
        np.concatenate([base.train, base.val])
    )
    return split_rows(order, data.whole, n_val, base.test)


@dataclass(frozen=True, eq=False)
class MultiFidelityFit:
    """A trained multi-fidelity surrogate and how it was trained (as ``FitResult``)."""

    surrogate: MultiFidelitySurrogate
    split: Split
    history: dict[str, list[float]] = field(default_factory=dict)
    best_epoch: tuple[int, ...] = ()
    epochs: int = 0


def _transform_with(norm: OutputNormaliser, k: int, y: np.ndarray) -> np.ndarray:
    """Output ``k``'s transform t of ``norm`` applied to ``y`` (NaN where undefined)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if not norm.log[k]:
            return np.asarray(y, dtype=np.float64)
        u = np.asarray(y, dtype=np.float64) + norm.offset[k]
        return np.log(np.where(u > 0, u, np.nan))


def _log_value(u: np.ndarray, p) -> np.ndarray:
    """ln of the float parameter ``p``'s value from its feature ``u`` (``Encoder``: its place in
    [low, high], on a log scale where ``p.log``)."""
    u = np.asarray(u, dtype=np.float64)
    if p.log:
        return math.log(p.low) + u * (math.log(p.high) - math.log(p.low))
    return np.log(p.low + u * (p.high - p.low))


def _physical_with(norm: OutputNormaliser, k: int, t: np.ndarray) -> np.ndarray:
    """Output ``k``'s value from its transform ``t`` (``_transform_with``'s inverse)."""
    t = np.asarray(t, dtype=np.float64)
    return np.exp(t) - norm.offset[k] if norm.log[k] else t


def delta_outputs(
    names: Sequence[str],
    low: Surrogate,
    targets: np.ndarray,
    proxies: Mapping[str, str] | None = None,
) -> tuple[str | None, ...]:
    """Per 3D output, the 2D output whose prediction is its base with the delta method: an FE
    metric (``sim.metrics.METRICS``) the 2D surrogate predicts, whose finite training values
    ``targets[:, j]`` the 2D surrogate's transform maps to finite numbers (a log metric's values
    positive), all but at most ``DELTA_UNMAPPED_MAX`` of them (``unmapped``: those are not
    learnt); None elsewhere (learnt directly)."""
    out: list[str | None] = []
    proxies = proxies or {}
    for j, m in enumerate(names):
        m = proxies.get(m, m)
        if (
            m not in METRICS
            or m not in low.metric_names
            or low.normaliser.observed[low.metric_names.index(m)] == 0
        ):
            out.append(None)
            continue
        y = targets[:, j][np.isfinite(targets[:, j])]
        bad = ~np.isfinite(_transform_with(low.normaliser, low.metric_names.index(m), y))
        out.append(m if bad.sum() <= DELTA_UNMAPPED_MAX * y.size else None)
    return tuple(out)


#: the share of a delta output's training values that its log scale may fail to map (a value
#: <= 0) and that are then left out rather than the output learnt directly: a reading that
#: failed on a few designs, not a metric whose scale is wrong. The contact area at 1 N of the
#: 3D dataset's pointed sections (n < 1.5) on long pads reads 0 on 1 of 94 designs, and 0.1 and
#: 4 mm^2 on two others (a ridge of nodes touching, narrower than the mesh resolves:
#: docs/model_3d.md, "Mesh convergence"), where the other designs read 6-200 mm^2
DELTA_UNMAPPED_MAX = 0.05


def unmapped(targets: np.ndarray, delta: Sequence[str | None], low: Surrogate) -> np.ndarray:
    """Where a delta output's value is one its 2D transform cannot map (``delta_outputs``):
    (n, n_metrics) booleans, False for outputs learnt directly and missing values."""
    out = np.zeros(targets.shape, dtype=bool)
    for j, d in enumerate(delta):
        if d is not None:
            y = targets[:, j]
            t = _transform_with(low.normaliser, low.metric_names.index(d), y)
            out[:, j] = np.isfinite(y) & ~np.isfinite(t)
    return out


#: the fewest training values per trend coefficient: below it an output's trend stays 0 (the
#: ensemble learns the whole difference, as ``"delta"``). 2: the fit keeps as many residual
#: degrees of freedom as it has coefficients; 3 left every trend at 0 in the 12- and 24-design
#: subsets of docs/multifidelity.md's study (10-15 trusted training values for 4 coefficients)
TREND_MIN_ROWS_PER_COEFFICIENT = 2


def fit_trend(
    targets: np.ndarray,
    base: np.ndarray,
    H: np.ndarray,
    delta: Sequence[str | None],
    low: Surrogate,
    names: Sequence[str],
) -> np.ndarray:
    """The trend (n_metrics, H's columns) of ``"delta-trend"``: per delta output ``names[j]``
    that the 2D model has, the least squares fit of ``t(y) - base`` (the FE value's difference
    to the 2D prediction on the 2D surrogate's scale, over the training rows where it is
    finite) on ``H`` (``trend_matrix``); a zero row for an output learnt directly, for the
    contact patch (its ratio to the 2D displacement, a proxy: on the first 64 designs of the
    default 3D sweep a trend made its predictions worse, ``docs/multifidelity.md``) and for an
    output with fewer than ``TREND_MIN_ROWS_PER_COEFFICIENT`` values per coefficient."""
    trend = np.zeros((len(delta), H.shape[1]))
    for j, d in enumerate(delta):
        if d is None or d != names[j]:  # learnt directly, or a proxy's ratio (the patch)
            continue
        k = low.metric_names.index(d)
        r = _transform_with(low.normaliser, k, targets[:, j]) - base[:, j]
        ok = np.isfinite(r)
        if ok.sum() < TREND_MIN_ROWS_PER_COEFFICIENT * H.shape[1]:
            continue
        trend[j] = np.linalg.lstsq(H[ok], r[ok], rcond=None)[0]
    return trend


def _fit_normaliser(
    targets: np.ndarray,
    base: np.ndarray,
    delta: Sequence[str | None],
    low: Surrogate | None,
    start: OutputNormaliser | None = None,
    start_names: Sequence[str] = (),
    names: Sequence[str] = (),
) -> OutputNormaliser:
    """The output normaliser, fitted on the training rows ``targets`` (n, n_metrics) whose delta
    outputs have the 2D predictions ``base``: ``OutputNormaliser.fit`` for the outputs learnt
    directly; for a delta output the 2D surrogate's transform t and the mean and std of
    ``t(y) - base``; an output of ``start`` (a warm start's 2D normaliser) kept as it is."""
    norm = OutputNormaliser.fit(targets)
    log, offset = norm.log.copy(), norm.offset.copy()
    shift, scale, observed = norm.shift.copy(), norm.scale.copy(), norm.observed.copy()
    for j, d in enumerate(delta):
        if d is None:
            continue
        k = low.metric_names.index(d)
        r = _transform_with(low.normaliser, k, targets[:, j]) - base[:, j]
        r = r[np.isfinite(r)]
        log[j], offset[j] = low.normaliser.log[k], low.normaliser.offset[k]
        observed[j] = r.size
        shift[j] = float(r.mean()) if r.size else 0.0
        sd = float(r.std()) if r.size else 0.0
        scale[j] = sd if sd > 1e-12 * max(1.0, abs(shift[j])) else 1.0
    if start is not None:
        for j, m in enumerate(names):
            if m in start_names:
                k = list(start_names).index(m)
                log[j], offset[j] = start.log[k], start.offset[k]
                shift[j], scale[j] = start.shift[k], start.scale[k]
    return OutputNormaliser(log, shift, scale, observed, offset)


def fit_multifidelity(
    data: SweepData,
    low: Surrogate | str | Path | None,
    method: str = "delta",
    config: TrainConfig | None = None,
    *,
    split: Split | None = None,
    progress: bool | Callable[[int], None] = True,
    threads: int | None = None,
) -> MultiFidelityFit:
    """Train a multi-fidelity surrogate of ``method`` on the 3D sweep ``data`` (``read_sweep(...,
    dimension="3d")``) with the low-fidelity 2D surrogate ``low``: its checkpoint file (or a
    training run folder), or a loaded ``Surrogate`` (whose file ``save_multifidelity`` then
    cannot record); None for "3d" (which ignores it).

    ``config``, ``split``, ``progress`` and ``threads`` as ``surrogate._train.fit``'s; the
    finetune method takes the members and hidden layers of the 2D ensemble and a third of
    ``config.lr``. The header records the method, the 3D data and the split; the low fidelity's
    identity is recorded by ``save_multifidelity``."""
    kind = method_class(method)
    config = TrainConfig() if config is None else config
    low_file = None
    if isinstance(low, str | Path):
        from ._checkpoint import checkpoint_file, load_checkpoint

        low_file = checkpoint_file(low)
        low = load_checkpoint(low_file)
    if kind.low_fidelity and low is None:
        raise DesignError("--low-fidelity", f"the {method} method needs a 2D surrogate")
    low = low if kind.low_fidelity else None
    if low is not None:
        check_low_fidelity(low, data.space)
    if config.members < 1:
        raise ValueError(f"members must be >= 1, got {config.members}")
    if kind.warm_start:
        config = replace(config, members=low.model.members, hidden=low.model.hidden)
    if kind.lr_factor != 1.0:
        config = replace(config, lr=config.lr * kind.lr_factor)
    if split is None:
        split = default_split(data, config.seed, config.fractions)
    _, init_seed, _ = _seeds(config.seed)
    names = data.metric_names
    log_tangents = low.encoder.log_tangents if kind.warm_start else config.log_tangents
    omega = 2.0 * math.pi * data.tapping_frequency_Hz
    own = Encoder(data.space, omega_rad_s=omega, log_tangents=log_tangents)
    own = own.fit_domain([data.points[i] for i in split.train])
    encoder = MultiFidelityEncoder(own, low)
    features = encoder.encode(data.points).features
    # values known by rule (an elastic design's hysteresis is 0) are not learnt
    targets = np.where(rule_mask(own, features[:, : own.n_features], names), np.nan, data.targets)
    delta = delta_outputs(names, low, targets[split.train], kind.proxies) if kind.delta else None
    if delta is not None:  # the few values a delta output's scale cannot take: not learnt
        targets = np.where(unmapped(targets, delta, low), np.nan, targets)
    grouping = config.groups
    if kind.warm_start:  # the nets of the 2D ensemble, grouped as it was trained
        grouping = str(low.header.get("training", {}).get("groups", grouping))
    groups = metric_groups(names, grouping)
    model = EnsembleMLP(
        encoder.n_own + (encoder.n_low if kind.low_inputs else 0),
        len(names),
        members=config.members,
        hidden=config.hidden,
        groups=groups,
        seed=init_seed,
    )
    # a provisional surrogate gives the bases; its normaliser is fitted below
    blank = OutputNormaliser.fit(targets[split.train])
    surrogate = MultiFidelitySurrogate(kind.name, model, encoder, blank, names, delta)
    base, _ = surrogate.base(features)
    trend = None
    if kind.trend_inputs and delta is not None:
        H = surrogate.trend_matrix(features)
        trend = fit_trend(
            targets[split.train], base[split.train], H[split.train], delta, low, names
        )
        surrogate.trend = trend
        base, _ = surrogate.base(features)
    start = low.normaliser if kind.warm_start else None
    normaliser = _fit_normaliser(
        targets[split.train],
        base[split.train],
        surrogate.delta,
        low,
        start,
        low.metric_names if start is not None else (),
        names,
    )
    surrogate.normaliser = normaliser
    if kind.warm_start:
        kind.start(model, low, own, names)
    if kind.zero_start and delta is not None:
        cols = [j for j, d in enumerate(delta) if d is not None]  # their means' columns
        with torch.no_grad():
            model.weights[-1][:, :, cols] = 0.0
            model.biases[-1][:, :, cols] = 0.0
    z_all = surrogate.transform(targets, features)
    mask_all = np.isfinite(z_all)
    z_all = np.where(mask_all, z_all, 0.0)
    c_all = np.zeros(z_all.shape, np.int8) if data.censored is None else data.censored
    x_all = surrogate.net_features(features)

    def tensors(rows: np.ndarray):
        return (
            torch.from_numpy(x_all[rows]),
            torch.from_numpy(z_all[rows].astype(np.float32)),
            torch.from_numpy(mask_all[rows].astype(np.float32)),
            torch.from_numpy(c_all[rows].astype(np.float32)),
        )

    train, val = tensors(split.train), tensors(split.val)
    with threads_set(torch_threads() if threads is None else threads) as threads:
        best, history, epochs = _train(model, config, train, val, progress)
    best.restore(model)
    surrogate = MultiFidelitySurrogate(
        kind.name,
        model,
        encoder,
        normaliser,
        names,
        delta,
        low_file=low_file if low else None,
        trend=trend,
    )
    mean_z, std_z = surrogate.predict_normalised(features[split.val])
    z_val = surrogate.transform(targets[split.val], features[split.val])
    factors, calibration = calibrate(mean_z, std_z, z_val, names, groups)
    surrogate.normaliser = normaliser.calibrated(factors)
    record = training_header(data, config, split, best, epochs, threads, log_tangents)
    record["training"]["groups"] = grouping
    record["training_data"].update(
        model="3d", solver_version=data.solver_version, space=data.space.to_dict()
    )
    surrogate.header.update(
        {
            **record,
            "calibration": calibration,
            "validation": _validation(surrogate, features[split.val], targets[split.val], best),
        }
    )
    return MultiFidelityFit(
        surrogate, split, history, tuple(int(e) for e in best.epoch), epochs=epochs
    )


def retrain_multifidelity(
    surrogate: MultiFidelitySurrogate,
    data: SweepData,
    points: Sequence[Mapping[str, Any]],
    targets: np.ndarray,
    *,
    seed: int,
    weight: int = 1,
    progress: bool | Callable[[int], None] = False,
    threads: int | None = None,
) -> MultiFidelitySurrogate:
    """``surrogate`` trained again, as its header records (method, hyper-parameters, the split of
    its 3D sweep ``data`` by table index, its low fidelity's file) but with ``seed``, on its 3D
    designs and new ones: ``points`` with their ``targets`` (one row per point, the columns of
    ``data.metric_names``; NaN: not learnt), each counted ``weight`` times, among the training
    designs. A search's active learning (``explore._retrain``): a few hundred 3D designs train
    in about a minute, so the multi-fidelity surrogate is trained afresh rather than warm-started
    (the 2D one, trained on thousands, is fine-tuned: ``fine_tune``)."""
    if list(data.metric_names) != list(surrogate.metric_names):
        raise ValueError("the sweep's metrics are not the surrogate's")
    aug, split, config = with_new_designs(surrogate.header, data, points, targets, weight)
    config = replace(config, seed=seed)
    kind = surrogate.method
    if kind.lr_factor != 1.0:  # the header holds the rate fit_multifidelity trained with
        config = replace(config, lr=config.lr / kind.lr_factor)
    fitted = fit_multifidelity(
        aug, surrogate.low, kind.name, config, split=split, progress=progress, threads=threads,
    )  # fmt: skip
    fitted.surrogate.low_file = surrogate.low_file  # the same 2D file, recorded when saved
    return fitted.surrogate


def calibrate(
    mean_z: np.ndarray,
    std_z: np.ndarray,
    z: np.ndarray,
    names: Sequence[str],
    groups: Sequence[int],
) -> tuple[np.ndarray, dict[str, Any]]:
    """Each FE metric's interval factor (``calibration_factors``, split conformal on the
    validation designs, from ``CALIBRATION_MIN_N`` values); a metric with fewer takes the factor
    of the scores of its net group's FE metrics pooled, when they are that many. A few dozen 3D
    designs leave a few validation designs, and fewer still with a metric: a design beyond the
    validity limits has no tapping metrics."""
    factors, info = calibration_factors(mean_z, std_z, z, names, min_n=CALIBRATION_MIN_N)
    with np.errstate(divide="ignore", invalid="ignore"):
        scores = np.abs(np.asarray(z) - mean_z) / std_z
    pooled: dict[str, str] = {}
    for g in sorted(set(groups)):
        cols = [j for j, m in enumerate(names) if groups[j] == g and m in METRICS_3D_MODEL]
        r = scores[:, cols]
        r = np.sort(r[np.isfinite(r)])
        k = math.ceil((r.size + 1) * CALIBRATION_COVERAGE)
        if r.size < CALIBRATION_MIN_N or k > r.size or r[k - 1] <= 0:
            continue
        for j in cols:
            if info["n"][names[j]] < CALIBRATION_MIN_N:
                factors[j] = float(r[k - 1]) / Z90
                info["interval_scale"][names[j]] = factors[j]
                pooled[names[j]] = f"net group {g}: {r.size} scores"
    info["pooled"] = pooled
    return factors, info


def _validation(
    surrogate: MultiFidelitySurrogate, features: np.ndarray, targets: np.ndarray, best: _Best
) -> dict[str, Any]:
    """Each net's validation NLL (normalised units) and each metric's R² on the validation
    designs."""
    median = surrogate.predict_features(features)["median"]
    return {
        "n_designs": len(features),
        "member_nll": [float(v) for v in best.loss.numpy()],
        "r2": {
            m: finite_or_none(r2_score(targets[:, j], median[:, j]))
            for j, m in enumerate(surrogate.metric_names)
        },
    }
