"""Fitting FAVAE: the C_last pre-run ("calibration"), the capacity-annealed main fit, and the fit's scores.

Both phases can be progressive (pro-VLAE, Li et al. 2020): the deepest ladder trains alone first and the shallower
ones are faded in one at a time (:func:`ladder_weights`), so the deepest takes the factors that shape the whole
sequence before a shallower ladder can, and what is left (detail) goes to the shallower ones. A ladder not yet in
has capacity 0, so the KL term holds its posterior at the prior (pro-VLAE's penalty on inactive latents).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
import torch

from famarl_cli.core.declare import default_of
from famarl_cli.core.errors import UsageError
from famarl_cli.core.macro_actions import cut_lengths
from famarl_cli.method.favae import CALIBRATION_BETA, MAX_PROGRESSIVE, Capacity, FavaeOptions, Measure
from famarl_cli.method.favae.loss import capacity, favae_loss, information_per_dim, kl_per_dim, marginal_per_dim
from famarl_cli.method.favae.model import Favae, FavaeConfig, to_input
from famarl_cli.method.metrics import mig_interval

ACTIVE_VARIANCE = 0.01
"""A latent whose posterior mean varies over the segments by more than this (variance) is active (Burda et al.
2016's active units); below it the latent says the same of every segment, whatever its KL."""
FADE_SHARE = 0.25
"""Share of a progressive stage over which its new ladder fades in (its weight rising from 0 to 1)."""


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
    epochs: int = default_of(FavaeOptions, "epochs")
    batch_size: int = 64
    learning_rate: float = 1e-3
    seed: int = default_of(FavaeOptions, "seed")
    measure: str = default_of(FavaeOptions, "capacity_measure").value
    """What the capacities constrain: the information each ladder carries, or its KL
    (:mod:`~famarl_cli.method.favae.loss`)."""
    progressive: float = default_of(FavaeOptions, "progressive")
    """Share of the epochs over which the ladders are added one by one, deepest first (0: all from the start)."""

    @staticmethod
    def of(options: FavaeOptions) -> TrainingParams:
        """The training that ``options`` declare (batch size and learning rate are the method's)."""
        return TrainingParams(
            epochs=options.epochs,
            seed=options.seed,
            measure=str(options.capacity_measure),
            progressive=options.progressive,
        )

    def __post_init__(self) -> None:
        if self.measure not in tuple(Measure):
            raise UsageError(f"capacity measure must be one of {tuple(map(str, Measure))}, got {self.measure!r}")
        if not 0.0 <= self.progressive <= MAX_PROGRESSIVE:
            raise UsageError(f"progressive must be in [0, {MAX_PROGRESSIVE}], got {self.progressive}")


def ladder_weights(epoch: int, epochs: int, ladders: int, progressive: float) -> list[float]:
    """The weight of each ladder's latent in the decoder at ``epoch`` (0-based), shallowest first.

    The deepest ladder is always in. With ``progressive`` p > 0 the first p of the epochs are split into
    ``ladders - 1`` equal stages: the deepest trains alone in the first, and at the end of each stage the next
    ladder, counted from the deepest, begins to fade in, its weight rising linearly from 0 to 1 over
    :data:`FADE_SHARE` of a stage. Ladder l < ladders enters at epoch ``p * epochs * (ladders - l) / (ladders - 1)``,
    so the shallowest enters at p * epochs. p = 0: all weights 1 from the start.
    """
    if progressive <= 0 or ladders == 1:
        return [1.0] * ladders
    stage = progressive * epochs / (ladders - 1)
    fade = max(FADE_SHARE * stage, 1.0)
    starts = [stage * (ladders - ladder) for ladder in range(1, ladders)] + [-fade]
    return [min(max((epoch + 1 - start) / fade, 0.0), 1.0) for start in starts]


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
    ladders = config.ladders
    for epoch in range(params.epochs):
        weights = ladder_weights(epoch, params.epochs, ladders, params.progressive)
        capacities = [w * c for w, c in zip(weights, capacity(c_last, epoch, params.epochs), strict=True)]
        sums = np.zeros(4 + 2 * ladders)
        for batch_index in torch.randperm(len(data), generator=shuffle).split(params.batch_size):
            batch = data[batch_index]
            terms = favae_loss(model(batch, weights=weights), batch, beta, capacities, params.measure)
            optimiser.zero_grad()
            terms.total.backward()
            optimiser.step()
            values = [terms.total, terms.reconstruction, terms.action_error, terms.on_off, *terms.kl]
            sums += np.array([v.item() for v in [*values, *terms.information]]) * len(batch)
        means = sums / len(data)
        row = {
            "epoch": epoch,
            "loss": means[0],
            "reconstruction": means[1],
            "action_error": means[2],
            "on_off": means[3],
        }
        row.update({f"kl_{i + 1}": means[4 + i] for i in range(ladders)})
        row.update({f"information_{i + 1}": means[4 + ladders + i] for i in range(ladders)})
        row.update({f"capacity_{i + 1}": c for i, c in enumerate(capacities)})
        if params.progressive:
            row.update({f"weight_{i + 1}": w for i, w in enumerate(weights)})
        log.append(row)
        if on_epoch:
            on_epoch(row)
    return model.eval(), log


def calibrate(
    padded: np.ndarray, config: FavaeConfig, params: TrainingParams, on_epoch=None, beta: float = CALIBRATION_BETA
) -> tuple[list[float], list[dict]]:
    """The C_last pre-run: train with a small beta (the paper's 0.1) and C = 0; each ladder's value in the last
    epoch of what the capacities constrain (``params.measure``: its information, or its KL) is its C_last."""
    _, log = train_favae(padded, config, beta, [0.0] * config.ladders, params, on_epoch)
    column = "kl" if params.measure == Measure.KL else "information"
    return [float(log[-1][f"{column}_{i + 1}"]) for i in range(config.ladders)], log


@torch.no_grad()
def evaluate_fit(model: Favae, padded: np.ndarray, lengths: np.ndarray, factors: np.ndarray) -> dict:
    """Scores of a fitted FAVAE on its segments, decoding posterior means (no sampling).

    - reconstruction: mean squared error per real action step and dimension;
    - length: how often the decoded macro action is cut at the true length, and the mean absolute error;
    - per latent dimension and per ladder: the KL from the prior, the information about the segments (the part of
      the KL that varies with them, :func:`~famarl_cli.method.favae.loss.information_per_dim`), the rest of the KL (the
      aggregate's shift and spread against the prior) and whether the latent is active (its posterior mean's
      variance over the segments above :data:`ACTIVE_VARIANCE`);
    - MIG of the posterior means against the experts' per-segment factors, with bootstrap intervals over the
      segments (:func:`famarl_cli.method.metrics.mig_interval`).
    """
    output = model(to_input(padded), sample=False)
    decoded = output.reconstruction.numpy().transpose(0, 2, 1)
    on = padded[..., -2]
    squared = ((decoded[..., :-2] - padded[..., :-2]) ** 2).sum(axis=2)
    decoded_lengths = cut_lengths(decoded[..., -2:])
    mu = torch.cat(output.mus, dim=1)
    logvar = torch.cat(output.logvars, dim=1)
    kl_dims = kl_per_dim(mu, logvar).mean(dim=0).numpy()
    information = information_per_dim(mu, logvar).numpy()
    marginal = marginal_per_dim(mu, logvar).numpy()
    variance = mu.var(dim=0, unbiased=False).numpy()
    splits = np.cumsum(model.config.latent_dims)[:-1]

    def per_ladder(values: np.ndarray) -> list[float]:
        return [float(v.sum()) for v in np.split(values, splits)]

    score = mig_interval(mu.numpy(), factors)
    return {
        "reconstruction_mse": float((squared * on).sum() / (on.sum() * (padded.shape[2] - 2))),
        "length_accuracy": float(np.mean(decoded_lengths == lengths)),
        "length_mean_abs_error": float(np.mean(np.abs(decoded_lengths - lengths))),
        "kl_per_dim": [float(k) for k in kl_dims],
        "kl_per_ladder": per_ladder(kl_dims),
        "information_per_dim": [float(i) for i in information],
        "information_per_ladder": per_ladder(information),
        "shift_per_ladder": per_ladder(marginal),
        "mean_variance_per_dim": [float(v) for v in variance],
        "active_per_ladder": [int(a) for a in per_ladder((variance > ACTIVE_VARIANCE).astype(float))],
        "mig": score["mig"],
        "mig_interval": score["interval"],
        "mig_per_factor": score["per_factor"],
        "mig_per_factor_interval": score["per_factor_interval"],
        "mig_bins": score["bins"],
        "mig_segments_for_half_width": score["samples_for_half_width"],
        **({"mig_note": score["note"]} if "note" in score else {}),
    }


def training_summary(params: TrainingParams, beta: float, c_last: list[float]) -> dict:
    return {**asdict(params), "beta": beta, "c_last": list(c_last)}
