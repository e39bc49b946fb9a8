"""Two sweeps of macro-action replicates side by side, seed by seed: C_last, information per ladder, MIG, length
accuracy and ladder 3's traversal effects. For the same replicates made two ways (batched and one by one, or
before and after a change of the code).

    python benchmarks/compare_replicates.py A/macros B/macros [--names before after]
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path


def replicate(folder: Path) -> dict:
    metrics = json.loads((folder / "favae.metrics.json").read_text())
    effects = json.loads((folder / "traverse.json").read_text())["effects_m"]
    return {
        "C_last": metrics["c_last"],
        "information": metrics["information_per_ladder"],
        "MIG": metrics["mig"],
        "length accuracy": metrics["length_accuracy"],
        "(3,1) m": effects.get("(3,1)"),
        "(3,2) m": effects.get("(3,2)"),
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    parser.add_argument("--names", nargs=2, default=["first", "second"])
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


if __name__ == "__main__":
    main()
