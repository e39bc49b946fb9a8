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
    """Each term per replicate, (K,) (a single model's: K = 1, or scalars from :func:`favae_loss`)."""

    total: torch.Tensor
    reconstruction: torch.Tensor
    action_error: torch.Tensor
    on_off: torch.Tensor
    kl: list[torch.Tensor]
    """Per ladder, the mean KL from the prior."""
    information: list[torch.Tensor]
    """Per ladder, the part of the KL that varies with the input (I above)."""


def kl_per_dim(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(..., B, dims) KL divergence of each Gaussian posterior dimension from N(0, 1)."""
    return -0.5 * (1 + logvar - mu.pow(2) - logvar.exp())


def _batch_mean(values: torch.Tensor, rows: torch.Tensor | None) -> torch.Tensor:
    """(..., B, dims) -> (..., dims): the mean over the batch, or over its rows where ``rows`` (..., B) is 1."""
    if rows is None:
        return values.mean(dim=-2)
    return (values * rows[..., None]).sum(dim=-2) / rows.sum(dim=-1, keepdim=True).clamp(min=1)


def _spread(mu: torch.Tensor, logvar: torch.Tensor, rows: torch.Tensor | None) -> torch.Tensor:
    """(..., dims) the aggregate posterior's variance over the batch: Var(mu) + E[sigma^2]."""
    centred = mu - _batch_mean(mu, rows)[..., None, :]
    return _batch_mean(centred.pow(2), rows) + _batch_mean(logvar.exp(), rows)


def information_per_dim(mu: torch.Tensor, logvar: torch.Tensor, rows: torch.Tensor | None = None) -> torch.Tensor:
    """(..., dims) I, the Gaussian bound on the information each latent carries about the batch's inputs (nats);
    ``rows`` (..., B) marks the batch's real rows where it is padded."""
    return 0.5 * (_spread(mu, logvar, rows).log() - _batch_mean(logvar, rows))


def marginal_per_dim(mu: torch.Tensor, logvar: torch.Tensor, rows: torch.Tensor | None = None) -> torch.Tensor:
    """(..., dims) M, the KL of the batch's moment-matched aggregate posterior from N(0, 1): mean KL = I + M."""
    spread = _spread(mu, logvar, rows)
    return 0.5 * (_batch_mean(mu, rows).pow(2) + spread - 1 - spread.log())


def kl_per_ladder(output: FavaeOutput) -> list[torch.Tensor]:
    return [kl_per_dim(mu, lv).sum(dim=1).mean() for mu, lv in zip(output.mus, output.logvars, strict=True)]


def replicate_loss(
    reconstruction: torch.Tensor,
    x: torch.Tensor,
    mus: list[torch.Tensor],
    logvars: list[torch.Tensor],
    beta: torch.Tensor,
    capacities: torch.Tensor,
    measure: str = Measure.INFORMATION,
    rows: torch.Tensor | None = None,
    steps: torch.Tensor | None = None,
) -> LossTerms:
    """The loss of K replicates at once, channels last: ``reconstruction`` and ``x`` are (K, B, L, D + 2), ``mus``
    and ``logvars`` per ladder (K, B, z), ``beta`` (K,), ``capacities`` (K, ladders) the C_l of each; ``rows``
    (K, B) marks each replicate's real rows of a padded batch and ``steps`` (K, L) its own steps of a padded L
    (None: all real). ``measure`` says what the capacities constrain (module docstring)."""
    count = x.new_tensor(x.shape[1]).expand(x.shape[0]) if rows is None else rows.sum(dim=1).clamp(min=1)
    on = x[..., -2]  # zero on padded rows and steps, as on each macro's own padding
    action_error = ((reconstruction[..., :-2] - x[..., :-2]).pow(2) * on[..., None]).sum(dim=(1, 2, 3)) / count
    # cross-entropy of the on/off logits against the target (class 1 where action_off): softplus of the other
    # logit's margin
    margin = reconstruction[..., -1] - reconstruction[..., -2]
    cross_entropy = functional.softplus((1 - 2 * x[..., -1]) * margin)
    if steps is not None:
        cross_entropy = cross_entropy * steps[:, None, :]
    if rows is not None:
        cross_entropy = cross_entropy * rows[..., None]
    on_off = cross_entropy.sum(dim=(1, 2)) / count
    kl = [_batch_mean(kl_per_dim(mu, lv), rows).sum(dim=-1) for mu, lv in zip(mus, logvars, strict=True)]
    information = [information_per_dim(mu, lv, rows).sum(dim=-1) for mu, lv in zip(mus, logvars, strict=True)]
    if measure == Measure.KL:
        penalty = sum((k - capacities[:, i]).abs() for i, k in enumerate(kl))
    else:
        # |I - C| + M: the rest of the KL, M = KL - I, is paid in full and never counts towards a capacity
        penalty = sum(
            (inf - capacities[:, i]).abs() + (k - inf) for i, (k, inf) in enumerate(zip(kl, information, strict=True))
        )
    reconstruction_term = action_error + on_off
    return LossTerms(reconstruction_term + beta * penalty, reconstruction_term, action_error, on_off, kl, information)


def favae_loss(
    output: FavaeOutput, x: torch.Tensor, beta: float, capacities: list[float], measure: str = Measure.INFORMATION
) -> LossTerms:
    """One model's loss (:func:`replicate_loss` with K = 1), as scalars: ``x`` is the (B, D + 2, L) input the
    output reconstructs; ``capacities`` holds C_l for each ladder."""
    terms = replicate_loss(
        output.reconstruction.transpose(1, 2)[None],
        x.transpose(1, 2)[None],
        [mu[None] for mu in output.mus],
        [lv[None] for lv in output.logvars],
        x.new_tensor([beta]),
        x.new_tensor([capacities]),
        measure,
    )
    return LossTerms(
        terms.total[0],
        terms.reconstruction[0],
        terms.action_error[0],
        terms.on_off[0],
        [k[0] for k in terms.kl],
        [i[0] for i in terms.information],
    )


def capacity(c_last: list[float], epoch: int, epochs: int) -> list[float]:
    """C_l at ``epoch`` (0-based): 0 at the first epoch, rising linearly to C_last,l at the last."""
    fraction = epoch / (epochs - 1) if epochs > 1 else 1.0
    return [c * fraction for c in c_last]
