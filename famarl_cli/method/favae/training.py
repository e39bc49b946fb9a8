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
    PROGRESSIVE,
    Capacity,
    Device,
    FavaeOptions,
    Measure,
)
from famarl_cli.method.favae.loss import capacity, data_information, kl_per_dim
from famarl_cli.method.favae.model import Favae, FavaeConfig, floor_share, to_input
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
    measure: str = MEASURE.value
    """What the capacities constrain: the information each ladder carries, or its KL
    (:mod:`~famarl_cli.method.favae.loss`)."""
    progressive: float = PROGRESSIVE
    """Share of the epochs over which the ladders are added one by one, deepest first (0: all from the start)."""

    @staticmethod
    def of(options: FavaeOptions) -> TrainingParams:
        """The training that ``options`` declare (batch size and learning rate are the method's)."""
        return TrainingParams(
            epochs=options.epochs,
            seed=options.seed,
            measure=str(options.measure),
            progressive=options.progressive_share,
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


def fit_device(name: str) -> torch.device:
    """The torch device a fit runs on (:class:`~famarl_cli.method.favae.Device`); a one-line error where the name is
    not one (a usage error) or no GPU is there (the machine's: exit code 1)."""
    if name not in tuple(Device):
        raise UsageError(f"device must be one of {', '.join(Device)}, got {name!r}")
    if name == Device.CUDA and not torch.cuda.is_available():
        raise FamarlError("--device cuda: torch sees no CUDA GPU here (torch.cuda.is_available() is False)")
    return torch.device(name)


LOG_EVERY = 50
"""Epochs between reading the log back from the tensors it accumulates in (progress reports come as often)."""


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


def _log_columns(ladders: int) -> list[str]:
    return [
        "loss",
        "reconstruction",
        "action_error",
        "on_off",
        *(f"kl_{i + 1}" for i in range(ladders)),
        *(f"information_{i + 1}" for i in range(ladders)),
    ]


def _batches(sizes: list[int], batch_size: int, shuffles: list[torch.Generator]):
    """One epoch's batches of every replicate, in lockstep: per step, (K, B) segment indices (``max(sizes)``, the
    data's all-zero row, on padding), the (K, B) mask of their real rows and the (K,) replicates that have a batch
    at that step, B being the largest batch at that step. Each replicate shuffles its own segments with its own
    generator, exactly as it would alone, and splits them into as few batches of at most ``batch_size`` as it can,
    of equal sizes give or take one (111 segments: 56 and 55, not 64 and 47), so that the information a batch's
    estimate can see is alike in every batch."""
    splits = [
        torch.randperm(n, generator=g).tensor_split(-(-n // batch_size)) for n, g in zip(sizes, shuffles, strict=True)
    ]
    replicates = len(sizes)
    for step in range(max(len(s) for s in splits)):
        width = max(len(split[step]) for split in splits if step < len(split))
        index = torch.full((replicates, width), max(sizes))  # the padding row, all zeros
        rows = torch.zeros(replicates, width)
        for k, split in enumerate(splits):
            if step < len(split):
                index[k, : len(split[step])] = split[step]
                rows[k, : len(split[step])] = 1.0
        yield index, rows, rows[:, 0] > 0


def train_replicates(
    replicates: list[Replicate], on_epoch: Callable[[int, dict], None] | None = None, device: str = "cpu"
) -> list[tuple[Favae, list[dict]]]:
    """Fit K fresh FAVAEs as one batched model (:class:`~famarl_cli.method.favae.ensemble.FavaeEnsemble`) on
    ``device`` (:func:`fit_device`); returns each replicate's model (on the CPU) and its log, one row per epoch.
    ``on_epoch(k, row)`` gets replicate k's rows, every :data:`LOG_EVERY` epochs and at the end.

    Replicate k starts from the weights ``torch.manual_seed(seed); Favae(config)`` makes, draws its sampling noise
    from a generator that continues that stream and shuffles its segments with a generator of its seed, so it fits
    the model it would fit alone, up to float rounding. The replicates must share their training but for the seed,
    and their config but for L; they may hold different numbers of segments (batches are padded and masked, and a
    replicate with fewer batches in an epoch skips the extra steps). Each row holds the epoch's means of the loss
    terms, KL and information per ladder, the capacity C per ladder (and each ladder's weight when progressive).

    On a GPU the initial weights, noise and shuffles are the same (drawn on the CPU, as alone); its kernels round
    differently from the CPU's, so its fits differ from the CPU's as two CPUs' do (docs/favae.md).
    """
    from famarl_cli.core.replicate_adam import ReplicateAdam
    from famarl_cli.method.favae.ensemble import FavaeEnsemble
    from famarl_cli.method.favae.loss import replicate_loss

    if not replicates:
        return []
    shared = {replace(r.params, seed=0) for r in replicates}
    if len(shared) != 1:
        raise ValueError("replicates fitted together must share their training parameters but for the seed")
    params = shared.pop()
    models, noises = [], []  # each replicate's initial weights and noise stream, as it would have them alone
    for replicate in replicates:
        torch.manual_seed(replicate.params.seed)
        models.append(Favae(replicate.config))
        noises.append(torch.Generator().set_state(torch.get_rng_state()))
    on = fit_device(device)
    ensemble = FavaeEnsemble(models, on)
    shuffles = [torch.Generator().manual_seed(r.params.seed) for r in replicates]
    sizes = [len(r.padded) for r in replicates]
    # every replicate's segments, padded to the longest L, and after the most segments an all-zero row that pads batches
    data = torch.zeros(len(replicates), max(sizes) + 1, ensemble.config.length, ensemble.config.action_dim + 2)
    for k, replicate in enumerate(replicates):
        data[k, : sizes[k], : replicate.config.length] = torch.as_tensor(replicate.padded)
    data = data.to(on)
    optimiser = ReplicateAdam(ensemble.flat, lr=params.learning_rate)
    gradient = torch.empty_like(ensemble.flat)
    ladders, latent = ensemble.config.ladders, ensemble.config.latent_size
    beta = torch.tensor([r.beta for r in replicates], device=on)
    population = torch.tensor(sizes, dtype=torch.float32, device=on)
    columns = _log_columns(ladders)
    sums = torch.zeros(params.epochs, len(replicates), len(columns), device=on)
    logs: list[list[dict]] = [[] for _ in replicates]
    everyone = torch.arange(len(replicates), device=on)[:, None]
    schedule = []
    for epoch in range(params.epochs):
        weights = torch.tensor(ladder_weights(epoch, params.epochs, ladders, params.progressive))
        capacities = weights * torch.tensor([capacity(r.c_last, epoch, params.epochs) for r in replicates])
        schedule.append((weights, capacities))
        weights, capacities = weights.to(on), capacities.to(on)
        for index, rows, active in _batches(sizes, params.batch_size, shuffles):
            counts = rows.sum(dim=1).long().tolist()
            width = index.shape[1]
            noise = torch.zeros(len(replicates), width, latent)
            for k, count in enumerate(counts):
                if count:  # ladder by ladder, as a Favae draws it alone (randn_like of each ladder's mean)
                    draws = [torch.randn(count, z, generator=noises[k]) for z in ensemble.config.latent_dims]
                    noise[k, :count] = torch.cat(draws, dim=1)
            batch = data[everyone, index.to(on)]
            noise, rows, weighed = noise.to(on), rows.to(on), active.to(on)
            # a replicate without a batch at this step is scored on padding (a finite loss) and weighed 0
            padded_rows = None if all(c == width for c in counts) else rows.masked_fill(~weighed[:, None], 1)
            reconstruction, mus, logvars, samples = ensemble.forward(batch, noise, weights.expand(len(replicates), -1))
            terms = replicate_loss(
                reconstruction,
                batch,
                mus,
                logvars,
                samples,
                beta,
                capacities,
                population,
                params.measure,
                padded_rows,
                ensemble.step_mask,
            )
            gradients = torch.autograd.grad((terms.total * weighed).sum(), ensemble.parameters)
            torch.cat([g.reshape(len(replicates), -1) for g in gradients], dim=1, out=gradient)
            optimiser.step(gradient, None if bool(active.all()) else active)
            values = torch.stack(
                [terms.total, terms.reconstruction, terms.action_error, terms.on_off, *terms.kl, *terms.information],
                dim=1,
            )
            sums[epoch] += values.detach() * rows.sum(dim=1, keepdim=True)
        if (epoch + 1) % LOG_EVERY == 0 or epoch + 1 == params.epochs:
            _read_log(sums, schedule, sizes, columns, params, logs, on_epoch)
    return list(zip(ensemble.models(), logs, strict=True))


def _read_log(sums, schedule, sizes, columns, params: TrainingParams, logs: list[list[dict]], on_epoch) -> None:
    """Turn the epochs accumulated since the last read into log rows (one host read for all of them)."""
    first = len(logs[0])
    means = (sums[first : len(schedule)].cpu() / torch.tensor(sizes, dtype=sums.dtype)[None, :, None]).tolist()
    for offset, epoch_means in enumerate(means):
        epoch = first + offset
        weights, capacities = schedule[epoch]
        for k, values in enumerate(epoch_means):
            row = {"epoch": epoch, **dict(zip(columns, values, strict=True))}
            row.update({f"capacity_{i + 1}": float(c) for i, c in enumerate(capacities[k])})
            if params.progressive:
                row.update({f"weight_{i + 1}": float(w) for i, w in enumerate(weights)})
            logs[k].append(row)
            if on_epoch:
                on_epoch(k, row)


def train_favae(
    padded: np.ndarray,
    config: FavaeConfig,
    beta: float,
    c_last: list[float],
    params: TrainingParams,
    on_epoch: Callable[[dict], None] | None = None,
) -> tuple[Favae, list[dict]]:
    """Fit a fresh FAVAE on (S, L, D + 2) padded macro actions; returns it and one log row per epoch
    (:func:`train_replicates` with one replicate)."""
    [result] = train_replicates(
        [Replicate(padded, config, beta, c_last, params)], None if on_epoch is None else (lambda _, row: on_epoch(row))
    )
    return result


def calibrate_replicates(
    replicates: list[Replicate], on_epoch: Callable[[int, dict], None] | None = None, device: str = "cpu"
) -> list[tuple[list[float], list[dict]]]:
    """The C_last pre-runs of K replicates at once: each ``Replicate``'s beta is its pre-run's (the paper's 0.1),
    its C_last ignored (C = 0); each ladder's value in the last epoch of what the capacities constrain
    (``params.measure``: its information, or its KL) is its C_last. Returns (C_last, log) per replicate. They run
    on ``device`` (:func:`train_replicates`)."""
    zero = [replace(r, c_last=[0.0] * r.config.ladders) for r in replicates]
    results = []
    for replicate, (_, log) in zip(zero, train_replicates(zero, on_epoch, device), strict=True):
        column = "kl" if replicate.params.measure == Measure.KL else "information"
        results.append(([float(log[-1][f"{column}_{i + 1}"]) for i in range(replicate.config.ladders)], log))
    return results


def calibrate(
    padded: np.ndarray, config: FavaeConfig, params: TrainingParams, on_epoch=None, beta: float = CALIBRATION_BETA
) -> tuple[list[float], list[dict]]:
    """The C_last pre-run of one FAVAE (:func:`calibrate_replicates` with one replicate)."""
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
