"""The FAVAE loss: reconstruction + beta * sum over ladders of |X_l - C_l| (capacity-controlled, CCI-VAE).

Reconstruction, per macro action and averaged over the batch:
- squared error of the action channels, summed over the *real* steps and action dimensions (padding is not an
  action: the decoder's values there are never executed, so they are not penalised), plus
- cross-entropy of the on/off logits against ``action_on`` / ``action_off``, summed over all L steps (this is what
  teaches the decoder where to cut).
Summing over steps (rather than averaging) keeps reconstruction on the scale of a log-likelihood, so beta means
what it means in beta-VAE papers.

X_l is what the capacity C_l constrains (:class:`~famarl_cli.method.favae.Measure`). The paper's is KL_l, the KL
divergence of ladder l's Gaussian posterior from N(0, I), summed over its dims, averaged over the segments. Averaged
over the data, that KL is the sum of two parts:

    E_x KL(q(z|x) || p(z)) = I(x; z) + KL(q(z) || p(z)),   q(z) = (1/N) sum_n q(z | x_n)  (the aggregate posterior)

I(x; z), the mutual information between the N segments and the latent, is what the latent says about which segment
it encodes; it cannot exceed log N, whatever the posterior's precision. The second part is what the aggregate
posterior's position and spread cost against the prior. A posterior shifted alike for every segment, or narrowed
alike for all, raises that part, not I. Under ``measure="kl"`` such a shift meets a capacity and carries nothing
(on our demos the fit met ladder 3's capacity with a shift of about 3.4, docs/favae.md); under
``measure="information"`` the capacity constrains I, and the rest of the KL is penalised with beta on its own, so only
information about the segments can meet a capacity and the aggregate is held at the prior the RL policy samples from.

I is estimated from samples z_i ~ q(z | x_i) as the mean of log q(z_i | x_i) - log q(z_i), each term at most log N
(q(z_i) >= q(z_i | x_i) / N): in training over the batch, with the mixture's other N - 1 components estimated by the
batch's other B - 1, each weighted by (N - 1) / (N (B - 1)) (an importance-weighted mixture in the manner of the
minibatch estimates of Chen et al. 2018, "Isolating Sources of Disentanglement in VAEs"), in a fit's scores
exactly over all N segments (:func:`data_information`). (An earlier estimate, the Gaussian bound
1/2 [log(Var(mu) + E[sigma^2]) - E[log sigma^2]], grew without limit as sigma shrank: a posterior met its capacity
by becoming precise rather than informative, reporting 6-7 nats about 111 segments.)

C_l rises linearly over the epochs from 0 to C_last,l (:func:`capacity`).
"""

from __future__ import annotations

import itertools
import math
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
    """Per ladder, the information its latent carries about the segments (I above, at most log N)."""


def kl_per_dim(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(..., B, dims) KL divergence of each Gaussian posterior dimension from N(0, 1)."""
    return -0.5 * (1 + logvar - mu.pow(2) - logvar.exp())


def _batch_mean(values: torch.Tensor, rows: torch.Tensor | None) -> torch.Tensor:
    """(..., B, dims) -> (..., dims): the mean over the batch, or over its rows where ``rows`` (..., B) is 1."""
    if rows is None:
        return values.mean(dim=-2)
    return (values * rows[..., None]).sum(dim=-2) / rows.sum(dim=-1, keepdim=True).clamp(min=1)


_LOG_2PI = math.log(2 * math.pi)


def log_density(z: torch.Tensor, mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """(..., B, B', dims): log q(z_i | x_j) of each sample i (``z`` (..., B, dims)) under each posterior j (``mu``,
    ``logvar`` (..., B', dims)), per dimension."""
    centred = z[..., :, None, :] - mu[..., None, :, :]
    return -0.5 * (_LOG_2PI + logvar[..., None, :, :] + centred.pow(2) * (-logvar[..., None, :, :]).exp())


def _mixture_weights(rows: torch.Tensor, population: torch.Tensor) -> torch.Tensor:
    """(..., B, B) log w_ij of the stratified estimate of the aggregate posterior at sample i: its own posterior
    weighs 1/N, each of the batch's B - 1 others (N - 1) / (N (B - 1)), standing for the N - 1 segments not its own;
    padding rows j (``rows`` 0) weigh 0, a row's own posterior always 1/N (so every row's estimate is finite)."""
    count = rows.sum(dim=-1)
    n = population.to(rows.dtype).expand_as(count)
    other = torch.where(count > 1, (n - 1) / (n * (count - 1).clamp(min=1)), torch.zeros_like(n)).log()
    eye = torch.eye(rows.shape[-1], dtype=torch.bool, device=rows.device)
    weights = torch.where(eye, -n.log()[..., None, None], other[..., None, None])
    return weights.masked_fill(~eye & (rows[..., None, :] == 0), -torch.inf)


def information(
    z: torch.Tensor,
    mu: torch.Tensor,
    logvar: torch.Tensor,
    population: torch.Tensor | float,
    rows: torch.Tensor | None = None,
) -> torch.Tensor:
    """(...,) the information (nats) a latent of ``dims`` carries about the N = ``population`` segments a batch is
    drawn from, estimated from the batch's samples ``z`` (..., B, dims) of its posteriors (``mu``, ``logvar``): the
    mean over its (real) rows of log q(z_i | x_i) - log q(z_i), each at most log N (module docstring)."""
    real = z.new_ones(z.shape[:-1]) if rows is None else rows
    pairs = log_density(z, mu, logvar).sum(dim=-1)  # (..., B, B): the latent's dims jointly
    own = pairs.diagonal(dim1=-2, dim2=-1)
    weights = _mixture_weights(real, torch.as_tensor(population, dtype=z.dtype))
    terms = own - torch.logsumexp(pairs + weights, dim=-1)
    return _batch_mean(terms[..., None], rows)[..., 0]


DATA_SAMPLES = 64
"""The most samples per segment behind :func:`data_information`."""
DATA_PAIRS = 2**20
"""Its budget of (sample, posterior) pairs: with more segments, fewer samples each (at least one), so a data set of
20,000 sequences costs 1 sample each, not 64 (each sample is a pass over all N^2 pairs)."""


@torch.no_grad()
def data_information(
    mu: torch.Tensor, logvar: torch.Tensor, groups: list[int], samples: int | None = None, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor]:
    """The information each latent dimension, and each group of ``groups`` consecutive dimensions (a ladder) jointly,
    carries about the N segments whose posteriors are ``mu``, ``logvar`` (N, dims): the mean over segments i and
    ``samples`` draws z ~ q(z | x_i) of log q(z | x_i) - log (1/N) sum_n q(z | x_n), the aggregate posterior exact
    over the data set. Every term is at most log N, so every estimate is; the draws come from a generator of
    ``seed``, so the same posteriors give the same numbers. ``samples`` defaults to :data:`DATA_SAMPLES`, fewer where
    N^2 of them would pass :data:`DATA_PAIRS` (64 up to N = 128). Returns (dims,) and (len(groups),)."""
    n, dims = mu.shape
    if samples is None:
        samples = max(1, min(DATA_SAMPLES, DATA_PAIRS // n**2))
    generator = torch.Generator().manual_seed(seed)
    per_dim, per_group = torch.zeros(dims, dtype=torch.float64), torch.zeros(len(groups), dtype=torch.float64)
    bounds = [0, *itertools.accumulate(groups)]
    chunk = max(1, 2**22 // max(n * dims, 1))  # rows per step, so that one step holds ~4M densities
    mixture = math.log(n)
    for _ in range(samples):
        z = mu + torch.randn(mu.shape, generator=generator) * (0.5 * logvar).exp()
        for first in range(0, n, chunk):
            rows = torch.arange(first, min(first + chunk, n))
            pairs = log_density(z[rows], mu, logvar)  # (chunk, N, dims)
            own = pairs[torch.arange(len(rows)), rows]  # (chunk, dims)
            per_dim += (own - (torch.logsumexp(pairs, dim=1) - mixture)).sum(dim=0).double()
            for g, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
                joint = pairs[..., a:b].sum(dim=-1)
                per_group[g] += (own[:, a:b].sum(dim=-1) - (torch.logsumexp(joint, dim=1) - mixture)).sum().double()
    return (per_dim / (n * samples)).float(), (per_group / (n * samples)).float()


def replicate_loss(
    reconstruction: torch.Tensor,
    x: torch.Tensor,
    mus: list[torch.Tensor],
    logvars: list[torch.Tensor],
    samples: list[torch.Tensor],
    beta: torch.Tensor,
    capacities: torch.Tensor,
    population: torch.Tensor,
    measure: str = Measure.INFORMATION,
    rows: torch.Tensor | None = None,
    steps: torch.Tensor | None = None,
) -> LossTerms:
    """The loss of K replicates at once, channels last: ``reconstruction`` and ``x`` are (K, B, L, D + 2), ``mus``,
    ``logvars`` and the latents ``samples`` drawn from them per ladder (K, B, z), ``beta`` (K,), ``capacities``
    (K, ladders) the C_l of each, ``population`` (K,) the number of segments each replicate's batches are drawn
    from; ``rows`` (K, B) marks each replicate's real rows of a padded batch and ``steps`` (K, L) its own steps of a
    padded L (None: all real). ``measure`` says what the capacities constrain (module docstring)."""
    # a fill, not a tensor from a Python number: a host-to-device copy cannot be part of a CUDA graph
    count = x.new_full((x.shape[0],), x.shape[1]) if rows is None else rows.sum(dim=1).clamp(min=1)
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
    carried = [information(z, mu, lv, population, rows) for z, mu, lv in zip(samples, mus, logvars, strict=True)]
    if measure == Measure.KL:
        penalty = sum((k - capacities[:, i]).abs() for i, k in enumerate(kl))
    else:
        # |I - C| + M: the rest of the KL, M = KL - I, is paid in full and never counts towards a capacity
        penalty = sum(
            (inf - capacities[:, i]).abs() + (k - inf) for i, (k, inf) in enumerate(zip(kl, carried, strict=True))
        )
    reconstruction_term = action_error + on_off
    return LossTerms(reconstruction_term + beta * penalty, reconstruction_term, action_error, on_off, kl, carried)


def favae_loss(
    output: FavaeOutput, x: torch.Tensor, beta: float, capacities: list[float], measure: str = Measure.INFORMATION
) -> LossTerms:
    """One model's loss (:func:`replicate_loss` with K = 1), as scalars: ``x`` is the (B, D + 2, L) input the
    output reconstructs, the whole population its information is about; ``capacities`` holds C_l for each ladder.
    The one-model form ``benchmarks/favae_step.py`` times and the tests hold the batched loss to; fits train with
    :func:`replicate_loss`."""
    terms = replicate_loss(
        output.reconstruction.transpose(1, 2)[None],
        x.transpose(1, 2)[None],
        [mu[None] for mu in output.mus],
        [lv[None] for lv in output.logvars],
        [z[None] for z in output.samples],
        x.new_tensor([beta]),
        x.new_tensor([capacities]),
        x.new_tensor([x.shape[0]]),
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
