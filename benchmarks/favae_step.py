"""Time per FAVAE optimiser step of each design, on the default pipeline's segments, one torch thread.

    python benchmarks/favae_step.py [--designs shared-kl,ladder-info-p20] [--segments PATH] [--steps 400]

One step is what the fit does per batch: forward (sampling), the loss with its capacity term, backward, Adam. The
designs (studies/favae_designs.py) take turns, ``--repeats`` times each, on the same batch of 64 segments (the
pipeline's batch size), and each reports the median over repeats of the mean time of ``--steps`` steps after a
warm-up. With no segments file (before ``dvc repro``) the batch is random data of the default pipeline's shape.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, STUDIES, write_result

from famarl_cli.artifacts.segments import read_segments
from famarl_cli.method.favae.loss import favae_loss
from famarl_cli.method.favae.model import Favae, FavaeConfig, to_input
from famarl_cli.method.favae.training import ladder_weights
from famarl_cli.sweep.plan import parse_values


def batch_of(path: Path) -> np.ndarray:
    if path.is_file():
        return read_segments(path).padded[:64]
    rng = np.random.default_rng(0)
    padded = np.zeros((64, 48, 4), dtype=np.float32)
    lengths = rng.integers(5, 48, 64)
    for row, length in zip(padded, lengths, strict=True):
        row[:length, :2] = rng.uniform(-1, 1, (length, 2))
        row[:length, 2], row[length:, 3] = 1.0, 1.0
    return padded


def time_steps(model: Favae, x: torch.Tensor, design, steps: int) -> float:
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
    # mid-training, when a progressive schedule has every ladder in: the cost of the full model
    weights = ladder_weights(1499, 1500, model.config.ladders, design.progressive)
    capacities = [1.0] * model.config.ladders

    def step() -> None:
        terms = favae_loss(model(x, weights=weights), x, 50.0, capacities, design.measure)
        optimiser.zero_grad()
        terms.total.backward()
        optimiser.step()

    for _ in range(20):
        step()
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return (time.perf_counter() - start) / steps


def designs() -> dict:
    """The designs of studies/favae_designs.py (the FAVAE studies compare what they learn; this times them)."""
    if str(STUDIES) not in sys.path:
        sys.path.insert(1, str(STUDIES))
    from favae_designs import DESIGNS

    return DESIGNS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--designs", default="shared-kl,ladder-info-p20")
    parser.add_argument("--segments", type=Path, default=Path("data/maze/macros/seed0/segments.h5"))
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, default=RESULTS / "favae_step.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    padded = batch_of(args.segments)
    x = to_input(padded)
    base = FavaeConfig(action_dim=padded.shape[2] - 2, length=padded.shape[1])
    names, known = parse_values(args.designs), designs()
    times: dict[str, list[float]] = {name: [] for name in names}
    for _ in range(args.repeats):
        for name in names:
            design = known[name]
            torch.manual_seed(0)
            config = replace(base, decoder=design.decoder, head=design.head, latent_dims=design.dims)
            times[name].append(time_steps(Favae(config), x, design, args.steps))
    first = float(np.median(times[names[0]]))
    results = {}
    for name in names:
        median = float(np.median(times[name]))
        results[name] = {
            "ms_per_step": 1000 * median,
            "ratio": median / first,
            "repeats_ms": [1000 * t for t in times[name]],
        }
        print(f"{name:22s} {1000 * median:6.2f} ms per step  ({median / first:.2f}x {names[0]})")
    write_result(
        args.out,
        {"segments": str(args.segments), "batch": len(padded), "length": padded.shape[1], "designs": results},
    )


if __name__ == "__main__":
    main()
