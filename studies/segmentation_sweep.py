"""Segmentation quality: boundary F1 of `famarl segment` per expert script, margin and segmenter seed.

    python studies/segmentation_sweep.py [--demos-dir data/demos] [--seeds 0 1 2] [--epochs 300]

Reads the four scripts' demos (make them with `famarl demos --script S`), trains one segmenter per script and
seed, and scores the boundaries at each margin against the experts' true boundaries. Prints a table (F1 within
+-2 steps, mean and spread over seeds, then exact F1) and writes the numbers as JSON.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from famarl_cli.artifacts import read_demos
from famarl_cli.experts.scripts import Environment, Script
from famarl_cli.method.segmentation import (
    AutoencoderConfig,
    SegmentParams,
    TrainingConfig,
    segment_demos,
    train_autoencoder,
)

SCRIPTS = [s for s in Script if s.environment == Environment.CONTINUOUS_WORLD]

MARGINS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--demos-dir", type=Path, default=Path("data/demos"))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--distance", default="euclidean")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    torch.set_num_threads(1)

    rows = []
    for script in SCRIPTS:
        demos = read_demos(args.demos_dir / f"{script.value}.h5")
        actions = [e.actions for e in demos.episodes]
        for seed in args.seeds:
            start = time.perf_counter()
            model, _ = train_autoencoder(actions, AutoencoderConfig(), TrainingConfig(epochs=args.epochs), seed)
            for margin in MARGINS:
                _, metrics = segment_demos(demos, model, SegmentParams(margin=margin, distance=args.distance))
                rows.append(
                    {
                        "script": script.value,
                        "seed": seed,
                        "margin": margin,
                        "f1_within_2": metrics["boundaries_within_2"]["f1"],
                        "precision_within_2": metrics["boundaries_within_2"]["precision"],
                        "recall_within_2": metrics["boundaries_within_2"]["recall"],
                        "f1_exact": metrics["boundaries_exact"]["f1"],
                        "true_boundaries": metrics["boundaries_exact"]["true"],
                        "segments_per_episode": metrics["segments_per_episode"],
                        "offsets_within_2": metrics["boundaries_within_2"]["offsets"],
                    }
                )
            print(f"{script.value} seed {seed}: {time.perf_counter() - start:.1f} s", flush=True)

    print(f"\nboundary F1 within +-2 steps, mean (min-max) over seeds {args.seeds}; distance {args.distance}")
    print(f"{'script':<20}" + "".join(f"{'margin ' + str(m):>20}" for m in MARGINS))
    for script in SCRIPTS:
        cells = []
        for margin in MARGINS:
            f1 = [r["f1_within_2"] for r in rows if r["script"] == script.value and r["margin"] == margin]
            cells.append(f"{np.mean(f1):.2f} ({min(f1):.2f}-{max(f1):.2f})")
        print(f"{script.value:<20}" + "".join(f"{c:>20}" for c in cells))
    args.out = args.out or Path(__file__).parent / "results" / f"segmentation_sweep_{args.distance}.json"
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"epochs": args.epochs, "distance": args.distance, "rows": rows}, indent=1) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
