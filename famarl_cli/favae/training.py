"""Fitting FAVAE: the C_last pre-run ("calibration"), the capacity-annealed main fit, and the fit's scores."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
import torch

from famarl_cli.errors import UsageError
from famarl_cli.favae import Capacity
from famarl_cli.favae.loss import capacity, favae_loss, kl_per_dim
from famarl_cli.favae.model import Favae, FavaeConfig, to_input
from famarl_cli.macro_actions import cut_lengths
from famarl_cli.metrics import mig_interval

CALIBRATION_BETA = 0.1
"""The paper's beta for the pre-run that measures C_last (with C = 0)."""


def allocate_capacity(c_last: list[float], allocation: str) -> list[float]:
    """The capacities C_last,l the fit anneals to, from the pre-run's measured ones.

    ``measured``: each ladder keeps the KL the pre-run gave it (the paper's recipe). ``deepest``: the pre-run's total
    goes to the deepest ladder and the others get 0, so the information the data needs is pushed into the ladder
    meant for the factors that shape the whole sequence (the FAVAE authors' tuned capacities for 2D Reaching are
    of this form: 0, 0, 0.99). ``half``: half of each shallower ladder's capacity moves to the deepest.
    """
    if allocation == Capacity.MEASURED:
        return list(c_last)
    if allocation == Capacity.DEEPEST:
        return [0.0] * (len(c_last) - 1) + [float(sum(c_last))]
    if allocation == Capacity.HALF:
        moved = [c / 2 for c in c_last[:-1]]
        return moved + [float(c_last[-1] + sum(moved))]
    raise UsageError(f"capacity allocation must be one of {tuple(map(str, Capacity))}, got {allocation!r}")


@dataclass(frozen=True)
class TrainingParams:
    epochs: int = 1500
    batch_size: int = 64
    learning_rate: float = 1e-3
    seed: int = 0


def train_favae(
    padded: np.ndarray,
    config: FavaeConfig,
    beta: float,
    c_last: list[float],
    params: TrainingParams,
    on_epoch: Callable[[dict], None] | None = None,
) -> tuple[Favae, list[dict]]:
    """Fit a fresh FAVAE on (S, L, D + 2) padded macro actions; returns it and one log row per epoch.

    Each row holds the epoch's means of the loss terms, KL per ladder and the capacity C per ladder.
    """
    if beta < 0:
        raise UsageError(f"beta must be >= 0, got {beta}")
    if len(c_last) != config.ladders:
        raise UsageError(f"C_last has {len(c_last)} values for {config.ladders} ladders")
    data = to_input(padded)
    torch.manual_seed(params.seed)
    model = Favae(config)
    optimiser = torch.optim.Adam(model.parameters(), lr=params.learning_rate)
    shuffle = torch.Generator().manual_seed(params.seed)
    log = []
    for epoch in range(params.epochs):
        capacities = capacity(c_last, epoch, params.epochs)
        sums = np.zeros(4 + config.ladders)
        for batch_index in torch.randperm(len(data), generator=shuffle).split(params.batch_size):
            batch = data[batch_index]
            terms = favae_loss(model(batch), batch, beta, capacities)
            optimiser.zero_grad()
            terms.total.backward()
            optimiser.step()
            values = [terms.total, terms.reconstruction, terms.action_error, terms.on_off, *terms.kl]
            sums += np.array([v.item() for v in values]) * len(batch)
        means = sums / len(data)
        row = {
            "epoch": epoch,
            "loss": means[0],
            "reconstruction": means[1],
            "action_error": means[2],
            "on_off": means[3],
        }
        row.update({f"kl_{i + 1}": means[4 + i] for i in range(config.ladders)})
        row.update({f"capacity_{i + 1}": c for i, c in enumerate(capacities)})
        log.append(row)
        if on_epoch:
            on_epoch(row)
    return model.eval(), log


def calibrate(
    padded: np.ndarray, config: FavaeConfig, params: TrainingParams, on_epoch=None
) -> tuple[list[float], list[dict]]:
    """The C_last pre-run: train with beta = 0.1 and C = 0; each ladder's KL in the last epoch is its C_last."""
    _, log = train_favae(padded, config, CALIBRATION_BETA, [0.0] * config.ladders, params, on_epoch)
    return [float(log[-1][f"kl_{i + 1}"]) for i in range(config.ladders)], log


@torch.no_grad()
def evaluate_fit(model: Favae, padded: np.ndarray, lengths: np.ndarray, factors: np.ndarray) -> dict:
    """Scores of a fitted FAVAE on its segments, decoding posterior means (no sampling).

    - reconstruction: mean squared error per real action step and dimension;
    - length: how often the decoded macro action is cut at the true length, and the mean absolute error;
    - KL per latent dimension (which latents carry information) and per ladder;
    - MIG of the posterior means against the experts' per-segment factors, with bootstrap intervals over the
      segments (:func:`famarl_cli.metrics.mig_interval`).
    """
    output = model(to_input(padded), sample=False)
    decoded = output.reconstruction.numpy().transpose(0, 2, 1)
    on = padded[..., -2]
    squared = ((decoded[..., :-2] - padded[..., :-2]) ** 2).sum(axis=2)
    decoded_lengths = cut_lengths(decoded[..., -2:])
    mu = torch.cat(output.mus, dim=1)
    logvar = torch.cat(output.logvars, dim=1)
    kl_dims = kl_per_dim(mu, logvar).mean(dim=0).numpy()
    splits = np.cumsum(model.config.latent_dims)[:-1]
    score = mig_interval(mu.numpy(), factors)
    return {
        "reconstruction_mse": float((squared * on).sum() / (on.sum() * (padded.shape[2] - 2))),
        "length_accuracy": float(np.mean(decoded_lengths == lengths)),
        "length_mean_abs_error": float(np.mean(np.abs(decoded_lengths - lengths))),
        "kl_per_dim": [float(k) for k in kl_dims],
        "kl_per_ladder": [float(k.sum()) for k in np.split(kl_dims, splits)],
        "mig": score["mig"],
        "mig_interval": score["interval"],
        "mig_per_factor": score["per_factor"],
        "mig_per_factor_interval": score["per_factor_interval"],
        "mig_bins": score["bins"],
        "mig_segments_for_half_width": score["samples_for_half_width"],
    }


def training_summary(params: TrainingParams, beta: float, c_last: list[float]) -> dict:
    return {**asdict(params), "beta": beta, "c_last": list(c_last)}
