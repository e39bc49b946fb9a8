"""The FAVAE loss: reconstruction + beta * sum over ladders of |X_l - C_l| (capacity-controlled, CCI-VAE).

Reconstruction, per macro action and averaged over the batch:
- squared error of the action channels, summed over the *real* steps and action dimensions (padding is not an
  action: the decoder's values there are never executed, so they are not penalised), plus
- cross-entropy of the on/off logits against ``action_on`` / ``action_off``, summed over all L steps (this is what
  teaches the decoder where to cut).
Summing over steps (rather than averaging) keeps reconstruction on the scale of a log-likelihood, so beta means
what it means in beta-VAE papers.

X_l is what the capacity C_l constrains (:class:`~famarl_cli.method.favae.Measure`). The paper's is KL_l, the KL
divergence of ladder l's Gaussian posterior from N(0, I), summed over its dims, averaged over the batch. That KL is
the sum of two parts (:func:`information_per_dim`, :func:`marginal_per_dim`):

    mean KL = I + M,  I = 1/2 [log(Var(mu) + E[sigma^2]) - E[log sigma^2]],
                      M = KL( N(mean mu, Var(mu) + E[sigma^2]) || N(0, 1) )     (per dimension, over the batch)

I is an upper bound on the mutual information between the segments and the latent (the Gaussian of the same
variance has the largest entropy), and it is 0 when the posterior does not depend on the input; M is what the
aggregate posterior's mean and spread cost against the prior. A posterior shifted by the same amount for every
segment, or narrowed alike for all, raises M, not I. Under ``measure="kl"`` such a shift meets a capacity and
carries nothing (on our demos the fit met ladder 3's capacity with a shift of about 3.4, docs/favae.md); under
``measure="information"`` the capacity constrains I, and M is penalised with beta on its own, so only information
about the segments can meet a capacity and the aggregate is held at the prior the RL policy samples from.

C_l rises linearly over the epochs from 0 to C_last,l (:func:`capacity`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch.nn import functional

from famarl_cli.method.favae import Measure
from famarl_cli.method.favae.model import FavaeOutput


@dataclass
class LossTerms:
    total: torch.Tensor
    reconstruction: torch.Tensor
    action_error: torch.Tensor
    on_off: torch.Tensor
    kl: list[torch.Tensor]
    """Per ladder, the mean KL from the prior."""
    information: list[torch.Tensor]
    """Per ladder, the part of the KL that varies with the input (I above)."""


def kl_per_dim(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(B, dims) KL divergence of each Gaussian posterior dimension from N(0, 1)."""
    return -0.5 * (1 + logvar - mu.pow(2) - logvar.exp())


def _spread(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(dims,) the aggregate posterior's variance over the batch: Var(mu) + E[sigma^2]."""
    return mu.var(dim=0, unbiased=False) + logvar.exp().mean(dim=0)


def information_per_dim(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(dims,) I, the Gaussian bound on the information each latent carries about the batch's inputs (nats)."""
    return 0.5 * (_spread(mu, logvar).log() - logvar.mean(dim=0))


def marginal_per_dim(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(dims,) M, the KL of the batch's moment-matched aggregate posterior from N(0, 1): mean KL = I + M."""
    spread = _spread(mu, logvar)
    return 0.5 * (mu.mean(dim=0).pow(2) + spread - 1 - spread.log())


def kl_per_ladder(output: FavaeOutput) -> list[torch.Tensor]:
    return [kl_per_dim(mu, lv).sum(dim=1).mean() for mu, lv in zip(output.mus, output.logvars, strict=True)]


def information_per_ladder(output: FavaeOutput) -> list[torch.Tensor]:
    return [information_per_dim(mu, lv).sum() for mu, lv in zip(output.mus, output.logvars, strict=True)]


def favae_loss(
    output: FavaeOutput, x: torch.Tensor, beta: float, capacities: list[float], measure: str = Measure.INFORMATION
) -> LossTerms:
    """``x`` is the (B, D + 2, L) input the output reconstructs; ``capacities`` holds C_l for each ladder;
    ``measure`` says what they constrain (module docstring)."""
    on = x[:, -2, :]
    actions, target = output.reconstruction[:, :-2, :], x[:, :-2, :]
    action_error = ((actions - target).pow(2) * on.unsqueeze(1)).sum(dim=(1, 2)).mean()
    on_off = functional.cross_entropy(output.reconstruction[:, -2:, :], x[:, -1, :].long(), reduction="sum") / len(x)
    kl = kl_per_ladder(output)
    information = information_per_ladder(output)
    if measure == Measure.KL:
        penalty = sum((k - c).abs() for k, c in zip(kl, capacities, strict=True))
    else:
        # |I - C| + M: the rest of the KL, M = KL - I, is paid in full and never counts towards a capacity
        penalty = sum((i - c).abs() + (k - i) for k, i, c in zip(kl, information, capacities, strict=True))
    reconstruction = action_error + on_off
    return LossTerms(reconstruction + beta * penalty, reconstruction, action_error, on_off, kl, information)


def capacity(c_last: list[float], epoch: int, epochs: int) -> list[float]:
    """C_l at ``epoch`` (0-based): 0 at the first epoch, rising linearly to C_last,l at the last."""
    fraction = epoch / (epochs - 1) if epochs > 1 else 1.0
    return [c * fraction for c in c_last]
