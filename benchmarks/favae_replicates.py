"""Time per step of K FAVAE replicates fitted as one batched model, and its arithmetic rate against the device's.

    python benchmarks/favae_replicates.py [--replicates 1,2,5,10] [--epochs 60] [--macros data/maze/macros]
                                          [--device cpu|cuda] [--no-graph]

A step is what the lockstep fit does per batch (the default pipeline's fit: batch 64, progressive, information
capacities): K batches, one per replicate, the orders and noise drawn, forward with sampling, the loss, backward and
the replicates' Adam. Each K fits the segments of replicates 0..K-1 of a default-pipeline sweep (``--macros``; random
segments of the same shape for the replicates it lacks), one torch thread. The step time is the wall of ``--epochs``
epochs over their steps, after two epochs of warm-up (on a GPU: the first run eagerly, the second captured as a CUDA
graph and replayed; ``--no-graph`` runs every epoch eagerly), so the models' set-up is not in it. The FLOPs of a step
are torch's FLOP counter's (matmuls, forward and backward; elementwise work is not counted), so the rate is a lower
bound; the device's rate is a 2048 x 2048 ``torch.mm`` on it. Also per replicate: the step time over K against K = 1.
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
from famarl_cli.method.favae.training import Replicate, TrainingParams, lockstep
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


def step_seconds(segments: list[np.ndarray], epochs: int, device: str, graph: bool) -> float:
    """The wall of a step of the lockstep fit of ``segments``' replicates, after two epochs of warm-up."""
    fit = lockstep(replicates(segments, epochs + 2), device, graph)
    fit.run(2)
    wait(device)
    start = time.perf_counter()
    fit.run(epochs)
    wait(device)
    return (time.perf_counter() - start) / (epochs * len(fit.plan))


def step_flops(segments: list[np.ndarray], device: str) -> float:
    fit = lockstep(replicates(segments, 1), device, graph=False)
    with FlopCounterMode(display=False) as counter:
        fit.run(1)
    return counter.get_total_flops() / len(fit.plan)


def records(rows: list[dict], command: str, device: str, graph: bool) -> dict[str, dict]:
    """measured.json's entry: the step time per K (and per replicate on the CPU), and the range of the device's
    rate reached."""
    shares = [row["share_of_core"] for row in rows]
    ks = " / ".join(str(row["replicates"]) for row in rows)
    if device == "cpu":
        return {
            "favae_replicates": {
                "what": f"a FAVAE optimiser step per replicate, K = {ks} replicates in one process",
                "command": command,
                "measured": " / ".join(f"{row['ms_per_replicate_step']:.1f}" for row in rows)
                + f" ms; {100 * min(shares):.0f}-{100 * max(shares):.0f}% of the core's `torch.mm` rate"
                + verdict(max(shares) >= 0.5),
                "target": ">= 50%",
                **numbers(rows, "ms_per_replicate_step"),
            }
        }
    steps = {row["replicates"]: row["ms_per_step"] for row in rows}
    goals = {10: 2.0, 1000: 40.0}
    met = [steps[k] <= goal for k, goal in goals.items() if k in steps]
    return {
        f"favae_replicates_{device}{'' if graph else '_eager'}": {
            "what": f"a FAVAE optimiser step of K = {ks} replicates in one process on {device}"
            + ("" if graph else ", every epoch launched op by op (no CUDA graph)"),
            "command": command,
            "measured": " / ".join(f"{row['ms_per_step']:.2f}" for row in rows)
            + f" ms a step; {100 * min(shares):.2g}-{100 * max(shares):.2g}% of the device's `torch.mm` rate"
            + (verdict(all(met)) if met and graph else ""),
            "target": "K = 10 <= 2 ms, K = 1000 <= 40 ms" if graph else "",
            **numbers(rows, "ms_per_step"),
        }
    }


def numbers(rows: list[dict], time: str) -> dict:
    """A record's numbers: each K's time (``time``, ms) and the least and most of the device's rate reached (%)."""
    values = {f"k{row['replicates']}": row[time] for row in rows}
    shares = [100 * row["share_of_core"] for row in rows]
    return {
        "values": {**values, "share_min": min(shares), "share_max": max(shares)},
        "unit": {**dict.fromkeys(values, "ms"), "share_min": "%", "share_max": "%"},
        "better": {"share_min": "higher", "share_max": "higher"},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replicates", default="1,2,5,10")
    parser.add_argument("--epochs", type=int, default=60)
    parser.add_argument("--macros", type=Path, default=Path("data/maze/macros"))
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
    parser.add_argument("--no-graph", action="store_true", help="on a GPU, launch every epoch op by op")
    parser.add_argument("--out", type=Path, default=None, help="[default: results/favae_replicates[_cuda].json]")
    args = parser.parse_args()
    suffix = "" if args.device == "cpu" else f"_{args.device}" + ("_eager" if args.no_graph else "")
    out = args.out or RESULTS / f"favae_replicates{suffix}.json"
    if args.device == "cuda" and not torch.cuda.is_available():
        raise SystemExit("error: --device cuda: torch sees no CUDA GPU here")
    torch.set_num_threads(1)
    core = mm_rate(args.device)
    print(f"torch.mm 2048 x 2048 on {args.device} (one thread): {core / 1e9:.1f} GFLOP/s")
    rows = []
    for k in map(int, parse_values(args.replicates)):
        segments = [segments_of(args.macros, i) for i in range(k)]
        flops = step_flops(segments, args.device)
        step = step_seconds(segments, args.epochs, args.device, not args.no_graph)
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
        print(
            f"K {k:4d}: {1000 * step:8.3f} ms per step, {1000 * step / k:7.3f} ms per replicate, "
            f"{flops / 1e6:9.1f} MFLOP, {flops / step / 1e9:7.1f} GFLOP/s = {flops / step / core:.1%} of the device",
            flush=True,
        )
    one = rows[0]["ms_per_replicate_step"]
    for row in rows:
        row["per_replicate_vs_one"] = row["ms_per_replicate_step"] / one
    write_result(
        out,
        {
            "core_gflop_per_s": core / 1e9,
            "device": args.device,
            "graph": not args.no_graph,
            "epochs": args.epochs,
            "macros": str(args.macros),
            "rows": rows,
        },
    )
    command = command_line(__file__, parser, args, shown=("macros",))
    for name, entry in records(rows, command, args.device, not args.no_graph).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
