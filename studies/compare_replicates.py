"""Two sweeps of macro-action replicates side by side, seed by seed: C_last, information per ladder, MIG, length
accuracy and ladder 3's traversal effects; then each score's paired difference (second - first) over the seeds
both hold, its mean with a 95% t-interval. For the same replicates made two ways (batched and one by one, before and
after a change of the code, on two devices).

    python studies/compare_replicates.py A/macros B/macros [--names before after] [--record NAME --what TEXT]

``--record`` writes the paired differences to studies/measured.json as entry NAME (``--what`` says what the two
sweeps are), so that a page can show them.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
from study import record

from famarl_cli.core.statistics import mean_interval


def replicate(folder: Path) -> dict:
    metrics = json.loads((folder / "favae.metrics.json").read_text())
    effects = json.loads((folder / "traverse.json").read_text())["effects_m"]
    return {
        "C_last": metrics["c_last"],
        "information": metrics["information_per_ladder"],
        "MIG": metrics["mig"],
        "length accuracy": metrics["length_accuracy"],
        "length within one": metrics["length_within_one"],
        "reconstruction MSE": metrics["reconstruction_mse"],
        "(3,1) m": effects.get("(3,1)"),
        "(3,2) m": effects.get("(3,2)"),
        # which of ladder 3's latents takes the direction is arbitrary: the larger effect is the one that compares
        "ladder 3's larger m": max((v for k, v in effects.items() if k.startswith("(3,")), default=None),
        "segments": metrics["segments"],
    }


def seeds(sweep: Path) -> dict[int, dict]:
    found = {}
    for folder in sweep.iterdir():
        match = re.fullmatch(r"seed(\d+)", folder.name)
        if match and (folder / "traverse.json").is_file():
            found[int(match[1])] = replicate(folder)
    return found


def shown(value) -> str:
    if isinstance(value, list):
        return " / ".join(f"{v:.2f}" for v in value)
    return f"{value:.3f}" if isinstance(value, float) else str(value)


def largest_difference(a, b) -> float:
    if isinstance(a, list):
        return max(abs(x - y) for x, y in zip(a, b, strict=True))
    return abs(a - b) if isinstance(a, float) else float(a != b)


def paired(a: dict[int, dict], b: dict[int, dict], shared: list[int]) -> dict[str, str]:
    """Each scalar score's (a ladder's, for scores per ladder) paired difference b - a over ``shared``: mean [95%
    t-interval]."""
    result = {}
    for key, value in a[shared[0]].items():
        if key == "segments" or value is None:
            continue
        parts = range(len(value)) if isinstance(value, list) else [None]
        for part in parts:
            differences = [
                (b[s][key] if part is None else b[s][key][part]) - (a[s][key] if part is None else a[s][key][part])
                for s in shared
            ]
            name = key if part is None else f"{key} {part + 1}"
            result[name] = mean_interval(np.asarray(differences)).text("{:+.3f}")
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    parser.add_argument("--names", nargs=2, default=["first", "second"])
    parser.add_argument("--record", default=None, help="write the paired differences to measured.json as this entry")
    parser.add_argument("--what", default="", help="with --record: what the two sweeps are")
    parser.add_argument("--command", default="", help="with --record: the commands that made the two sweeps")
    args = parser.parse_args()
    a, b = seeds(args.first), seeds(args.second)
    shared = sorted(set(a) & set(b))
    if not shared:
        raise SystemExit(f"error: no seed has a finished replicate in both {args.first} and {args.second}")
    keys = list(a[shared[0]])
    print("| seed | " + " | ".join(f"{key}: {args.names[0]} -> {args.names[1]}" for key in keys) + " |")
    print("|---" * (len(keys) + 1) + "|")
    for seed in shared:
        cells = [f"{shown(a[seed][key])} -> {shown(b[seed][key])}" for key in keys]
        print(f"| {seed} | " + " | ".join(cells) + " |")
    print("\nlargest difference over the seeds: " + ", ".join(
        f"{key} {max(largest_difference(a[s][key], b[s][key]) for s in shared):.3g}" for key in keys
    ))  # fmt: skip
    differences = paired(a, b, shared)
    print(f"\npaired difference {args.names[1]} - {args.names[0]}, mean [95% t-interval], n = {len(shared)}:")
    for name, text in differences.items():
        print(f"  {name}: {text}")
    if args.record:
        record(
            args.record,
            what=args.what or f"{args.names[1]} against {args.names[0]}, paired by replicate",
            command=args.command or f"python studies/compare_replicates.py {args.first} {args.second}",
            measured=f"n = {len(shared)} replicates, paired difference {args.names[1]} - {args.names[0]}, mean [95% "
            "t-interval]: " + "; ".join(f"{name} {text}" for name, text in differences.items()),
        )


if __name__ == "__main__":
    main()
