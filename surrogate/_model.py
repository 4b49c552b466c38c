"""The deep ensemble: M independent members evaluated as one batched network.

Each member maps encoded design features to a Gaussian per (normalised) metric: a mean and a
log-variance. A member is one MLP per *group* of metrics (by default two: the tapping
protocol's metrics, and the rest), so that metrics of different protocols do not compete for
one hidden representation. All M x G MLPs ("nets") are stacked along a leading axis,
``W[l]`` of shape (M G, in, out), net ``s = m G + g`` for member m and group g; one
``torch.baddbmm`` per layer evaluates every net at once. Nets never share parameters, so
training them together with a summed loss trains them independently (and each keeps its own
early-stopping point). The ensemble is the equal-weight mixture of its members (``mixture``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import torch
from torch import nn

__all__ = [
    "MODELS",
    "ROWS_MULTIPLE",
    "EnsembleMLP",
    "FrozenEnsemble",
    "Workspace",
    "gaussian_nll",
    "member_variance",
    "mixture",
    "mixture_of_variances",
]

#: log-variance bounds in normalised units (a softly clipped head keeps the NLL finite)
LOGVAR_MIN, LOGVAR_MAX = -12.0, 4.0


class EnsembleMLP(nn.Module):
    """``members`` members of one SiLU MLP per metric group, from ``n_inputs`` features to a
    mean and a log-variance for each of ``n_outputs`` normalised metrics.

    ``groups``: the group index of each output (default: one group, a single MLP per member).
    Every net has all ``2 n_outputs`` output units; only its group's are used (and trained).
    The initial weights are drawn from ``seed`` (PyTorch's ``nn.Linear`` rule, uniform
    +-1/sqrt(fan_in)), net after net.
    """

    def __init__(
        self,
        n_inputs: int,
        n_outputs: int,
        *,
        members: int = 5,
        hidden: Sequence[int] = (96, 96),
        groups: Sequence[int] | None = None,
        seed: int,
    ) -> None:
        super().__init__()
        if members < 1:
            raise ValueError(f"members must be >= 1, got {members}")
        groups = tuple(int(g) for g in (groups if groups is not None else [0] * n_outputs))
        numbered = sorted(set(groups)) == list(range(max(groups, default=0) + 1))
        if len(groups) != n_outputs or not numbered:
            raise ValueError(f"groups must number the {n_outputs} outputs 0..G-1, got {groups}")
        self.n_inputs, self.n_outputs, self.members = n_inputs, n_outputs, members
        self.hidden = tuple(int(h) for h in hidden)
        self.groups = groups
        self.n_groups = max(groups, default=0) + 1
        nets = members * self.n_groups
        # (G, m) one-hot: which outputs each group's net gives
        self.register_buffer(
            "group_mask",
            nn.functional.one_hot(torch.tensor(groups), self.n_groups).T.float(),
            persistent=False,
        )
        gen = torch.Generator().manual_seed(int(seed))
        dims = [n_inputs, *self.hidden, 2 * n_outputs]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for d_in, d_out in itertools.pairwise(dims):
            bound = 1.0 / math.sqrt(max(d_in, 1))
            w = (torch.rand(nets, d_in, d_out, generator=gen) * 2 - 1) * bound
            b = (torch.rand(nets, 1, d_out, generator=gen) * 2 - 1) * bound
            self.weights.append(nn.Parameter(w))
            self.biases.append(nn.Parameter(b))

    @property
    def nets(self) -> int:
        """Number of stacked MLPs: members x groups."""
        return self.members * self.n_groups

    def config(self) -> dict:
        return {
            "n_inputs": self.n_inputs,
            "n_outputs": self.n_outputs,
            "members": self.members,
            "hidden": list(self.hidden),
            "groups": list(self.groups),
        }

    def net_mask(self) -> torch.Tensor:
        """(nets, 1, n_outputs): 1 where a net's output belongs to its group."""
        return self.group_mask.repeat(self.members, 1).unsqueeze(1)

    def forward_nets(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Every net's ``(mean, logvar)``, each (nets, n, n_outputs). ``x``: (n, n_inputs)
        shared by every net, or (nets, n, n_inputs) one batch per net."""
        h = x if x.dim() == 3 else x.unsqueeze(0).expand(self.nets, -1, -1)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = torch.baddbmm(b, h, w)
            if i < last:
                h = nn.functional.silu(h)
        return self._head(h, self.n_outputs)

    def _assemble(self, t: torch.Tensor) -> torch.Tensor:
        """(nets, n, m) -> (members, n, m): each output from its group's net."""
        if self.n_groups == 1:
            return t
        t = t.view(self.members, self.n_groups, *t.shape[1:])
        return (t * self.group_mask[None, :, None, :]).sum(dim=1)

    @staticmethod
    def _head(out: torch.Tensor, n_outputs: int) -> tuple[torch.Tensor, torch.Tensor]:
        return out[..., :n_outputs], bounded_logvar(out[..., n_outputs:])

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``x``: (n, n_inputs) shared by every member, or (M, n, n_inputs) one batch per
        member (shared by its group nets). Returns ``(mean, logvar)``, each (M, n, n_outputs)."""
        if x.dim() == 3:
            x = x.repeat_interleave(self.n_groups, dim=0)
        mean, logvar = self.forward_nets(x)
        return self._assemble(mean), self._assemble(logvar)

    def forward_member(self, x: torch.Tensor, k: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Member ``k`` alone, net by net and layer by layer (the reference for the batched
        ``forward``)."""
        mean = torch.empty(len(x), self.n_outputs)
        logvar = torch.empty(len(x), self.n_outputs)
        last = len(self.weights) - 1
        for g in range(self.n_groups):
            s, cols = k * self.n_groups + g, [j for j, gj in enumerate(self.groups) if gj == g]
            h = x
            for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
                h = h @ w[s] + b[s, 0]
                if i < last:
                    h = nn.functional.silu(h)
            mu, lv = self._head(h, self.n_outputs)
            mean[:, cols], logvar[:, cols] = mu[:, cols], lv[:, cols]
        return mean, logvar


#: the rows of a forward pass are padded (with zeros) to a multiple of this: the per-row
#: results of this machine's kernels then do not depend on how many designs share the pass
#: (MKL picks its matrix kernels by shape, and an element-wise kernel takes its last < 32
#: elements through a scalar path with other rounding), so a design's prediction is the same
#: bits alone, in any batch, at any position (tests/test_fast_predict.py)
ROWS_MULTIPLE = 32


def padded_rows(n: int) -> int:
    """``n`` rounded up to a multiple of ``ROWS_MULTIPLE`` (at least one multiple)."""
    return max(-(-n // ROWS_MULTIPLE), 1) * ROWS_MULTIPLE


class FrozenEnsemble:
    """An ``EnsembleMLP``'s weights laid out for prediction only (no autograd), from design
    features to the members' mixture: ``mixture(*model(x))`` to float32 round-off (the mean
    bit for bit on this machine's kernels; the std, through ``member_variance``, within 5e-7
    relative, a few float32 ulps, on the shipped table and on samples of its space), faster:

    - the first layer of every net is one matrix product (all nets read the same features);
    - the last layer of a group's nets computes only the group's outputs (a net computes all
      ``2 n_outputs`` outputs in ``forward``; the other group's are discarded), one batched
      product per group over its members, each padded with zero columns to a multiple of 16
      (one product for every net, padded to the largest group, computed 480 columns where
      these compute 320 with the shipped checkpoint's groups of 6 and 17 metrics), and the
      log-variance head takes only those outputs;
    - the head is ``member_variance``'s closed form (one sigmoid, not two softplus and an
      exp); it and the mixture take every metric at once, group after group (each element's
      result does not depend on its column), and only the mixture's (n, n_outputs) mean and
      std are put back in the metrics' order;
    - every layer writes into buffers of a ``Workspace`` made once per prediction call, not
      one array per layer and batch (fresh memory costs page faults);
    - the rows are padded to a multiple of ``ROWS_MULTIPLE``: a design's bits do not depend
      on the batch it is in.

    A snapshot: made again when the model's weights change (``matches``).
    """

    def __init__(self, model: EnsembleMLP) -> None:
        self.members, self.n_outputs = model.members, model.n_outputs
        self.n_inputs = model.n_inputs
        self.n_groups, self.nets = model.n_groups, model.nets
        self._key = _weights_key(model)
        w = [p.detach() for p in model.weights]
        b = [p.detach() for p in model.biases]
        # (in + 1, nets * h): column block s is net s's first layer, the last row its bias
        # (the features end with a column of ones: x @ w + b in one product, the same bits as
        # torch.addmm, which first copies the bias into every row); None without hidden layers
        self.first = None
        if len(w) > 1:
            self.first = torch.cat(
                [w[0].permute(1, 0, 2).reshape(w[0].shape[1], -1), b[0].reshape(1, -1)]
            ).contiguous()
        self.middle = list(zip(w[1:-1], b[1:-1], strict=True)) if len(w) > 2 else []
        self.hidden = [int(t.shape[-1]) for t in w[:-1]]
        groups = torch.tensor(model.groups)
        self.columns = [torch.nonzero(groups == g).flatten() for g in range(self.n_groups)]
        self.sizes = [len(c) for c in self.columns]
        self.last = self._last_layer(w[-1], b[-1])
        # the outputs come group after group: this index puts them back in the metrics' order
        order = torch.cat(self.columns)
        identity = torch.equal(order, torch.arange(self.n_outputs))
        self.unorder = None if identity else torch.argsort(order)

    def _last_layer(
        self, w: torch.Tensor, b: torch.Tensor
    ) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """Per group, its nets' last layer, the group's outputs only (means then log-variances,
        then zero columns up to a multiple of 16, which a batched product runs faster than the
        2 k columns themselves): (members, h, width) and (members, 1, width)."""
        layers = []
        for g, c in enumerate(self.columns):
            cols = torch.cat([c, self.n_outputs + c])
            nets = torch.arange(self.members) * self.n_groups + g
            width = -(-len(cols) // 16) * 16
            w_out = torch.zeros(self.members, w.shape[1], width)
            b_out = torch.zeros(self.members, 1, width)
            w_out[:, :, : len(cols)] = w[nets][:, :, cols]
            b_out[:, :, : len(cols)] = b[nets][:, :, cols]
            layers.append((w_out, b_out))
        return layers

    def matches(self, model: EnsembleMLP) -> bool:
        """Whether ``model``'s weights are still those of this snapshot."""
        return self._key == _weights_key(model)

    def workspace(self, rows: int) -> Workspace:
        """Buffers for forward passes of up to ``rows`` designs (one per caller: not shared
        between threads)."""
        return Workspace(self, padded_rows(rows))

    def __call__(
        self, x: torch.Tensor, workspace: Workspace | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The mixture's mean and std (each (n, n_outputs), new tensors) of features ``x``
        (n, n_inputs), in ``workspace`` (one for ``n`` rows when None). Call under
        ``torch.inference_mode()``."""
        n = len(x)
        rows = padded_rows(n)
        ws = workspace if workspace is not None and workspace.rows >= rows else None
        ws = ws or self.workspace(n)
        xb = ws.x[:rows]  # the features, then a column of ones
        xb[:n, :-1] = x
        xb[n:, :-1] = 0.0
        if self.first is None:
            h = xb[:, :-1].unsqueeze(0).expand(self.nets, -1, -1)
        else:
            h = ws.view(0, (rows, self.nets * self.hidden[0]))
            torch.mm(xb, self.first, out=h)
            nn.functional.silu(h, inplace=True)
            h = h.view(rows, self.nets, -1).transpose(0, 1)  # (nets, n, h), a view
        for i, (w, b) in enumerate(self.middle, start=1):
            out = ws.view(i, (self.nets, rows, self.hidden[i]))
            h = nn.functional.silu(torch.baddbmm(b, h, w, out=out), inplace=True)
        h = h.unflatten(0, (self.members, self.n_groups))  # (M, groups, n, h), a view
        outs, start = [], 0
        for g, (w, b) in enumerate(self.last):
            out = ws.view(len(self.hidden), (self.members, rows, w.shape[-1]), start)
            outs.append(torch.baddbmm(b, h[:, g], w, out=out))
            start += out.numel()
        # (M, n, n_outputs) each, contiguous, group after group: every element of the
        # element-wise head below takes the same (vectorised) path
        shape = (self.members, rows, self.n_outputs)
        mean, raw = ws.view(-2, shape), ws.view(-1, shape)
        torch.cat([out[:, :, :k] for out, k in zip(outs, self.sizes, strict=True)], 2, out=mean)
        torch.cat([o[:, :, k : 2 * k] for o, k in zip(outs, self.sizes, strict=True)], 2, out=raw)
        mu, sd = mixture_of_variances(mean, member_variance(raw, inplace=True))
        if self.unorder is None:
            return mu[:n], sd[:n]
        return mu[:n].index_select(1, self.unorder), sd[:n].index_select(1, self.unorder)


class Workspace:
    """Preallocated buffers of a ``FrozenEnsemble``'s forward pass for up to ``rows`` rows: the
    padded features (and a column of ones), each hidden layer's activations, the last layer,
    and the mean and raw log-variance of every member."""

    def __init__(self, net: FrozenEnsemble, rows: int) -> None:
        self.rows = rows
        self.x = torch.ones(rows, net.n_inputs + 1)
        sizes = [net.nets * rows * h for h in net.hidden]
        sizes += [net.members * rows * sum(w.shape[-1] for w, _ in net.last)]
        sizes += [net.members * rows * net.n_outputs] * 2
        self._buffers = [torch.empty(s) for s in sizes]

    def view(self, i: int, shape: tuple[int, ...], start: int = 0) -> torch.Tensor:
        """Buffer ``i`` from element ``start`` as a contiguous tensor of ``shape`` (within its
        size)."""
        return self._buffers[i][start : start + math.prod(shape)].view(shape)


def _weights_key(model: EnsembleMLP) -> tuple:
    """Changes whenever a weight tensor is replaced or modified in place."""
    return tuple((id(p), _version(p)) for p in (*model.weights, *model.biases))


def _version(t: torch.Tensor) -> int:
    """The in-place modification counter (-1 for a tensor made in inference mode: none)."""
    try:
        return t._version
    except RuntimeError:
        return -1


def bounded_logvar(raw: torch.Tensor) -> torch.Tensor:
    """A net's raw log-variance outputs, softly clipped to [``LOGVAR_MIN``, ``LOGVAR_MAX``]."""
    logvar = LOGVAR_MAX - nn.functional.softplus(LOGVAR_MAX - raw)
    return LOGVAR_MIN + nn.functional.softplus(logvar - LOGVAR_MIN)


#: architectures by name (the checkpoint records the name and ``config()``)
MODELS: dict[str, type[EnsembleMLP]] = {"ensemble_mlp": EnsembleMLP}


def gaussian_nll(
    mean: torch.Tensor,
    logvar: torch.Tensor,
    y: torch.Tensor,
    mask: torch.Tensor,
    beta: float = 0.0,
    censor: torch.Tensor | None = None,
    cap: float | None = None,
) -> torch.Tensor:
    """Per-member mean Gaussian NLL over the observed entries (``mask``), constant dropped.

    ``mean``, ``logvar``: (M, n, m); ``y``, ``mask``: (M, n, m) or (n, m). Returns (M,).
    ``beta`` > 0: the beta-NLL of Seitzer et al. (ICLR 2022), each entry weighted by
    ``var**beta`` (not differentiated), so that hard designs are fitted rather than explained
    away by a large variance; ``beta = 0`` is the plain NLL.
    ``censor`` (like ``y``): +1 where ``y`` is only a lower bound of the value, -1 an upper
    bound, 0 exact; a bound's entry is the Tobit term -log P(value beyond y) =
    -log Phi(censor (mean - y) / sigma) (a probability: no constant to drop).
    ``cap``: every entry's NLL at most this (a robust score for model selection, not a loss to
    train on: an entry far outside its predicted spread counts as much as one just beyond it).
    """
    nll = 0.5 * (logvar + (y - mean) ** 2 * torch.exp(-logvar))
    if beta:
        nll = nll * torch.exp(beta * logvar).detach()
    if censor is not None and bool(censor.any()):  # none: the very same operations as before
        censor = censor.expand_as(nll)
        t = censor * (mean - y) * torch.exp(-0.5 * logvar)
        nll = torch.where(censor != 0, -torch.special.log_ndtr(t), nll)
    if cap is not None:
        nll = nll.clamp(max=cap)
    mask = mask.expand_as(nll)
    return (nll * mask).sum(dim=(1, 2)) / mask.sum(dim=(1, 2)).clamp(min=1)


def mixture(mean: torch.Tensor, logvar: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The equal-weight mixture of the members' Gaussians: mean and std, each (n, m)."""
    return mixture_of_variances(mean, torch.exp(logvar))


def mixture_of_variances(
    mean: torch.Tensor, var: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """``mixture`` of members given by their means and variances (M, n, m)."""
    mu = mean.mean(dim=0)
    var = var.mean(dim=0) + ((mean - mu) ** 2).mean(dim=0)
    return mu, torch.sqrt(var)


def member_variance(raw: torch.Tensor, *, inplace: bool = False) -> torch.Tensor:
    """``exp(bounded_logvar(raw))`` in closed form: since ``exp(softplus(z)) = 1 + exp(z)``,
    ``exp(LOGVAR_MIN) + exp(LOGVAR_MAX) sigmoid(raw - LOGVAR_MAX)``. One sigmoid instead of two
    softplus and an exp (five transcendental functions an element): the prediction path's
    head, several times faster and closer to the exact value in float32 (largest relative error
    on raw in [-40, 40]: 6.9e-7, against 1.5e-6 for the composed functions; the two differ by
    at most 1.3e-6). Softplus's linear branch above 20 changes it by e^-20 relative. In place
    of ``raw`` if ``inplace``."""
    z = raw.sub_(LOGVAR_MAX) if inplace else raw - LOGVAR_MAX
    z = torch.sigmoid(z, out=z)
    return z.mul_(math.exp(LOGVAR_MAX)).add_(math.exp(LOGVAR_MIN))
