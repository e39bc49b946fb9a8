"""K FAVAE replicates trained epoch by epoch in lockstep, every tensor of an epoch on the fit's device.

An epoch is one unit of device work that reads nothing back from the host and nothing from it:

- **Batches** are fixed by the numbers of segments alone (:func:`plan_epoch`): each replicate splits its segments
  into as few batches of at most ``batch_size`` as it can, of equal sizes give or take one (111 segments: 56 and 55,
  not 64 and 47), so that the information a batch's estimate can see is alike in every batch. Which replicates
  have a batch at each step, and how many rows, is known before the fit starts.
- **Which segments** fill them is the epoch's random order of each replicate's segments, and the sampling noise is
  drawn per replicate and step: both are counter-based draws (:mod:`~famarl_cli.core.counter_random`) keyed by the
  replicate's seed and counted by a device tensor the epoch advances itself, so replicate k sees the same orders
  and noise whichever replicates share its batch, on every device, and no host loop draws them.
- **The schedule** (each ladder's weight and each replicate's capacities, per epoch) is a device table indexed by
  that counter; the log accumulates on the device and is read back every :data:`LOG_EVERY` epochs.

So on a GPU the epoch is captured once as a CUDA graph and replayed (:class:`~famarl_cli.core.replay.Replayed`); on
the CPU it runs as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from famarl_cli.core import counter_random, flat_parameters
from famarl_cli.core.replay import Replayed
from famarl_cli.core.replicate_adam import ReplicateAdam
from famarl_cli.method.favae.loss import replicate_loss
from famarl_cli.method.favae.model import Favae, FavaeConfig

LOG_EVERY = 50
"""Epochs between reading the log back from the device (progress reports come as often)."""


@dataclass(frozen=True)
class EpochStep:
    """One step of an epoch, the same in every epoch."""

    positions: torch.Tensor
    """(K, B) int64: row b of replicate k's batch is the segment at this position of its epoch order (0 on a
    padding row)."""
    real: torch.Tensor
    """(K, B) bool: the replicate's real rows; the others are the data's all-zero padding row."""
    counts: torch.Tensor
    """(K, 1) float: real rows per replicate (what the log's epoch means weigh by)."""
    active: tuple[bool, ...]
    """Which replicates have a batch at this step (the others skip it, their optimiser step included)."""
    weighed: torch.Tensor
    """(K,) float: ``active`` as 1 / 0, the weight of each replicate's loss."""
    scored: torch.Tensor | None
    """(K, B) float: the rows each replicate's loss averages over (a replicate without a batch is scored on padding
    and weighed 0); None where every row of every replicate is real."""


def plan_epoch(sizes: list[int], batch_size: int, device: torch.device | str = "cpu") -> list[EpochStep]:
    """The steps of an epoch of K replicates holding ``sizes`` segments: replicate k splits its epoch order into
    ``ceil(n_k / batch_size)`` batches, the first ``n_k mod that`` of them one row larger (``torch.tensor_split``'s
    rule); step s holds every replicate's s-th batch, padded to the widest."""
    if batch_size < 1 or min(sizes) < 1:
        raise ValueError(f"batches need a size >= 1 and replicates >= 1 segment, got {batch_size} and {sizes}")
    splits = []
    for n in sizes:
        batches = -(-n // batch_size)
        base, extra = divmod(n, batches)
        splits.append([base + (i < extra) for i in range(batches)])
    steps = []
    for s in range(max(map(len, splits))):
        counts = [split[s] if s < len(split) else 0 for split in splits]
        width = max(counts)
        positions = torch.zeros(len(sizes), width, dtype=torch.int64)
        real = torch.zeros(len(sizes), width, dtype=torch.bool)
        for k, (split, count) in enumerate(zip(splits, counts, strict=True)):
            first = sum(split[:s])
            positions[k, :count] = torch.arange(first, first + count)
            real[k, :count] = True
        active = torch.tensor([c > 0 for c in counts])
        rows = real.float()
        scored = None if all(c == width for c in counts) else rows.masked_fill(~active[:, None], 1.0)
        steps.append(
            EpochStep(
                positions.to(device),
                real.to(device),
                rows.sum(dim=1, keepdim=True).to(device),
                tuple(bool(a) for a in active),
                active.float().to(device),
                None if scored is None else scored.to(device),
            )
        )
    return steps


class Lockstep:
    """K fresh FAVAEs fitted as one batched model (:class:`~famarl_cli.method.favae.model.Favae`) on ``device``.

    Replicate k starts from the weights ``torch.manual_seed(seeds[k]); Favae(configs[k])`` makes (drawn on the CPU,
    so every device starts from the same weights), with its own segments (``segments[k]``, (S, L, D + 2)), beta and
    Adam state. ``weights`` (E, ladders) is each ladder's weight in the decoder per epoch, ``capacities`` (E, K,
    ladders) each replicate's C per epoch. :meth:`run` trains; ``sums`` holds, per epoch and replicate, the log's
    columns (:data:`COLUMNS` order) summed over the epoch's real rows."""

    def __init__(
        self,
        segments: list[np.ndarray],
        configs: list[FavaeConfig],
        seeds: list[int],
        betas: list[float],
        measure: str,
        learning_rate: float,
        batch_size: int,
        weights: torch.Tensor,
        capacities: torch.Tensor,
        device: torch.device | str = "cpu",
        graph: bool = True,
    ) -> None:
        self.model = model = Favae(configs, device, seeds)
        self.device = device = model.flat.device
        replicates = len(segments)
        self.sizes = [len(s) for s in segments]
        # every replicate's segments, padded to the longest L, then after the most segments an all-zero padding row
        data = torch.zeros(replicates, max(self.sizes) + 1, model.config.length, model.config.action_dim + 2)
        for k, padded in enumerate(segments):
            data[k, : len(padded), : padded.shape[1]] = torch.as_tensor(padded)
        self.data = data.to(device)
        self.plan = plan_epoch(self.sizes, batch_size, device)
        self.measure = measure
        self.optimiser = ReplicateAdam(model.flat, lr=learning_rate)
        self.gradient = torch.empty_like(model.flat)
        self.betas = torch.tensor(betas, device=device)
        self.population = torch.tensor(self.sizes, dtype=torch.float32, device=device)
        self.schedule_weights, self.schedule_capacities = weights, capacities
        self.weights, self.capacities = weights.to(device), capacities.to(device)
        self.epochs = len(weights)
        self.noise_keys = counter_random.stream_keys(seeds, counter_random.NOISE, device)
        self.order_keys = counter_random.stream_keys(seeds, counter_random.ORDER, device)
        # each replicate's own steps per epoch: its noise counter is epoch * that + step, as alone
        self.own_steps = torch.tensor([-(-n // batch_size) for n in self.sizes], device=device)
        self.segment_counts = torch.tensor(self.sizes, device=device)
        self.everyone = torch.arange(replicates, device=device)[:, None]
        self.epoch = torch.zeros((), dtype=torch.int64, device=device)
        self.sums = torch.zeros(self.epochs, replicates, len(self.columns(model.config.ladders)), device=device)
        self.replay = Replayed(self._epoch, device, graph)

    @staticmethod
    def columns(ladders: int) -> list[str]:
        """The log's columns, in the order of :attr:`sums`."""
        return [
            "loss",
            "reconstruction",
            "action_error",
            "on_off",
            *(f"kl_{i + 1}" for i in range(ladders)),
            *(f"information_{i + 1}" for i in range(ladders)),
        ]

    def _epoch(self) -> None:
        """One epoch of every replicate, then the epoch counter advanced (device work only)."""
        model, replicates = self.model, len(self.sizes)
        at = self.epoch.view(1)
        counters = self.epoch.expand(replicates)
        order = counter_random.orders(self.order_keys, counters, self.segment_counts, self.data.shape[1] - 1)
        weights = self.weights.index_select(0, at).expand(replicates, -1)
        capacities = self.capacities.index_select(0, at)[0]
        padding = self.data.shape[1] - 1
        for s, step in enumerate(self.plan):
            index = torch.where(step.real, order.gather(1, step.positions), padding)
            batch = self.data[self.everyone, index]
            noise = counter_random.normal(
                self.noise_keys, counters * self.own_steps + s, (index.shape[1], model.config.latent_size)
            )
            reconstruction, mus, logvars, samples = model.batched(batch, noise, weights)
            terms = replicate_loss(
                reconstruction,
                batch,
                mus,
                logvars,
                samples,
                self.betas,
                capacities,
                self.population,
                self.measure,
                step.scored,
                model.step_mask,
            )
            gradients = torch.autograd.grad((terms.total * step.weighed).sum(), model.parameters())
            self.optimiser.step(flat_parameters.gather(gradients, self.gradient), step.active)
            values = torch.stack(
                [terms.total, terms.reconstruction, terms.action_error, terms.on_off, *terms.kl, *terms.information],
                dim=1,
            )
            self.sums.index_add_(0, at, (values.detach() * step.counts)[None])
        self.epoch.add_(1)

    def run(self, epochs: int) -> None:
        """Train ``epochs`` more epochs (at most the schedule's)."""
        self.replay(epochs)

    def means(self, first: int, last: int) -> torch.Tensor:
        """(last - first, K, columns) on the CPU: the log's epoch means of epochs first .. last - 1."""
        return self.sums[first:last].cpu() / torch.tensor(self.sizes, dtype=self.sums.dtype)[None, :, None]

    def models(self) -> list[Favae]:
        return self.model.models()
