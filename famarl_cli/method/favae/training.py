"""Fitting FAVAE: the C_last pre-run ("calibration"), the capacity-annealed main fit, and the fit's scores.

Both phases can be progressive (pro-VLAE, Li et al. 2020): the deepest ladder trains alone first and the shallower
ones are faded in one at a time (:func:`ladder_weights`), so the deepest takes the factors that shape the whole
sequence before a shallower ladder can, and what is left (detail) goes to the shallower ones. A ladder not yet in
has capacity 0, so the KL term holds its posterior at the prior (pro-VLAE's penalty on inactive latents).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, replace

import numpy as np
import torch

from famarl_cli.core.declare import default_of
from famarl_cli.core.errors import FamarlError, UsageError
from famarl_cli.core.macro_actions import cut_lengths
from famarl_cli.method.favae import (
    CALIBRATION_BETA,
    MAX_PROGRESSIVE,
    MEASURE,
    PRE_RUN,
    PROGRESSIVE,
    Capacity,
    Device,
    FavaeOptions,
    Measure,
)
from famarl_cli.method.favae.loss import capacity, data_information, kl_per_dim
from famarl_cli.method.favae.model import Favae, FavaeConfig, floor_share, to_input
from famarl_cli.method.favae.schedule import ladder_weights, pre_run_window
from famarl_cli.method.metrics import mig_interval

ACTIVE_VARIANCE = 0.01
"""A latent whose posterior mean varies over the segments by more than this (variance) is active (Burda et al.
2016's active units); below it the latent says the same of every segment, whatever its KL."""


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
    measure: str = MEASURE.value
    """What the capacities constrain: the information each ladder carries, or its KL
    (:mod:`~famarl_cli.method.favae.loss`)."""
    progressive: float = PROGRESSIVE
    """Share of the epochs over which the ladders are added one by one, deepest first (0: all from the start)."""
    pre_run: float = PRE_RUN
    """The C_last pre-run's length, a share of ``epochs`` (:data:`~famarl_cli.method.favae.PRE_RUN`)."""

    @staticmethod
    def of(options: FavaeOptions) -> TrainingParams:
        """The training that ``options`` declare (batch size and learning rate are the method's)."""
        return TrainingParams(
            epochs=options.epochs,
            seed=options.seed,
            measure=str(options.measure),
            progressive=options.progressive_share,
            pre_run=options.pre_run_share,
        )

    def __post_init__(self) -> None:
        if self.measure not in tuple(Measure):
            raise UsageError(f"capacity measure must be one of {tuple(map(str, Measure))}, got {self.measure!r}")
        if not 0.0 <= self.progressive <= MAX_PROGRESSIVE:
            raise UsageError(f"progressive must be in [0, {MAX_PROGRESSIVE}], got {self.progressive}")
        if not 0.0 < self.pre_run <= 1.0:
            raise UsageError(f"the pre-run's share must be in (0, 1], got {self.pre_run}")


def fit_device(name: str) -> torch.device:
    """The torch device a fit runs on (:class:`~famarl_cli.method.favae.Device`); a one-line error where the name is
    not one (a usage error) or no GPU is there (the machine's: exit code 1)."""
    if name not in tuple(Device):
        raise UsageError(f"device must be one of {', '.join(Device)}, got {name!r}")
    if name == Device.CUDA and not torch.cuda.is_available():
        raise FamarlError("--device cuda: torch sees no CUDA GPU here (torch.cuda.is_available() is False)")
    return torch.device(name)


@dataclass(frozen=True)
class Replicate:
    """One FAVAE to fit: its segments, its config, its beta and C_last, and its training (seed included)."""

    padded: np.ndarray
    """(S, L, D + 2) padded macro actions."""
    config: FavaeConfig
    beta: float
    c_last: list[float]
    params: TrainingParams

    def __post_init__(self) -> None:
        if self.beta < 0:
            raise UsageError(f"beta must be >= 0, got {self.beta}")
        if len(self.c_last) != self.config.ladders:
            raise UsageError(f"C_last has {len(self.c_last)} values for {self.config.ladders} ladders")


def schedule(replicates: list[Replicate], params: TrainingParams) -> tuple[torch.Tensor, torch.Tensor]:
    """Per epoch, each ladder's weight in the decoder (E, ladders) and each replicate's capacities (E, K,
    ladders): the weight times C_l (:func:`ladder_weights`, :func:`~famarl_cli.method.favae.loss.capacity`)."""
    ladders, epochs = replicates[0].config.ladders, params.epochs
    weights = torch.tensor([ladder_weights(e, epochs, ladders, params.progressive) for e in range(epochs)])
    # capacity(c, e, E) is c times the epoch's fraction: the same float64 products, made for all replicates at once
    fractions = torch.tensor([capacity([1.0], e, epochs)[0] for e in range(epochs)], dtype=torch.float64)
    c_last = torch.tensor([r.c_last for r in replicates], dtype=torch.float64)
    return weights, weights[:, None, :] * (fractions[:, None, None] * c_last[None]).float()


def lockstep(replicates: list[Replicate], device: str = "cpu", graph: bool = True, stop: int | None = None):
    """The batched fit of ``replicates`` on ``device`` (:func:`fit_device`), ready to run
    (:class:`~famarl_cli.method.favae.lockstep.Lockstep`; on a GPU each epoch one replayed CUDA graph, unless
    ``graph`` is off): the first ``stop`` epochs of their schedule (all without it). The replicates must share
    their training but for the seed, and their config but for L."""
    from famarl_cli.method.favae.lockstep import Lockstep

    shared = {replace(r.params, seed=0) for r in replicates}
    if len(shared) != 1:
        raise ValueError("replicates fitted together must share their training parameters but for the seed")
    params = shared.pop()
    weights, capacities = schedule(replicates, params)
    epochs = params.epochs if stop is None else stop
    return Lockstep(
        [r.padded for r in replicates],
        [r.config for r in replicates],
        [r.params.seed for r in replicates],
        [r.beta for r in replicates],
        params.measure,
        params.learning_rate,
        params.batch_size,
        weights[:epochs],
        capacities[:epochs],
        fit_device(device),
        graph,
    )


def train_replicates(
    replicates: list[Replicate],
    on_epoch: Callable[[int, dict], None] | None = None,
    device: str = "cpu",
    graph: bool = True,
    stop: int | None = None,
) -> list[tuple[Favae, list[dict]]]:
    """Fit K fresh FAVAEs as one batched model, their epochs in lockstep (:func:`lockstep`); returns each
    replicate's model (on the CPU) and its log, one row per epoch. ``on_epoch(k, row)`` gets replicate k's rows,
    every :data:`~famarl_cli.method.favae.lockstep.LOG_EVERY` epochs and at the end. ``stop`` trains only the
    schedule's first ``stop`` epochs (the pre-run).

    Replicate k starts from the weights ``torch.manual_seed(seed); Favae(config)`` makes and draws its epoch orders
    and sampling noise from counter-based streams of its seed, so it fits the model it would fit alone, up to float
    rounding, on any device. The replicates may hold different numbers of segments (batches are padded and masked,
    and a replicate with fewer batches in an epoch skips the extra steps). Each row holds the epoch's means of the
    loss terms, KL and information per ladder, the capacity C per ladder (and each ladder's weight when
    progressive).
    """
    from famarl_cli.method.favae.lockstep import LOG_EVERY

    if not replicates:
        return []
    fit = lockstep(replicates, device, graph, stop)
    columns = fit.columns(replicates[0].config.ladders)
    progressive = replicates[0].params.progressive
    logs: list[list[dict]] = [[] for _ in replicates]
    for first in range(0, fit.epochs, LOG_EVERY):
        last = min(first + LOG_EVERY, fit.epochs)
        fit.run(last - first)
        # as Python lists, a chunk at a time: a tensor read per row costs seconds at a thousand replicates
        means, capacities = fit.means(first, last).tolist(), fit.schedule_capacities[first:last].tolist()
        weights = fit.schedule_weights[first:last].tolist()
        for offset, epoch_means in enumerate(means):
            epoch = first + offset
            for k, values in enumerate(epoch_means):
                row = {"epoch": epoch, **dict(zip(columns, values, strict=True))}
                row.update({f"capacity_{i + 1}": c for i, c in enumerate(capacities[offset][k])})
                if progressive:
                    row.update({f"weight_{i + 1}": w for i, w in enumerate(weights[offset])})
                logs[k].append(row)
                if on_epoch:
                    on_epoch(k, row)
    return list(zip(fit.models(), logs, strict=True))


def train_favae(
    padded: np.ndarray,
    config: FavaeConfig,
    beta: float,
    c_last: list[float],
    params: TrainingParams,
    on_epoch: Callable[[dict], None] | None = None,
) -> tuple[Favae, list[dict]]:
    """Fit a fresh FAVAE on (S, L, D + 2) padded macro actions; returns it and one log row per epoch
    (:func:`train_replicates` with one replicate: the one-model form benchmarks/ calls; the stages fit replicates
    through :func:`train_replicates`)."""
    [result] = train_replicates(
        [Replicate(padded, config, beta, c_last, params)], None if on_epoch is None else (lambda _, row: on_epoch(row))
    )
    return result


def calibrate_replicates(
    replicates: list[Replicate], on_epoch: Callable[[int, dict], None] | None = None, device: str = "cpu"
) -> list[tuple[list[float], list[dict]]]:
    """The C_last pre-runs of K replicates at once: each ``Replicate``'s beta is its pre-run's (the paper's 0.1),
    its C_last ignored (C = 0); the pre-run trains the first ``params.pre_run`` of the fit's schedule, and each
    ladder's mean, over the pre-run's window (:func:`~famarl_cli.method.favae.schedule.pre_run_window`), of what the
    capacities constrain (``params.measure``: its information, or its KL) is its C_last. Returns (C_last, log) per
    replicate. They run on ``device`` (:func:`train_replicates`)."""
    if not replicates:
        return []
    zero = [replace(r, c_last=[0.0] * r.config.ladders) for r in replicates]
    params, ladders = replicates[0].params, replicates[0].config.ladders
    window = pre_run_window(params.pre_run, params.epochs, ladders, params.progressive)
    results = []
    for replicate, (_, log) in zip(zero, train_replicates(zero, on_epoch, device, stop=window.stop), strict=True):
        column = "kl" if replicate.params.measure == Measure.KL else "information"
        c_last = [float(np.mean([log[e][f"{column}_{i + 1}"] for e in window])) for i in range(ladders)]
        results.append((c_last, log))
    return results


def calibrate(
    padded: np.ndarray, config: FavaeConfig, params: TrainingParams, on_epoch=None, beta: float = CALIBRATION_BETA
) -> tuple[list[float], list[dict]]:
    """The C_last pre-run of one FAVAE (:func:`calibrate_replicates` with one replicate: the one-model form
    benchmarks/ calls)."""
    [result] = calibrate_replicates(
        [Replicate(padded, config, beta, [0.0] * config.ladders, params)],
        None if on_epoch is None else (lambda _, row: on_epoch(row)),
    )
    return result


FLOOR_BINDS = 0.5
"""A fit whose floor holds more than this share of a ladder's posterior variances is said to lean on it. The share is
a ladder's, over its latents together: a ladder of two latents, one on the floor for every segment and the other
off it, reads 0.50 and does not count; ``python benchmarks/floor_per_latent.py`` counts latent by latent."""


@torch.no_grad()
def evaluate_fit(model: Favae, padded: np.ndarray, lengths: np.ndarray, factors: np.ndarray) -> dict:
    """Scores of a fitted FAVAE on its segments, decoding posterior means (no sampling).

    - reconstruction: mean squared error per real action step and dimension;
    - length: how often the decoded macro action is cut at the true length, how often within one step of it, and
      the mean absolute error;
    - per latent dimension and per ladder: the KL from the prior, the information about the N segments (exact over
      them, at most log N, :func:`~famarl_cli.method.favae.loss.data_information`; a ladder's is its latent's
      jointly), the rest of the KL (the aggregate's shift and spread against the prior), whether the latent is
      active (its posterior mean's variance over the segments above :data:`ACTIVE_VARIANCE`) and the share of
      posterior variances the std floor holds (:func:`~famarl_cli.method.favae.model.floor_share`);
    - MIG of the posterior means against the experts' per-segment factors, with basic bootstrap intervals over the
      segments (:func:`famarl_cli.method.metrics.mig_interval`).
    """
    output = model(to_input(padded), sample=False)
    decoded = output.reconstruction.numpy().transpose(0, 2, 1)
    on = padded[..., -2]
    squared = ((decoded[..., :-2] - padded[..., :-2]) ** 2).sum(axis=2)
    errors = np.abs(cut_lengths(decoded[..., -2:]) - lengths)
    mu = torch.cat(output.mus, dim=1)
    logvar = torch.cat(output.logvars, dim=1)
    dims = list(model.config.latent_dims)
    kl_dims = kl_per_dim(mu, logvar).mean(dim=0).numpy()
    information_dims, information_ladders = data_information(mu, logvar, dims)
    variance = mu.var(dim=0, unbiased=False).numpy()
    splits = np.cumsum(dims)[:-1]

    def per_ladder(values: np.ndarray) -> list[float]:
        return [float(v.sum()) for v in np.split(values, splits)]

    kl_ladders = per_ladder(kl_dims)
    floor = [floor_share(lv) for lv in output.logvars]
    score = mig_interval(mu.numpy(), factors)
    return {
        "reconstruction_mse": float((squared * on).sum() / (on.sum() * (padded.shape[2] - 2))),
        "length_accuracy": float(np.mean(errors == 0)),
        "length_within_one": float(np.mean(errors <= 1)),
        "length_mean_abs_error": float(np.mean(errors)),
        "kl_per_dim": [float(k) for k in kl_dims],
        "kl_per_ladder": kl_ladders,
        "information_per_dim": information_dims.tolist(),
        "information_per_ladder": information_ladders.tolist(),
        "information_bound": float(np.log(len(padded))),
        "shift_per_ladder": [k - i for k, i in zip(kl_ladders, information_ladders.tolist(), strict=True)],
        "mean_variance_per_dim": [float(v) for v in variance],
        "active_per_ladder": [int(a) for a in per_ladder((variance > ACTIVE_VARIANCE).astype(float))],
        "floor_share_per_ladder": floor,
        "floor_binds": bool(max(floor) > FLOOR_BINDS),
        "mig": score["mig"],
        "mig_interval": score["interval"],
        "mig_interval_method": score["interval_method"],
        "mig_per_factor": score["per_factor"],
        "mig_per_factor_interval": score["per_factor_interval"],
        "mig_bins": score["bins"],
        "mig_segments_for_half_width": score["samples_for_half_width"],
        **({"mig_note": score["note"]} if "note" in score else {}),
    }


def training_summary(params: TrainingParams, beta: float, c_last: list[float]) -> dict:
    return {**asdict(params), "beta": beta, "c_last": list(c_last)}
