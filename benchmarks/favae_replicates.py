"""Time per step of K FAVAE replicates fitted as one batched model, and its arithmetic rate against the core's.

    python benchmarks/favae_replicates.py [--replicates 1,2,5,10] [--epochs 60] [--macros data/maze/macros]
                                          [--device cpu|cuda]

A step is what ``train_replicates`` does per batch (the default pipeline's fit: batch 64, progressive, information
capacities): K batches, one per replicate, forward with sampling, the loss, backward and ReplicateAdam, with the
epoch's shuffles and log. Each K fits the segments of replicates 0..K-1 of a default-pipeline sweep (``--macros``;
without it random segments of the same shape), one torch thread, and the step time is the fit's wall over its
steps (after a 5-epoch warm-up fit). The FLOPs of one step are torch's FLOP counter's (matmuls, forward and
backward; elementwise work is not counted), so the rate is a lower bound; the core's rate is a 2048 x 2048
``torch.mm`` on the same thread. Also per replicate: the step time over K against K = 1. ``--device cuda`` fits
on the GPU (the fit's own log reads wait for it) and takes the GPU's 2048 x 2048 ``torch.mm`` as its rate.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, command_line, record, verdict, write_result
from torch.utils.flop_counter import FlopCounterMode

from famarl_cli.artifacts.segments import read_segments
from famarl_cli.method.favae.model import FavaeConfig
from famarl_cli.method.favae.training import Replicate, TrainingParams, train_replicates
from famarl_cli.sweep.plan import parse_values


def segments_of(folder: Path, k: int) -> np.ndarray:
    path = folder / f"seed{k}" / "segments.h5"
    if path.is_file():
        return read_segments(path).padded
    rng = np.random.default_rng(k)
    padded = np.zeros((111, 48, 4), dtype=np.float32)
    for row, length in zip(padded, rng.integers(5, 48, len(padded)), strict=True):
        row[:length, :2] = rng.uniform(-1, 1, (length, 2))
        row[:length, 2], row[length:, 3] = 1.0, 1.0
    return padded


def replicates(segments: list[np.ndarray], epochs: int) -> list[Replicate]:
    return [
        Replicate(
            padded,
            FavaeConfig(action_dim=padded.shape[2] - 2, length=padded.shape[1]),
            50.0,
            [0.5, 0.5, 3.0],
            TrainingParams(epochs=epochs, seed=k),
        )
        for k, padded in enumerate(segments)
    ]


def steps_per_epoch(segments: list[np.ndarray], batch_size: int = 64) -> int:
    return max(-(-len(s) // batch_size) for s in segments)


def mm_rate(device: str, size: int = 2048, repeats: int = 10) -> float:
    a, b = torch.randn(size, size, device=device), torch.randn(size, size, device=device)
    torch.mm(a, b)
    wait(device)
    start = time.perf_counter()
    for _ in range(repeats):
        torch.mm(a, b)
    wait(device)
    return 2 * size**3 * repeats / (time.perf_counter() - start)


def wait(device: str) -> None:
    if device == "cuda":
        torch.cuda.synchronize()


def records(rows: list[dict], command: str, device: str) -> dict[str, dict]:
    """measured.json's entry: the step time per replicate at each K, and the range of the core's rate reached."""
    shares = [row["share_of_core"] for row in rows]
    return {
        f"favae_replicates{'' if device == 'cpu' else '_' + device}": {
            "what": "a FAVAE optimiser step per replicate, K = "
            + " / ".join(str(row["replicates"]) for row in rows)
            + f" replicates in one process{'' if device == 'cpu' else ' on ' + device}",
            "command": command,
            "measured": " / ".join(f"{row['ms_per_replicate_step']:.1f}" for row in rows)
            + f" ms; {100 * min(shares):.0f}-{100 * max(shares):.0f}% of the core's `torch.mm` rate"
            + verdict(max(shares) >= 0.5),
            "target": ">= 50%",
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replicates", default="1,2,5,10")
    parser.add_argument("--epochs", type=int, default=60)
    parser.add_argument("--macros", type=Path, default=Path("data/maze/macros"))
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
    parser.add_argument("--out", type=Path, default=None, help="[default: results/favae_replicates[_cuda].json]")
    args = parser.parse_args()
    suffix = "" if args.device == "cpu" else f"_{args.device}"
    out = args.out or RESULTS / f"favae_replicates{suffix}.json"
    if args.device == "cuda" and not torch.cuda.is_available():
        raise SystemExit("error: --device cuda: torch sees no CUDA GPU here")
    torch.set_num_threads(1)
    core = mm_rate(args.device)
    print(f"torch.mm 2048 x 2048 on {args.device} (one thread): {core / 1e9:.1f} GFLOP/s")
    rows = []
    for k in map(int, parse_values(args.replicates)):
        segments = [segments_of(args.macros, i) for i in range(k)]
        with FlopCounterMode(display=False) as counter:
            train_replicates(replicates(segments, 1), device=args.device)
        flops = counter.get_total_flops() / steps_per_epoch(segments)
        train_replicates(replicates(segments, 5), device=args.device)  # warm-up
        start = time.perf_counter()
        train_replicates(replicates(segments, args.epochs), device=args.device)
        step = (time.perf_counter() - start) / (args.epochs * steps_per_epoch(segments))
        rows.append(
            {
                "replicates": k,
                "ms_per_step": 1000 * step,
                "ms_per_replicate_step": 1000 * step / k,
                "mflop_per_step": flops / 1e6,
                "gflop_per_s": flops / step / 1e9,
                "share_of_core": flops / step / core,
            }
        )
    one = rows[0]["ms_per_replicate_step"]
    for row in rows:
        row["per_replicate_vs_one"] = row["ms_per_replicate_step"] / one
        print(
            f"K {row['replicates']:3d}: {row['ms_per_step']:7.2f} ms per step, {row['ms_per_replicate_step']:6.2f} ms "
            f"per replicate ({row['per_replicate_vs_one']:.2f}x K=1), {row['gflop_per_s']:5.1f} GFLOP/s "
            f"= {row['share_of_core']:.0%} of the core"
        )
    write_result(
        out,
        {
            "core_gflop_per_s": core / 1e9,
            "device": args.device,
            "epochs": args.epochs,
            "macros": str(args.macros),
            "rows": rows,
        },
    )
    command = command_line(__file__, parser, args, shown=("macros",))
    for name, entry in records(rows, command, args.device).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
