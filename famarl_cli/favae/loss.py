"""The FAVAE loss: reconstruction + beta * sum over ladders of |KL_l - C_l| (capacity-controlled, CCI-VAE).

Reconstruction, per macro action and averaged over the batch:
- squared error of the action channels, summed over the *real* steps and action dimensions (padding is not an
  action: the decoder's values there are never executed, so they are not penalised), plus
- cross-entropy of the on/off logits against ``action_on`` / ``action_off``, summed over all L steps (this is what
  teaches the decoder where to cut).
Summing over steps (rather than averaging) keeps reconstruction on the scale of a log-likelihood, so beta means
what it means in beta-VAE papers.

KL_l is the KL divergence of ladder l's Gaussian posterior from N(0, I), summed over its dims, averaged over the
batch. C_l rises linearly over the epochs from 0 to C_last,l (:func:`capacity`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch.nn import functional

from famarl_cli.favae.model import FavaeOutput


@dataclass
class LossTerms:
    total: torch.Tensor
    reconstruction: torch.Tensor
    action_error: torch.Tensor
    on_off: torch.Tensor
    kl: list[torch.Tensor]


def kl_per_dim(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(B, dims) KL divergence of each Gaussian posterior dimension from N(0, 1)."""
    return -0.5 * (1 + logvar - mu.pow(2) - logvar.exp())


def kl_per_ladder(output: FavaeOutput) -> list[torch.Tensor]:
    return [kl_per_dim(mu, lv).sum(dim=1).mean() for mu, lv in zip(output.mus, output.logvars, strict=True)]


def favae_loss(output: FavaeOutput, x: torch.Tensor, beta: float, capacities: list[float]) -> LossTerms:
    """``x`` is the (B, D + 2, L) input the output reconstructs; ``capacities`` holds C_l for each ladder."""
    on = x[:, -2, :]
    actions, target = output.reconstruction[:, :-2, :], x[:, :-2, :]
    action_error = ((actions - target).pow(2) * on.unsqueeze(1)).sum(dim=(1, 2)).mean()
    on_off = functional.cross_entropy(output.reconstruction[:, -2:, :], x[:, -1, :].long(), reduction="sum") / len(x)
    kl = kl_per_ladder(output)
    penalty = sum((k - c).abs() for k, c in zip(kl, capacities, strict=True))
    reconstruction = action_error + on_off
    return LossTerms(reconstruction + beta * penalty, reconstruction, action_error, on_off, kl)


def capacity(c_last: list[float], epoch: int, epochs: int) -> list[float]:
    """C_l at ``epoch`` (0-based): 0 at the first epoch, rising linearly to C_last,l at the last."""
    fraction = epoch / (epochs - 1) if epochs > 1 else 1.0
    return [c * fraction for c in c_last]
