"""Training: split a sweep, fit the normalisers on the training designs, train the ensemble with
a Gaussian NLL and per-member early stopping on the validation loss; then calibrate each FE
metric's 90 % interval on the validation designs (``calibration_factors``).

Reproducible from the seed: the split, the initial weights and every member's minibatch order
come from ``numpy.random.SeedSequence(seed)``; torch runs with deterministic algorithms, on
``surrogate._threads.torch_threads()`` intra-op threads (1: a reduction's sum depends on the
thread count, see ``MAX_TRAINING_THREADS``), recorded in the header (``training.torch_threads``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, fields, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np
import torch

from sim.metrics import metric_registry
from sim.protocols import LAYER_STRAIN_OUTPUTS, TRUST_OUTPUTS
from sim.provenance import finite_or_none, git_commit, recorded_path

from ._encoding import Encoder
from ._io import SweepData
from ._model import EnsembleMLP, gaussian_nll
from ._normalise import Z90, OutputNormaliser
from ._surrogate import Surrogate, rule_mask
from ._threads import threads_set, torch_threads

__all__ = [
    "GROUPINGS",
    "FitResult",
    "Split",
    "TrainConfig",
    "calibration_factors",
    "fine_tune",
    "fit",
    "metric_groups",
    "split_indices",
]


@dataclass(frozen=True)
class TrainConfig:
    """Hyper-parameters of ``fit`` (the defaults train ~2000 designs in minutes on a CPU)."""

    seed: int = 0
    members: int = 5
    hidden: tuple[int, ...] = (96, 96)
    max_epochs: int = 1500
    patience: int = 100  # epochs without a better validation loss in any member
    batch_size: int = 32
    lr: float = 3e-3
    weight_decay: float = 1e-4
    fractions: tuple[float, float, float] = (0.70, 0.15, 0.15)  # train, validation, test
    beta_nll: float = 0.0  # training loss: beta-NLL weight (0 = Gaussian NLL); early stopping: NLL
    # nets per member (``GROUPINGS``): the tapping metrics | the rest ("tapping_metrics")
    groups: str = "tapping_metrics"
    # rehearsal (``fine_tune``): 0, every epoch passes over every training design; k > 0, over
    # the new designs (``Split.new``) and k of the others, drawn afresh every epoch
    replay: int = 0
    # material descriptors: also the log10 of each layer's loss tangents (``Encoder.log_tangents``)
    # and the learning rate on a plateau, net by net (``_LearningRate``): ``decay_patience``
    # epochs after a net's last improvement of its validation NLL it restarts from its best
    # weights at ``lr_decay`` times its rate, at most ``lr_decays`` times; training stops when
    # every net is ``patience`` epochs past its last improvement or decay with none left
    # (``lr_decay = 1``: a constant rate, the earlier rule). On the 4096-design sweep
    # (``docs/surrogate_accuracy.md``, 3482 designs, fixed test split, 3 seeds) the two
    # together took the hysteresis median from 2.20 to 2.06 % and its 95th percentile from 20
    # to 18 %, the displacement medians from 0.34-0.38 to 0.27-0.31 %, in half the epochs.
    # One setting, not tuned: a decay after half the early-stopping patience, by 0.3 (between
    # ReduceLROnPlateau's default 0.1 and a gentle 0.5), three times: the last rate 1/37 of
    # the first
    log_tangents: bool = True
    lr_decay: float = 0.3
    lr_decays: int = 3
    decay_patience: int = 50

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


#: how metrics share nets (``TrainConfig.groups``):
#:
#: - "tapping_metrics" (the default): the tapping protocol's FE metrics (compliance, hysteresis,
#:   sag) get a net of their own; the plate and wedge metrics and every trust output (also the
#:   tapping's strain, J and settling figures, which every design has, the untrusted ones too,
#:   with their extreme values) share the other. Same inference cost as "tapping" (two nets per
#:   member). On the default space's sweep (675 designs, fixed 15 % test split, 574 training +
#:   validation designs, 3 seeds, ``docs/surrogate_accuracy.md``): median error of
#:   hysteresis_Nmm 11.5 -> 9.4 %, with the per-protocol trust of ``read_sweep`` 9.7 -> 6.6 %
#:   (5-fold cross-validation over the 675 designs: each tapping metric's median error 10-18 %
#:   lower); credibility of the test designs predicted right 92.7 % against 93.1 %;
#: - "tapping": the tapping protocol's metrics and trust outputs in one net, the plate and
#:   wedge ones in the other (3 seeds on 2560 designs of the previous space,
#:   fit(..., TrainConfig(seed=s, groups=...)) scored on each seed's test split: hysteresis
#:   median error 3.6 % against 4.0 % in one net; a net for the plate's single metric was not
#:   worth its inference time);
#: - "none": one net for all.
GROUPINGS = ("tapping_metrics", "tapping", "none")


def metric_groups(metric_names: Sequence[str], grouping: str) -> tuple[int, ...]:
    """The net-group index of each metric: the tapping protocol's first (its FE metrics only
    with "tapping_metrics", with its trust outputs too with "tapping"), then the rest (one group
    when only one kind is present)."""
    if grouping not in GROUPINGS:
        raise ValueError(f"groups must be one of {', '.join(GROUPINGS)}, got {grouping!r}")
    if grouping == "none":
        return tuple(0 for _ in metric_names)
    # the 3D model's contact patch is measured in the taps: with the tapping's metrics
    protocol = {m: v[0] for m, v in metric_registry("3d").items()}
    if grouping == "tapping":
        protocol.update(TRUST_OUTPUTS)
        protocol.update({m: p for m, (p, _) in LAYER_STRAIN_OUTPUTS.items()})
    kind = [0 if protocol.get(m) == "tapping" else 1 for m in metric_names]
    present = sorted(set(kind))
    return tuple(present.index(k) for k in kind)


@dataclass(frozen=True, eq=False)
class Split:
    """Row positions (into ``SweepData.points``) of the train / validation / test designs;
    the last ``new`` training rows are new designs (``fine_tune``'s), which every epoch of a
    rehearsal (``TrainConfig.replay``) passes over."""

    train: np.ndarray
    val: np.ndarray
    test: np.ndarray
    new: int = 0


def _seeds(seed: int) -> tuple[int, int, int]:
    """Independent seeds for the split, the initial weights and the minibatch order."""
    a, b, c = (int(s.generate_state(1)[0]) for s in np.random.SeedSequence(seed).spawn(3))
    return a, b, c


def split_indices(n: int, seed: int, fractions=(0.70, 0.15, 0.15)) -> Split:
    """A random split of ``n`` designs; validation and test get >= 1 design each."""
    if n < 4:
        raise ValueError(f"need >= 4 designs with FE results to split, got {n}")
    _, f_val, f_test = fractions
    n_val = max(1, round(f_val * n))
    n_test = max(1, round(f_test * n))
    perm = np.random.default_rng(_seeds(seed)[0]).permutation(n)
    return Split(
        np.sort(perm[n_val + n_test :]),
        np.sort(perm[:n_val]),
        np.sort(perm[n_val : n_val + n_test]),
    )


@dataclass(frozen=True, eq=False)
class FitResult:
    """A trained surrogate and how it was trained.

    ``history``: per epoch, members' mean training and validation NLL (normalised units);
    ``best_epoch``: the epoch of each member's kept weights.
    """

    surrogate: Surrogate
    split: Split
    history: dict[str, list[float]] = field(default_factory=dict)
    best_epoch: tuple[int, ...] = ()
    epochs: int = 0


@contextmanager
def _deterministic():
    old = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(old)


def training_header(
    data: SweepData,
    config: TrainConfig,
    split: Split,
    best: _Best,
    epochs: int,
    threads: int,
    log_tangents: bool,
) -> dict[str, Any]:
    """The checkpoint header's record of a training: when, by which solver's data and commit,
    the configuration and its outcome (epochs, each net's best epoch, torch threads), and the
    sweep with the designs of each part of the split (by their table index)."""
    return {
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "solver_version": data.solver_version,
        "git_commit": git_commit(),
        "training": {
            **config.to_dict(),
            "log_tangents": log_tangents,
            "epochs": epochs,
            "best_epoch": [int(e) for e in best.epoch],
            "torch_threads": threads,
        },
        "training_data": {
            "sweep": recorded_path(data.folder),  # the same on every checkout
            "table_sha256": data.table_sha256,
            "n_rows": data.n_rows,
            "n_used": len(data.points),
            "split_table_index": {
                "train": [int(data.index[i]) for i in split.train],
                "val": [int(data.index[i]) for i in split.val],
                "test": [int(data.index[i]) for i in split.test],
            },
        },
    }


def fit(
    data: SweepData,
    config: TrainConfig = TrainConfig(),
    *,
    progress: bool | Callable[[int], None] = True,
    split: Split | None = None,
    init: Surrogate | None = None,
    threads: int | None = None,
) -> FitResult:
    """Train an ensemble on ``data`` (a sweep) and return a ``FitResult``.

    ``progress``: True shows a bar of the epochs, False nothing; a callable is called with 1
    after each epoch instead (the caller's own bar: ``fingertip run``'s retraining).

    ``split``: row positions of train/validation/test (default: a random split from the seed
    and ``config.fractions``). ``init``: warm start from a trained surrogate with the same
    encoding, metrics and architecture: its weights are the starting point and its output
    normaliser is kept (so the start is exactly the trained model); the input domain is refitted
    on the new training rows. ``threads``: torch's intra-op threads while it trains (default
    ``torch_threads()``: no FE beside it); the caller's count is set again afterwards.
    """
    if config.members < 1:
        raise ValueError(f"members must be >= 1, got {config.members}")
    if split is None:
        split = split_indices(len(data.points), config.seed, config.fractions)
    _, init_seed, _ = _seeds(config.seed)
    train_points = [data.points[i] for i in split.train]
    omega = 2.0 * math.pi * data.tapping_frequency_Hz  # the taps the sweep was made with
    # a warm start keeps the descriptors its weights were trained on (a checkpoint may predate
    # the log loss tangents)
    log_tangents = init.encoder.log_tangents if init is not None else config.log_tangents
    encoder = Encoder(data.space, omega_rad_s=omega, log_tangents=log_tangents)
    encoder = encoder.fit_domain(train_points)
    x_all = encoder.encode(data.points).features
    # values known by rule (an elastic design's hysteresis is 0) are not learnt
    targets = np.where(rule_mask(encoder, x_all, data.metric_names), np.nan, data.targets)
    # fitted on training designs ONLY; a warm start keeps the one its weights were trained in
    # (its intervals are calibrated again below, on this fit's validation designs)
    normaliser = (
        init.normaliser.calibrated(np.ones(len(data.metric_names)))
        if init is not None
        else OutputNormaliser.fit(targets[split.train])
    )
    z_all = normaliser.transform(targets)
    mask_all = np.isfinite(z_all)
    z_all = np.where(mask_all, z_all, 0.0)
    # bounds stay bounds in z: the normalisation is increasing (log or linear, scale > 0)
    c_all = np.zeros(z_all.shape, np.int8) if data.censored is None else data.censored

    def tensors(rows: np.ndarray):
        return (
            torch.from_numpy(x_all[rows]),
            torch.from_numpy(z_all[rows].astype(np.float32)),
            torch.from_numpy(mask_all[rows].astype(np.float32)),
            torch.from_numpy(c_all[rows].astype(np.float32)),
        )

    model = EnsembleMLP(
        x_all.shape[1],
        z_all.shape[1],
        members=config.members,
        hidden=config.hidden,
        # a warm start keeps the nets' grouping its weights were trained in (a checkpoint may
        # predate the default's change: "tapping" before "tapping_metrics")
        groups=init.model.groups
        if init is not None
        else metric_groups(data.metric_names, config.groups),
        seed=init_seed,
    )
    if init is not None:
        if init.encoder.n_features != x_all.shape[1] or tuple(init.metric_names) != tuple(
            data.metric_names
        ):
            raise ValueError("warm start: the surrogate's encoding or metrics differ")
        model.load_state_dict(init.model.state_dict(), strict=True)
    train, val = tensors(split.train), tensors(split.val)
    with threads_set(torch_threads() if threads is None else threads) as threads:
        best, history, epochs = _train(model, config, train, val, progress, new=split.new)
    best.restore(model)
    header = training_header(data, config, split, best, epochs, threads, log_tangents)
    surrogate = Surrogate(model, encoder, normaliser, data.metric_names, header)
    surrogate.header["validation"] = validation_metrics(
        surrogate, x_all[split.val], targets[split.val], best.loss.numpy()
    )
    mean_z, std_z = surrogate.predict_normalised(x_all[split.val])
    factors, info = calibration_factors(
        mean_z, std_z, normaliser.transform(targets[split.val]), data.metric_names
    )
    surrogate.normaliser = normaliser.calibrated(factors)
    surrogate.header["calibration"] = info
    return FitResult(surrogate, split, history, tuple(int(e) for e in best.epoch), epochs=epochs)


def fine_tune(
    surrogate: Surrogate,
    data: SweepData,
    points: Sequence[dict[str, Any]],
    targets: np.ndarray,
    *,
    epochs: int,
    seed: int,
    weight: int = 1,
    batch_size: int | None = None,
    replay: int = 0,
    progress: bool | Callable[[int], None] = False,
    threads: int | None = None,
) -> Surrogate:
    """``surrogate`` trained further (warm-started, ``fit``'s ``init``) on its training sweep
    ``data`` and new designs: ``points`` with their ``targets`` (one row per point, the columns
    of ``data.metric_names``; NaN: not learnt), each counted ``weight`` times.

    The split is the one the checkpoint records (its train/validation/test designs, found in
    ``data`` by table index); the new designs join the training designs. The hyper-parameters
    are the checkpoint's but ``seed``, ``epochs`` (at most this many, and the patience), when
    given, ``batch_size``, and ``replay``: 0, every epoch passes over the whole training sweep
    and the new designs; k > 0, a rehearsal: every epoch passes over the new designs and k
    designs of the sweep drawn afresh (an epoch's cost no longer grows with the sweep).
    ``progress`` and ``threads`` as ``fit``'s."""
    aug, split, config = with_new_designs(surrogate.header, data, points, targets, weight)
    changed = {"seed": seed, "max_epochs": epochs, "patience": epochs, "replay": replay}
    if batch_size is not None:
        changed["batch_size"] = batch_size
    config = replace(config, **changed)
    fitted = fit(aug, config, progress=progress, split=split, init=surrogate, threads=threads)
    return fitted.surrogate


def with_new_designs(
    header: dict[str, Any],
    data: SweepData,
    points: Sequence[dict[str, Any]],
    targets: np.ndarray,
    weight: int,
) -> tuple[SweepData, Split, TrainConfig]:
    """What a checkpoint (its ``header``) trains on again with new designs: its training sweep
    ``data`` plus ``points`` with their ``targets`` (one row per point, the columns of
    ``data.metric_names``), each ``weight`` times; the split it records (its train /
    validation / test designs, found in ``data`` by table index), the new designs among the
    training ones (``Split.new``); and its recorded hyper-parameters (``TrainConfig``).
    ``fine_tune`` and ``retrain_multifidelity`` share it."""
    if weight < 1:
        raise ValueError(f"weight must be >= 1, got {weight}")
    extra = [dict(p) for p in points for _ in range(weight)]
    rows = np.asarray(targets, dtype=np.float64).reshape(-1, len(data.metric_names))
    aug = data.with_rows(extra, np.repeat(rows, weight, axis=0))
    split_idx = header.get("training_data", {}).get("split_table_index", {})
    row_of = {int(i): r for r, i in enumerate(data.index)}

    def split_rows(key: str) -> np.ndarray:
        return np.array([row_of[i] for i in split_idx.get(key, []) if i in row_of], dtype=int)

    train, val, test = split_rows("train"), split_rows("val"), split_rows("test")
    if len(train) == 0 or len(val) == 0:
        raise ValueError("the checkpoint does not record its training split")
    train = np.concatenate([train, len(data.points) + np.arange(len(extra))])
    names = {f.name for f in fields(TrainConfig)}
    old = {k: v for k, v in header.get("training", {}).items() if k in names}
    old = {k: tuple(v) if isinstance(v, list) else v for k, v in old.items()}
    return aug, Split(train, val, test, new=len(extra)), TrainConfig(**old)


#: features, targets, their mask, their censoring (+1 lower bound, -1 upper, 0 exact)
_Tensors = tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]


#: Early stopping scores each validation entry's NLL capped at this (``gaussian_nll``'s
#: ``cap``; the training loss is not capped). Without it one output the nets cannot predict
#: stopped a whole net: on the default sweep's first 4096 designs the ``failed`` flag of the 17
#: validation designs whose FE failed (5 % of them) drove that output's validation NLL from 5
#: to 740 within 40 epochs, while every other output of its net was still improving, and
#: every member kept its plate / wedge / trust net from epoch 0-61 (plate force median error
#: 15 % instead of 1.8 %). 10 is a miss of about 4.5 sigma at a typical spread.
VALIDATION_NLL_CAP = 10.0


@dataclass(eq=False)
class _Best:
    """Each net's best validation NLL so far, its epoch and its weights (per-net early
    stopping: the nets of one ensemble are kept at different epochs)."""

    loss: torch.Tensor
    epoch: torch.Tensor
    state: list[torch.Tensor]

    @classmethod
    def start(cls, model: EnsembleMLP) -> _Best:
        return cls(
            torch.full((model.nets,), math.inf),
            torch.zeros(model.nets, dtype=torch.long),
            [p.detach().clone() for p in model.parameters()],
        )

    def update(self, val: torch.Tensor, epoch: int, model: EnsembleMLP) -> None:
        """Keep the epoch and weights of every net whose validation NLL ``val`` is its best."""
        better = val < self.loss
        if better.any():
            self.loss = torch.where(better, val, self.loss)
            self.epoch[better] = epoch
            for kept, p in zip(self.state, model.parameters(), strict=True):
                kept[better] = p.detach()[better]

    def restore(self, model: EnsembleMLP) -> None:
        """Every net's kept weights back into ``model``, left in eval mode."""
        with torch.no_grad():
            for kept, p in zip(self.state, model.parameters(), strict=True):
                p.copy_(kept)
        model.eval()


def _train(
    model: EnsembleMLP,
    config: TrainConfig,
    train: _Tensors,
    val: _Tensors,
    progress: bool | Callable[[int], None] = True,
    new: int = 0,
) -> tuple[_Best, dict[str, list[float]], int]:
    """Train ``model`` epoch by epoch (AdamW, the minibatch order from the seed) until no net
    has improved its validation NLL for ``patience`` epochs, or for ``max_epochs``: the best of
    each net (not yet restored into ``model``), the per-epoch history and the number of epochs.
    ``progress`` as ``fit``'s; ``new``: the last rows of ``train`` that a rehearsal
    (``config.replay``) passes over every epoch."""
    from tqdm import tqdm

    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    gen = torch.Generator().manual_seed(_seeds(config.seed)[2])
    n = len(train[0])
    net_mask = model.net_mask()  # each net is trained and stopped on its group's metrics only
    x_va, z_va, m_va, c_va = val
    m_va = m_va.unsqueeze(0) * net_mask
    best = _Best.start(model)
    rate = _LearningRate(model, config)
    history: dict[str, list[float]] = {"train_nll": [], "val_nll": []}
    epoch = 0
    with _deterministic():
        bar = tqdm(
            range(config.max_epochs),
            desc="train",
            unit="epoch",
            disable=progress is not True,
            mininterval=0.5,
        )
        tick = progress if callable(progress) else None
        for epoch in bar:
            order = _epoch_order(config.members, n, new, config.replay, gen)
            train_nll = _train_epoch(model, opt, train, net_mask, order, config, rate)
            model.eval()
            with torch.no_grad():
                val_nll = gaussian_nll(
                    *model.forward_nets(x_va), z_va, m_va, censor=c_va, cap=VALIDATION_NLL_CAP
                )
                best.update(val_nll, epoch, model)
            history["train_nll"].append(float(train_nll.mean()))
            history["val_nll"].append(float(val_nll.mean()))
            bar.set_postfix(val_nll=f"{float(best.loss.mean()):.3f}", refresh=False)
            if tick is not None:
                tick(1)
            if rate.stop_after(epoch, best):
                break
        bar.close()
    return best, history, epoch + 1


class _LearningRate:
    """Each net's learning rate on a plateau of its validation NLL, and the stopping rule
    (``TrainConfig.lr_decay``). Net s, ``decay_patience`` epochs after its last improvement (or
    decay) with decays left, goes back to its best weights and has its rate multiplied by
    ``lr_decay`` (``torch.optim.lr_scheduler.ReduceLROnPlateau``'s rule, net by net, with a
    restart from the best). Training stops when every net has gone ``patience`` epochs without
    an improvement or a decay and has no decay left. The nets share one optimiser: a net's
    rate is applied by scaling its update (Adam's step is proportional to the rate)."""

    def __init__(self, model: EnsembleMLP, config: TrainConfig) -> None:
        self.config = config
        self.params = list(model.parameters())
        decays = config.lr_decays if config.lr_decay < 1.0 else 0
        self.left = torch.full((model.nets,), decays, dtype=torch.long)
        self.since = torch.full((model.nets,), -1, dtype=torch.long)
        self.scale = torch.ones(model.nets)
        # the weights before a step (buffers made at the first decay) and, per parameter, the
        # scale shaped to broadcast over its net (none while every net is at the full rate)
        self._before: list[torch.Tensor] = []
        self._factor: list[torch.Tensor] = []

    def before_step(self) -> None:
        for old, p in zip(self._before, self.params, strict=False):  # none before a decay
            old.copy_(p.detach())

    def after_step(self) -> None:
        """Each net's update scaled by its rate's factor: ``old + scale (new - old)``."""
        if self._factor:
            with torch.no_grad():
                for p, old, f in zip(self.params, self._before, self._factor, strict=True):
                    p.sub_(old).mul_(f).add_(old)

    def stop_after(self, epoch: int, best: _Best) -> bool:
        """After ``epoch``: decay the rate of every net due; True when training is over."""
        quiet = epoch - torch.maximum(best.epoch, self.since)
        due = (self.left > 0) & (quiet >= self.config.decay_patience)
        if due.any():
            self.scale[due] *= self.config.lr_decay
            self.left[due] -= 1
            self.since[due] = epoch
            if not self._before:  # views of ``scale``: they follow its later decays
                self._before = [torch.empty_like(p) for p in self.params]
                self._factor = [self.scale.view(-1, *[1] * (p.dim() - 1)) for p in self.params]
            with torch.no_grad():  # back to the best weights of the decayed nets
                for kept, p in zip(best.state, self.params, strict=True):
                    p[due] = kept[due]
            quiet = epoch - torch.maximum(best.epoch, self.since)
        return bool(((self.left == 0) & (quiet >= self.config.patience)).all())


def _epoch_order(members: int, n: int, new: int, replay: int, gen: torch.Generator) -> torch.Tensor:
    """The training rows of one epoch, in each member's order (a row per member): all ``n``,
    or with ``replay`` > 0 (a rehearsal) the last ``new`` rows and ``replay`` of the others,
    drawn afresh for each member (every row when there are no more)."""
    old = n - new
    if replay <= 0 or replay >= old:
        return torch.argsort(torch.rand(members, n, generator=gen), dim=1)
    drawn = torch.argsort(torch.rand(members, old, generator=gen), dim=1)[:, :replay]
    rows = torch.cat([drawn, torch.arange(old, n).expand(members, -1)], dim=1)
    shuffle = torch.argsort(torch.rand(members, replay + new, generator=gen), dim=1)
    return rows.gather(1, shuffle)


def _train_epoch(
    model: EnsembleMLP,
    opt: torch.optim.Optimizer,
    train: _Tensors,
    net_mask: torch.Tensor,
    order: torch.Tensor,
    config: TrainConfig,
    rate: _LearningRate,
) -> torch.Tensor:
    """One pass over the training designs in minibatches, each member in its own ``order`` (a
    row per member); the mean training loss of each net."""
    x_tr, z_tr, m_tr, c_tr = train
    model.train()
    total, steps = torch.zeros(model.nets), 0
    for s in range(0, order.shape[1], config.batch_size):
        idx = order[:, s : s + config.batch_size]  # each member its own minibatch
        idx = idx.repeat_interleave(model.n_groups, dim=0)  # shared by the member's group nets
        mean, logvar = model.forward_nets(x_tr[idx])
        loss = gaussian_nll(
            mean, logvar, z_tr[idx], m_tr[idx] * net_mask, config.beta_nll, censor=c_tr[idx]
        )
        opt.zero_grad(set_to_none=True)
        loss.sum().backward()
        rate.before_step()
        opt.step()
        rate.after_step()
        total += loss.detach()
        steps += 1
    return total / steps


#: the coverage the 90 % intervals are calibrated to, and the fewest validation values a metric
#: needs for it (fewer: the ensemble's own spread is kept)
CALIBRATION_COVERAGE = 0.90
CALIBRATION_MIN_N = 20


def calibration_factors(
    mean_z: np.ndarray,
    std_z: np.ndarray,
    z: np.ndarray,
    metric_names: Sequence[str],
    coverage: float = CALIBRATION_COVERAGE,
    min_n: int = CALIBRATION_MIN_N,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Per-metric factors of the ensemble's spread such that the central 90 % interval holds
    ``coverage`` of held-out FE values: split conformal prediction (Vovk et al. 2005; Angelopoulos
    & Bates 2021, "A gentle introduction to conformal prediction", section 2) with the
    normalised score ``r = |z - mean_z| / std_z`` on the validation designs. With ``n`` scores,
    the factor is ``r_(k) / Z90``, ``k = ceil((n + 1) coverage)``: a new design exchangeable with
    them falls inside with probability at least ``coverage``.

    Only FE metrics (``sim.metrics.METRICS``, and the 3D model's ``METRICS_3D``) with ``min_n``
    finite values are calibrated; trust outputs (censored bounds, yes/no flags) keep 1. Returns
    the factors (n_metrics,) and the header's ``calibration`` record."""
    factors = np.ones(len(metric_names))
    fe_metrics = metric_registry("3d")
    with np.errstate(divide="ignore", invalid="ignore"):
        scores = np.abs(np.asarray(z) - mean_z) / std_z
    counts: dict[str, int] = {}
    for j, name in enumerate(metric_names):
        r = scores[:, j]
        r = np.sort(r[np.isfinite(r)])
        counts[name] = int(r.size)
        if name not in fe_metrics or r.size < min_n:
            continue
        k = math.ceil((r.size + 1) * coverage)
        if k <= r.size and r[k - 1] > 0:
            factors[j] = float(r[k - 1]) / Z90
    info = {
        "method": "split conformal on the validation designs, score |z - mean| / std",
        "coverage": coverage,
        "interval_scale": {m: float(f) for m, f in zip(metric_names, factors, strict=True)},
        "n": counts,
    }
    return factors, info


def validation_metrics(
    surrogate: Surrogate, features: np.ndarray, targets: np.ndarray, member_nll: np.ndarray
) -> dict[str, Any]:
    """NLL (normalised units) and per-metric R² on the validation designs."""
    mean_z, std_z = surrogate.predict_normalised(features)
    z = surrogate.normaliser.transform(targets)
    ok = np.isfinite(z)
    with np.errstate(divide="ignore", invalid="ignore"):
        nll = 0.5 * (np.log(2 * np.pi * std_z**2) + (z - mean_z) ** 2 / std_z**2)
    mean = surrogate.normaliser.to_physical(mean_z, std_z)["mean"]
    r2 = {}
    for j, m in enumerate(surrogate.metric_names):
        r2[m] = finite_or_none(r2_score(targets[:, j], mean[:, j]))
    return {
        "n_designs": len(features),
        "member_nll": [float(v) for v in member_nll],
        "ensemble_nll": finite_or_none(nll[ok].mean()) if ok.any() else None,
        "r2": r2,
    }


def r2_score(y: np.ndarray, pred: np.ndarray) -> float:
    """R² over the finite FE values (NaN with fewer than 2 or no spread)."""
    ok = np.isfinite(y) & np.isfinite(pred)
    if ok.sum() < 2:
        return math.nan
    y, pred = y[ok], pred[ok]
    ss_tot = float(((y - y.mean()) ** 2).sum())
    if ss_tot == 0:
        return math.nan
    return 1.0 - float(((y - pred) ** 2).sum()) / ss_tot
