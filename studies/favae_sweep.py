"""FAVAE quality per beta and seed: reconstruction, length accuracy, MIG, and which latents carry information.

    python studies/favae_sweep.py --script down-and-up [--betas 0.1 1 50] [--seeds 0 1 2] [--epochs 1500]

Reads data/segments/<script>.h5 and data/favae/<script>.calibration.json (make them with `famarl segment` and
`famarl favae calibrate`), fits one FAVAE per beta and seed with that C_last, prints a table and writes JSON.
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from pathlib import Path

import numpy as np
import torch

from famarl_cli.artifacts.segments import read_segments
from famarl_cli.method.favae.checkpoint import read_calibration
from famarl_cli.method.favae.model import FavaeConfig
from famarl_cli.method.favae.training import TrainingParams, evaluate_fit, train_favae


def spread(rows: list[dict], key: str, digits: int) -> str:
    values = [r[key] for r in rows]
    return f"{np.mean(values):.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--script", required=True)
    parser.add_argument("--betas", type=float, nargs="+", default=[0.1, 1.0, 50.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--epochs", type=int, default=1500)
    parser.add_argument("--data", type=Path, default=Path("data"))
    args = parser.parse_args()
    torch.set_num_threads(1)

    segments = read_segments(args.data / "segments" / f"{args.script}.h5")
    config = FavaeConfig(action_dim=segments.action_dim, length=segments.max_length)
    c_last = read_calibration(args.data / "favae" / f"{args.script}.calibration.json", config, TrainingParams())
    rows = []
    for beta in args.betas:
        for seed in args.seeds:
            start = time.perf_counter()
            params = TrainingParams(epochs=args.epochs, seed=seed)
            model, _ = train_favae(segments.padded, config, beta, c_last, params)
            scores = evaluate_fit(model, segments.padded, segments.length, segments.factors)
            active = int(np.sum(np.array(scores["information_per_dim"]) > 0.1))
            rows.append(
                {
                    "script": args.script,
                    "beta": beta,
                    "seed": seed,
                    "active_latents": active,
                    **scores,
                    "seconds": time.perf_counter() - start,
                }
            )
            print(
                f"{args.script} beta {beta:g} seed {seed}: MIG {scores['mig']:.3f} recon "
                f"{scores['reconstruction_mse']:.4f} length {scores['length_accuracy']:.2f} "
                f"active {active} ({rows[-1]['seconds']:.0f} s)",
                flush=True,
            )

    print(f"\n{args.script}: mean (min-max) over seeds {args.seeds}, C_last {np.round(c_last, 2).tolist()}")
    print(f"{'beta':>6} {'MIG':>20} {'recon MSE':>24} {'length accuracy':>20} {'active latents':>16}")
    for beta in args.betas:
        mine = [r for r in rows if r["beta"] == beta]
        cell = functools.partial(spread, mine)
        print(
            f"{beta:>6g} {cell('mig', 3):>20} {cell('reconstruction_mse', 4):>24} "
            f"{cell('length_accuracy', 2):>20} {cell('active_latents', 1):>16}"
        )
    out = Path(__file__).parent / "results" / f"favae_sweep_{args.script}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"c_last": c_last, "epochs": args.epochs, "rows": rows}, indent=1) + "\n")
    print(f"written {out}")


if __name__ == "__main__":
    main()
