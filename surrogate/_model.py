"""The deep ensemble: M independent MLPs evaluated as one batched network.

Each member maps encoded design features to a Gaussian per (normalised) metric: a mean and a
log-variance. Member weights are stacked along a leading member axis, ``W[l]`` of shape
(M, in, out), so one ``torch.baddbmm`` per layer evaluates every member at once; members never
share parameters, so training them together with a summed loss trains them independently.
The ensemble is the equal-weight mixture of its members (``mixture``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import torch
from torch import nn

__all__ = ["MODELS", "EnsembleMLP", "gaussian_nll", "mixture"]

#: log-variance bounds in normalised units (a softly clipped head keeps the NLL finite)
LOGVAR_MIN, LOGVAR_MAX = -12.0, 4.0


class EnsembleMLP(nn.Module):
    """``members`` MLPs with SiLU hidden layers, from ``n_inputs`` features to a mean and a
    log-variance for each of ``n_outputs`` normalised metrics.

    The initial weights are drawn from ``seed`` (PyTorch's ``nn.Linear`` rule, uniform
    +-1/sqrt(fan_in)), member after member.
    """

    def __init__(
        self,
        n_inputs: int,
        n_outputs: int,
        *,
        members: int = 5,
        hidden: Sequence[int] = (96, 96),
        seed: int,
    ) -> None:
        super().__init__()
        if members < 1:
            raise ValueError(f"members must be >= 1, got {members}")
        self.n_inputs, self.n_outputs, self.members = n_inputs, n_outputs, members
        self.hidden = tuple(int(h) for h in hidden)
        gen = torch.Generator().manual_seed(int(seed))
        dims = [n_inputs, *self.hidden, 2 * n_outputs]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for d_in, d_out in itertools.pairwise(dims):
            bound = 1.0 / math.sqrt(max(d_in, 1))
            w = (torch.rand(members, d_in, d_out, generator=gen) * 2 - 1) * bound
            b = (torch.rand(members, 1, d_out, generator=gen) * 2 - 1) * bound
            self.weights.append(nn.Parameter(w))
            self.biases.append(nn.Parameter(b))

    def config(self) -> dict:
        return {
            "n_inputs": self.n_inputs,
            "n_outputs": self.n_outputs,
            "members": self.members,
            "hidden": list(self.hidden),
        }

    @staticmethod
    def _head(out: torch.Tensor, n_outputs: int) -> tuple[torch.Tensor, torch.Tensor]:
        mean, raw = out[..., :n_outputs], out[..., n_outputs:]
        logvar = LOGVAR_MAX - nn.functional.softplus(LOGVAR_MAX - raw)
        logvar = LOGVAR_MIN + nn.functional.softplus(logvar - LOGVAR_MIN)
        return mean, logvar

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``x``: (n, n_inputs) shared by every member, or (M, n, n_inputs) one batch per
        member. Returns ``(mean, logvar)``, each (M, n, n_outputs)."""
        h = x if x.dim() == 3 else x.unsqueeze(0).expand(self.members, -1, -1)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = torch.baddbmm(b, h, w)
            if i < last:
                h = nn.functional.silu(h)
        return self._head(h, self.n_outputs)

    def forward_member(self, x: torch.Tensor, k: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Member ``k`` alone, layer by layer (the reference for the batched ``forward``)."""
        h = x
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ w[k] + b[k, 0]
            if i < last:
                h = nn.functional.silu(h)
        return self._head(h, self.n_outputs)


#: architectures by name (the checkpoint records the name and ``config()``)
MODELS: dict[str, type[EnsembleMLP]] = {"ensemble_mlp": EnsembleMLP}


def gaussian_nll(
    mean: torch.Tensor,
    logvar: torch.Tensor,
    y: torch.Tensor,
    mask: torch.Tensor,
    beta: float = 0.0,
) -> torch.Tensor:
    """Per-member mean Gaussian NLL over the observed entries (``mask``), constant dropped.

    ``mean``, ``logvar``: (M, n, m); ``y``, ``mask``: (M, n, m) or (n, m). Returns (M,).
    ``beta`` > 0: the beta-NLL of Seitzer et al. (ICLR 2022), each entry weighted by
    ``var**beta`` (not differentiated), so that hard designs are fitted rather than explained
    away by a large variance; ``beta = 0`` is the plain NLL.
    """
    nll = 0.5 * (logvar + (y - mean) ** 2 * torch.exp(-logvar))
    if beta:
        nll = nll * torch.exp(beta * logvar).detach()
    mask = mask.expand_as(nll)
    return (nll * mask).sum(dim=(1, 2)) / mask.sum(dim=(1, 2)).clamp(min=1)


def mixture(mean: torch.Tensor, logvar: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The equal-weight mixture of the members' Gaussians: mean and std, each (n, m)."""
    mu = mean.mean(dim=0)
    var = torch.exp(logvar).mean(dim=0) + ((mean - mu) ** 2).mean(dim=0)
    return mu, torch.sqrt(var)
