"""What a GPU fit shares with the CPU's: the same draws to the bit, and weights that differ by rounding alone.

    python benchmarks/device_agreement.py [--epochs 4] [--macros data/maze/macros]

Needs a CUDA GPU. Checks that the counter-based draws (orders and sampling noise) are bit-identical on the CPU and
the GPU, then fits three replicates (replicates 0-2 of ``--macros``, or random segments) for ``--epochs`` epochs on
the CPU, on the GPU launched op by op and on the GPU as replayed CUDA graphs, and prints the largest weight
difference between each pair: graph against op by op is the capture's own error (0 where the kernels are the same),
GPU against CPU the two devices' rounding grown over the epochs. Exit status 1 when the draws differ or the graph
does not compute what the eager fit computes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch
from favae_replicates import replicates, segments_of

from famarl_cli.core import counter_random
from famarl_cli.method.favae.training import train_replicates


def largest_difference(a, b) -> float:
    return max(
        float((x - y).abs().max())
        for (ma, _), (mb, _) in zip(a, b, strict=True)
        for x, y in zip(ma.state_dict().values(), mb.state_dict().values(), strict=True)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--macros", type=Path, default=Path("data/maze/macros"))
    args = parser.parse_args()
    if not torch.cuda.is_available():
        raise SystemExit("error: torch sees no CUDA GPU here")
    torch.set_num_threads(1)
    seeds = [0, 1, 2**40 + 3]
    draws = {}
    for device in ("cpu", "cuda"):
        keys = counter_random.stream_keys(seeds, counter_random.NOISE, device)
        counters = torch.tensor([0, 7, 123456], device=device)
        draws[device] = (
            counter_random.normal(keys, counters, (64, 6)).cpu(),
            counter_random.orders(keys, counters, torch.tensor([111, 50, 3], device=device), 112).cpu(),
        )
    same = all(torch.equal(a, b) for a, b in zip(draws["cpu"], draws["cuda"], strict=True))
    print(f"counter-based draws on the CPU and the GPU: {'bit-identical' if same else 'DIFFERENT'}")
    segments = [segments_of(args.macros, k) for k in range(3)]
    fits = {
        name: train_replicates(replicates(segments, args.epochs), device=device, graph=graph)
        for name, device, graph in (("cpu", "cpu", False), ("eager", "cuda", False), ("graph", "cuda", True))
    }
    capture = largest_difference(fits["graph"], fits["eager"])
    print(f"largest weight difference after {args.epochs} epochs: GPU graph vs GPU op by op {capture:.3g}")
    print(f"GPU op by op vs CPU {largest_difference(fits['eager'], fits['cpu']):.3g}")
    print(f"GPU graph vs CPU {largest_difference(fits['graph'], fits['cpu']):.3g}")
    losses = [[row["loss"] for row in log] for _, log in fits["graph"]]
    print("GPU graph losses per epoch:", [[round(v, 3) for v in replicate] for replicate in losses])
    if not same or capture > 1e-4:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
